"""Physical plausibility of joint positions: bone lengths, foot skate, floor contact, limb motion, jerk,
heading.

Every function takes clips as (T, J, 3) arrays in metres, y up, the floor at y = 0.

Contact rule of ``foot_skate``: a foot joint is planted in a frame when it lies within ``PLANTED_TOL``
(3 cm) of the clip's lowest foot height (the lowest any foot joint reaches in that clip), in that frame
and the next; no speed threshold, since a speed threshold would hide the sliding it measures.

Heading (``heading_error``): the direction of travel is the root's horizontal displacement over
``HEADING_SPAN`` (0.5 s, longer than a stride's sway), the body's facing line the perpendicular of the
axis between the two hips (the top joints of the leg chains) at the span's middle; only spans where the
root moves at ``MOVING_SPEED`` (0.5 m/s) or more count.

Late hand speed: the mean hand speed over the last third of each clip (``LATE_SHARE``), beside the mean
over the whole clip: a decode that meets the mean with a burst and then stops shows there.

Foot sync (``foot_sync``): the correlation over a clip's frame steps of the two ankles' horizontal
velocities relative to the pelvis (the hips' parent; Pearson's r over both horizontal axes): a gait
alternates its feet (real Bandai walks −0.4 to −0.65, runs −0.6 to −0.9; double support pulls walks
towards 0), +1 is both feet moving together, a hop. Clips where an ankle does not move relative to the
pelvis are left out.

Feet backward (``feet_backward``): over the moving spans of the heading rule, the share of (span, foot)
pairs whose foot is planted (its toe joint within ``PLANTED_TOL`` of the clip's lowest foot height, at the
span's middle) and points against the direction of travel (the ankle-to-toe bone seen from above): real
gaits put their feet down pointing the way they go; a decoder that turns the feet round does not.

Foot pop (``foot_pop``): the 99th percentile, over every frame step and foot joint of a set, of the
joints' vertical speed: feet that jump up or drop down faster than real feet lift and land (a clean-up
that pins a foot on the floor and lets it go in one frame) show there while the planted-foot speed looks
right.

Hand rhythm (``limb_rhythm``): the power-weighted mean frequency (Hz) of the hands' velocity relative to
the pelvis over each clip (Hann-windowed, its mean taken out): a wave that sweeps the arm slowly where real
ones shake it at about 2 Hz moves its hands at part of their speed and shows the reason here.

Pelvis height (``pelvis_height``): the mean height over the floor of the pelvis (the hips' parent; the
root without leg chains) over every frame: a decode that draws its legs up and is lowered onto the floor
by the foot clean-up runs crouched (its feet and their skate look right), one that floats stands tall.

Torso twist (``torso_twist``): the angle, seen from above, between the axis through the tops of the two
arms (the shoulders) and the axis through the two hips, in every frame (real Bandai walks: 6.8° mean
absolute, one clip per style, from 2.2° elderly to 13.7° active; waves about 1°).
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
from scipy.signal import periodogram

from engine.motion.contact import (
    ankle_pair,
    floats,
    foot_joints,
    foot_lines,
    hand_joints,
    hip_pair,
    pelvis_joint,
    shoulder_pair,
)
from engine.motion.skeleton import Skeleton

PLANTED_TOL = 0.03
PENETRATION_TOL = 0.02
HEADING_SPAN = 0.5
MOVING_SPEED = 0.5
LATE_SHARE = 1 / 3
POP_QUANTILE = 0.99


def bone_length_cv(joints: np.ndarray, parents: np.ndarray) -> float:
    """Worst bone's std/mean length over the frames of one clip (0 for fixed bones)."""
    pos = np.asarray(joints, dtype=np.float64)
    kids = np.flatnonzero(np.asarray(parents) >= 0)
    lengths = np.linalg.norm(pos[:, kids] - pos[:, np.asarray(parents)[kids]], axis=-1)
    mean = lengths.mean(axis=0)
    cv = lengths.std(axis=0) / np.maximum(mean, 1e-9)
    return float(cv[mean > 1e-6].max(initial=0.0))


def median_bone_length_cv(clips: Sequence[np.ndarray], parents: np.ndarray) -> float:
    """Median over clips of ``bone_length_cv``."""
    return float(np.median([bone_length_cv(c, parents) for c in clips]))


def _planted_speeds(
    joints: np.ndarray, feet: Sequence[int], fps: float, tol: float = PLANTED_TOL
) -> np.ndarray:
    """Horizontal speeds (m/s) of foot joints over the frame steps where they are planted (within ``tol``)."""
    pos = np.asarray(joints, dtype=np.float64)[:, list(feet)]
    height = pos[..., 1]
    planted = height <= height.min() + tol
    both = planted[1:] & planted[:-1]
    speed = np.linalg.norm(np.diff(pos[..., [0, 2]], axis=0), axis=-1) * fps
    return speed[both]


def foot_skate(
    clips: Sequence[np.ndarray], feet: Sequence[int], fps: float, tol: float = PLANTED_TOL
) -> float:
    """Mean horizontal speed (m/s) of planted foot joints (within ``tol`` of the clip's lowest foot
    height) over every planted frame step of ``clips``."""
    speeds = np.concatenate([_planted_speeds(c, feet, fps, tol) for c in clips] or [np.zeros(0)])
    return float(speeds.mean()) if speeds.size else float("nan")


def foot_pop(clips: Sequence[np.ndarray], feet: Sequence[int], fps: float) -> float:
    """The ``POP_QUANTILE`` quantile (m/s) of foot joints' vertical speed over every step of ``clips``."""
    steps = [np.abs(np.diff(np.asarray(c, np.float64)[:, list(feet), 1], axis=0)).ravel() for c in clips]
    speeds = np.concatenate(steps or [np.zeros(0)]) * fps
    return float(np.quantile(speeds, POP_QUANTILE)) if speeds.size else float("nan")


def pelvis_height(clips: Sequence[np.ndarray], pelvis: int) -> float:
    """Mean over ``clips`` of the ``pelvis`` joint's mean height (m) over the floor."""
    return float(np.mean([np.asarray(c, dtype=np.float64)[:, pelvis, 1].mean() for c in clips]))


def floor_penetration(clips: Sequence[np.ndarray], feet: Sequence[int]) -> tuple[float, float]:
    """Share of frames whose lowest foot joint is more than 2 cm under the floor, and the deepest
    point's depth under the floor (m, 0 when nothing is below it)."""
    lowest = np.concatenate([np.asarray(c)[:, list(feet), 1].min(axis=1) for c in clips])
    return float(np.mean(lowest < -PENETRATION_TOL)), float(max(0.0, -lowest.min()))


def float_share(clips: Sequence[np.ndarray], feet: Sequence[int], fps: float) -> float:
    """Share of clips in which the feet float (see ``floats``)."""
    return float(np.mean([floats(c, feet, fps) for c in clips]))


def limb_speed(joints: np.ndarray, limbs: Sequence[int], fps: float, last: float = 1.0) -> float:
    """Mean speed (m/s) of joints ``limbs`` over the last ``last`` share of a clip's frame steps (1: all)."""
    pos = np.asarray(joints, dtype=np.float64)[:, list(limbs)]
    steps = np.linalg.norm(np.diff(pos, axis=0), axis=-1)
    return float(steps[-max(1, round(len(steps) * last)) :].mean() * fps)


def oscillation_amplitude(joints: np.ndarray, limbs: Sequence[int], root: int) -> float:
    """RMS distance (m) of joints ``limbs`` from their mean position relative to the root, in one clip."""
    pos = np.asarray(joints, dtype=np.float64)
    local = pos[:, list(limbs)] - pos[:, root : root + 1]
    return float(np.sqrt(np.square(local - local.mean(axis=0)).sum(axis=-1).mean()))


def limb_rhythm(joints: np.ndarray, limbs: Sequence[int], root: int, fps: float) -> float:
    """Power-weighted mean frequency (Hz) of joints ``limbs``' root-relative velocity in one clip (NaN if
    they keep a constant velocity)."""
    pos = np.asarray(joints, dtype=np.float64)
    velocity = np.diff(pos[:, list(limbs)] - pos[:, root : root + 1], axis=0) * fps
    freqs, power = periodogram(velocity, fs=fps, window="hann", detrend="constant", axis=0)
    power = power.sum(axis=(1, 2))[1:]  # the mean is out: no power at 0 Hz
    total = power.sum()
    return float(freqs[1:] @ power / total) if total > 1e-12 else np.nan


def mean_jerk(joints: np.ndarray, fps: float) -> float:
    """Mean norm (m/s³) of the third time difference of every joint in one clip."""
    pos = np.asarray(joints, dtype=np.float64)
    if len(pos) < 4:
        return float("nan")
    return float(np.linalg.norm(np.diff(pos, n=3, axis=0), axis=-1).mean() * fps**3)


def _moving_spans(pos: np.ndarray, root: int, fps: float) -> tuple[np.ndarray, np.ndarray]:
    """The horizontal travel (S, 2) of ``root`` over every span of ``HEADING_SPAN`` in one clip (T, J, 3)
    and the poses (S, J, 3) at the spans' middles, for the spans moving at ``MOVING_SPEED`` or more."""
    span = max(1, round(HEADING_SPAN * fps))
    if len(pos) <= span:
        return np.zeros((0, 2)), pos[:0]
    travel = pos[span:, root, ::2] - pos[:-span, root, ::2]
    middle = pos[span // 2 : span // 2 + len(travel)]
    moving = np.linalg.norm(travel, axis=-1) >= MOVING_SPEED * span / fps
    return travel[moving], middle[moving]


def heading_errors(joints: np.ndarray, hips: tuple[int, int], root: int, fps: float) -> np.ndarray:
    """Angles (degrees, 0..90) between the body's facing line and its direction of travel in one clip,
    one per moving span (see the module docstring): 0 walking forwards or backwards, 90 side-stepping."""
    travel, middle = _moving_spans(np.asarray(joints, dtype=np.float64), root, fps)
    axis = middle[:, hips[0], ::2] - middle[:, hips[1], ::2]
    norms = np.linalg.norm(travel, axis=-1) * np.linalg.norm(axis, axis=-1)
    cos = np.abs(np.einsum("ti,ti->t", travel, axis))[norms > 0] / norms[norms > 0]
    return np.degrees(np.arcsin(np.clip(cos, 0.0, 1.0)))


def feet_backward(
    clips: Sequence[np.ndarray], feet: Sequence[tuple[int, int]], root: int, fps: float
) -> float:
    """Share of (moving span, foot) pairs whose planted foot points against the direction of travel (see
    the module docstring); ``feet`` are (ankle, toe) joint pairs. NaN when no span moves with a foot
    planted."""
    backward = counted = 0
    for clip in clips:
        pos = np.asarray(clip, dtype=np.float64)
        floor = pos[:, [j for pair in feet for j in pair], 1].min(initial=np.inf)
        travel, middle = _moving_spans(pos, root, fps)
        for ankle, toe in feet:
            bone = middle[:, toe, ::2] - middle[:, ankle, ::2]
            planted = (middle[:, toe, 1] <= floor + PLANTED_TOL) & (np.linalg.norm(bone, axis=-1) > 0)
            backward += int(np.sum(planted & (np.einsum("ti,ti->t", bone, travel) < 0)))
            counted += int(np.sum(planted))
    return backward / counted if counted else float("nan")


def heading_error(clips: Sequence[np.ndarray], hips: tuple[int, int], root: int, fps: float) -> float:
    """Mean ``heading_errors`` (degrees) over every moving span of ``clips``; 0 when none moves."""
    angles = np.concatenate([heading_errors(c, hips, root, fps) for c in clips] or [np.zeros(0)])
    return float(angles.mean()) if angles.size else 0.0


def foot_syncs(clips: Sequence[np.ndarray], ankles: tuple[int, int], pelvis: int) -> np.ndarray:
    """Per clip, the correlation of the two ``ankles``' horizontal velocities relative to ``pelvis`` (NaN
    where either does not move)."""
    out = []
    for clip in clips:
        pos = np.asarray(clip, dtype=np.float64)
        local = pos[:, list(ankles)][..., ::2] - pos[:, pelvis : pelvis + 1, ::2]
        vel = np.diff(local, axis=0)  # (T-1, 2, 2)
        left, right = vel[:, 0].ravel(), vel[:, 1].ravel()
        moving = len(left) > 1 and left.std() > 1e-9 and right.std() > 1e-9
        out.append(float(np.corrcoef(left, right)[0, 1]) if moving else np.nan)
    return np.array(out)


def foot_sync(clips: Sequence[np.ndarray], ankles: tuple[int, int], pelvis: int) -> float:
    """Mean ``foot_syncs`` over the clips whose ankles move (NaN when none does)."""
    r = foot_syncs(clips, ankles, pelvis)
    return float(np.nanmean(r)) if np.isfinite(r).any() else float("nan")


def torso_twists(joints: np.ndarray, hips: tuple[int, int], shoulders: tuple[int, int]) -> np.ndarray:
    """Per frame of one clip, the signed angle (degrees, −180..180) from the hips' axis to the shoulders'
    axis about +y (left − right joint of each pair, horizontal parts)."""
    pos = np.asarray(joints, dtype=np.float64)
    h = pos[:, hips[0], ::2] - pos[:, hips[1], ::2]
    s = pos[:, shoulders[0], ::2] - pos[:, shoulders[1], ::2]
    return np.degrees(np.arctan2(h[:, 1] * s[:, 0] - h[:, 0] * s[:, 1], (h * s).sum(-1)))


def torso_twist(clips: Sequence[np.ndarray], hips: tuple[int, int], shoulders: tuple[int, int]) -> float:
    """Mean absolute ``torso_twists`` (degrees) over every frame of ``clips``."""
    angles = np.concatenate([torso_twists(c, hips, shoulders) for c in clips] or [np.zeros(0)])
    return float(np.abs(angles).mean()) if angles.size else 0.0


def physics_metrics(clips: Sequence[np.ndarray], skeleton: Skeleton, fps: float) -> dict[str, float]:
    """Every plausibility figure of a set of clips (feet and hands found by name, the heading from two leg
    chains, the torso twist from them and two arms; each left out without)."""
    feet, hands, root = foot_joints(skeleton), hand_joints(skeleton), skeleton.root
    hips, shoulders, ankles = hip_pair(skeleton), shoulder_pair(skeleton), ankle_pair(skeleton)
    pelvis = pelvis_joint(skeleton)
    out = {"bone_length_cv": median_bone_length_cv(clips, skeleton.parents)}
    if feet:
        out["foot_skate_m_s"] = foot_skate(clips, feet, fps)
        out["foot_pop_m_s"] = foot_pop(clips, feet, fps)
        out["floor_penetration"], out["floor_depth_m"] = floor_penetration(clips, feet)
        out["float_share"] = float_share(clips, feet, fps)
    for name, limbs in (("hand", hands), ("foot", feet)):
        if limbs:
            out[f"{name}_speed_m_s"] = float(np.mean([limb_speed(c, limbs, fps) for c in clips]))
            out[f"{name}_amplitude_m"] = float(
                np.mean([oscillation_amplitude(c, limbs, root) for c in clips])
            )
    if hands:
        out["late_hand_speed_m_s"] = float(np.mean([limb_speed(c, hands, fps, LATE_SHARE) for c in clips]))
        rhythms = np.array([limb_rhythm(c, hands, pelvis, fps) for c in clips])
        if np.isfinite(rhythms).any():  # left out where no hand moves
            out["hand_rhythm_hz"] = float(np.nanmean(rhythms))
    out["jerk_m_s3"] = float(np.nanmean([mean_jerk(c, fps) for c in clips]))
    out["pelvis_height_m"] = pelvis_height(clips, pelvis)
    if hips is not None:  # travel is the pelvis's (the hips' parent)
        out["heading_error_deg"] = heading_error(clips, hips, pelvis, fps)
    if hips is not None and shoulders is not None:
        out["torso_twist_deg"] = torso_twist(clips, hips, shoulders)
    if ankles is not None and hips is not None:
        out["foot_sync"] = foot_sync(clips, ankles, pelvis)
    toes = foot_lines(skeleton)
    backward = feet_backward(clips, toes, pelvis, fps) if toes and hips else np.nan
    if np.isfinite(backward):  # left out where nothing travels with a foot down
        out["feet_backward"] = backward
    return out
