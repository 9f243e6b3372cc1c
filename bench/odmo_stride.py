"""Does an ODMO decoder keep the stride and the wave when it runs on its own poses (README, stop 40)?

    python bench/odmo_stride.py --data DATA --model resources/models/bandai2-odmo
        [--actions walk run wave-right-hand] [--n 60] [--prime 2] [--fit 300]

Held-out windows of each action are encoded and decoded with their own codes and ends three times:
running free (as sampling does), teacher-forced (every previous pose taken from the real window; each
frame is then a one-step prediction) and primed (the first ``--prime`` previous poses real, then free).
Prints JSON per action: for the real windows and each decode (before the foot clean-up), the stride (the
first ankle's lead over the second along the window's travel: its std over frames, mean over windows),
its per-window correlation with the real window's (how well the decode keeps the real phase), the
mean speed of the faster hand about the root, the hands' rhythm (``limb_rhythm``) and the per-window
correlation of their velocity about the pelvis with the real window's (how well the decode follows the
real hands), the mean speed of the lowest foot and the mean height gap between the two legs' lowest foot
joints (a gait stands on one foot and swings the other: README, stop 42); and how far the teacher-forced
decode moves (mean over joints, and over the hands) when the previous poses are another window's (how
much it reads them); and how much of a training window's first and last pose (about the root) and of
its hands' rhythm (the 1–2.7 Hz Fourier coefficients of their velocity about the pelvis) its code says
(cross-validated R² of a linear probe). With ``--fit N`` the free decode is also taken from each
window's code fitted to the window by N Adam steps, the decoder fixed: what no code makes the decoder
do, the encoder cannot learn (README, stop 48). A decoder that keeps the stride teacher-forced and loses
it running free either damps its own motion or never starts it: a primed decode that keeps it says
which (README, stop 41).
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

import numpy as np
import torch
from sklearn.linear_model import RidgeCV
from sklearn.metrics import r2_score
from sklearn.model_selection import cross_val_predict

if __package__ in (None, ""):
    sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from bench.heldout import heldout_split
from engine.generate import bank_window, encode_clips
from engine.generate._decode import display_lift, ready_model
from engine.metrics.physics import limb_rhythm
from engine.model.losses import stance_speeds
from engine.model.odmo import OdmoModel
from engine.modelio import LoadedModel, load_model
from engine.motion.contact import hand_joints, leg_chains, pelvis_joint
from engine.motion.datasets import load_folder
from engine.motion.motion import Motion


def strides(joints: np.ndarray, ankles: tuple[int, int], root: int) -> np.ndarray:
    """(N, T): the first ankle's lead over the second along each window's travel (the root's path from
    first to last frame on the floor; +z where it moves under 20 cm) of ``joints`` (N, T, J, 3)."""
    travel = joints[:, -1, root, [0, 2]] - joints[:, 0, root, [0, 2]]
    length = np.linalg.norm(travel, axis=1, keepdims=True)
    forward = np.where(length > 0.2, travel / np.maximum(length, 1e-9), np.array([[0.0, 1.0]]))
    apart = joints[:, :, ankles[0]][..., [0, 2]] - joints[:, :, ankles[1]][..., [0, 2]]
    return np.einsum("ntk,nk->nt", apart, forward)


def correlations(mine: np.ndarray, theirs: np.ndarray) -> np.ndarray:
    """Per window, Pearson's r over every other axis of ``mine`` and ``theirs`` (N, ...) about their
    means over the second axis (0 where either does not vary)."""
    a = (mine - mine.mean(1, keepdims=True)).reshape(len(mine), -1)
    b = (theirs - theirs.mean(1, keepdims=True)).reshape(len(theirs), -1)
    denominator = np.sqrt((a * a).sum(1) * (b * b).sum(1))
    return np.where(denominator > 1e-12, (a * b).sum(1) / np.maximum(denominator, 1e-12), 0.0)


def hand_velocities(joints: np.ndarray, hands: list[int], pelvis: int) -> np.ndarray:
    """(N, T − 1, H, 3) frame steps of the hands about the pelvis."""
    return np.diff(joints[:, :, hands] - joints[:, :, pelvis : pelvis + 1], axis=1)


def stride_figures(
    joints: np.ndarray,
    real: np.ndarray,
    ankles: tuple[int, int],
    hands: list[int],
    root: int,
    fps: float,
    pelvis: int | None = None,
) -> dict[str, float]:
    """Stride (m), its mean per-window correlation with ``real``'s, the faster hand's mean speed about
    the root (m/s), and the hands' rhythm (Hz) and velocity correlation with ``real``'s about ``pelvis``
    (None: the root) of ``joints`` (N, T, J, 3) decoded from the windows ``real`` (N, T, J, 3)."""
    pelvis = root if pelvis is None else pelvis
    mine = strides(joints, ankles, root)
    corr = correlations(mine, strides(real, ankles, root))
    local = joints[:, :, hands] - joints[:, :, root : root + 1]
    hand_speed = np.linalg.norm(np.diff(local, axis=1), axis=-1).mean(1).max(-1) * fps  # (N,)
    follow = correlations(hand_velocities(joints, hands, pelvis), hand_velocities(real, hands, pelvis))
    rhythm = np.nanmean([limb_rhythm(j, hands, pelvis, fps) for j in joints])
    return {
        "stride_m": round(float(mine.std(1).mean()), 3),
        "phase_r": round(float(corr.mean()), 2),
        "hand_speed_m_s": round(float(hand_speed.mean()), 2),
        "hand_rhythm_hz": round(float(rhythm), 2),
        "hand_r": round(float(follow.mean()), 2),
    }


def stance_figures(
    joints: np.ndarray, feet: list[int], rest: tuple[float, ...], legs: tuple[int, int], fps: float
) -> dict[str, float]:
    """Mean speed (m/s) of the lowest foot joint (``stance_speeds``, the ``w_stance`` term's measure) and
    mean height gap (m) between the two legs' lowest-resting joints ``legs`` of ``joints`` (N, T, J, 3)
    over resting heights ``rest`` of ``feet``: a gait stands on the lower foot and swings the other."""
    tensor = torch.from_numpy(np.ascontiguousarray(joints[:, :, feet], dtype=np.float32))
    speed = stance_speeds(tensor, rest, torch.ones(joints.shape[:2], dtype=torch.bool), fps)
    heights = [joints[:, :, j, 1] - rest[feet.index(j)] for j in legs]
    return {
        "stance_m_s": round(float(speed.mean()), 3),
        "foot_gap_m": round(float(np.abs(heights[0] - heights[1]).mean()), 3),
    }


def primed_decode(
    model: OdmoModel,
    z: torch.Tensor,
    actions: torch.Tensor,
    ends: torch.Tensor,
    truth: torch.Tensor,
    frames: int,
) -> torch.Tensor:
    """Joints (B, T, J, 3) of ``model`` decoding codes ``z`` whose previous poses are the real ``truth``
    (B, T, J, 3) for its first ``frames`` frames and its own after (0: the free decode; T: teacher-forced)."""
    previous = truth.clone()
    for t in range(frames, truth.shape[1] - 1):
        previous[:, t] = model.decode_full(z, actions, ends, prev_truth=previous, tf_rate=1.0).raw[:, t]
    return model.decode_full(z, actions, ends, prev_truth=previous, tf_rate=1.0).joints


def fitted_codes(
    model: OdmoModel,
    z: torch.Tensor,
    actions: torch.Tensor,
    ends: torch.Tensor,
    truth: torch.Tensor,
    steps: int,
    lr: float = 0.05,
) -> torch.Tensor:
    """Codes (B, D) fitted from ``z`` by ``steps`` Adam steps on the squared error of ``model``'s free
    decode about the root against ``truth`` (B, T, J, 3), the model's weights fixed."""
    root = model.skeleton.root if model.skeleton is not None else 0
    about = truth - truth[:, :, root : root + 1]
    fitted = z.detach().clone().requires_grad_(True)
    optimiser = torch.optim.Adam([fitted], lr=lr)
    frozen = [p for p in model.parameters() if p.requires_grad]
    for p in frozen:
        p.requires_grad_(False)
    try:
        for _ in range(steps):
            joints = model.decode_full(fitted, actions, ends).joints
            loss = (joints - joints[:, :, root : root + 1] - about).square().mean()
            optimiser.zero_grad()
            loss.backward()
            optimiser.step()
    finally:
        for p in frozen:
            p.requires_grad_(True)
    return fitted.detach()


def lowest_feet(loaded: LoadedModel) -> tuple[list[int], tuple[float, ...], tuple[int, int]] | None:
    """The model's foot joints, their resting heights and each of two legs' lowest-resting foot joint
    (None for a model without foot contacts or two legs)."""
    config = loaded.config
    feet, rest = list(config.foot_joints), tuple(config.foot_heights)
    legs = [[j for j in (chain[2], *chain[3]) if j in feet] for chain in leg_chains(loaded.skeleton)]
    if not rest or len(legs) != 2 or not all(legs):
        return None
    low = tuple(min(leg, key=lambda j: rest[feet.index(j)]) for leg in legs)
    return feet, rest, (low[0], low[1])


def full_windows(loaded: LoadedModel, clips: list[Motion]) -> list[Motion]:
    """The bank windows of those ``clips`` at least one model window long."""
    return [bank_window(loaded, c) for c in clips if c.duration * loaded.fps >= loaded.window]


#: The band (Hz) of the hands' rhythm whose Fourier coefficients the code probe reads: a wave shakes there.
RHYTHM_BAND = (1.0, 2.7)


def code_probe(
    loaded: LoadedModel, clips: list[Motion], root: int, hands: list[int], pelvis: int
) -> dict[str, float]:
    """How much of a window's first and last root-relative pose, and of its hands' rhythm (the real and
    imaginary parts of their velocity's Fourier coefficients in ``RHYTHM_BAND``), its code says:
    ``probe_r2`` over the windows of ``clips``."""
    windows = full_windows(loaded, clips)
    codes, _ = encode_clips(loaded, windows)
    joints = np.stack([w.joints for w in windows])
    local = (joints - joints[:, :, root : root + 1]).reshape(len(joints), joints.shape[1], -1)
    steps = hand_velocities(joints, hands, pelvis)
    freqs = np.fft.rfftfreq(steps.shape[1], 1 / loaded.fps)
    band = (freqs >= RHYTHM_BAND[0]) & (freqs <= RHYTHM_BAND[1])
    coefficients = np.fft.rfft(steps - steps.mean(1, keepdims=True), axis=1)[:, band].reshape(len(joints), -1)
    return {
        "code_r2_first_pose": round(probe_r2(codes, local[:, 0]), 2),
        "code_r2_last_pose": round(probe_r2(codes, local[:, -1]), 2),
        "code_r2_hand_rhythm": round(probe_r2(codes, np.hstack([coefficients.real, coefficients.imag])), 2),
    }


def probe_r2(codes: np.ndarray, targets: np.ndarray) -> float:
    """Variance-weighted R² of a ridge regression from ``codes`` (N, D) to ``targets`` (N, V), 5-fold
    cross-validated (0: no better than the mean; negative: worse)."""
    predicted = cross_val_predict(RidgeCV(alphas=np.logspace(-3, 3, 7)), codes, targets, cv=5)
    return float(r2_score(targets, predicted, multioutput="variance_weighted"))


def main() -> int:
    """Print the figures per action."""
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--data", required=True, type=Path)
    p.add_argument("--model", required=True, type=Path)
    p.add_argument("--actions", nargs="+", default=["walk", "run", "wave-right-hand"])
    p.add_argument("--n", type=int, default=60)
    p.add_argument(
        "--prime", type=int, default=2, help="real previous poses before a primed decode runs free"
    )
    p.add_argument(
        "--fit", type=int, default=0, help="Adam steps fitting each window's code to it (0: no fitted decode)"
    )
    args = p.parse_args()
    torch.set_num_threads(1)
    loaded = load_model(args.model)
    model, lift = ready_model(loaded), display_lift(loaded)
    ankles = tuple(chain[2] for chain in leg_chains(loaded.skeleton))[:2]
    if len(ankles) != 2:
        raise SystemExit(f"{args.model}: the skeleton has no two legs to measure a stride on")
    hands, root = hand_joints(loaded.skeleton), loaded.skeleton.root
    pelvis = pelvis_joint(loaded.skeleton)
    stance = lowest_feet(loaded)
    train_clips, test_clips = heldout_split(load_folder(args.data).clips)
    report = {}
    for action in args.actions:
        windows = full_windows(loaded, [c for c in test_clips if c.action == action])[: args.n]
        codes, ends = encode_clips(loaded, windows)
        real = np.stack([w.joints for w in windows]).astype(np.float32)
        z, e = torch.from_numpy(codes), torch.from_numpy(ends)
        a = torch.full((len(z),), loaded.action_names.index(action))
        truth = torch.from_numpy(real - lift)
        with torch.no_grad():
            free = model.decode_full(z, a, e).joints.numpy() + lift
            forced = model.decode_full(z, a, e, prev_truth=truth, tf_rate=1.0).joints.numpy() + lift
            primed = primed_decode(model, z, a, e, truth, args.prime).numpy() + lift
            swapped = (
                model.decode_full(z, a, e, prev_truth=truth.roll(1, 0), tf_rate=1.0).joints.numpy() + lift
            )
        sets = {"real": real, "free": free, "forced": forced, f"primed_{args.prime}": primed}
        if args.fit:
            fitted = fitted_codes(model, z, a, e, truth, args.fit)
            with torch.no_grad():
                sets["fitted"] = model.decode_full(fitted, a, e).joints.numpy() + lift
        sets = {k: js.reshape(real.shape) for k, js in sets.items()}
        figures = {
            k: stride_figures(js, real, ankles, hands, root, loaded.fps, pelvis) for k, js in sets.items()
        }
        if stance is not None:
            for k, js in sets.items():
                figures[k] |= stance_figures(js, *stance, loaded.fps)
        effect = np.linalg.norm(sets["forced"] - swapped.reshape(real.shape), axis=-1).mean((0, 1))
        reads = {
            "previous_pose_effect_m": round(float(effect.mean()), 4),
            "on_hands": round(float(effect[hands].mean()), 4),
        }
        probe = code_probe(loaded, [c for c in train_clips if c.action == action], root, hands, pelvis)
        report[action] = {"n": len(windows)} | figures | reads | probe
    print(json.dumps({"model": args.model.name, **report}, indent=1))
    return 0


if __name__ == "__main__":
    sys.exit(main())
