"""Train, evaluate and package the bundled Action2Motion model on Bandai-Namco-2.

    python bench/train_a2m.py --data "$(../shared/data/unpack)" [--resume]

Same held-out split as ODMO (bench/heldout.py: 15 % of the clips per action × style, seed 2022): the
model trains on the rest (10 % of which is its internal validation set) and is evaluated on the held-out
clips with ``engine.metrics.a2m_eval`` and the bundled ODMO model's classifier, so its figures compare
with bandai2-odmo's. ``--pose-rep joints`` trains the paper's "w/o Lie" ablation at the same settings.
Resumable (``--resume``); one torch thread by default. The model folder gets MODEL_CARD.md, the data's
LICENSE (CC BY-NC 4.0) and heldout_clips.txt.
"""

from __future__ import annotations

import argparse
import json
import platform
import shutil
import sys
import time
from collections.abc import Sequence
from functools import partial
from pathlib import Path
from typing import Any

import torch

if __package__ in (None, ""):
    sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from bench.heldout import HELDOUT_FRACTION, SPLIT_SEED, heldout_split
from bench.model_card import METRICS, cell, per_action_table, physics_targets, repo_path, training_command
from bench.warm_start import warm_start_from, warm_start_line
from engine.fileio import atomic_write_text
from engine.generators.a2m import load_a2m
from engine.metrics.a2m_eval import evaluate_a2m, prior_accuracy
from engine.metrics.classifier import META_FILE, Classifier, load_classifier, train_classifier
from engine.model.a2m import A2mConfig
from engine.motion.datasets import load_folder
from engine.motion.motion import Motion
from engine.train.a2m_loop import train_a2m

ROOT = Path(__file__).resolve().parents[1]
DEFAULT_OUT = ROOT / "resources" / "models" / "bandai2-a2m"
CLASSIFIER = ROOT / "resources" / "models" / "bandai2-odmo" / "classifier"
SHIPPED = ("model.safetensors", "model.json", "latent_bank.npz", "train_log.csv")
SELECT_CLASSIFIER = "select_classifier"  # --work subfolder of the classifier that scores checkpoints


def parse_args() -> argparse.Namespace:
    """Command-line options."""
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--data", required=True, type=Path)
    p.add_argument("--out", type=Path, default=DEFAULT_OUT)
    p.add_argument("--work", type=Path, default=Path("runs/bandai2-a2m"), help="checkpoints and logs")
    p.add_argument("--pose-rep", default="lie", choices=("lie", "joints"))
    p.add_argument("--epochs", type=int, default=100)
    p.add_argument("--lr", type=float, default=1e-3)
    p.add_argument("--lr-floor", type=float, default=1.0, help="cosine learning-rate floor (1: constant)")
    p.add_argument(
        "--warm-start", type=Path, help="start from this A2M model folder's weights (trained on this split)"
    )
    p.add_argument(
        "--select",
        action="store_true",
        help="keep the checkpoint whose prior samples (--select-samples) the classifier reads best",
    )
    p.add_argument("--select-samples", type=int, default=50, help="prior samples per action scoring an epoch")
    p.add_argument("--checkpoint-every", type=int, default=10, help="epochs between checkpoints (and scores)")
    p.add_argument("--kl-weight", type=float, default=0.001)
    p.add_argument("--trajectory-weight", type=float, default=0.8)
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--repeats", type=int, default=10)
    p.add_argument("--n-per-action", type=int, default=50)
    p.add_argument("--classifier", type=Path, default=CLASSIFIER)
    p.add_argument("--device", default="cpu")
    p.add_argument("--threads", type=int, default=1, help="torch CPU threads")
    p.add_argument("--resume", action="store_true")
    p.add_argument("--skip-train", action="store_true", help="reuse the trained model in --work")
    p.add_argument("--no-package", action="store_true", help="evaluate only; do not write --out")
    p.add_argument("--reuse-eval", action="store_true", help="reuse --work/eval.json for the card")
    return p.parse_args()


def main() -> int:
    """Train, evaluate and package."""
    args = parse_args()
    torch.set_num_threads(args.threads)
    dataset = load_folder(args.data)
    train_clips, test_clips = heldout_split(dataset.clips)
    names = list(dataset.action_names)
    config = A2mConfig(
        n_actions=len(names),
        n_joints=dataset.skeleton.n_joints,
        pose_rep=args.pose_rep,
        epochs=args.epochs,
        lr=args.lr,
        lr_floor=args.lr_floor,
        kl_weight=args.kl_weight,
        trajectory_weight=args.trajectory_weight,
    )
    work = args.work
    if not args.skip_train:

        def show(p) -> None:
            if p.stage == "train" and p.step == p.steps:
                losses = " ".join(f"{k} {v:.4g}" for k, v in p.losses.items())
                print(f"epoch {p.epoch}/{p.epochs} {losses} eta {p.eta_s / 60:.0f} min", flush=True)

        start = None if args.warm_start is None else warm_start_from(args.warm_start, test_clips, load_a2m)
        select, chooser = None, None
        if args.select:
            evaluation = load_classifier(args.classifier)
            judge = selection_classifier(work, train_clips, names, evaluation, args.seed)
            chooser = {"samples": args.select_samples, "classifier_accuracy": judge.test_accuracy}
            select = partial(
                prior_accuracy, skeleton=dataset.skeleton, action_names=names,
                classifier=judge, n_per_action=args.select_samples, seed=args.seed,
            )  # fmt: skip
        result = train_a2m(
            train_clips,
            names,
            work,
            config,
            seed=args.seed,
            device=args.device,
            resume=args.resume,
            progress=show,
            warm_start=start,
            select=select,
            checkpoint_every=args.checkpoint_every,
        )
        summary = {
            "train_seconds": result.train_seconds,
            "windows_per_s": result.windows_per_s,
            "n_train": result.n_train,
            "n_val": result.n_val,
            "torch_threads": torch.get_num_threads(),
            "select": chooser,
        }
        atomic_write_text(work / "train_summary.json", json.dumps(summary, indent=2))
    summary = json.loads((work / "train_summary.json").read_text())
    if args.reuse_eval and (work / "eval.json").is_file():
        report = json.loads((work / "eval.json").read_text())
    else:
        started = time.time()
        evaluation = {"repeats": args.repeats, "n_per_action": args.n_per_action, "seed": args.seed}
        report = evaluate_a2m(load_a2m(work), test_clips, load_classifier(args.classifier), **evaluation)
        report["meta"]["eval_seconds"] = time.time() - started
        atomic_write_text(work / "eval.json", json.dumps(report, indent=2))
    gen, real = report["generated"], report["real"]
    print(f"accuracy {gen['accuracy']['mean']:.3f} (real {real['accuracy']['mean']:.3f})")
    print(f"FID {gen['fid']['mean']:.2f}")
    if args.no_package:
        return 0
    out = args.out
    out.mkdir(parents=True, exist_ok=True)
    for name in SHIPPED:
        shutil.copy2(work / name, out / name)
    shutil.copy2(args.data / "LICENSE", out / "LICENSE")  # the data's CC BY-NC 4.0, which the model inherits
    heldout = sorted(str(Path(c.meta["source"]).name) for c in test_clips)
    atomic_write_text(out / "heldout_clips.txt", "\n".join(heldout) + "\n")
    shipped = report | {
        "meta": report["meta"] | {"model": out.name, "classifier": repo_path(args.classifier)}
    }
    atomic_write_text(out / "eval.json", json.dumps(shipped, indent=2))  # no machine paths in what ships
    trained = load_a2m(work)
    summary["windows_seen"] = trained.provenance["windows_seen"]
    summary["warm_start"] = trained.provenance.get("warm_start")
    summary["selected_epoch"] = trained.provenance.get("selected_epoch")
    command = training_command("bench/train_a2m.py", work, sys.argv[1:], trained=not args.skip_train)
    card = model_card(report, trained.config, summary, command, len(test_clips), dataset.fingerprint)
    atomic_write_text(out / "MODEL_CARD.md", card)
    return 0


def model_card(
    report: dict[str, Any],
    config: A2mConfig,
    summary: dict[str, Any],
    command: str,
    n_heldout: int,
    fingerprint: str,
) -> str:
    """MODEL_CARD.md from the evaluation report and the training summary (never typed by hand)."""
    gen, real = report["generated"], report["real"]
    acc_gap = real["accuracy"]["mean"] - gen["accuracy"]["mean"]
    fid = gen["fid"]["mean"]
    rows = ["| metric | real (held-out) | Action2Motion (generated) |", "|---|---|---|"]
    labels = dict(METRICS)
    for key in [k for k, _ in METRICS] + sorted(set(gen) - set(labels)):
        if key in real or key in gen:
            rows.append(f"| {labels.get(key, key)} | {cell(real, key)} | {cell(gen, key)} |")
    windows = summary.get("windows_seen", config.epochs * config.epoch_size)
    rep = (
        "so(3) joint rotations + root translation through forward kinematics"
        if config.pose_rep == "lie"
        else 'joint positions (the paper\'s "w/o Lie" ablation)'
    )
    meta = report["meta"]
    lines = [
        "# bandai2-a2m: Action2Motion on Bandai-Namco-2",
        "",
        "Generated by `bench/train_a2m.py` from its evaluation report; do not edit by hand.",
        "",
        "Action2Motion (Guo et al. 2020, *Action2Motion: Conditioned Generation of 3D Human Motions*):",
        "a per-frame conditional temporal VAE with a learned prior GRU, a posterior GRU and a 2-layer",
        f"generator GRU, the time counter c_t = t/T and teacher forcing; poses are {rep} on the data's",
        "fixed skeleton.",
        "Its map codes are the principal components of each training clip's posterior-mean sequence",
        "z_1..z_T; its modes come from the same GMM procedure as ODMO's bank.",
        "",
        "## Data and licence",
        "",
        "Bandai Namco Research Inc., *Bandai-Namco-Research-Motiondataset* (dataset 2), 2022, "
        "**CC BY-NC 4.0** (LICENSE, copied from the dataset): 10 actions × 7 styles, 2,902 BVH clips at "
        "30 fps. The model and its latent bank are derived from this data and inherit the "
        "**non-commercial** term; keep the attribution wherever they ship.",
        "",
        "## Quality targets (held-out clips)",
        "",
        f"- Recognition accuracy within 8 points of real: {gen['accuracy']['mean']:.3f} against real "
        f"{real['accuracy']['mean']:.3f}, {acc_gap * 100:.1f} points below — "
        + ("met." if acc_gap <= 0.08 else "**not met**."),
        f"- FID ≤ 3: {fid:.2f} — " + ("met." if fid <= 3 else "**not met**."),
        *physics_targets(report),
        "",
        "## Evaluation",
        "",
        f"{n_heldout} held-out clips ({HELDOUT_FRACTION:.0%} of the clips per action × style, "
        f"seed {SPLIT_SEED}; the same split and evaluation as bandai2-odmo, `engine.metrics.a2m_eval`); "
        f"{meta['repeats']} repeats of {meta['n_per_action']} motions per action sampled from the learned "
        f"prior; the classifier of bandai2-odmo (accuracy {meta['classifier_test_accuracy']:.3f} on its "
        "test windows). Mean ± 95 % interval over the repeats.",
        "",
        *rows,
        "",
        *per_action_table(report),
        "",
        "## Training",
        "",
        f"- Command: `{command}`",
        f"- Budget: {config.epochs} epochs × {config.epoch_size:,} class-balanced windows "
        f"({windows:,} windows, {config.epochs * -(-config.epoch_size // config.batch_size):,} Adam steps of "
        f"batch {config.batch_size}) in {summary['train_seconds'] / 60:.0f} min of CPU training on "
        f"{summary['torch_threads']} torch thread ({platform.processor() or platform.machine()}, a machine "
        "shared with other jobs).",
        *warm_start_line(summary.get("warm_start")),
        *selected_line(summary.get("selected_epoch"), config.epochs, summary.get("select")),
        f"- Settings: hidden {config.hidden}, z {config.latent_dim} per frame, {config.gen_layers}-layer "
        f"generator GRU, window {config.window} frames at {config.fps:g} fps; λ_KL {config.kl_weight:g}, "
        f"λ_trajec {config.trajectory_weight:g} (the released HumanAct12 configuration; the paper's "
        f"text says λ = 0.01), teacher forcing p {config.tf_rate:g} per batch, Adam lr {config.lr:g} "
        f"(the paper's 2e-4 raised for the CPU budget{lr_decay(config)}), weight decay "
        f"{config.weight_decay:g}; code space {config.code_dim}-d.",
        f"- Data: Bandai-Namco-Research-Motiondataset-2, {summary['n_train']} training and "
        f"{summary['n_val']} validation clips (the held-out clips are never seen); prepared-data "
        f"fingerprint `{fingerprint[:16]}`.",
        "",
        "## Use",
        "",
        "`odmo sample --model resources/models/bandai2-a2m --action walk --n 4 --out walk.bvh`; in Python",
        "`open_generator(path)` (`engine.generators`), whose `sample`, `decode` and `interpolate` work in",
        "its code space, and `generate_a2m(..., bone_scale=...)` scales the skeleton's bones (the paper's",
        "body-shape control).",
        "",
    ]
    return "\n".join(lines)


def selection_classifier(
    work: Path, clips: Sequence[Motion], names: list[str], evaluation: Classifier, seed: int
) -> Classifier:
    """The classifier that scores checkpoints for ``--select``: trained once into ``work`` on the training
    ``clips`` alone, with the ``evaluation`` classifier's settings but the next seed (its own weights and
    validation clips), so the evaluation's classifier does not choose the epoch it then reads."""
    folder = work / SELECT_CLASSIFIER
    if not (folder / META_FILE).is_file():
        c = evaluation.config
        train_classifier(
            clips, names, folder, window=c.window, fps=c.fps, epochs=c.epochs, batch_size=c.batch_size,
            stride=c.stride, lr_floor=c.lr_floor, seed=seed + 1,
        )  # fmt: skip
    return load_classifier(folder)


def selected_line(epoch: int | None, epochs: int, chooser: dict[str, Any] | None) -> list[str]:
    """The card's line on the epoch chosen by the prior's samples, if the run chose one."""
    if epoch is None or chooser is None:
        return []
    return [
        f"- Weights of epoch {epoch} of {epochs}: the checkpoint whose {chooser['samples']} prior samples "
        "per action a selection classifier of the run's own read best (the evaluation classifier's settings "
        "and another seed, trained on the training clips; accuracy "
        f"{chooser['classifier_accuracy']:.3f} on its validation windows). Neither a held-out clip nor the "
        "evaluation's classifier chooses the epoch."
    ]


def lr_decay(config: A2mConfig) -> str:
    """How the learning rate falls, for the card (nothing when it is constant)."""
    return "" if config.lr_floor >= 1 else f", falling along a cosine to {config.lr * config.lr_floor:g}"


if __name__ == "__main__":
    sys.exit(main())
