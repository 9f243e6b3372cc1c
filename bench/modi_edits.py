"""Measure the style edits of a MoDi model folder with a style classifier trained on real clips.

    python bench/modi_edits.py --data "$(../shared/data/unpack)" --model resources/models/bandai2-modi \
        --out runs/modi-edits/edits.json

Trains (once, kept under --work) a classifier of the same architecture as the action classifier on the
styles of the clips the model trained on, then edits the bank's inverted "normal" clips towards each
--style by --amount spreads and reports, per style, the share of edits that raise the classifier's
probability of the target and the share whose predicted action stays (``engine.metrics.edits``).
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import sys
from pathlib import Path

import numpy as np
import torch

if __package__ in (None, ""):
    sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from engine.fileio import atomic_write_text
from engine.generators import open_generator
from engine.metrics.classifier import load_classifier, train_classifier
from engine.metrics.edits import edit_effect
from engine.motion.datasets import load_folder

ROOT = Path(__file__).resolve().parents[1]
CLASSIFIER = ROOT / "resources" / "models" / "bandai2-odmo" / "classifier"


def main() -> int:
    """Train the style classifier if needed, edit, write the JSON report."""
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--data", required=True, type=Path)
    p.add_argument("--model", required=True, type=Path)
    p.add_argument("--out", required=True, type=Path)
    p.add_argument("--work", type=Path, default=Path("runs/modi-edits"))
    p.add_argument("--classifier", type=Path, default=CLASSIFIER, help="the action classifier")
    p.add_argument(
        "--style", action="append", default=None, help="target styles (elderly, exhausted, feminine)"
    )
    p.add_argument("--source-style", default="normal")
    p.add_argument("--amount", type=float, default=2.0)
    p.add_argument("--epochs", type=int, default=10, help="style classifier epochs")
    args = p.parse_args()
    torch.set_num_threads(1)
    generator = open_generator(args.model)
    trained = set(generator.loaded.provenance["train_sources"])
    clips = [c for c in load_folder(args.data).clips if str(c.meta["source"]) in trained]
    styles = sorted({str(c.meta["style"]) for c in clips})
    folder = args.work / "style_classifier"
    if (folder / "classifier.json").is_file():
        style_clf = load_classifier(folder)
    else:
        relabelled = [dataclasses.replace(c, action=str(c.meta["style"])) for c in clips]
        style_clf = train_classifier(relabelled, styles, folder, epochs=args.epochs)
    bank = generator.bank
    rows = [i for i, m in enumerate(bank.meta) if m.get("style") == args.source_style]
    actions = [
        None if generator.action_names is None else bank.action_names[int(bank.actions[i])] for i in rows
    ]
    action_clf = load_classifier(args.classifier)
    report = {
        "style_classifier_accuracy": style_clf.test_accuracy,
        "style_classifier_per_style": style_clf.test_accuracy_per_action,
        "source_style": args.source_style,
        "n_codes": len(rows),
        "amount": args.amount,
        "edits": [],
    }
    for style in args.style or ["elderly", "exhausted", "feminine"]:
        effect = edit_effect(
            generator, bank.codes[rows], actions, f"style={style}", args.amount, style_clf, action_clf
        )
        report["edits"].append(dataclasses.asdict(effect))
        print(f"{style}: raised {effect.raised:.0%}, action kept {effect.kept:.0%}, "
              f"p {effect.before:.3f} -> {effect.after:.3f}", flush=True)  # fmt: skip
    args.out.parent.mkdir(parents=True, exist_ok=True)
    atomic_write_text(args.out, json.dumps(report, indent=2, default=float) + "\n")
    print(f"style classifier held-out accuracy {style_clf.test_accuracy:.3f}; codes {len(rows)}")
    return 0 if np.isfinite(style_clf.test_accuracy) else 1


if __name__ == "__main__":
    sys.exit(main())
