"""What truncation does to a model's samples: the held-out evaluation at each ψ, side by side.

    python bench/truncation.py --data DATA --model resources/models/bandai2-a2m --psi 1 0.7 0.5 [--repeats 3]
        [--strategy mode_preserving]

For a kind that truncates (Action2Motion: ψ scales its learned prior's standard deviation; MoDi: ψ pulls
w towards the mean w), evaluates samples at each ψ against the held-out clips of bench/heldout.py with
``engine.metrics.by_kind.evaluate_generator`` (the same real sets, classifier and seed for every ψ) and
prints a markdown table: accuracy, FID, diversity and the physical figures that truncation trades
(jerk, planted-foot speed, hand speed), real first. ``--strategy`` samples Action2Motion's codes from its
bank's modes instead of its prior. ``--json`` writes every report.
"""

from __future__ import annotations

import argparse
import json
import sys
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import torch

if __package__ in (None, ""):
    sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from bench.heldout import heldout_split
from bench.model_card import cell
from engine.fileio import atomic_write_text
from engine.generators import open_generator
from engine.generators.base import Generator
from engine.metrics.by_kind import evaluate_generator
from engine.metrics.classifier import Classifier, load_classifier
from engine.motion.datasets import load_folder
from engine.motion.motion import Motion

CLASSIFIER = Path(__file__).resolve().parents[1] / "resources" / "models" / "bandai2-odmo" / "classifier"
COLUMNS = (
    ("accuracy", "accuracy"),
    ("fid", "FID"),
    ("diversity", "diversity"),
    ("jerk_m_s3", "jerk (m/s³)"),
    ("foot_skate_m_s", "planted-foot speed (m/s)"),
    ("hand_speed_m_s", "hand speed (m/s)"),
)


def sweep(
    generator: Generator,
    clips: Sequence[Motion],
    classifier: Classifier,
    psis: Sequence[float],
    **options: Any,
) -> dict[float, dict[str, Any]]:
    """The evaluation report of ``generator``'s samples at each truncation ψ (``options``: repeats,
    n_per_action, seed, as ``evaluate_generator`` takes them)."""
    return {psi: evaluate_generator(generator, clips, classifier, truncation=psi, **options) for psi in psis}


def sweep_table(reports: dict[float, dict[str, Any]]) -> str:
    """Markdown: the real row, then one row per ψ, each metric as mean ± 95 % interval."""
    header = "| sampled | " + " | ".join(label for _, label in COLUMNS) + " |"
    rows = [header, "|---" * (len(COLUMNS) + 1) + "|"]
    real = next(iter(reports.values()))["real"]
    rows.append("| real (held-out) | " + " | ".join(cell(real, key) for key, _ in COLUMNS) + " |")
    for psi, report in reports.items():
        gen = report["generated"]
        rows.append(f"| ψ {psi:g} | " + " | ".join(cell(gen, key) for key, _ in COLUMNS) + " |")
    return "\n".join(rows)


def main() -> int:
    """Evaluate at each ψ and print the table."""
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--data", required=True, type=Path)
    p.add_argument("--model", required=True, type=Path)
    p.add_argument("--psi", type=float, nargs="+", default=[1.0, 0.7, 0.5])
    p.add_argument(
        "--strategy", choices=("mode_preserving", "conventional"), help="(Action2Motion) from modes"
    )
    p.add_argument("--classifier", type=Path, default=CLASSIFIER)
    p.add_argument("--repeats", type=int, default=3)
    p.add_argument("--n-per-action", type=int, default=50)
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--threads", type=int, default=1)
    p.add_argument("--json", type=Path)
    args = p.parse_args()
    torch.set_num_threads(args.threads)
    _, test_clips = heldout_split(load_folder(args.data).clips)
    options = {"repeats": args.repeats, "n_per_action": args.n_per_action, "seed": args.seed}
    options["strategy"] = args.strategy
    generator, classifier = open_generator(args.model), load_classifier(args.classifier)
    reports = sweep(generator, test_clips, classifier, args.psi, **options)
    print(sweep_table(reports))
    if args.json is not None:
        atomic_write_text(args.json, json.dumps({str(k): v for k, v in reports.items()}, indent=2))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
