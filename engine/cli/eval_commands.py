"""``odmo train-classifier | eval``: the evaluation classifier and the metrics table."""

from __future__ import annotations

import argparse
import json
import math
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import Any

from engine.cli.options import add_up_axis, positive_int
from engine.metrics.per_action import per_action_cell, present_columns

# Printed order of the metrics table; any other metric follows in the order evaluate() returns it.
TABLE_ORDER = (
    "accuracy",
    "fid",
    "diversity",
    "multimodality",
    "apd",
    "n_apd",
    "mode_homogeneity",
    "style_nmi",
    "style_ari",
    "reconstruction_error_m",
    "reconstruction_accuracy",
    "end_error_m",
    "end_error_pct",
    "control_accuracy",
    "end_error_out_m",
    "end_error_out_pct",
    "control_accuracy_out",
    "bone_length_cv",
    "foot_skate_m_s",
    "floor_penetration",
    "floor_depth_m",
    "float_share",
)


@contextmanager
def _bar(desc: str) -> Iterator[Callable[[str, float], None]]:
    """A tqdm bar driven by ``progress(stage, fraction)`` callbacks."""
    from tqdm import tqdm

    with tqdm(total=1000, desc=desc, leave=False, bar_format="{desc}: {percentage:3.0f}%|{bar}|") as bar:

        def progress(stage: str, fraction: float) -> None:
            bar.set_description(stage, refresh=False)
            bar.update(round(1000 * fraction) - bar.n)

        yield progress


def _load_clips(path: str, args: argparse.Namespace) -> Any:
    from engine.motion.datasets import load_folder

    return load_folder(path, pattern=args.pattern, labels=args.labels, up_axis=args.up_axis)


def _add_label_options(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--pattern", help="file-name regex with (?P<action>...) (folders without sidecars)")
    parser.add_argument("--labels", help="CSV/JSON sidecar of labels, relative to the folder")
    add_up_axis(parser)


def _cmd_train_classifier(args: argparse.Namespace) -> int:
    from engine.metrics.classifier import train_classifier

    data = _load_clips(args.data, args)
    with _bar("training classifier") as progress:
        clf = train_classifier(
            data.clips,
            data.action_names,
            args.out,
            window=args.window,
            fps=args.fps,
            epochs=args.epochs,
            stride=args.stride,
            seed=args.seed,
            val_fraction=args.val_fraction,
            progress=progress,
        )
    print(f"classifier: {args.out}")
    print(
        f"held-out accuracy: {clf.test_accuracy:.4f} on {clf.n_test_windows} windows of {clf.n_test} clips "
        f"({len(data.clips)} clips in all)"
    )
    for action, accuracy in clf.test_accuracy_per_action.items():
        print(f"  {action}: {accuracy:.4f}")
    return 0


def format_table(result: dict[str, Any]) -> str:
    """The metrics as a text table: one row per metric, real and generated as mean ± 95 % CI."""
    names = [m for m in TABLE_ORDER if m in result["real"] or m in result["generated"]]
    names += [m for m in (*result["real"], *result["generated"]) if m not in names]
    names = list(dict.fromkeys(names))

    def cell(column: dict[str, dict[str, float]], name: str) -> str:
        if name not in column or math.isnan(column[name]["mean"]):
            return "-"
        return f"{column[name]['mean']:.4g} ± {column[name]['ci95']:.2g}"

    width = max(len(n) for n in names)
    lines = [f"{'metric':<{width}}  {'real':>20}  {'generated':>20}"]
    lines += [
        f"{n:<{width}}  {cell(result['real'], n):>20}  {cell(result['generated'], n):>20}" for n in names
    ]
    return "\n".join(lines)


def format_per_action(result: dict[str, Any]) -> str:
    """Per action, each physical figure as generated / real (means)."""
    per_action = result.get("per_action") or {}
    columns = present_columns(per_action)
    if not columns:
        return ""
    width = max(len(a) for a in per_action)
    lines = [f"{'action':<{width}}  " + "  ".join(f"{c.short:>17}" for c in columns)]
    lines += [
        f"{a:<{width}}  " + "  ".join(f"{per_action_cell(row, c):>17}" for c in columns)
        for a, row in per_action.items()
    ]
    return "per action, generated / real (m/s, m, m/s³):\n" + "\n".join(lines)


def _cmd_eval(args: argparse.Namespace) -> int:
    from engine.fileio import atomic_write_text
    from engine.generators import open_generator
    from engine.metrics.by_kind import check_evaluable, evaluate_generator
    from engine.metrics.classifier import META_FILE, load_classifier
    from engine.motion.datasets import drop_extra_joints

    loaded = open_generator(args.model)
    clf_dir = args.classifier
    if clf_dir is None and (Path(args.model) / "classifier" / META_FILE).is_file():
        clf_dir = Path(args.model) / "classifier"
    classifier = None if clf_dir is None else load_classifier(clf_dir)
    data = _load_clips(args.real, args)
    clips = [drop_extra_joints(clip, loaded.skeleton.names) for clip in data.clips]
    check_evaluable(loaded, clips, classifier, args.truncation)  # fail before the progress bar appears
    with _bar("evaluating") as progress:
        result = evaluate_generator(
            loaded,
            clips,
            classifier,
            repeats=args.repeats,
            n_per_action=args.n_per_action,
            seed=args.seed,
            strategy=args.strategy,
            truncation=args.truncation,
            progress=progress,
        )
    print(format_table(result))
    per_action = format_per_action(result)
    if per_action:
        print(per_action)
    if classifier is None:
        print(
            "(no classifier: accuracy, FID, diversity and multimodality left out; see odmo train-classifier)"
        )
    if args.json is not None:
        atomic_write_text(args.json, json.dumps(_json_ready(result), indent=2, allow_nan=False) + "\n")
        print(f"wrote {args.json}")
    return 0


def _json_ready(value: Any) -> Any:
    """``value`` with NaN floats replaced by None (strict JSON)."""
    if isinstance(value, dict):
        return {k: _json_ready(v) for k, v in value.items()}
    if isinstance(value, list | tuple):
        return [_json_ready(v) for v in value]
    if isinstance(value, float) and not math.isfinite(value):
        return None
    return value


def register(subparsers: argparse._SubParsersAction) -> None:
    """Add ``train-classifier`` and ``eval`` to the ``odmo`` parser."""
    p = subparsers.add_parser(
        "train-classifier",
        help="train the evaluation classifier on a labelled folder",
        description="Train the GRU action classifier whose features FID, diversity and multimodality use.",
    )
    p.add_argument("--data", required=True, help="labelled dataset folder")
    p.add_argument("--out", required=True, type=Path, help="classifier folder to write")
    p.add_argument("--epochs", type=positive_int, default=60, help="passes over the training clips (60)")
    p.add_argument("--seed", type=int, default=0, help="random seed (0)")
    p.add_argument("--window", type=positive_int, default=60, help="frames per window, as the model (60)")
    p.add_argument("--fps", type=float, default=20.0, help="frame rate of the windows, as the model (20)")
    p.add_argument("--stride", type=positive_int, default=10, help="frames between window starts (10)")
    p.add_argument("--val-fraction", type=float, default=0.2, help="clips held out for the accuracy (0.2)")
    _add_label_options(p)
    p.set_defaults(func=_cmd_train_classifier)

    e = subparsers.add_parser(
        "eval",
        help="evaluate a model against real clips (mean ± 95%% CI)",
        description="Metrics of real and generated motions (MODEL/classifier when --classifier is absent).",
    )
    e.add_argument("--model", required=True, help="model folder")
    e.add_argument("--real", required=True, help="labelled folder of real clips")
    e.add_argument("--classifier", type=Path, help="classifier folder (from odmo train-classifier)")
    e.add_argument("--repeats", type=positive_int, default=10, help="sample sets for the intervals (10)")
    e.add_argument("--n-per-action", type=positive_int, default=50, help="motions per action and set (50)")
    e.add_argument(
        "--strategy",
        choices=("mode_preserving", "conventional"),
        help="draw codes from the bank's modes: ODMO's (its default mode_preserving) or Action2Motion's "
        "(its default: the learned prior)",
    )
    e.add_argument(
        "--truncation",
        type=float,
        default=1.0,
        metavar="PSI",
        help="sample truncated by PSI (kinds that truncate: Action2Motion's prior, MoDi's W; 1: none)",
    )
    e.add_argument("--json", type=Path, help="write the results as JSON here")
    e.add_argument("--seed", type=int, default=0, help="random seed (0)")
    _add_label_options(e)
    e.set_defaults(func=_cmd_eval)
