"""Train, evaluate and package the bundled DVGAN model on Bandai-Namco-2.

    python bench/train_dvgan.py --data "$(../shared/data/unpack)" --epochs 100 [--resume]

Trains ``engine.train.dvgan_loop.train_dvgan`` (RNN generator, dense critic) on the training part of the
held-out split every model of docs/RESULTS.md uses (bench/heldout.py), resuming from --work; with
``--hold-out-action A`` the clips of action A are left out of training as well (the phrase ablation:
its words must appear in other actions' phrases). Then evaluates it on the held-out clips with the
bundled ODMO model's classifier (``engine.metrics.dvgan_eval``: generated windows, completion against
zero velocity, 3,000-frame sequences, and what it makes of phrases it never trained on), writes
--out with its card and replaces the DVGAN section of docs/RESULTS.md.
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
from tqdm import tqdm

if __package__ in (None, ""):
    sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from bench._report import replace_section
from bench.heldout import HELDOUT_FRACTION, SPLIT_SEED, heldout_split
from bench.model_card import (
    licence_lines,
    metric_table,
    per_action_table,
    physics_targets,
    repo_path,
    training_command,
)
from bench.warm_start import warm_start_from, warm_start_line
from engine.errors import ConfigError
from engine.fileio import atomic_write_text
from engine.generators import SampleRequest, open_generator
from engine.generators.dvgan import DvganGenerator, load_dvgan
from engine.metrics.classifier import Classifier, load_classifier
from engine.metrics.dvgan_eval import HORIZONS_MS, completion_errors, evaluate_dvgan, long_sequences
from engine.metrics.unconditional import classify_joints
from engine.model.dvgan import DvganConfig
from engine.motion.datasets import load_folder
from engine.train.dvgan_loop import train_dvgan
from engine.train.epochs import TrainProgress

ROOT = Path(__file__).resolve().parents[1]
DEFAULT_OUT = ROOT / "resources" / "models" / "bandai2-dvgan"
CLASSIFIER = ROOT / "resources" / "models" / "bandai2-odmo" / "classifier"
RESULTS = ROOT / "docs" / "RESULTS.md"
SHIPPED = ("model.safetensors", "model.json", "latent_bank.npz", "train_log.csv")
#: Phrases made of the training phrases' words that no training clip is labelled with.
NEW_PHRASES = ("run turn left", "run turn right", "walk wave right hand")
LONG_FRAMES = 3000
SECTION = "## DVGAN: generation, completion and long sequences"


def parse_args() -> argparse.Namespace:
    """Command-line options."""
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--data", required=True, type=Path)
    p.add_argument("--work", type=Path, default=Path("runs/bandai2-dvgan"), help="the trained model folder")
    p.add_argument("--out", type=Path, default=DEFAULT_OUT, help="the packaged model folder")
    p.add_argument("--classifier", type=Path, default=CLASSIFIER)
    p.add_argument("--repeats", type=int, default=10)
    p.add_argument("--n-per-action", type=int, default=50)
    p.add_argument("--skip-train", action="store_true", help="package the model already in --work")
    p.add_argument("--reuse-eval", action="store_true", help="reuse --work/eval.json for the card")
    p.add_argument("--no-results", action="store_true", help="leave docs/RESULTS.md alone")
    p.add_argument("--epochs", type=int, default=100)
    p.add_argument("--generator", default="rnn", choices=("rnn", "cnn"))
    p.add_argument("--tape-windows", type=int, default=2, help="windows per generated tape (final cut)")
    p.add_argument(
        "--warm-start", type=Path, help="start from this DVGAN folder's generator (trained on this split)"
    )
    p.add_argument("--hold-out-action", help="leave this action's clips out of training (phrase ablation)")
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--threads", type=int, default=1, help="torch CPU threads")
    p.add_argument("--resume", action="store_true")
    return p.parse_args()


def main() -> int:
    """Train (resuming), evaluate, write the card and package the folder."""
    args = parse_args()
    torch.set_num_threads(args.threads)
    dataset = load_folder(args.data)
    train_clips, held = heldout_split(dataset.clips)
    names = list(dataset.action_names)
    if args.hold_out_action:
        if args.hold_out_action not in names:
            raise SystemExit(f"--hold-out-action {args.hold_out_action!r}: not one of {', '.join(names)}")
        names.remove(args.hold_out_action)
        train_clips = [c for c in train_clips if c.action != args.hold_out_action]
    if not args.skip_train:
        config = DvganConfig(
            n_actions=len(names), n_joints=dataset.skeleton.n_joints, epochs=args.epochs,
            generator=args.generator, tape_windows=args.tape_windows,
        )  # fmt: skip
        bar = tqdm(total=config.epochs, desc="dvgan", unit="epoch")

        def show(p: TrainProgress) -> None:
            if p.step == p.steps:
                bar.n = p.epoch
                bar.set_postfix(
                    {k: f"{v:.3g}" for k, v in p.losses.items()} | {"w/s": f"{p.windows_per_s:.0f}"}
                )
                bar.refresh()

        start = None if args.warm_start is None else warm_start_from(args.warm_start, held, load_dvgan)
        train_dvgan(
            train_clips, names, args.work, config, seed=args.seed, device="cpu", resume=args.resume,
            progress=show, warm_start=start,
        )  # fmt: skip
        bar.close()
    generator = open_generator(args.work)
    assert isinstance(generator, DvganGenerator)
    classifier = load_classifier(args.classifier)
    if args.reuse_eval and (args.work / "eval.json").is_file():
        report = json.loads((args.work / "eval.json").read_text())
    else:
        report = evaluation(generator, [c for c in held if c.action in names], classifier, args)
        atomic_write_text(args.work / "eval.json", json.dumps(report, indent=2))
    out = args.out
    out.mkdir(parents=True, exist_ok=True)
    for name in SHIPPED:
        shutil.copy2(args.work / name, out / name)
    shutil.copy2(args.data / "LICENSE", out / "LICENSE")  # the data's CC BY-NC 4.0, which the model inherits
    atomic_write_text(
        out / "heldout_clips.txt", "\n".join(sorted(Path(c.meta["source"]).name for c in held)) + "\n"
    )
    report = report | {"meta": report["meta"] | {"model": out.name, "classifier": repo_path(args.classifier)}}
    atomic_write_text(out / "eval.json", json.dumps(report, indent=2))
    command = training_command("bench/train_dvgan.py", args.work, sys.argv[1:], trained=not args.skip_train)
    atomic_write_text(out / "MODEL_CARD.md", model_card(report, generator, command, len(held)))
    if not args.no_results:
        anchors = ("## Unconditional: MoDi", "## How it was made")
        replace_section(RESULTS, SECTION, "\n".join(results_section(report)), before=anchors)
    print(f"wrote {out}")
    return 0


def evaluation(
    generator: DvganGenerator, held: list, classifier: Classifier, args: argparse.Namespace
) -> dict[str, Any]:
    """The whole report: generated windows, completion, long sequences and new phrases, with timings."""
    started = time.time()
    options = {"repeats": args.repeats, "n_per_action": args.n_per_action, "seed": args.seed}
    report = evaluate_dvgan(generator, held, classifier, **options)
    report["completion"] = completion_errors(generator, held, seed=args.seed)
    report["long"] = long_sequences(generator, held, classifier, frames=LONG_FRAMES, seed=args.seed)
    report["phrases"] = phrase_probe(generator, classifier, args.seed)
    report["meta"]["eval_seconds"] = time.time() - started
    return report


def phrase_probe(generator: DvganGenerator, classifier: Classifier, seed: int, n: int = 50) -> dict[str, Any]:
    """What the classifier calls ``n`` samples of each phrase the model was never trained on."""
    window = classifier.config.window
    out = {}
    for phrase in (*NEW_PHRASES, *(a.replace("-", " ") for a in missing_actions(generator, classifier))):
        try:
            samples = generator.sample(SampleRequest(phrase, n, seed), frames=window)
        except ConfigError as exc:  # a word it does not know: say so in the report
            out[phrase] = {"error": str(exc)}
            continue
        _, predicted = classify_joints(
            classifier, np.stack([s.motion.joints for s in samples]), generator.skeleton
        )
        labels, counts = np.unique(np.array(classifier.action_names)[predicted], return_counts=True)
        order = np.argsort(counts)[::-1]
        out[phrase] = {str(labels[i]): float(counts[i] / n) for i in order}
    return out


def missing_actions(generator: DvganGenerator, classifier: Classifier) -> list[str]:
    """Actions the classifier knows that the model never trained on (the held-out phrase, if any)."""
    return [a for a in classifier.action_names if a not in generator.label_names]


def _met(ok: bool) -> str:
    return "met" if ok else "**not met**"


def target_lines(report: dict[str, Any]) -> list[str]:
    """The issue's quality targets, judged from the report."""
    gen, real = report["generated"], report["real"]
    completion = report["completion"]
    beaten = [a for a, r in completion.items() if r["model"]["400"] < r["zero_velocity"]["400"]]
    long = report["long"]
    recognised = [a for a, r in long.items() if r["accuracy"] >= 0.8]
    plausible = [
        a for a, r in long.items()
        if r["bone_length_cv_whole"] <= 0.01 and r["floor_penetration"] < 0.01
        and r["float_share"] <= real["float_share"]["mean"] + 0.10
    ]  # fmt: skip
    acc_gap = real["accuracy"]["mean"] - gen["accuracy"]["mean"]
    fid = gen["fid"]["mean"]
    return [
        f"- Completion error below zero velocity at 400 ms for ≥ 8 of {len(completion)} actions: "
        f"{len(beaten)} ({', '.join(beaten) or 'none'}) — {_met(len(beaten) >= 8)}.",
        f"- {LONG_FRAMES:,}-frame sequences recognised as their action (≥ 0.8 of windows): {len(recognised)}"
        f"/{len(long)} — {_met(len(recognised) == len(long))}.",
        f"- {LONG_FRAMES:,}-frame sequences within the plausibility aims over their whole length (bone "
        "cv ≤ 1 %, < 1 % of frames under the floor, floating windows ≤ real + 10 points): "
        f"{len(plausible)}/{len(long)} — {_met(len(plausible) == len(long))}.",
        f"- Generated windows: accuracy within 10 points of real ({gen['accuracy']['mean']:.3f} vs "
        f"{real['accuracy']['mean']:.3f}) — {_met(acc_gap <= 0.10)}; FID ≤ 1.0 ({fid:.2f}) — "
        f"{_met(fid <= 1.0)}.",
        *physics_targets(report),
    ]


def completion_table(report: dict[str, Any]) -> list[str]:
    """Per action: mean joint error (cm) of the model / zero velocity at each horizon."""
    heads = " | ".join(f"{ms} ms" for ms in HORIZONS_MS)
    rows = [f"| action | clips | {heads} |", "|---|---|" + "|".join("---" for _ in HORIZONS_MS) + "|"]
    for action, r in report["completion"].items():
        cells = " | ".join(
            f"{100 * r['model'][str(ms)]:.1f} / {100 * r['zero_velocity'][str(ms)]:.1f}" for ms in HORIZONS_MS
        )
        rows.append(f"| {action} | {r['n_clips']} | {cells} |")
    return rows


def long_table(report: dict[str, Any]) -> list[str]:
    """Per action: the 3,000-frame sequence's figures."""
    rows = [
        "| action | recognised windows | root height range (m) | windows in real height range | bone cv | "
        "planted-foot speed (m/s) | frames under floor | floating windows | hand speed (m/s) |",
        "|---|---|---|---|---|---|---|---|---|",
    ]
    for action, r in report["long"].items():
        rows.append(
            f"| {action} | {r['accuracy']:.0%} | {r['root_height_min_m']:.2f}–{r['root_height_max_m']:.2f} | "
            f"{r['windows_in_real_height_range']:.0%} | {r['bone_length_cv_whole']:.2%} | "
            f"{r.get('foot_skate_m_s', float('nan')):.3f} | {r.get('floor_penetration', 0):.2%} | "
            f"{r.get('float_share', 0):.0%} | {r.get('hand_speed_m_s', float('nan')):.2f} |"
        )
    return rows


def phrase_lines(report: dict[str, Any]) -> list[str]:
    """What the classifier calls samples of phrases never trained on."""
    lines = []
    for phrase, shares in report["phrases"].items():
        if "error" in shares:
            lines.append(f'- "{phrase}": {shares["error"]}')
        else:
            lines.append(f'- "{phrase}": ' + ", ".join(f"{a} {v:.0%}" for a, v in list(shares.items())[:3]))
    return lines


def model_card(report: dict[str, Any], generator: DvganGenerator, command: str, n_held: int) -> str:
    """MODEL_CARD.md from the evaluation report and the model's provenance; never typed by hand."""
    config: DvganConfig = generator.loaded.config
    made = generator.loaded.provenance
    meta = report["meta"]
    params = sum(t.numel() for t in generator.network.parameters())
    lines = [
        "# bandai2-dvgan: DVGAN on Bandai-Namco-2",
        "",
        "Generated by `bench/train_dvgan.py` from its evaluation report; do not edit by hand.",
        "",
        "DVGAN (Lin & Amer 2018, *Human Motion Modeling using DVGANs*), re-implemented from the paper (no",
        f"public code): the {config.generator.upper()} generator (per-frame plots of noise and the action",
        "phrase, an LSTM adding a difference to the previous frame; final cut of a 2N-frame tape), a",
        "critic validating densely at every time scale with the shift augmentation, WGAN-GP (λ = "
        f"{config.gp_weight:g}), the action read word by word by a 2-layer LSTM language model. Motion is",
        "exponential maps per joint (about the data's typical rest pose), the root's heading change, step",
        "and height, and foot contacts, decoded by forward kinematics on a fixed skeleton; planted feet are",
        "pinned at decode time. It completes a prefix and continues a motion for any length.",
        "",
        *licence_lines(),
        "",
        "## Quality targets (held-out clips)",
        "",
        *target_lines(report),
        "",
        "## Generated windows",
        "",
        f"{n_held} held-out clips (bench/heldout.py, {HELDOUT_FRACTION:.0%} per action × style, seed "
        f"{SPLIT_SEED}); {meta['repeats']} repeats of {meta['n_per_action']} samples per action of "
        f"{meta['window']} frames (`sample(frames={meta['window']})`, codes from N(0, I)) against real "
        f"windows, with the classifier of bandai2-odmo (accuracy {meta['classifier_test_accuracy']:.3f} on "
        "its test windows). Mean ± 95 % interval over the repeats.",
        "",
        *metric_table(report, "DVGAN"),
        "",
        *per_action_table(report),
        "",
        "## Completion",
        "",
        "Each held-out clip long enough gives one 20-frame (1 s) prefix from its middle; mean joint error "
        "(cm) of 4 continuations / of zero velocity (the prefix's last frame held), at each horizon:",
        "",
        *completion_table(report),
        "",
        f"## {LONG_FRAMES:,}-frame sequences",
        "",
        f"One sequence per action, cut into {meta['window']}-frame windows:",
        "",
        *long_table(report),
        "",
        "## Phrases it never trained on",
        "",
        "Share of 50 samples the classifier gives each action:",
        "",
        *phrase_lines(report),
        "",
        "## Training",
        "",
        f"- Command: `{command}`",
        f"- Budget: {made['epochs']} epochs, {made.get('steps', 0):,} generator updates of batch "
        f"{config.batch_size} with {config.critic_steps} critic updates each, "
        f"{made['train_seconds'] / 3600:.2f} h on the CPU ({platform.processor() or platform.machine()}, "
        "a machine shared with other jobs); no GPU.",
        f"- Settings: k = {config.hidden}, noise {config.noise_dim} per frame, window {config.window} frames "
        f"at {config.fps:g} fps (tape {config.tape}), Adam {config.lr:g} (β 0.5, 0.9), "
        f"{config.prefix_rate:.0%} of generator batches completing a real prefix of 1–{config.max_prefix} "
        f"frames; {params / 1e6:.2f} M generator parameters. The paper's k = 256 and 10 critic updates "
        "per generator update did not fit two CPU cores.",
        *warm_start_line(made.get("warm_start")),
        f"- Data: {made['n_train']} training and {made['n_val']} validation clips; fingerprint "
        f"`{made['data_fingerprint'][:16]}`.",
        f"- Evaluation took {meta['eval_seconds'] / 60:.1f} min.",
        "",
        "## Use",
        "",
        "`odmo sample --model resources/models/bandai2-dvgan --action walk --frames 3000 --out long.bvh`;",
        "`odmo complete --model resources/models/bandai2-dvgan --prefix clip.bvh --frames 40 --n 3 --out",
        "futures/`. In Python `open_generator(path).complete(prefix, frames, n)` (`engine.generators`).",
        "",
    ]
    return "\n".join(lines)


def results_section(report: dict[str, Any]) -> list[str]:
    """The DVGAN section of docs/RESULTS.md."""
    meta = report["meta"]
    return [
        SECTION,
        "",
        f"The bundled `{meta['model']}`, from its evaluation report (`eval.json`, written by "
        "`bench/train_dvgan.py`) on the held-out split above, with the same classifier. Generated windows:",
        "",
        *metric_table(report, "DVGAN"),
        "",
        "Completion against zero velocity (mean joint error in cm, model / zero velocity):",
        "",
        *completion_table(report),
        "",
        f"{LONG_FRAMES:,}-frame sequences:",
        "",
        *long_table(report),
        "",
        "Section rewritten by `python bench/train_dvgan.py` (see the model card for the command).",
        "",
    ]


if __name__ == "__main__":
    sys.exit(main())
