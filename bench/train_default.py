"""Reproduce the bundled default model: ODMO on Bandai-Namco-2, its classifier, its evaluation and card.

    python bench/train_default.py --data "$(../shared/data/unpack)" [--resume]

The defaults are the bundled model's settings (100 epochs, teacher forcing decaying from 1 towards 0.3
over those 100 epochs, no same-action pull, the loss weights of ``BUNDLED_WEIGHTS``, log speed errors, the
free-running skate term on the decode's own contacts, the reversed encoder, the residual pose decoder
started at the mean pose, seed 0, one torch thread: training results differ between thread counts).
``--warm-start FOLDER`` starts from a model folder's weights instead (a fine-tune, e.g. with another loss
weight and ``--tf-start 0.3``). The evaluation classifier in --work/classifier is reused when present.

Holds out 15 % of the clips (stratified by action and style, seed 2022; see bench/heldout.py), trains
ODMO on the rest, trains the evaluation classifier on the same training clips, evaluates on the held-out
clips with ``engine.metrics.evaluate`` and writes the model folder with MODEL_CARD.md. Resumable.
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import platform
import shutil
import sys
import time
from pathlib import Path

import numpy as np
import torch
from tqdm import tqdm

if __package__ in (None, ""):
    sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from bench.heldout import HELDOUT_FRACTION, SPLIT_SEED, heldout_split
from bench.model_card import training_command, write_model_card
from bench.warm_start import warm_start_from
from engine.fileio import atomic_write_text
from engine.generate import interpolate
from engine.metrics.classifier import load_classifier, train_classifier
from engine.metrics.evaluate import evaluate
from engine.metrics.smoothness import max_frame_jump
from engine.model.config import (
    COORDINATION_ON,
    FREE_SKATE_CONTACTS,
    POSE_OUTPUTS,
    POSE_UPDATES,
    SPEED_ERRORS,
    OdmoConfig,
)
from engine.modelio import load_model
from engine.motion.datasets import load_folder
from engine.motion.resample import resample_motion
from engine.train.loop import train

#: The bundled model's loss weights where they differ from OdmoConfig's defaults (README, "Where the model
#: differs from the paper").
BUNDLED_WEIGHTS = ("w_skate=0.01", "w_free=1", "w_speed=0.1", "w_velocity=0.1", "w_spectrum=0.5")
BUNDLED_WEIGHTS += ("w_free_skate=0.05", "w_foot_height=10", "w_heading=1", "w_twist=1", "w_start=10")
BUNDLED_WEIGHTS += ("w_stance=1", "w_rollout=10", "w_foot_twist=1", "w_upper_speed=0.3")
DEFAULT_OUT = Path(__file__).resolve().parents[1] / "resources" / "models" / "bandai2-odmo"


def parse_args() -> argparse.Namespace:
    """Command-line options."""
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--data", required=True, type=Path)
    p.add_argument("--out", type=Path, default=DEFAULT_OUT)
    p.add_argument("--work", type=Path, default=Path("runs/bandai2-odmo"), help="checkpoints and logs")
    p.add_argument("--epochs", type=int, default=100)
    p.add_argument(
        "--tf-decay-epochs", type=int, default=100, help="epochs until teacher forcing reaches its floor"
    )
    p.add_argument(
        "--tf-start", type=float, default=1.0, help="teacher-forcing rate at the first epoch (its floor: 0.3)"
    )
    p.add_argument(
        "--warm-start",
        type=Path,
        help="start from this ODMO model folder's weights (trained on this split; e.g. to fine-tune it with "
        "another loss weight)",
    )
    p.add_argument(
        "--contrastive-pull", type=float, default=0.0, help="weight of the same-action pull (1: the paper's)"
    )
    p.add_argument(
        "--speed-error",
        choices=SPEED_ERRORS,
        default="log",
        help="how the w_speed term compares joint speeds (log: relative errors)",
    )
    p.add_argument(
        "--free-span",
        type=int,
        default=1,
        help="frames per run whose mean pose the w_free term compares (1: every frame's pose)",
    )
    p.add_argument(
        "--free-shift",
        type=int,
        default=0,
        help="frames the w_free term may shift each window in time to fit it (0: none)",
    )
    p.add_argument(
        "--start-frames",
        type=int,
        default=3,
        help="first frames of the free-running decode the w_start term compares (OdmoConfig.start_frames)",
    )
    p.add_argument(
        "--rollout-frames",
        type=int,
        default=15,
        help="frames the w_rollout term decodes free-running after teacher-forced ones",
    )
    p.add_argument(
        "--speed-span",
        type=int,
        default=0,
        help="frames per span over which the w_speed term compares mean speeds (0: the whole window)",
    )
    p.add_argument(
        "--upper-speed-span",
        type=int,
        default=20,
        help="frames per span over which the w_upper_speed term compares the upper body's speeds",
    )
    p.add_argument(
        "--spectrum-span",
        type=int,
        default=0,
        help="frames per span over which the w_spectrum term compares spectra (0: the whole window)",
    )
    p.add_argument(
        "--spectrum-no-legs", action="store_true", help="leave the legs out of the w_spectrum term"
    )
    p.add_argument(
        "--free-skate-contacts",
        choices=FREE_SKATE_CONTACTS,
        default="own",
        help="where the w_free_skate term holds the feet: where the data's are planted or the decode's own",
    )
    p.add_argument(
        "--coordination-on",
        choices=COORDINATION_ON,
        default="all",
        help="the joints the w_coordination term compares: all, or the legs only",
    )
    p.add_argument(
        "--root-velocity-input",
        action="store_true",
        help="feed the pose decoder each frame's root velocity (OdmoConfig.root_velocity_input)",
    )
    p.add_argument(
        "--mean-pose-init",
        action=argparse.BooleanOptionalAction,
        default=True,
        help="start the pose decoder's output at the mean training pose (OdmoConfig.mean_pose_init)",
    )
    p.add_argument(
        "--pose-output",
        choices=POSE_OUTPUTS,
        default="joints",
        help="what the pose decoder emits: joint positions, or local rotations (OdmoConfig.pose_output; "
        "rotations need --pose-update absolute)",
    )
    p.add_argument(
        "--pose-update",
        choices=POSE_UPDATES,
        default="residual",
        help="a joint decoder's poses afresh each frame, or as steps from the previous pose "
        "(OdmoConfig.pose_update)",
    )
    p.add_argument(
        "--step-input",
        action="store_true",
        help="a residual decoder also reads its previous step (OdmoConfig.step_input)",
    )
    p.add_argument(
        "--encoder-reverse",
        action=argparse.BooleanOptionalAction,
        default=True,
        help="the LMP encoder reads each window backwards (OdmoConfig.encoder_reverse)",
    )
    p.add_argument(
        "--clock-hz",
        type=float,
        nargs="+",
        default=[],
        metavar="HZ",
        help="frequencies whose sin and cos of time the pose decoder reads (OdmoConfig.clock_hz)",
    )
    p.add_argument(
        "--code-rhythms",
        type=int,
        default=0,
        metavar="M",
        help="rhythms the code sets: sums of the clock's sines (OdmoConfig.code_rhythms)",
    )
    p.add_argument(
        "--traj-y-weight",
        type=float,
        default=1.0,
        help="weight of the root path's vertical axis in the trajectory loss (the reference's 5 for "
        "HumanAct12; OdmoConfig.traj_y_weight)",
    )
    p.add_argument(
        "--weight",
        action="append",
        default=list(BUNDLED_WEIGHTS),
        metavar="NAME=VALUE",
        help="a loss weight of OdmoConfig (w_*), e.g. --weight w_skate=1; repeatable, later ones win "
        f"(default: the bundled model's {' '.join(BUNDLED_WEIGHTS)})",
    )
    p.add_argument(
        "--classifier",
        type=Path,
        help="evaluate with this classifier folder (e.g. the shipped model's classifier/) instead of "
        "training one in --work/classifier",
    )
    p.add_argument("--classifier-epochs", type=int, default=20)
    p.add_argument(
        "--classifier-lr-floor", type=float, default=1.0, help="classifier lr cosine floor (1: constant)"
    )
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--repeats", type=int, default=10)
    p.add_argument("--n-per-action", type=int, default=50)
    p.add_argument("--device", default="auto")
    p.add_argument("--threads", type=int, default=1, help="torch CPU threads (more crawl on a busy machine)")
    p.add_argument("--resume", action="store_true")
    p.add_argument("--skip-train", action="store_true", help="reuse the trained model in --work")
    p.add_argument("--reuse-eval", action="store_true", help="reuse --work/eval.json for the card")
    return p.parse_args()


def main() -> int:
    """Train, evaluate and package the default model."""
    args = parse_args()
    weights = loss_weights(args.weight)
    torch.set_num_threads(args.threads)
    dataset = load_folder(args.data)
    train_clips, test_clips = heldout_split(dataset.clips)
    names = list(dataset.action_names)
    config = OdmoConfig(
        n_actions=len(names),
        n_joints=dataset.skeleton.n_joints,
        epochs=args.epochs,
        tf_decay_epochs=args.tf_decay_epochs,
        tf_start=args.tf_start,
        contrastive_pull=args.contrastive_pull,
        speed_error=args.speed_error,
        free_span=args.free_span,
        free_shift=args.free_shift,
        start_frames=args.start_frames,
        rollout_frames=args.rollout_frames,
        upper_speed_span=args.upper_speed_span,
        speed_span=args.speed_span,
        spectrum_span=args.spectrum_span,
        spectrum_legs=not args.spectrum_no_legs,
        free_skate_contacts=args.free_skate_contacts,
        coordination_on=args.coordination_on,
        root_velocity_input=args.root_velocity_input,
        mean_pose_init=args.mean_pose_init,
        pose_output=args.pose_output,
        pose_update=args.pose_update,
        step_input=args.step_input,
        encoder_reverse=args.encoder_reverse,
        clock_hz=tuple(args.clock_hz),
        code_rhythms=args.code_rhythms,
        traj_y_weight=args.traj_y_weight,
        **weights,
    )
    work = args.work
    started = time.time()
    if not args.skip_train:
        bar = tqdm(total=config.epochs, desc="odmo", unit="epoch")

        def show(p) -> None:
            if p.stage == "train" and p.step == p.steps:
                bar.n = p.epoch
                bar.set_postfix(
                    {k: f"{v:.3g}" for k, v in p.losses.items()} | {"w/s": f"{p.windows_per_s:.0f}"}
                )
                bar.refresh()

        start = None if args.warm_start is None else warm_start_from(args.warm_start, test_clips, load_model)
        result = train(
            train_clips,
            names,
            work,
            config,
            seed=args.seed,
            device=args.device,
            resume=args.resume,
            progress=show,
            warm_start=start,
        )
        bar.close()
        # train() can leave torch on more threads than asked (2 after --threads 1): evaluate on those.
        torch.set_num_threads(args.threads)
        train_seconds = result.train_seconds
        (work / "train_summary.json").write_text(
            json.dumps(
                {
                    "train_seconds": train_seconds,
                    "windows_per_s": result.windows_per_s,
                    "n_train": result.n_train,
                    "n_val": result.n_val,
                    "device": str(args.device),
                    "torch_threads": args.threads,
                },
                indent=2,
            )
        )
    summary = json.loads((work / "train_summary.json").read_text())
    clf_dir = args.classifier or work / "classifier"
    if args.classifier is None and not (clf_dir / "classifier.json").is_file():
        train_classifier(
            train_clips,
            names,
            clf_dir,
            window=config.window,
            fps=config.fps,
            epochs=args.classifier_epochs,
            lr_floor=args.classifier_lr_floor,
            seed=args.seed,
        )
    classifier = load_classifier(clf_dir)
    loaded = load_model(work)
    if args.reuse_eval and (work / "eval.json").is_file():
        report = json.loads((work / "eval.json").read_text())
    else:
        evaluation = {"repeats": args.repeats, "n_per_action": args.n_per_action, "seed": args.seed}
        report = evaluate(loaded, test_clips, classifier, **evaluation)
        atomic_write_text(work / "eval.json", json.dumps(report, indent=2))
    smooth = interpolation_smoothness(loaded, test_clips)

    out = args.out
    out.mkdir(parents=True, exist_ok=True)
    for name in ("model.safetensors", "model.json", "latent_bank.npz", "train_log.csv"):
        shutil.copy2(work / name, out / name)
    if clf_dir.resolve() != (out / "classifier").resolve():
        shutil.copytree(clf_dir, out / "classifier", dirs_exist_ok=True)
    shipped = report | {"meta": report["meta"] | {"model": out.name, "classifier": "classifier"}}
    atomic_write_text(out / "eval.json", json.dumps(shipped, indent=2))  # no machine paths in what ships
    heldout = sorted(str(Path(c.meta["source"]).name) for c in test_clips)
    atomic_write_text(out / "heldout_clips.txt", "\n".join(heldout) + "\n")
    command = training_command("bench/train_default.py", work, sys.argv[1:], trained=not args.skip_train)
    write_model_card(
        out,
        report,
        {
            "command": command,
            "seed": loaded.provenance.get("seed", args.seed),
            "epochs": loaded.provenance.get("epochs", loaded.config.epochs),
            "train_seconds": summary["train_seconds"],
            "windows_per_s": summary["windows_per_s"],
            "device": f"{args.device} ({platform.processor() or platform.machine()}, "
            f"{summary['torch_threads']} torch threads)",
            "n_train": summary["n_train"],
            "n_val": summary["n_val"],
            "n_heldout": len(test_clips),
            "heldout": f"{HELDOUT_FRACTION:.0%} of clips per action × style, seed {SPLIT_SEED}",
            "classifier_accuracy": classifier.test_accuracy,
            "classifier_per_action": classifier.test_accuracy_per_action,
            "total_seconds": time.time() - started,
            "fingerprint": dataset.fingerprint,
            "model_switches": model_switches(loaded.config),
            "warm_start": loaded.provenance.get("warm_start"),
        },
        smooth,
    )
    print(f"default model written to {out} ({_size_mb(out):.1f} MB)")
    return 0


def loss_weights(pairs: list[str]) -> dict[str, float]:
    """``["w_skate=0.01", ...]`` as config fields; a name that is not a loss weight exits with its name."""
    weights = {f.name for f in dataclasses.fields(OdmoConfig) if f.name.startswith("w_")}
    out = {}
    for pair in pairs:
        name, _, value = pair.partition("=")
        if name not in weights:
            raise SystemExit(f"--weight {pair}: not a loss weight (one of {', '.join(sorted(weights))})")
        try:
            out[name] = float(value)
        except ValueError:
            raise SystemExit(f"--weight {pair}: {value!r} is not a number") from None
    return out


def interpolation_smoothness(loaded, clips) -> dict[str, dict]:
    """Per action: largest frame step of a 10-step strip between its two largest modes vs real clips."""
    out = {}
    for index, name in enumerate(loaded.action_names):
        modes = loaded.bank.modes.get(index)
        real = [resample_motion(c, loaded.fps).joints for c in clips if c.action == name]
        if modes is None or len(modes.weights_) < 2 or not real:
            continue
        a, b = np.argsort(modes.weights_)[::-1][:2]
        strip = interpolate(loaded, modes.means_[a], modes.means_[b], index, steps=10)
        generated = max_frame_jump(np.stack([s.motion.joints for s in strip]))
        real_jump = max(max_frame_jump(r[None]) for r in real)
        out[name] = {"modes": f"{a}→{b}", "generated": generated, "real": real_jump}
    return out


def model_switches(config: OdmoConfig) -> str:
    """The card's line on where this model departs from the paper (README: "Where the model differs")."""
    parts = []
    if config.use_end_location and config.exact_end:
        parts.append("`exact_end` (the root path is sheared to end exactly at the requested end location)")
    if config.root_relative_poses:
        parts.append(
            "`root_relative_poses` (the decoder emits the local movement profile; the root is the "
            "generated trajectory)"
        )
    if config.pose_output == "rotations":
        parts.append(
            "`pose_output = rotations` (the pose decoder emits local joint rotations; forward kinematics "
            "on the skeleton places the joints)"
        )
    elif config.bone_projection:
        parts.append("`bone_projection` (decoded joints lie on the skeleton's bone lengths by construction)")
    if config.clock_hz:
        hz = ", ".join(f"{f:g}" for f in config.clock_hz)
        parts.append(f"`clock_hz = ({hz})` (the pose decoder reads sin and cos of time at these frequencies)")
    if config.code_rhythms:
        parts.append(
            f"`code_rhythms = {config.code_rhythms}` (the pose decoder also reads that many sums of those "
            "sines and cosines weighted by the code: rhythms whose phase the code sets)"
        )
    if config.encoder_reverse:
        parts.append("`encoder_reverse` (the LMP encoder reads each window from its end back to its start)")
    if config.pose_update == "residual":
        parts.append("`pose_update = residual` (each frame's pose a step from the previous one)")
    if config.step_input:
        parts.append("`step_input` (the pose decoder also reads its previous step)")
    if config.foot_contact:
        parts.append(
            "`foot_contact` (a foot-contact head and loss; planted feet pinned to the floor at decode time)"
        )
    if config.foot_contact and config.w_skate != 1.0:
        parts.append(f"`w_skate = {config.w_skate:g}` (the weight of the planted-foot speed loss)")
    parts += _weighted(config, "w_velocity", "an L2 loss on joint velocities")
    if config.w_free > 0:
        per = f" of the mean pose per {config.free_span}-frame span" if config.free_span > 1 else ""
        if config.free_shift:
            per += f", at the time shift of at most {config.free_shift} frames that fits each window best"
        parts.append(f"`w_free = {config.w_free:g}` (a reconstruction loss{per} on a free-running decode)")
    if config.w_start > 0:
        parts.append(
            f"`w_start = {config.w_start:g}` (a loss on that decode's first {config.start_frames} "
            "root-relative poses)"
        )
    if config.w_rollout > 0:
        parts.append(
            f"`w_rollout = {config.w_rollout:g}` (a loss on {config.rollout_frames} poses decoded "
            "free-running after teacher-forced ones, from a random frame)"
        )
    if config.w_speed > 0:
        what = "log " if config.speed_error == "log" else ""
        per = f"{config.speed_span}-frame span" if config.speed_span else "window"
        parts.append(f"`w_speed = {config.w_speed:g}` (a loss on that decode's per-{per} {what}joint speeds)")
    if config.w_upper_speed > 0:
        what = "log " if config.speed_error == "log" else ""
        parts.append(
            f"`w_upper_speed = {config.w_upper_speed:g}` (a loss on that decode's per-"
            f"{config.upper_speed_span}-frame-span {what}speeds of the joints outside the legs)"
        )
    parts += _weighted(
        config, "w_foot_twist", "a loss on the turn of that decode's feet against its hips' axis"
    )
    if config.w_spectrum > 0:
        legs = "" if config.spectrum_legs else ", legs left out"
        per = f" per {config.spectrum_span}-frame span" if config.spectrum_span else ""
        parts.append(
            f"`w_spectrum = {config.w_spectrum:g}` (a loss on that decode's log amplitude spectra{per}{legs})"
        )
    if config.w_free_skate > 0:
        where = "its own" if config.free_skate_contacts == "own" else "the data's"
        parts.append(
            f"`w_free_skate = {config.w_free_skate:g}` (the planted-foot speed loss on that decode, "
            f"where {where} feet are planted)"
        )
    parts += _weighted(
        config,
        "w_skim",
        "a loss on how far that decode's planted-foot speed, by the skate rule made soft, exceeds the data's",
    )
    parts += _weighted(config, "w_stand", "a loss on that decode's root height over its lowest foot")
    parts += _weighted(config, "w_floor", "a loss on that decode's lowest-foot heights over the data's floor")
    parts += _weighted(config, "w_foot_height", "a loss on that decode's sorted foot heights")
    parts += _weighted(config, "w_stance", "a loss on the speed of that decode's lowest foot")
    parts += _weighted(config, "w_heading", "a loss on that decode's heading against its path")
    parts += _weighted(config, "w_twist", "a loss on that decode's torso twist")
    if config.w_coordination > 0:
        which = "legs" if config.coordination_on == "legs" else "joints"
        parts.append(
            f"`w_coordination = {config.w_coordination:g}` "
            f"(a loss on how that decode's {which} move together)"
        )
    if config.root_velocity_input:
        parts.append("`root_velocity_input` (the pose decoder reads each frame's root velocity)")
    if config.traj_y_weight != 1.0:
        weight = f"`traj_y_weight = {config.traj_y_weight:g}`"
        parts.append(f"{weight} (the root path's height counts that many times its floor position)")
    if config.mean_pose_init:
        parts.append("`mean_pose_init` (the pose decoder starts at the mean training pose)")
    if config.contrastive_pull != 1.0:
        parts.append(
            f"`contrastive_pull = {config.contrastive_pull:g}` (the same-action pull of the contrastive term)"
        )
    if not parts:
        return "the paper's model"
    exact = config.use_end_location and config.exact_end and config.root_relative_poses
    return (
        "paper sizes, with "
        + " and ".join(parts)
        + ("; a requested end location's floor position is reached exactly" if exact else "")
    )


def _weighted(config: OdmoConfig, name: str, what: str) -> list[str]:
    """The card's words for loss weight ``name`` (``what`` it weights) when the config turns it on."""
    weight = getattr(config, name)
    return [f"`{name} = {weight:g}` ({what})"] if weight > 0 else []


def _size_mb(folder: Path) -> float:
    return sum(f.stat().st_size for f in folder.rglob("*") if f.is_file()) / 2**20


if __name__ == "__main__":
    np.set_printoptions(precision=4)
    sys.exit(main())
