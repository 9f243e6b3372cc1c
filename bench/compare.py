"""Compare ODMO, its ablations and the Action2Motion baseline on the fixed held-out split → docs/RESULTS.md.

    python bench/compare.py --data "$(../shared/data/unpack)" [--epochs 300] [--reuse]

Every model trains on the training part of ``bench.heldout.heldout_split`` with the same windows, seed and
budget (epochs × windows per epoch) and is evaluated on the held-out part with the same classifier and the
same real sets (``engine.metrics.evaluate`` for ODMO, ``engine.metrics.a2m_eval`` for A2M). Models live in
``runs/compare/<name>/``; ``--reuse`` keeps finished ones (unfinished ones resume). The ODMO row reuses the
default model (resources/models/bandai2-odmo) when its data, seed, config and epochs match.
"""

from __future__ import annotations

import argparse
import datetime as dt
import hashlib
import json
import logging
import sys
import time
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import Any

import numpy as np
import torch
from tqdm import tqdm

if __package__ in (None, ""):
    sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from bench._report import machine, replace_section
from bench.heldout import HELDOUT_FRACTION, SPLIT_SEED, heldout_split
from bench.train_dvgan import results_section
from engine.fileio import atomic_write_text
from engine.generate._decode import decode_tensors
from engine.generators import Generator, SampleRequest, open_generator
from engine.generators.a2m import LoadedA2m, load_a2m
from engine.metrics.a2m_eval import evaluate_a2m
from engine.metrics.by_kind import evaluate_generator
from engine.metrics.classifier import Classifier, load_classifier, train_classifier
from engine.metrics.evaluate import evaluate
from engine.metrics.per_action import per_action_markdown
from engine.model.a2m import A2mConfig
from engine.model.config import OdmoConfig
from engine.modelio import META_FILE, LoadedModel, load_model
from engine.motion.datasets import load_folder
from engine.motion.motion import Motion
from engine.train.a2m_loop import train_a2m
from engine.train.epochs import TrainProgress
from engine.train.loop import train
from engine.train.windows import prepare_clips

log = logging.getLogger("bench.compare")

REPO = Path(__file__).resolve().parents[1]
RESULTS = REPO / "docs" / "RESULTS.md"
DEFAULT_MODEL = REPO / "resources" / "models" / "bandai2-odmo"
MODI_MODEL = REPO / "resources" / "models" / "bandai2-modi"
DVGAN_MODEL = REPO / "resources" / "models" / "bandai2-dvgan"
CLASSIFIERS = (REPO / "runs" / "bandai2-odmo" / "classifier", DEFAULT_MODEL / "classifier")
SPEED_BATCH = 64
WINDOW, FPS = 60, 20.0  # the OdmoConfig / A2mConfig defaults every model here uses

ROWS = {
    "odmo": "ODMO (mode-preserving sampling)",
    "odmo_conv": "ODMO, conventional sampling",
    "odmo_no_contrastive": "ODMO w/o contrastive (plain VAE)",
    "odmo_no_end": "ODMO w/o end location",
    "odmo_push_only": "ODMO, contrastive push only (no same-action pull)",
    "odmo_push_bf16": "ODMO, contrastive push only, trained under bfloat16 autocast",
    "odmo_default": "ODMO, the bundled default model (its own budget and settings)",
    "odmo_previous": "ODMO, a given earlier model folder (--previous)",
    "a2m": "Action2Motion (so(3) poses through FK, the bundled bandai2-a2m's settings)",
    "a2m_no_lie": "Action2Motion w/o Lie (joint positions)",
}
#: The A2M rows: the bundled model's settings (bench/train_a2m.py), with and without the Lie poses.
A2M_VARIANTS: dict[str, dict[str, Any]] = {
    "a2m": {"pose_rep": "lie", "lr": 1e-3},
    "a2m_no_lie": {"pose_rep": "joints", "lr": 1e-3},
}
# The comparison rows keep the model they had before issue 18 (no bone projection, contact head, velocity
# loss, free-running samples or free-running loss terms); the bundled default row has them.
_BEFORE_18 = {
    "bone_projection": False,
    "foot_contact": False,
    "w_velocity": 0.0,
    "scheduled_sampling": "one_step",
    "w_free": 0.0,
    "w_speed": 0.0,
}
ODMO_VARIANTS: dict[str, dict[str, Any]] = {
    "odmo": dict(_BEFORE_18),
    "odmo_no_contrastive": {"w_contrastive": 0.0, **_BEFORE_18},
    "odmo_no_end": {"use_end_location": False, **_BEFORE_18},
    "odmo_push_only": {"contrastive_pull": 0.0, **_BEFORE_18},
    "odmo_push_bf16": {"contrastive_pull": 0.0, "train_precision": "bfloat16", **_BEFORE_18},
}
# (header, metric key, decimals); "→" means closer to the real row is better.
COLUMNS = (
    ("Acc ↑", "accuracy", 3),
    ("FID ↓", "fid", 3),
    ("Diversity →", "diversity", 3),
    ("Multimodality →", "multimodality", 3),
    ("n-APD →", "n_apd", 3),
    ("Mode homog. (%)", "mode_homogeneity", 2),
    ("Style NMI", "style_nmi", 3),
    ("Style ARI", "style_ari", 3),
    ("End error (m)", "end_error_m", 3),
    ("Recon. error (m)", "reconstruction_error_m", 4),
    ("Recon. acc. ↑", "reconstruction_accuracy", 3),
    ("Bone cv ↓", "bone_length_cv", 4),
    ("Foot skate (m/s) →", "foot_skate_m_s", 3),
    ("Foot pop (m/s) →", "foot_pop_m_s", 2),
    ("Under floor →", "floor_penetration", 3),
    ("Floating →", "float_share", 3),
    ("Hand speed (m/s) →", "hand_speed_m_s", 3),
    ("Hand rhythm (Hz) →", "hand_rhythm_hz", 2),
    ("Jerk (m/s³) →", "jerk_m_s3", 0),
    ("Pelvis height (m) →", "pelvis_height_m", 2),
    ("Heading (°) →", "heading_error_deg", 1),
    ("Torso twist (°) →", "torso_twist_deg", 1),
    ("Foot sync (r) →", "foot_sync", 2),
    ("Feet backward ↓", "feet_backward", 3),
    ("Joint range ↓", "joint_range_excess", 3),
)
# The unconditional table (MoDi): (header, metric key, decimals).
UNCONDITIONAL_COLUMNS = (
    ("FID ↓", "fid", 3),
    ("KID ↓", "kid", 4),
    ("Precision ↑", "precision", 3),
    ("Recall ↑", "recall", 3),
    ("Action KL ↓", "action_kl", 3),
    ("Diversity →", "diversity", 3),
    ("Inversion error (m) ↓", "inversion_error_m", 4),
    ("Bone cv ↓", "bone_length_cv", 4),
    ("Foot skate (m/s) →", "foot_skate_m_s", 3),
    ("Foot pop (m/s) →", "foot_pop_m_s", 2),
    ("Under floor →", "floor_penetration", 3),
    ("Floating →", "float_share", 3),
    ("Hand speed (m/s) →", "hand_speed_m_s", 3),
    ("Hand rhythm (Hz) →", "hand_rhythm_hz", 2),
    ("Jerk (m/s³) →", "jerk_m_s3", 0),
    ("Pelvis height (m) →", "pelvis_height_m", 2),
)


def parse_args(argv: Sequence[str] | None = None) -> argparse.Namespace:
    """Command-line options."""
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--data", type=Path, help="the Bandai-Namco-2 folder (every mode but --modi-only)")
    p.add_argument("--epochs", type=int, default=300, help="epochs of 2,048 windows, every model")
    p.add_argument("--reuse", action="store_true", help="keep finished models in --runs")
    p.add_argument("--runs", type=Path, default=REPO / "runs" / "compare")
    p.add_argument("--results", type=Path, default=RESULTS)
    p.add_argument("--classifier", type=Path, help="evaluation classifier folder (default: the shipped one)")
    p.add_argument("--modi", type=Path, default=MODI_MODEL, help="MoDi model folder whose eval.json to show")
    p.add_argument(
        "--modi-only", action="store_true",
        help="rewrite only the MoDi section of --results from --modi's eval.json (nothing is trained)",
    )  # fmt: skip
    p.add_argument("--classifier-epochs", type=int, default=40)
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--repeats", type=int, default=10)
    p.add_argument("--n-per-action", type=int, default=50)
    p.add_argument("--device", default="auto")
    p.add_argument("--threads", type=int, default=1, help="torch threads")
    p.add_argument(
        "--rows", default=",".join(ROWS), help=f"comma-separated rows to make (default all: {','.join(ROWS)})"
    )
    p.add_argument(
        "--previous", type=Path, action="append", default=[],
        help="an earlier model folder for an odmo_previous row (repeatable)",
    )  # fmt: skip
    p.add_argument(
        "--previous-label", action="append", default=[], help="what each odmo_previous row is called"
    )
    p.add_argument(
        "--model", type=Path, action="append", default=[],
        help="a model folder of any kind evaluated as it is, one row each (repeatable)",
    )  # fmt: skip
    p.add_argument("--model-label", action="append", default=[], help="what each --model row is called")
    args = p.parse_args(argv)
    if args.modi_only:
        return args
    if args.data is None:
        p.error("--data is required (except with --modi-only)")
    args.rows = [r.strip() for r in args.rows.split(",") if r.strip()]
    unknown = sorted(set(args.rows) - set(ROWS))
    if unknown:
        p.error(f"unknown rows {', '.join(unknown)}; choose from {', '.join(ROWS)}")
    if "odmo_previous" in args.rows and not args.previous:
        p.error("the odmo_previous row needs --previous DIR")
    if len(args.previous_label) > len(args.previous):
        p.error("more --previous-label than --previous folders")
    if len(args.model_label) != len(args.model):
        p.error("give one --model-label per --model folder")
    return args


def previous_key(index: int) -> str:
    """Row key of the ``index``-th --previous folder: odmo_previous, odmo_previous_2, ..."""
    return "odmo_previous" if index == 0 else f"odmo_previous_{index + 1}"


def shown(path: Path, outside: str) -> str:
    """``path`` relative to the repository when inside it, else ``outside`` (a placeholder such as the
    option's name: no machine paths, no fragments of a temporary folder)."""
    try:
        return str(Path(path).resolve().relative_to(REPO))
    except ValueError:
        return outside


def _cell(block: dict[str, dict[str, float]], key: str, decimals: int) -> str:
    """``mean ± ci95`` of ``key`` or n/a."""
    value = block.get(key)
    if value is None or not np.isfinite(value["mean"]):
        return "n/a"
    return f"{value['mean']:.{decimals}f} ± {value['ci95']:.{decimals}f}"


def per_action_section(per_action: dict[str, Any], label: str) -> list[str]:
    """Markdown lines: the per-action physical figures of one row, generated / real."""
    rows = per_action_markdown(per_action)
    return [f"## Per action: {label} / real", "", *rows, ""] if rows else []


def per_action_entries(entries: Sequence[dict[str, Any]]) -> list[dict[str, Any]]:
    """The rows whose per-action figures RESULTS.md shows: the bundled ODMO model (else the first row
    that has them) and the faithful Action2Motion."""
    with_figures = [e for e in entries if e.get("per_action")]
    odmo = [e for e in with_figures if e["row"] == "odmo_default"] or with_figures[:1]
    return odmo + [e for e in with_figures if e["row"] == "a2m" and e not in odmo]


def results_markdown(
    real: dict[str, dict[str, float]],
    entries: Sequence[dict[str, Any]],
    info: dict[str, str],
    labels: dict[str, str] | None = None,
    unconditional: dict[str, Any] | None = None,
    dvgan: dict[str, Any] | None = None,
) -> str:
    """RESULTS.md: the table (real row, then one row per entry), the unconditional model's table (its
    evaluation report ``unconditional``, when given) and the bullet list ``info``.

    ``real`` and each entry's ``generated`` are ``{metric: {"mean", "ci95"}}`` blocks; an entry has ``row``
    (a ROWS key) and an optional ``speed`` (decoded motions/s at batch 64).
    """
    headers = [h for h, _, _ in COLUMNS] + ["Decode (motions/s)"]
    lines = [
        "# Results: ODMO, ablations and the Action2Motion baseline",
        "",
        "This file is generated by `bench/compare.py`; do not edit it by hand. Values are mean ± 95 % "
        "interval over the evaluation repeats; → means closer to the real row is better. n/a: the metric "
        "does not apply (A2M has no end location and its evaluation does not score modes; the real row "
        "generates nothing).",
        "",
        "| Model | " + " | ".join(headers) + " |",
        "|---|" + "|".join("---" for _ in headers) + "|",
    ]
    names = ROWS | (labels or {})
    rows = [("Real motions", real, None)]
    rows += [(names[e["row"]], e["generated"], e.get("speed")) for e in entries]
    for name, block, speed in rows:
        cells = [_cell(block, key, d) for _, key, d in COLUMNS]
        if name == "Real motions":
            for key in ("reconstruction_error_m", "reconstruction_accuracy"):
                cells[[k for _, k, _ in COLUMNS].index(key)] = "n/a"
        cells.append("n/a" if speed is None else f"{speed:.0f}")
        lines.append(f"| {name} | " + " | ".join(cells) + " |")
    lines.append("")
    for entry in per_action_entries(entries):
        lines += per_action_section(entry["per_action"], names[entry["row"]])
    if dvgan is not None:
        lines += results_section(dvgan)
    if unconditional is not None:
        lines += unconditional_markdown(unconditional)
    lines += ["## How it was made", ""]
    lines += [f"- **{key}**: {value}" for key, value in info.items()]
    return "\n".join(lines) + "\n"


def unconditional_markdown(report: dict[str, Any]) -> list[str]:
    """The MoDi section: its evaluation report's real and generated rows and what they were measured on."""
    meta = report["meta"]
    headers = [h for h, _, _ in UNCONDITIONAL_COLUMNS]
    lines = [
        "## Unconditional: MoDi",
        "",
        f"The bundled `{meta['model']}`, from its own evaluation report (`eval.json`, written by "
        f"`bench/train_modi.py`): {meta['n_real_clips']} real clips it never trained on, "
        f"{meta['repeats']} repeats of {meta['n_per_action']} prior samples per action (ψ = "
        f"{meta['truncation']:g}), cut to the classifier's {meta['window']} frames and labelled by it "
        "(so accuracy does not apply). Its real clips are "
        + ("the held-out split above." if meta.get("split") == "heldout" else "its training run's own "
           "validation clips, not the held-out split above, so its real row differs from the table's.")
        + f" Inversion: {meta['n_inverted_clips']} of those clips in W+ ({meta['inversion_steps']} steps).",
        "",
        "| Model | " + " | ".join(headers) + " |",
        "|---|" + "|".join("---" for _ in headers) + "|",
    ]  # fmt: skip
    for name, block in (("Real motions", report["real"]), ("MoDi (prior, ψ = 1)", report["generated"])):
        cells = [_cell(block, key, d) for _, key, d in UNCONDITIONAL_COLUMNS]
        lines.append(f"| {name} | " + " | ".join(cells) + " |")
    shares = {a: row["generated"]["predicted_share"]["mean"] for a, row in report["per_action"].items()
              if "predicted_share" in row["generated"]}  # fmt: skip
    if shares:
        lines += [
            "",
            "Predicted action of its samples: " + ", ".join(f"{a} {v:.1%}" for a, v in shares.items()),
        ]
    lines += [
        "",
        "This section alone is rewritten from its `eval.json` by `python bench/compare.py --modi-only`.",
    ]
    return [*lines, ""]


def _write_modi_section(results: Path, report_path: Path) -> int:
    """Replace (or add, before "How it was made") the MoDi section of ``results`` from ``report_path``."""
    section = "\n".join(unconditional_markdown(json.loads(report_path.read_text())))
    replace_section(results, "## Unconditional: MoDi", section, before="## How it was made")
    print(f"wrote the MoDi section of {results}")
    return 0


def _choose_classifier(
    args: argparse.Namespace, train_clips: Sequence[Motion], names: list[str], skeleton_names: tuple[str, ...]
) -> Classifier:
    """The given classifier, else the shipped one if it fits the data, else one trained on the train split."""
    candidates = [args.classifier] if args.classifier else list(CLASSIFIERS)
    for folder in candidates:
        if not (folder / "classifier.json").is_file():
            continue
        clf = load_classifier(folder)
        fits = clf.config.window == WINDOW and clf.config.fps == FPS
        if fits and set(names) <= set(clf.action_names) and clf.skeleton_names == skeleton_names:
            return clf
        log.warning("%s does not fit this data set; not used", folder)
    out = args.runs / "classifier"
    if (out / "classifier.json").is_file() and args.reuse:
        return load_classifier(out)
    return train_classifier(
        train_clips, names, out, epochs=args.classifier_epochs, seed=args.seed, window=WINDOW, fps=FPS
    )


def _finished(folder: Path, epochs: int) -> bool:
    """Whether ``folder`` holds a model trained for ``epochs`` epochs."""
    meta = folder / META_FILE
    return meta.is_file() and json.loads(meta.read_text()).get("provenance", {}).get("epochs") == epochs


def _default_matches(config: OdmoConfig | None, fingerprint: str, seed: int) -> bool:
    """Whether the shipped default model was trained on the same data and seed, and (unless ``config`` is
    None) with exactly ``config``."""
    meta_file = DEFAULT_MODEL / META_FILE
    if not meta_file.is_file() or (config is not None and not _finished(DEFAULT_MODEL, config.epochs)):
        return False
    meta = json.loads(meta_file.read_text())
    prov = meta["provenance"]
    same_config = config is None or OdmoConfig.from_dict(meta["config"]) == config
    return same_config and prov["data_fingerprint"] == fingerprint and prov["seed"] == seed


def _bar(name: str, epochs: int) -> tuple[tqdm, Callable[[TrainProgress], None]]:
    """A tqdm bar over epochs and the progress callback that moves it."""
    bar = tqdm(total=epochs, desc=name, unit="epoch")

    def show(p: TrainProgress) -> None:
        if p.stage == "train" and p.step == p.steps:
            bar.n = p.epoch
            bar.set_postfix({k: f"{v:.3g}" for k, v in p.losses.items()} | {"w/s": f"{p.windows_per_s:.0f}"})
            bar.refresh()

    return bar, show


def speeds(decoders: dict[str, Callable[[], object]], repeats: int = 20) -> dict[str, float]:
    """Motions per second of each decoder (a batch of SPEED_BATCH): the median of ``repeats`` rounds that
    time every decoder once in turn, so that the machine's load drifts over all of them alike."""
    times: dict[str, list[float]] = {name: [] for name in decoders}
    for decode in decoders.values():
        decode()
    for _ in range(repeats):
        for name, decode in decoders.items():
            t0 = time.perf_counter()
            decode()
            times[name].append(time.perf_counter() - t0)
    return {name: SPEED_BATCH / float(np.median(t)) for name, t in times.items()}


def odmo_decoder(loaded: LoadedModel) -> Callable[[], None]:
    """One ODMO decode of a batch of 64 (codes and end locations of the bank)."""
    bank = loaded.bank
    idx = np.arange(SPEED_BATCH) % len(bank.codes)
    z = torch.from_numpy(np.asarray(bank.codes[idx], np.float32))
    actions = torch.from_numpy(np.asarray(bank.actions[idx], np.int64))
    ends = (
        torch.from_numpy(np.asarray(bank.ends[idx], np.float32)) if loaded.config.use_end_location else None
    )

    def decode() -> None:
        decode_tensors(loaded, z, actions, ends)  # bone projection and foot clean-up included

    return decode


def a2m_decoder(loaded: LoadedA2m) -> Callable[[], None]:
    """One A2M sampling of a batch of 64 (prior sampling, seed 0)."""
    actions = torch.arange(SPEED_BATCH) % loaded.config.n_actions
    generator = torch.Generator().manual_seed(0)

    def decode() -> None:
        with torch.inference_mode():
            loaded.model.sample(actions, generator)

    return decode


def sample_decoder(generator: Generator) -> Callable[[], None]:
    """One ``sample`` of a batch of 64 of the generator's first action (seed 0), as the CLI makes it."""
    request = SampleRequest(generator.label_names[0], SPEED_BATCH, 0)

    def decode() -> None:
        generator.sample(request)

    return decode


#: Path options and how a value outside the repository is shown.
_PATH_OPTIONS = {
    "--data": "DATA",
    "--previous": "PREVIOUS",
    "--model": "MODEL",
    "--classifier": "CLASSIFIER",
    "--runs": "RUNS",
    "--results": "RESULTS",
}


def _shown_argv(argv: Sequence[str]) -> list[str]:
    """The command line with path values shown by ``shown`` (no machine paths) and spaces quoted."""
    out = []
    for i, token in enumerate(argv):
        if i > 0 and argv[i - 1] in _PATH_OPTIONS:
            token = shown(Path(token), _PATH_OPTIONS[argv[i - 1]])
        out.append(f"'{token}'" if " " in token else token)
    return out


def engine_fingerprint() -> str:
    """A hash of every engine source file: an evaluation the engine made before a code change is stale."""
    digest = hashlib.sha256()
    for path in sorted((REPO / "engine").rglob("*.py")):
        digest.update(path.relative_to(REPO).as_posix().encode() + b"\0" + path.read_bytes())
    return digest.hexdigest()[:16]


def _fresh_eval(
    saved: Path, folder: Path, classifier: Classifier, evaluation: dict[str, Any], strategy: str | None
) -> bool:
    """Whether ``saved`` evaluated the model now in ``folder`` (written after its weights) with this
    classifier (same held-out accuracy), evaluation settings, strategy (None: whichever its kind's
    evaluation uses) and engine code (``engine_fingerprint``)."""
    weights = Path(folder) / "model.safetensors"
    if not saved.is_file() or not weights.is_file() or saved.stat().st_mtime < weights.stat().st_mtime:
        return False
    meta = json.loads(saved.read_text()).get("meta", {})
    same_strategy = strategy is None or meta.get("strategy") == strategy
    same = all(meta.get(k) == v for k, v in evaluation.items()) and same_strategy
    same_classifier = meta.get("classifier_test_accuracy") == classifier.test_accuracy
    same_code = meta.get("engine_fingerprint") == engine_fingerprint()
    return same and same_classifier and same_code and meta.get("model") == str(folder)


def _saved_or_run(saved: Path, reuse: bool, run: Callable[[], dict[str, Any]]) -> tuple[dict[str, Any], bool]:
    """``saved``'s evaluation report when ``reuse``, else ``run()``'s, written to ``saved``; and whether it
    was reused."""
    if reuse:
        return json.loads(saved.read_text()), True
    report = run()
    report["meta"] = report.get("meta", {}) | {"engine_fingerprint": engine_fingerprint()}
    atomic_write_text(saved, json.dumps(report, indent=2))
    return report, False


def _reused_note(saved: Path) -> str:
    """The Models note of a reused evaluation."""
    return f" (evaluation reused from {shown(saved, f'RUNS/{saved.name}')})"


def _check_same_real(first: dict[str, Any], other: dict[str, Any], row: str) -> None:
    """RuntimeError unless ``row`` was evaluated against the same real sets (NaN-safe comparison)."""
    if json.dumps(first, sort_keys=True) != json.dumps(other, sort_keys=True):
        raise RuntimeError(f"{row}: the real sets differ from the first evaluation's")


def main(argv: Sequence[str] | None = None) -> int:
    """Train or reuse every model, evaluate them all, write RESULTS.md."""
    args = parse_args(argv)
    if args.modi_only:
        return _write_modi_section(args.results, args.modi / "eval.json")
    logging.basicConfig(level=logging.INFO, format="%(name)s: %(message)s")
    torch.set_num_threads(args.threads)
    started = time.time()
    dataset = load_folder(args.data)
    train_clips, test_clips = heldout_split(dataset.clips)
    names = list(dataset.action_names)
    skeleton = dataset.skeleton
    fingerprint = prepare_clips(train_clips, names, FPS, WINDOW).fingerprint()
    classifier = _choose_classifier(args, train_clips, names, tuple(skeleton.names))
    evaluation = {"repeats": args.repeats, "n_per_action": args.n_per_action, "seed": args.seed}

    folders: dict[str, Path] = {}
    notes: dict[str, str] = {}
    wanted = set(args.rows)
    for key, changes in ODMO_VARIANTS.items():
        if key not in wanted and not (key == "odmo" and "odmo_conv" in wanted):
            continue
        config = OdmoConfig(n_actions=len(names), n_joints=skeleton.n_joints, epochs=args.epochs, **changes)
        folder = args.runs / key
        if key == "odmo" and _default_matches(config, fingerprint, args.seed):
            folder, notes[key] = DEFAULT_MODEL, f"reused the default model {shown(DEFAULT_MODEL, 'DEFAULT')}"
        elif args.reuse and _finished(folder, args.epochs):
            notes[key] = f"reused {shown(folder, f'RUNS/{key}')}"
        else:
            bar, show = _bar(key, config.epochs)
            train(
                train_clips, names, folder, config, seed=args.seed, device=args.device, resume=args.reuse,
                progress=show, bank_projections=("pca",),
            )  # fmt: skip
            bar.close()
            notes[key] = f"trained into {shown(folder, f'RUNS/{key}')}"
        folders[key] = folder
    default_wanted = "odmo_default" in wanted and DEFAULT_MODEL not in folders.values()
    if default_wanted and _default_matches(None, fingerprint, args.seed):
        folders["odmo_default"] = DEFAULT_MODEL
        provenance = json.loads((DEFAULT_MODEL / META_FILE).read_text())["provenance"]
        start = provenance.get("warm_start")
        origin = f" from the {start['epochs']}-epoch weights {start['weights_sha256'][:12]}" if start else ""
        notes["odmo_default"] = (
            f"{shown(DEFAULT_MODEL, 'DEFAULT')}, trained {provenance['epochs']} epochs{origin} by "
            "bench/train_default.py (its MODEL_CARD.md has the command and settings)"
        )
    labels = {}
    previous = [previous_key(i) for i in range(len(args.previous))] if "odmo_previous" in wanted else []
    for i, key in enumerate(previous):
        folders[key] = args.previous[i]
        labels[key] = args.previous_label[i] if i < len(args.previous_label) else ROWS["odmo_previous"]
        notes[key] = f"evaluated as it is ({shown(args.previous[i], 'PREVIOUS')})"
    a2m_config = A2mConfig(n_actions=len(names), n_joints=skeleton.n_joints, epochs=args.epochs)
    for key, changes in A2M_VARIANTS.items():
        if key not in wanted:
            continue
        config = A2mConfig(n_actions=len(names), n_joints=skeleton.n_joints, epochs=args.epochs, **changes)
        folders[key] = args.runs / key
        if args.reuse and _finished(folders[key], args.epochs):
            notes[key] = f"reused {shown(folders[key], f'RUNS/{key}')}"
        else:
            bar, show = _bar(key, config.epochs)
            train_a2m(
                train_clips, names, folders[key], config, seed=args.seed, device=args.device,
                resume=args.reuse, progress=show, bank_projections=("pca",),
            )  # fmt: skip
            bar.close()
            notes[key] = f"trained into {shown(folders[key], f'RUNS/{key}')}"

    entries: list[dict[str, Any]] = []
    decoders: dict[str, Callable[[], None]] = {}
    real: dict[str, dict[str, float]] = {}
    for row, key, strategy in (
        ("odmo", "odmo", "mode_preserving"),
        ("odmo_conv", "odmo", "conventional"),
        ("odmo_no_contrastive", "odmo_no_contrastive", "mode_preserving"),
        ("odmo_no_end", "odmo_no_end", "mode_preserving"),
        ("odmo_push_only", "odmo_push_only", "mode_preserving"),
        ("odmo_push_bf16", "odmo_push_bf16", "mode_preserving"),
        ("odmo_default", "odmo_default", "mode_preserving"),
        *((key, key, "mode_preserving") for key in previous),
    ):
        if key not in folders or (row not in wanted and row not in previous):
            continue
        loaded = load_model(folders[key], device="cpu")
        saved = args.runs / f"eval_{row}.json"
        report, reused = _saved_or_run(
            saved,
            args.reuse and _fresh_eval(saved, folders[key], classifier, evaluation, strategy),
            lambda loaded=loaded, strategy=strategy: evaluate(
                loaded, test_clips, classifier, strategy=strategy, **evaluation
            ),
        )
        if reused:
            notes[key] = notes.get(key, "") + _reused_note(saved)
        real = real or report["real"]
        _check_same_real(real, report["real"], row)
        entries.append({"row": row, "generated": report["generated"], "per_action": report["per_action"]})
        decoders[row] = odmo_decoder(loaded)
        log.info("%s evaluated", row)
    for key in A2M_VARIANTS:
        if key not in folders:
            continue
        a2m = load_a2m(folders[key], device="cpu")
        saved = args.runs / f"eval_{key}.json"
        report, reused = _saved_or_run(
            saved,
            args.reuse and _fresh_eval(saved, folders[key], classifier, evaluation, None),
            lambda a2m=a2m: evaluate_a2m(a2m, test_clips, classifier, **evaluation),
        )
        if reused:
            notes[key] += _reused_note(saved)
        real = real or report["real"]
        _check_same_real(real, report["real"], key)
        entries.append({"row": key, "generated": report["generated"], "per_action": report["per_action"]})
        decoders[key] = a2m_decoder(a2m)
    for i, folder in enumerate(args.model):
        key = f"model_{i + 1}"
        generator = open_generator(folder)
        labels[key] = args.model_label[i]
        notes[key] = f"evaluated as it is ({shown(folder, 'MODEL')}, a {generator.kind} model)"
        saved = args.runs / f"eval_{key}.json"
        report, reused = _saved_or_run(
            saved,
            args.reuse and _fresh_eval(saved, folder, classifier, evaluation, None),
            lambda generator=generator: evaluate_generator(generator, test_clips, classifier, **evaluation),
        )
        if reused:
            notes[key] += _reused_note(saved)
        real = real or report["real"]
        _check_same_real(real, report["real"], key)
        entries.append({"row": key, "generated": report["generated"], "per_action": report["per_action"]})
        decoders[key] = sample_decoder(generator)
    measured = speeds(decoders)
    for entry in entries:
        entry["speed"] = measured[entry["row"]]

    windows = f"{a2m_config.epoch_size:,}"
    info = {
        "Data": f"`{shown(args.data, args.data.name)}`: {len(dataset.clips)} clips, {len(names)} actions "
        f"({', '.join(names)}), {skeleton.n_joints} joints, windows of 60 frames at 20 fps",
        "Split": f"`bench/heldout.py`: {HELDOUT_FRACTION:.0%} of the clips of every action × style held out "
        f"(seed {SPLIT_SEED}): {len(train_clips)} train, {len(test_clips)} held-out; every model also keeps "
        "10 % of its train clips for validation (seed of the model)",
        "Budget": f"{args.epochs} epochs × {windows} class-balanced windows for every model "
        f"(ODMO: batch 128 = 64 contrastive pairs, Adam 1e-3; A2M: batch {a2m_config.batch_size}, "
        f"Adam {A2M_VARIANTS['a2m']['lr']:g}, weight decay {a2m_config.weight_decay:g}, "
        f"λ_KL {a2m_config.kl_weight:g}, λ_trajec {a2m_config.trajectory_weight:g}, "
        f"teacher forcing p {a2m_config.tf_rate:g} per batch)"
        + (
            "; the bundled default row keeps its own budget (see Models)" if "odmo_default" in folders else ""
        ),
        "Models": "; ".join(f"{(ROWS | labels)[k]}: {v}" for k, v in notes.items()),
        "Seeds": f"training seed {args.seed}; evaluation seed {args.seed} "
        f"({args.repeats} repeats × {args.n_per_action} motions per action, repeat r uses rng [seed, r])",
        "Classifier": f"`{shown(classifier.path, 'CLASSIFIER')}`: accuracy {classifier.test_accuracy:.3f} "
        "on every window "
        f"(stride {classifier.config.stride}) of {classifier.n_test} held-out training-side clips; "
        "per action "
        + ", ".join(f"{a} {v:.3f}" for a, v in classifier.test_accuracy_per_action.items())
        + "; the same classifier and real sets for every row",
        "Physical figures": "`engine.metrics.physics` at display height (floor y = 0): worst-bone length "
        "std/mean per clip (median), horizontal speed of foot joints planted within 3 cm of the clip's "
        "lowest foot height, the 99th percentile of the foot joints' vertical speed (foot pop: feet "
        "released from or slammed onto the floor), share of frames with the lowest foot joint > 2 cm under "
        "the floor, share of clips whose feet stay > 10 cm up for 0.5 s, mean hand speed, mean jerk of "
        "every joint, the angle between the hips' facing line and the pelvis's travel over 0.5 s where it "
        "moves at 0.5 m/s or more (heading), the mean absolute angle between the shoulders' axis and the "
        "hips' (torso twist), the correlation of the two ankles' horizontal velocities relative to the "
        "pelvis per clip (foot sync: real gaits alternate, about −0.5 to −0.9; standing actions near +1)",
        "Rows": "this run made "
        + ", ".join((ROWS | labels)[e["row"]] for e in entries)
        + (
            "; rows not listed were not re-run (the previous full table, with the earlier classifier, is in "
            "this file's git history)"
            if set(args.rows) != set(ROWS) - {"odmo_previous"}
            else ""
        ),
        "Reconstruction": "ODMO: encode → decode with the true action and end location; A2M: posterior means "
        "z_1..z_T of the real window, decoded free-running (A2M: a 30-d code per frame; ODMO: one 20-d code)",
        "Decode speed": f"motions/s at batch {SPEED_BATCH}, median of 20 rounds that time every row in "
        f"turn, CPU, {torch.get_num_threads()} torch thread(s); ODMO: one decode of bank codes; A2M: prior "
        "sampling; --model rows: `sample` of their first action, as the CLI makes it",
        "Machine": machine(),
        "Date": dt.datetime.now(dt.UTC).strftime("%Y-%m-%d %H:%M UTC"),
        "Wall time": f"{(time.time() - started) / 60:.1f} min",
        "Command": "`"
        + " ".join(["python", "bench/compare.py", *_shown_argv(argv if argv is not None else sys.argv[1:])])
        + "`",
        "Reproduce": f"`python bench/compare.py --data DATA --epochs {args.epochs} --repeats {args.repeats} "
        f"--n-per-action {args.n_per_action} --classifier-epochs {args.classifier_epochs} "
        f"--seed {args.seed}` "
        "(add `--reuse` to keep trained models; the classifier is the shipped one when present)",
    }
    modi_report = args.modi / "eval.json"
    unconditional = json.loads(modi_report.read_text()) if modi_report.is_file() else None
    dvgan_report = DVGAN_MODEL / "eval.json"
    dvgan = json.loads(dvgan_report.read_text()) if dvgan_report.is_file() else None
    atomic_write_text(args.results, results_markdown(real, entries, info, labels, unconditional, dvgan))
    print(f"wrote {args.results}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
