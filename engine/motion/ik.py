"""Inverse kinematics: joint positions to local joint rotations on a skeleton with fixed bone lengths.

Policy
------
- Bone lengths are the median over the clip of each parent-to-child distance.
- Rest pose: each bone points along its offset in the input skeleton, scaled to the median length
  (a bone whose input offset is zero points along its median observed direction); the rebuilt root
  offset is zero, so ``root_translation`` alone places the root.
- A joint with two or more children (root, chest) is oriented by weighted Kabsch
  (:meth:`scipy.spatial.transform.Rotation.align_vectors`) of its rest child offsets onto the
  observed child directions, weighted by bone length.
- A joint with one child takes the shortest-arc rotation, in its parent's frame, from the rest
  offset to the observed direction. Twist policy ``"minimal"``: no rotation about the bone axis
  relative to the parent frame beyond what the shortest arc implies.
- Leaf joints get the identity; quaternions are made sign-continuous along time.
"""

from __future__ import annotations

import logging
from collections.abc import Sequence

import numpy as np
from scipy.spatial.transform import Rotation

from engine.errors import ConfigError
from engine.motion.contact import floats, leg_chains
from engine.motion.motion import Motion
from engine.motion.skeleton import Skeleton

log = logging.getLogger(__name__)

TWIST_POLICIES = ("minimal",)
PLANT_RAMP = 3  # frames over which a planted foot's shift fades in and out
PLANT_BRIDGE = 2  # frames: a shorter break between two contacts is the contact head flickering
PLANT_REACH = 0.3  # metres a planted foot may be held along the floor from where it was decoded
PLANT_SLACK = 0.04  # metres past the leg's length a pinned ankle may be placed (the IK lifts it that much)
_EPS = 1e-9


def joints_to_rotations(
    motion: Motion, twist: str = "minimal"
) -> tuple[Skeleton, np.ndarray, np.ndarray, float]:
    """Solve local rotations reproducing ``motion.joints`` with fixed bone lengths.

    Returns
    -------
    skeleton : the input topology with rest offsets rebuilt from median bone lengths.
    local_rotations : (T, J, 4) float64 quaternions (w, x, y, z), each joint relative to its parent.
    root_translation : (T, 3) float64 root positions in metres.
    fk_error_m : mean per-joint distance between forward kinematics of the result and the input.
    """
    from engine.motion.rotations import forward_kinematics, quat_continuity

    if twist not in TWIST_POLICIES:
        raise ConfigError(f"unknown twist policy {twist!r}; choose one of {', '.join(TWIST_POLICIES)}")
    skel = motion.skeleton
    joints = motion.joints.astype(np.float64)
    T, J = joints.shape[:2]
    parents = skel.parents
    rest = _rest_offsets(skel, joints)
    rest_len = np.linalg.norm(rest, axis=1)

    local = np.zeros((T, J, 4))
    local[..., 0] = 1.0
    # Each bone aims from its solved (not observed) start, so errors do not accumulate down chains.
    solved = np.empty_like(joints)
    solved[:, skel.root] = joints[:, skel.root]
    global_rot: list[Rotation] = [Rotation.identity(T)] * J
    for j in range(J):
        parent_rot = Rotation.identity(T) if parents[j] < 0 else global_rot[int(parents[j])]
        kids = [c for c in skel.children(j) if rest_len[c] > _EPS]
        if kids:
            # Observed child directions expressed in the parent's frame.
            to_parent_frame = parent_rot.inv()
            seen = np.stack([to_parent_frame.apply(joints[:, c] - solved[:, j]) for c in kids], axis=1)
            if len(kids) == 1 or _collinear(rest[kids]):
                lead = int(np.argmax(rest_len[kids]))
                rot = _shortest_arc(rest[kids[lead]], seen[:, lead])
            else:
                rot = _kabsch(rest[kids], seen, rest_len[kids])
            local[:, j] = rot.as_quat(scalar_first=True)
        global_rot[j] = parent_rot * Rotation.from_quat(local[:, j], scalar_first=True)
        for c in skel.children(j):
            solved[:, c] = solved[:, j] + global_rot[j].apply(rest[c])

    local = quat_continuity(local)
    root_translation = joints[:, skel.root].copy()
    rest_skel = Skeleton(skel.names, parents, rest, skel.end_sites, "m")
    fk = forward_kinematics(rest_skel, local, root_translation)
    fk_error = float(np.mean(np.linalg.norm(fk - joints, axis=-1)))
    log.debug("IK on %d frames x %d joints: mean FK error %.4f m", T, J, fk_error)
    return rest_skel, local, root_translation, fk_error


def _rest_offsets(skel: Skeleton, joints: np.ndarray) -> np.ndarray:
    """(J, 3) rest offsets: input offset directions scaled to the clip's median bone lengths."""
    rest = np.zeros((skel.n_joints, 3))
    for j, p in enumerate(skel.parents):
        if p < 0:
            continue
        bone = joints[:, j] - joints[:, p]
        length = float(np.median(np.linalg.norm(bone, axis=1)))
        direction = skel.offsets[j]
        if np.linalg.norm(direction) <= _EPS:
            direction = np.median(bone, axis=0)
        norm = np.linalg.norm(direction)
        if norm > _EPS:
            rest[j] = direction / norm * length
    return rest


def _collinear(vectors: np.ndarray) -> bool:
    """True when the (K, 3) ``vectors`` span at most a line (Kabsch would be ill-defined)."""
    units = vectors / np.linalg.norm(vectors, axis=1, keepdims=True)
    return bool(np.linalg.matrix_rank(units, tol=1e-3) < 2)


def _shortest_arc(u: np.ndarray, v: np.ndarray) -> Rotation:
    """Rotations (T,) taking the fixed direction ``u`` (3,) onto each direction ``v`` (T, 3)."""
    u = u / np.linalg.norm(u)
    v_norm = np.linalg.norm(v, axis=1, keepdims=True)
    v = np.where(v_norm > _EPS, v / np.maximum(v_norm, _EPS), u)
    quat = np.concatenate([np.cross(u, v), 1.0 + v @ u[:, None]], axis=1)
    opposite = quat[:, 3] < 1e-8
    if np.any(opposite):
        # Half turn about any axis perpendicular to u.
        axis = np.cross(u, [1.0, 0.0, 0.0] if abs(u[0]) < 0.9 else [0.0, 1.0, 0.0])
        quat[opposite] = np.append(axis / np.linalg.norm(axis), 0.0)
    return Rotation.from_quat(quat)


def _kabsch(rest: np.ndarray, seen: np.ndarray, weights: np.ndarray) -> Rotation:
    """Rotations (T,) best mapping the (K, 3) ``rest`` directions onto each frame of ``seen`` (T, K, 3)."""
    quats = np.empty((seen.shape[0], 4))
    for t, frame in enumerate(seen):
        quats[t] = Rotation.align_vectors(frame, rest, weights=weights)[0].as_quat()
    return Rotation.from_quat(quats)


#: Seconds over which a longer clip finds its floor (windows this long, each overlapping the next by half):
#: longer than any generator's window here (1.6-3.2 s), so only a long sequence is cut.
FLOOR_SECONDS = 4.0


def _floor_drops(
    feet: np.ndarray, heights: np.ndarray, planted: np.ndarray | None, fps: float | None
) -> np.ndarray:
    """Per clip of foot joints (N, T, F, 3), how far ``lower_to_floor`` moves it down (N,)."""
    above = feet[..., 1] - heights  # (N, T, F)
    drop = np.maximum(above.min(axis=(1, 2)), 0.0)
    if planted is not None and fps is not None:
        lowered = feet - drop[:, None, None, None] * np.array([0.0, 1.0, 0.0])
        for b in np.flatnonzero(floats(lowered, range(feet.shape[2]), fps) & planted.any(axis=(1, 2))):
            drop[b] = max(drop[b], float(np.median(above[b][planted[b]])))
    return drop


def lower_to_floor(
    joints: np.ndarray,
    feet: Sequence[int],
    heights: Sequence[float],
    contact: np.ndarray | None = None,
    fps: float | None = None,
) -> np.ndarray:
    """Joints (B, T, J, 3), floor y = 0, each clip moved down rigidly until the foot joint that comes
    nearest its resting height (``heights`` (F,) of ``feet``) in any frame reaches it; a clip whose feet
    reach the floor somewhere is left as it is. Given the model's ``contact`` (B, T, F) and ``fps``, a
    clip whose feet then still float (``floats``) is lowered further by the median height over rest of
    its foot joints in their predicted-contact frames (a gait that skips a step keeps both feet up
    between the frames where they touch). A model that places the first root frame at a fixed height
    gives a clip in a crouching gait (a walk, a run) feet that never come down.

    Given ``fps``, a clip longer than ``FLOOR_SECONDS`` (a long sequence whose height drifts) finds its
    floor so in each window of that length, half overlapping, and is moved down by their drops
    interpolated linearly between the windows' centres."""
    out = np.asarray(joints)
    foot = out[..., list(feet), :]  # (B, T, F, 3)
    rest = np.asarray(heights, dtype=out.dtype)
    planted = None if contact is None else np.asarray(contact, bool)
    frames = out.shape[1]
    span = frames if fps is None else max(2, round(FLOOR_SECONDS * fps))
    if frames <= span:
        drop = np.repeat(_floor_drops(foot, rest, planted, fps)[:, None], frames, axis=1)
    else:
        starts = np.unique(np.r_[np.arange(0, frames - span, span // 2), frames - span])
        cut = np.stack([foot[:, s : s + span] for s in starts], axis=1)  # (B, K, span, F, 3)
        cut_planted = (
            None if planted is None else np.stack([planted[:, s : s + span] for s in starts], axis=1)
        )
        flat = None if cut_planted is None else cut_planted.reshape(-1, *cut_planted.shape[2:])
        drops = _floor_drops(cut.reshape(-1, *cut.shape[2:]), rest, flat, fps).reshape(len(out), len(starts))
        centres = starts + (span - 1) / 2
        drop = np.stack([np.interp(np.arange(frames), centres, d) for d in drops])
    if not drop.any():
        return out
    out = out.copy()
    out[..., 1] -= drop[:, :, None].astype(out.dtype)
    return out


def plant_feet(
    joints: np.ndarray,
    contact: np.ndarray,
    skeleton: Skeleton,
    feet: Sequence[int],
    heights: Sequence[float],
    ramp: int = PLANT_RAMP,
    reach: float = PLANT_REACH,
    ground: bool = True,
    fps: float | None = None,
    given: int = 0,
) -> np.ndarray:
    """Joints (B, T, J, 3), floor y = 0, with planted feet pinned and no foot under its resting height.
    The first ``given`` frames (a prefix the motion continues) come back as they are, nothing is lowered,
    and a contact that began in them holds the foot where they planted it.

    With ``ground`` a clip whose feet never come down to the floor is first lowered onto it
    (``lower_to_floor``; by its predicted contacts where it floats, when ``fps`` is given). Per leg
    (``leg_chains``): while its lowest-resting foot joint (the toe) is planted (``contact`` (B, T, F) over
    ``feet``, resting ``heights`` (F,); breaks of up to ``PLANT_BRIDGE`` frames filled), that joint keeps
    the mean floor position of the contact and sits at its resting height. It is held no more than
    ``reach`` metres along the floor from where it was decoded, nor further than the leg reaches from its
    hip (plus ``PLANT_SLACK``): a foot decoded sliding further is dragged rather than torn from the leg or
    lifted off the floor. The shift fades out over ``ramp`` frames either side, and passes linearly from
    one contact's shift to the next across a shorter gap, so pinning never makes a foot jump. Any frame
    whose foot joints dip under their resting heights is lifted to them. The foot moves rigidly and the
    knee is re-solved by two-bone IK (hip fixed, bone lengths kept; a target out of reach is approached
    along the hip-to-target line), so the pose stays one a BVH holds exactly.
    """
    out = np.array(joints, dtype=np.float64, copy=True)
    feet, heights = list(feet), np.asarray(heights, dtype=np.float64)
    if ground and not given:
        out = lower_to_floor(out, feet, heights, contact, fps)
    planted = np.asarray(contact, bool)
    for hip, knee, ankle, below in leg_chains(skeleton):
        leg = [ankle, *below]
        cols = [feet.index(j) for j in leg if j in feet]
        if not cols:
            continue
        rest = heights[cols]
        low = cols[int(np.argmin(rest))]
        toe_planted = _bridged(planted[..., low], PLANT_BRIDGE)
        delta = _pin_shift(out[:, :, feet[low]], toe_planted, rest.min(), ramp, reach, given)
        moved = out[:, :, [feet[c] for c in cols]] + delta[:, :, None]
        delta[..., 1] += np.maximum(0.0, (rest - moved[..., 1]).max(axis=-1))
        delta[:, :given] = 0.0
        moving = np.abs(delta).max(axis=-1) > 1e-9  # (B, T): frames left alone stay bit-identical
        if not moving.any():
            continue
        legs = out[moving]  # (N, J, 3)
        target = legs[:, ankle] + _within_leg(delta[moving], legs[:, hip], legs[:, knee], legs[:, ankle])
        new_knee, reached = _two_bone(legs[:, hip], legs[:, knee], legs[:, ankle], target)
        legs[:, below] += (reached - legs[:, ankle])[:, None]
        legs[:, knee], legs[:, ankle] = new_knee, reached
        out[moving] = legs
    return out.astype(np.asarray(joints).dtype)


def _spans(planted: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(B, T) index of the last planted frame at or before each frame (-1: none) and of the next one at
    or after it (T: none)."""
    t = planted.shape[1]
    frames = np.arange(t)[None, :]
    last = np.maximum.accumulate(np.where(planted, frames, -1), axis=1)
    nxt = np.minimum.accumulate(np.where(planted, frames, t)[:, ::-1], axis=1)[:, ::-1]
    return last, nxt


def _bridged(planted: np.ndarray, gap: int) -> np.ndarray:
    """``planted`` (B, T) with every break of at most ``gap`` frames between two contacts filled."""
    last, nxt = _spans(planted)
    return planted | ((last >= 0) & (nxt < planted.shape[1]) & (nxt - last - 1 <= gap))


def _pin_shift(
    pos: np.ndarray, planted: np.ndarray, rest: float, ramp: int, reach: float, given: int = 0
) -> np.ndarray:
    """(B, T, 3) shift that holds joint positions ``pos`` (B, T, 3) at height ``rest`` and at the mean
    floor point of each contact (``planted`` (B, T)), or ``reach`` metres short of it where the joint
    strays further; a contact that began in the first ``given`` frames, at their mean floor point.
    Between contacts the shift fades out linearly over ``ramp`` frames, and across a gap too short for
    both fades it passes linearly from one contact's shift to the next one's."""
    b, t = planted.shape
    starts = planted & ~np.concatenate([np.zeros((b, 1), bool), planted[:, :-1]], axis=1)
    seg = np.cumsum(starts, axis=1) + (np.arange(b) * (t + 1))[:, None]
    ids = seg[planted]
    weight = np.ones(ids.shape)
    if given:
        first = np.broadcast_to(np.arange(t) < given, (b, t))[planted]
        weight = np.where(np.bincount(ids, weights=first, minlength=b * (t + 1))[ids] > 0, first, 1.0)
    count = np.bincount(ids, weights=weight, minlength=b * (t + 1))
    delta = np.zeros((b, t, 3))
    for axis in (0, 2):
        total = np.bincount(ids, weights=weight * pos[..., axis][planted], minlength=count.size)
        mean = total / np.maximum(count, 1e-12)
        delta[..., axis][planted] = mean[ids] - pos[..., axis][planted]
    far = np.hypot(delta[..., 0], delta[..., 2])
    delta[..., [0, 2]] *= np.minimum(1.0, reach / np.maximum(far, _EPS))[..., None]
    delta[..., 1][planted] = rest - pos[..., 1][planted]
    last, nxt = _spans(planted)
    frames = np.arange(t)[None, :]
    span = np.where((last >= 0) & (nxt < t), np.clip(nxt - last, 1, ramp + 1), ramp + 1)
    fade_out = np.where(last >= 0, np.clip(1.0 - (frames - last) / span, 0.0, 1.0), 0.0)
    fade_in = np.where(nxt < t, np.clip(1.0 - (nxt - frames) / span, 0.0, 1.0), 0.0)
    before = np.take_along_axis(delta, np.clip(last, 0, t - 1)[..., None], axis=1)
    after = np.take_along_axis(delta, np.clip(nxt, 0, t - 1)[..., None], axis=1)
    return np.where(planted[..., None], delta, fade_out[..., None] * before + fade_in[..., None] * after)


def _within_leg(delta: np.ndarray, hip: np.ndarray, knee: np.ndarray, ankle: np.ndarray) -> np.ndarray:
    """``delta`` (..., 3) with its floor part shortened where it would put the ankle further from the
    hip than the leg's length plus ``PLANT_SLACK``."""
    reach = np.linalg.norm(knee - hip, axis=-1) + np.linalg.norm(ankle - knee, axis=-1) + PLANT_SLACK
    start = ankle - hip
    start[..., 1] += delta[..., 1]
    floor = delta * np.array([1.0, 0.0, 1.0])
    # |start + s·floor|² ≤ reach²: the largest s in [0, 1] that satisfies it.
    a = (floor**2).sum(-1)
    b = (start * floor).sum(-1)
    c = (start**2).sum(-1) - reach**2
    root = (-b + np.sqrt(np.maximum(b**2 - a * c, 0.0))) / np.maximum(a, 1e-12)
    share = np.where(a + 2 * b + c <= 0.0, 1.0, np.where(c > 0.0, 0.0, np.clip(root, 0.0, 1.0)))
    out = delta.copy()
    out[..., [0, 2]] *= share[..., None]
    return out


def _two_bone(
    hip: np.ndarray, knee: np.ndarray, ankle: np.ndarray, target: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """Knee and ankle positions (..., 3) with the hip fixed, both bone lengths kept and the ankle at
    ``target`` (or as near as the leg reaches along the hip-to-target line), bending in the knee's plane."""
    l1 = np.linalg.norm(knee - hip, axis=-1, keepdims=True)
    l2 = np.linalg.norm(ankle - knee, axis=-1, keepdims=True)
    v = target - hip
    d = np.linalg.norm(v, axis=-1, keepdims=True)
    u = v / np.maximum(d, _EPS)
    d = np.clip(d, np.abs(l1 - l2) + 1e-6, l1 + l2 - 1e-6)
    along = (l1**2 - l2**2 + d**2) / (2 * d)
    across = np.sqrt(np.maximum(l1**2 - along**2, 0.0))
    # the knee's side of the leg as decoded (off the hip-to-ankle line), not of the new hip-to-target line:
    # a nearly straight leg whose target moves would otherwise flip its knee across
    line = ankle - hip
    line = line / np.maximum(np.linalg.norm(line, axis=-1, keepdims=True), _EPS)
    pole = knee - hip
    pole = pole - (pole * line).sum(-1, keepdims=True) * line
    w = pole - (pole * u).sum(-1, keepdims=True) * u
    w_norm = np.linalg.norm(w, axis=-1, keepdims=True)
    fallback = np.cross(u, [1.0, 0.0, 0.0])
    w = np.where(w_norm > 1e-9, w / np.maximum(w_norm, 1e-12), fallback)
    return hip + along * u + across * w, hip + d * u
