"""Write MODEL_CARD.md for the default model from its evaluation report (never typed by hand)."""

from __future__ import annotations

import datetime as dt
import json
from pathlib import Path
from typing import Any

from bench.warm_start import warm_start_line
from engine.fileio import atomic_write_text
from engine.metrics.per_action import per_action_markdown

METRICS = (
    ("accuracy", "Recognition accuracy (0..1)"),
    ("fid", "FID (classifier features)"),
    ("diversity", "Diversity"),
    ("multimodality", "Multimodality"),
    ("apd", "APD (m)"),
    ("n_apd", "n-APD"),
    ("mode_homogeneity", "Mode homogeneity"),
    ("style_nmi", "Style NMI of modes"),
    ("style_ari", "Style ARI of modes"),
    ("end_error_m", "End-point error (m)"),
    ("end_error_pct", "End-point error (% of root travel)"),
    ("reconstruction_error_m", "Reconstruction error (m)"),
    ("reconstruction_accuracy", "Held-out reconstructions recognised as their action (0..1)"),
    ("bone_length_cv", "Worst-bone length variation (std/mean, median over clips)"),
    ("foot_skate_m_s", "Planted-foot speed (m/s)"),
    ("foot_pop_m_s", "Foot pop: vertical foot speed, 99th percentile of frame steps (m/s)"),
    ("floor_penetration", "Frames with a foot > 2 cm under the floor (share)"),
    ("floor_depth_m", "Deepest foot point under the floor (m)"),
    ("float_share", "Clips floating > 10 cm for ≥ 0.5 s (share)"),
    ("hand_speed_m_s", "Mean hand speed (m/s)"),
    ("hand_amplitude_m", "Hand oscillation amplitude (m, RMS about its mean)"),
    ("late_hand_speed_m_s", "Hand speed over each clip's last third (m/s)"),
    ("hand_rhythm_hz", "Hand rhythm: power-weighted mean frequency of the hands' velocity (Hz)"),
    ("foot_speed_m_s", "Mean foot speed (m/s)"),
    ("foot_amplitude_m", "Foot oscillation amplitude (m)"),
    ("jerk_m_s3", "Mean jerk (m/s³)"),
    ("pelvis_height_m", "Pelvis height over the floor (m, mean over frames)"),
    ("heading_error_deg", "Heading: body's facing line against its direction of travel (degrees)"),
    ("torso_twist_deg", "Torso twist: shoulders' axis against the hips' (degrees, mean absolute)"),
    ("foot_sync", "Foot sync: correlation of the two ankles' velocities (−: alternating, +1: a hop)"),
    ("feet_backward", "Planted feet pointing against the direction of travel (share of moving spans)"),
    ("joint_range_excess", "Joint rotations outside 99 % of real ones (share of frame × joint)"),
)
SKATE_FLOOR = 0.02  # m/s: the planted-foot target for actions that stand still
POP_RATIO, POP_FLOOR = 1.25, 0.1  # foot pop a model may reach: 1.25× real's, 0.1 m/s for standing actions
PELVIS_TOL = 0.10  # how far (share of real) a model's mean pelvis height may lie from real's
SYNC_TOL = 0.3  # foot sync (a correlation) a gait may differ from real's: walks −0.4 to −0.65, a hop +1
BACKWARD_TOL = 0.05  # share of planted feet pointing against travel a model may add to real's (0–0.1 %)
STEP_SPEED = 0.1  # m/s: real feet slower than this on average do not step, so have no gait to alternate


REPO = Path(__file__).resolve().parents[1]


def licence_lines() -> list[str]:
    """The card section on the data's licence, for a model and bank in a folder with the dataset's LICENSE."""
    return [
        "## Data and licence",
        "",
        "Bandai Namco Research Inc., *Bandai-Namco-Research-Motiondataset* (dataset 2), 2022, "
        "**CC BY-NC 4.0** (LICENSE, copied from the dataset). The model and its latent bank are derived "
        "from this data and inherit the **non-commercial** term; keep the attribution wherever they ship.",
    ]


def repo_path(path: Path) -> str:
    """``path`` relative to the repository when inside it, else its name (no machine paths on a card)."""
    try:
        return str(path.resolve().relative_to(REPO))
    except ValueError:
        return path.name


def cell(summary: dict[str, Any], key: str) -> str:
    """``mean ± ci95`` of one metric, or a dash when it was not measured."""
    if key not in summary:
        return "–"
    return f"{summary[key]['mean']:.4g} ± {summary[key]['ci95']:.2g}"


def metric_table(report: dict[str, Any], model: str = "ODMO") -> list[str]:
    """Markdown rows: each metric for real held-out motion and for ``model``'s generated motion."""
    rows = [f"| metric | real (held-out) | {model} (generated) |", "|---|---|---|"]
    keys = dict(METRICS)
    extra = sorted(set(report["generated"]) - set(keys))
    for key, label in (*METRICS, *((k, k) for k in extra)):
        if key in report["real"] or key in report["generated"]:
            rows.append(f"| {label} | {cell(report['real'], key)} | {cell(report['generated'], key)} |")
    return rows


def per_action_table(report: dict[str, Any]) -> list[str]:
    """Markdown rows: each physical figure per action, generated / real."""
    return per_action_markdown(report.get("per_action") or {})


def physics_targets(report: dict[str, Any]) -> list[str]:
    """The plausibility targets of issue 18, judged per action (generated against real held-out clips)."""
    per_action = report.get("per_action") or {}
    if not per_action:
        return []

    def mean(side: dict[str, Any], key: str) -> float:
        return float(side[key]["mean"]) if key in side else float("nan")

    checks = {  # name: (the metric it needs, the check of one action's generated and real sides)
        "worst-bone length variation ≤ 1 %": (
            "bone_length_cv",
            lambda g, r: mean(g, "bone_length_cv") <= 0.01,
        ),
        "planted-foot speed ≤ 1.5× real (2 cm/s floor)": (
            "foot_skate_m_s",
            lambda g, r: mean(g, "foot_skate_m_s") <= max(1.5 * mean(r, "foot_skate_m_s"), SKATE_FLOOR),
        ),
        "feet lifting and landing no faster than real ones (foot pop ≤ 1.25× real, 0.1 m/s floor; this "
        "project's)": (
            "foot_pop_m_s",
            lambda g, r: mean(g, "foot_pop_m_s") <= max(POP_RATIO * mean(r, "foot_pop_m_s"), POP_FLOOR),
        ),
        "body at its real height (pelvis height within 10 % of real; this project's)": (
            "pelvis_height_m",
            lambda g, r: abs(mean(g, "pelvis_height_m") / mean(r, "pelvis_height_m") - 1) <= PELVIS_TOL,
        ),
        "under 1 % of frames with a foot 2 cm under the floor": (
            "floor_penetration",
            lambda g, r: mean(g, "floor_penetration") < 0.01,
        ),
        "floating clips at most 10 points above real": (
            "float_share",
            lambda g, r: mean(g, "float_share") <= mean(r, "float_share") + 0.10,
        ),
        "mean hand speed ≥ 0.8× real": (
            "hand_speed_m_s",
            lambda g, r: mean(g, "hand_speed_m_s") >= 0.8 * mean(r, "hand_speed_m_s"),
        ),
        "feet alternating as real ones (foot sync within 0.3 of real where real feet step; this project's)": (
            "foot_sync",
            lambda g, r: (
                mean(r, "foot_speed_m_s") < STEP_SPEED
                or abs(mean(g, "foot_sync") - mean(r, "foot_sync")) <= SYNC_TOL
            ),
        ),
        "feet pointing the way they go (feet backward at most 5 points above real where real ones travel; "
        "this project's)": (
            "feet_backward",
            lambda g, r: not mean(r, "feet_backward") < mean(g, "feet_backward") - BACKWARD_TOL,
        ),
    }
    lines = []
    for name, (metric, check) in checks.items():
        if not any(metric in side["generated"] for side in per_action.values()):
            continue  # an evaluation made before the metric existed: nothing to judge
        failed = [a for a, s in per_action.items() if not check(s["generated"], s["real"])]
        verdict = "met" if not failed else f"missed ({', '.join(failed)})"
        lines.append(f"- {name}: {len(per_action) - len(failed)}/{len(per_action)} actions — {verdict}.")
    return lines


def targets(report: dict[str, Any], smooth: dict[str, Any]) -> list[str]:
    """The issue's quality targets that can be judged from this report, each with its verdict."""
    real, gen = report["real"], report["generated"]
    lines = []
    if "accuracy" in real and "accuracy" in gen:
        gap = 100 * (real["accuracy"]["mean"] - gen["accuracy"]["mean"])
        lines.append(
            f"- Accuracy within 5 points of real held-out motion: gap {gap:.1f} points — "
            f"{'met' if gap <= 5 else 'missed'}."
        )
    if "end_error_pct" in gen:
        pct = gen["end_error_pct"]["mean"]
        lines.append(
            f"- End-point error under 5 % of root travel (inside the training range): {pct:.2f} % — "
            f"{'met' if pct < 5 else 'missed'}"
            + (" (by construction: see Model above)." if pct < 1e-3 else ".")
        )
    if "control_accuracy" in gen and "accuracy" in gen:
        gap = 100 * (gen["accuracy"]["mean"] - gen["control_accuracy"]["mean"])
        lines.append(
            f"- Controlled accuracy within 3 points of uncontrolled: gap {gap:.1f} points — "
            f"{'met' if gap <= 3 else 'missed'}."
        )
    if smooth:
        worse = [a for a, v in smooth.items() if v["generated"] > v["real"]]
        lines.append(
            f"- Interpolation between two modes never jumps more than real clips of the action: "
            f"{len(smooth) - len(worse)}/{len(smooth)} actions — {'met' if not worse else 'missed'}"
            + (f" ({', '.join(worse)})." if worse else ".")
        )
    if "fid" in real and "fid" in gen:
        ratio = gen["fid"]["mean"] / max(real["fid"]["mean"], 1e-12)
        lines.append(
            f"- FID at most 10× the real-vs-real floor: {gen['fid']['mean']:.3g} against "
            f"{real['fid']['mean']:.3g} ({ratio:.1f}×) — {'met' if ratio <= 10 else 'missed'}."
        )
    if "style_nmi" in gen:
        nmi = gen["style_nmi"]["mean"]
        lines.append(f"- Style NMI ≥ 0.45: {nmi:.3f} — {'met' if nmi >= 0.45 else 'missed'}.")
    lines += physics_targets(report)
    lines.append(
        "- FID against the Action2Motion-style baseline and style NMI against the plain-VAE "
        "ablation: see `docs/RESULTS.md` (generated by `bench/compare.py`)."
    )
    return lines


def write_model_card(out: Path, report: dict[str, Any], info: dict[str, Any], smooth: dict[str, Any]) -> None:
    """Write ``out/MODEL_CARD.md``."""
    hours = info["train_seconds"] / 3600
    lines = [
        "# bandai2-odmo — the default ODMO Explorer model",
        "",
        "ODMO (Lu et al., ACM MM 2022), re-implemented in this project, trained on real motion capture.",
        "This card is generated by `bench/train_default.py`; do not edit it by hand.",
        "",
        "## Data and licence",
        "",
        "Bandai Namco Research Inc., *Bandai-Namco-Research-Motiondataset* (dataset 2), 2022, "
        "**CC BY-NC 4.0**: 10 actions × 7 styles, 2,902 BVH clips at 30 fps. The model, its latent bank "
        "and its classifier are derived from this data and inherit the **non-commercial** term; keep the "
        "attribution wherever they ship. The style label is never used in training; it is the ground "
        "truth that discovered modes are compared with.",
        "",
        "## Training",
        "",
        f"- Command: `{info['command']}`",
        f"- Seed: {info['seed']}; epochs: {info['epochs']} (2,048 class-balanced windows each)",
        f"- Training time: {info['train_seconds']:.0f} s ({hours:.2f} h) at {info['windows_per_s']:.0f} "
        f"windows/s on {info['device']}",
        f"- Clips: {info['n_train']} training + {info['n_val']} validation; {info['n_heldout']} held out "
        f"for evaluation ({info['heldout']}; listed in `heldout_clips.txt`)",
        f"- Data fingerprint: `{info['fingerprint']}`",
        f"- Model: {info['model_switches']}",
        *warm_start_line(info.get("warm_start")),
        f"- Evaluation classifier (in `classifier/`): accuracy {info['classifier_accuracy']:.3f} on every "
        "window (stride 10) of held-out training-side clips"
        + (
            "; per action: " + ", ".join(f"{a} {v:.3f}" for a, v in info["classifier_per_action"].items())
            if info.get("classifier_per_action")
            else ""
        ),
        f"- Written: {dt.datetime.now(dt.UTC).strftime('%Y-%m-%d %H:%M UTC')}",
        "",
        "## Evaluation on held-out clips",
        "",
        f"`odmo eval`'s core (`engine.metrics.evaluate`) with repeats = {report['meta']['repeats']}, "
        f"{report['meta']['n_per_action']} motions per action, strategy {report['meta']['strategy']}; "
        "mean ± 95 % interval (1.96·s/√n).",
        "",
        *metric_table(report),
        "",
        "Physical figures: feet are the Foot/Toes joints, hands the Hand joints (found by name), floor "
        "y = 0; a foot joint is planted within 3 cm of the clip's lowest foot height; foot pop is the 99th "
        "percentile of the foot joints' vertical speed over every frame step (`engine.metrics.physics`).",
        "",
        "## Per action (generated / real)",
        "",
        *per_action_table(report),
        "",
        "## Quality targets",
        "",
        *targets(report, smooth),
        "",
    ]
    if smooth:
        lines += [
            "## Interpolation smoothness (largest frame-to-frame joint step, m)",
            "",
            "| action | modes | generated | real |",
            "|---|---|---|---|",
        ]
        lines += [
            f"| {a} | {v['modes']} | {v['generated']:.4f} | {v['real']:.4f} |" for a, v in smooth.items()
        ]
        lines.append("")
    atomic_write_text(out / "MODEL_CARD.md", "\n".join(lines))


def card_argv(argv: list[str]) -> list[str]:
    """The command line as the card shows it: the data folder as DATA, the warm start's folder relative to
    the repository, no --work/--out/--skip-train/--reuse-eval/--no-results (they only say where files go),
    so no machine paths."""
    out, skip = [], False
    for i, token in enumerate(argv):
        if skip:
            skip = False
            continue
        name = token.split("=", 1)[0]
        if name in ("--work", "--out"):
            skip = "=" not in token
            continue
        if name in ("--skip-train", "--reuse-eval", "--no-results"):
            continue
        if i > 0 and argv[i - 1] == "--data":
            token = "DATA"
        elif i > 0 and argv[i - 1] == "--warm-start":
            token = repo_path(Path(token))
        elif name == "--data" and "=" in token:
            token = "--data=DATA"
        out.append(token)
    return out


TRAINING_COMMAND = "train_command.json"


def training_argv(work: Path, argv: list[str], trained: bool) -> list[str]:
    """The training's options as a card shows them (``card_argv``): this run's when it ``trained``,
    recorded in ``work``; a run that only evaluates that folder (``--skip-train``, perhaps with other
    options such as ``--threads``) gets the recorded ones, or its own where the training recorded none."""
    record = work / TRAINING_COMMAND
    if trained:
        atomic_write_text(record, json.dumps(card_argv(argv)))
    return json.loads(record.read_text()) if record.is_file() else card_argv(argv)


def training_command(script: str, work: Path, argv: list[str], trained: bool) -> str:
    """The card's training command: ``script`` with its ``training_argv``."""
    return " ".join(["python", script, *training_argv(work, argv, trained)])
