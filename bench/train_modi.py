"""Train, evaluate and package the bundled MoDi model on Bandai-Namco-2.

    python bench/train_modi.py --data "$(../shared/data/unpack)" --epochs 40 [--from-run DIR]

Trains ``engine.train.modi_loop.train_modi`` on the training part of the held-out split every model of
docs/RESULTS.md uses (bench/heldout.py; ``--split all``: on every clip, keeping only its own 10 %
validation clips unseen), resuming from --work (or from the checkpoint of another run of the same
settings, --from-run), then writes the model folder with a bank of inverted clips (--bank-per-label per
action) and labelled prior samples. It is evaluated (``engine.metrics.modi_eval``) on the clips the
generator and its critic never trained on, with the bundled ODMO model's classifier; the card reports
every figure.
"""

from __future__ import annotations

import argparse
import json
import platform
import shutil
import sys
import time
from pathlib import Path
from typing import Any

import numpy as np
import torch

if __package__ in (None, ""):
    sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from bench.heldout import HELDOUT_FRACTION, SPLIT_SEED, heldout_split
from bench.model_card import (
    METRICS,
    cell,
    licence_lines,
    per_action_table,
    physics_targets,
    repo_path,
    training_argv,
    training_command,
)
from engine.fileio import atomic_write_text
from engine.generators import open_generator
from engine.generators.modi import ModiGenerator
from engine.metrics.classifier import load_classifier
from engine.metrics.modi_eval import evaluate_modi
from engine.model.modi import ModiConfig
from engine.motion.datasets import load_folder
from engine.motion.motion import Motion
from engine.train.epochs import TrainProgress
from engine.train.modi_loop import train_modi
from engine.train.modi_steps import ClipFeatures, clip_features
from engine.train.windows import PreparedClips, prepare_clips

ROOT = Path(__file__).resolve().parents[1]
DEFAULT_OUT = ROOT / "resources" / "models" / "bandai2-modi"
CLASSIFIER = ROOT / "resources" / "models" / "bandai2-odmo" / "classifier"
SHIPPED = ("model.safetensors", "model.json", "latent_bank.npz", "train_log.csv")
UNCONDITIONAL = (
    ("kid", "KID (classifier features)"),
    ("precision", "Precision (k = 3)"),
    ("recall", "Recall (k = 3)"),
    ("action_kl", "KL(real ‖ generated) of predicted actions"),
    ("inversion_error_m", "W+ inversion error of held-out clips (m)"),
)


def parse_args(argv: list[str] | None = None) -> argparse.Namespace:
    """Command-line options (``argv``; None: the process's)."""
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--data", required=True, type=Path)
    p.add_argument("--out", type=Path, default=DEFAULT_OUT)
    p.add_argument("--work", type=Path, default=Path("runs/bandai2-modi"), help="checkpoints and logs")
    p.add_argument("--from-run", type=Path, help="start from this run's checkpoint (same settings)")
    p.add_argument("--epochs", type=int, default=40, help="epochs of 2,048 windows (128 steps)")
    p.add_argument("--split", choices=("heldout", "all"), default="heldout", help="the clips it trains on")
    p.add_argument("--classifier", type=Path, default=CLASSIFIER)
    p.add_argument("--bank-per-label", type=int, default=30, help="clips inverted per action for the bank")
    p.add_argument("--bank-samples", type=int, default=2000, help="prior samples in the bank")
    p.add_argument("--bank-steps", type=int, default=200, help="inversion steps of a bank clip")
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--repeats", type=int, default=10)
    p.add_argument("--n-per-action", type=int, default=50)
    p.add_argument("--threads", type=int, default=1, help="torch CPU threads")
    p.add_argument("--reuse-eval", action="store_true", help="reuse --work/eval.json for the card")
    p.add_argument("--skip-train", action="store_true", help="package the model and bank already in --work")
    return p.parse_args(argv)


def cached_features(work: Path, prepared: PreparedClips) -> ClipFeatures:
    """The clips' inverse-kinematics features, computed once per prepared data and kept in ``work``."""
    cache = work / f"features-{prepared.fingerprint()[:16]}.npz"
    if cache.is_file():
        z = np.load(cache)
        n = prepared.n_clips
        return ClipFeatures(*([z[f"{k}{i}"] for i in range(n)] for k in ("r", "p", "c")))
    found = clip_features(prepared)
    parts = zip("rpc", (found.rotations, found.root, found.contacts), strict=True)
    arrays = {f"{k}{i}": v for k, part in parts for i, v in enumerate(part)}
    np.savez(cache, **arrays)
    return found


def main() -> int:
    """Train (resuming), build the bank, evaluate, write the card and package the folder."""
    args = parse_args()
    torch.set_num_threads(args.threads)
    work = args.work
    work.mkdir(parents=True, exist_ok=True)
    if args.from_run is not None and not (work / "checkpoints" / "last.pt").is_file():
        (work / "checkpoints").mkdir(exist_ok=True)
        shutil.copy2(args.from_run / "checkpoints" / "last.pt", work / "checkpoints" / "last.pt")
        shutil.copy2(args.from_run / "train_log.csv", work / "train_log.csv")
        for cache in args.from_run.glob("features-*.npz"):
            shutil.copy2(cache, work / cache.name)
    dataset = load_folder(args.data)
    clips = dataset.clips if args.split == "all" else heldout_split(dataset.clips)[0]
    names = dataset.action_names
    config = ModiConfig(n_joints=dataset.skeleton.n_joints, n_actions=len(names), epochs=args.epochs)
    prepared = prepare_clips(clips, names, config.fps, config.window)
    classifier = load_classifier(args.classifier)

    def show(p: TrainProgress) -> None:
        if p.stage == "train" and p.step == p.steps:
            losses = " ".join(f"{k} {v:.4g}" for k, v in p.losses.items())
            print(f"epoch {p.epoch}/{p.epochs} {losses} eta {p.eta_s / 60:.0f} min", flush=True)

    if not args.skip_train:
        train_modi(
            clips, names, work, config, seed=args.seed, device="cpu", resume=True, progress=show,
            clip_features=cached_features(work, prepared), classifier=classifier,
            bank_samples=args.bank_samples, bank_per_label=args.bank_per_label, bank_steps=args.bank_steps,
        )  # fmt: skip
    generator = open_generator(work)
    made = generator.loaded.provenance
    summary = {k: made[k] for k in ("train_seconds", "n_train", "n_val")}
    trained = set(generator.loaded.provenance["train_sources"])
    held = (
        heldout_split(dataset.clips)[1]
        if args.split == "heldout"
        else [c for c in dataset.clips if str(c.meta["source"]) not in trained]
    )
    if args.reuse_eval and (work / "eval.json").is_file():
        report = json.loads((work / "eval.json").read_text())
    else:
        started = time.time()
        options = {"repeats": args.repeats, "n_per_action": args.n_per_action, "seed": args.seed}
        report = evaluate_modi(generator, held, classifier, **options)
        report["meta"]["eval_seconds"] = time.time() - started
        atomic_write_text(work / "eval.json", json.dumps(report, indent=2))
    gen = report["generated"]
    print(f"FID {gen['fid']['mean']:.2f} precision {gen['precision']['mean']:.2f} recall "
          f"{gen['recall']['mean']:.2f} action KL {gen['action_kl']['mean']:.3f}")  # fmt: skip
    out = args.out
    out.mkdir(parents=True, exist_ok=True)
    for name in SHIPPED:
        shutil.copy2(work / name, out / name)
    shutil.copy2(args.data / "LICENSE", out / "LICENSE")  # the data's CC BY-NC 4.0, which the model inherits
    heldout = sorted(str(Path(c.meta["source"]).name) for c in held)
    atomic_write_text(out / "heldout_clips.txt", "\n".join(heldout) + "\n")
    meta = report["meta"] | {"model": out.name, "classifier": repo_path(args.classifier), "split": args.split}
    atomic_write_text(out / "eval.json", json.dumps(report | {"meta": meta}, indent=2))
    edits_path = out / "edits.json"
    edits = json.loads(edits_path.read_text()) if edits_path.is_file() else None
    command = training_command("bench/train_modi.py", work, sys.argv[1:], trained=not args.skip_train)
    summary["torch_threads"] = parse_args(training_argv(work, sys.argv[1:], trained=False)).threads
    card = model_card(report, generator, summary, command, held, prepared.fingerprint(), args.split, edits)
    atomic_write_text(out / "MODEL_CARD.md", card)
    return 0


EDIT_RAISED, EDIT_KEPT = 0.8, 0.9  # the shares of edits that raise the style / keep the action


def edit_targets(edits: dict[str, Any] | None) -> list[str]:
    """The card's style-edit lines: each edit's shares, and whether elderly and two others pass."""
    if edits is None:
        return ["- Style edits: not measured (run bench/modi_edits.py into the folder's edits.json)."]
    passed = {e["target"]: e["raised"] >= EDIT_RAISED and e["kept"] >= EDIT_KEPT for e in edits["edits"]}
    ok = passed.get("elderly", False) and sum(passed.values()) >= 3
    shares = "; ".join(
        f"{e['target']} raised {e['raised']:.0%}, action kept {e['kept']:.0%}" for e in edits["edits"]
    )
    return [
        f"- Style edits {edits['source_style']} → style (amount {edits['amount']:g}, {edits['n_codes']} "
        f"inverted clips; a style classifier of held-out accuracy {edits['style_classifier_accuracy']:.3f}, "
        f"bench/modi_edits.py): {shares}. Elderly and two others at ≥ {EDIT_RAISED:.0%} raised and "
        f"≥ {EDIT_KEPT:.0%} kept — {_met(ok)}",
    ]


def _met(ok: bool) -> str:
    return "met." if ok else "**not met**."


def model_card(
    report: dict[str, Any],
    generator: ModiGenerator,
    summary: dict[str, Any],
    command: str,
    held: list[Motion],
    fingerprint: str,
    split: str,
    edits: dict[str, Any] | None = None,
) -> str:
    """MODEL_CARD.md from the evaluation report, the training summary and ``edits`` (the report of
    bench/modi_edits.py, when the folder has one); never typed by hand."""
    gen, real = report["generated"], report["real"]
    config: ModiConfig = generator.loaded.config
    provenance = generator.loaded.provenance
    labels = dict(METRICS) | dict(UNCONDITIONAL)
    keys = ["fid", *[k for k, _ in UNCONDITIONAL], *[k for k, _ in METRICS if k != "fid"]]
    rows = ["| metric | real (held-out) | MoDi (generated) |", "|---|---|---|"]
    rows += [
        f"| {labels.get(k, k)} | {cell(real, k)} | {cell(gen, k)} |" for k in keys if k in real or k in gen
    ]
    shares = {a: row["generated"].get("predicted_share", {}).get("mean", 0.0)
              for a, row in report["per_action"].items()}  # fmt: skip
    share_rows = ["| action | share of samples |", "|---|---|"]
    share_rows += [f"| {a} | {v:.1%} |" for a, v in shares.items()]
    fid, p, r, kl = (gen[k]["mean"] for k in ("fid", "precision", "recall", "action_kl"))
    inversion = gen.get("inversion_error_m", {}).get("mean", float("nan"))
    params = sum(t.numel() for t in generator.loaded.model.parameters())
    steps = provenance.get("steps", config.epochs * -(-config.epoch_size // config.batch_size))
    meta = report["meta"]
    lines = [
        "# bandai2-modi: MoDi on Bandai-Namco-2",
        "",
        "Generated by `bench/train_modi.py` from its evaluation report; do not edit by hand.",
        "",
        "MoDi (Raab et al. 2023, *MoDi: Unconditional Motion Synthesis from Diverse Data*), re-implemented",
        "for two CPU cores: a skeleton-aware StyleGAN2 generator (mapping network z → w, modulated",
        "skeletal convolutions on a hierarchy of pooled skeletons built from the parents array, per-level",
        "noise) of per-joint 6D rotations, the root displacement and foot contacts, decoded by forward",
        "kinematics on the data's fixed skeleton; a skeleton-aware critic; non-saturating loss with lazy",
        "R1 and the foot-contact losses. Unconditional: its bank labels codes by action only to colour",
        "the map (inverted clips by their own label, prior samples by the classifier).",
        "",
        *licence_lines(),
        "",
        "## Quality targets (held-out clips)",
        "",
        f"- FID ≤ 1.0: {fid:.2f} (real vs real {real['fid']['mean']:.3f}) — {_met(fid <= 1.0)}",
        f"- Precision ≥ 0.6 and recall ≥ 0.5: {p:.2f} and {r:.2f} — {_met(p >= 0.6 and r >= 0.5)}",
        f"- Every action ≥ 3 % of samples: least {min(shares.values()):.1%} — "
        f"{_met(min(shares.values()) >= 0.03)}",
        f"- KL of the predicted-action histogram to real ≤ 0.1: {kl:.3f} — {_met(kl <= 0.1)}",
        f"- W+ inversion of {meta['n_inverted_clips']} held-out clips, mean joint error ≤ 5 cm: "
        f"{100 * inversion:.1f} cm — {_met(inversion <= 0.05)}",
        *physics_targets(report),
        *edit_targets(edits),
        "",
        "## Evaluation",
        "",
        f"{len(held)} held-out clips, never seen by the generator or its critic: "
        + (
            "the held-out split of bandai2-odmo and docs/RESULTS.md (bench/heldout.py, "
            f"{HELDOUT_FRACTION:.0%} per action × style, seed {SPLIT_SEED}). "
            if split == "heldout"
            else "the training run's own validation split (10 % per action, seed 0; it trained on every "
            "other clip), so its real row differs from bandai2-odmo's. "
        )
        + f"{meta['repeats']} repeats of {meta['n_per_action']} × "
        f"{len(shares)} prior samples (ψ = 1), each cut to its centre {meta['window']} frames for the "
        f"classifier of bandai2-odmo (accuracy {meta['classifier_test_accuracy']:.3f} on its test windows), "
        "which also labels them; accuracy is not applicable. Mean ± 95 % interval over the repeats "
        f"(inversion: over clips, {meta['inversion_steps']} Adam steps in W+).",
        "",
        *rows,
        "",
        "Predicted action of the prior samples:",
        "",
        *share_rows,
        "",
        *per_action_table(report),
        "",
        "## Training",
        "",
        f"- Command: `{command}`",
        f"- Budget: {provenance['epochs']} epochs, {steps:,} steps of batch {config.batch_size} "
        f"({provenance.get('windows_seen', 0):,} windows) in {summary['train_seconds'] / 3600:.1f} h of CPU "
        f"training on {summary['torch_threads']} torch thread ({platform.processor() or platform.machine()}, "
        "a machine shared with other jobs); no GPU.",
        f"- Settings: {config.levels} levels, channels {config.channels}…{config.min_channels}, w "
        f"{config.w_dim}, {config.mapping_layers}-layer mapping network, {params / 1e6:.2f} M generator "
        f"parameters, window {config.window} frames at {config.fps:g} fps; Adam lr {config.lr:g} "
        f"(β = 0, 0.99), R1 γ {config.r1_gamma:g} every {config.r1_every} steps, style mixing "
        f"{config.mixing:g}, foot-contact weights {config.touch_weight:g} / {config.fcon_weight:g}; the "
        f"shipped generator is the EMA (half-life {config.ema_windows:,} windows).",
        f"- Data: {summary['n_train']} training and {summary['n_val']} validation clips; prepared-data "
        f"fingerprint `{fingerprint[:16]}`.",
        "",
        "## Use",
        "",
        "`odmo sample --model resources/models/bandai2-modi --n 4 --truncation 0.7 --out s.bvh`;",
        "`odmo invert --model resources/models/bandai2-modi clip.bvh`; `odmo mix`, `odmo crowd`,",
        "`odmo edit --list`. In Python `open_generator(path)` (`engine.generators`).",
        "",
    ]
    return "\n".join(lines)


if __name__ == "__main__":
    sys.exit(main())
