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

import numpy as np
from scipy.spatial.transform import Rotation

from engine.errors import ConfigError
from engine.motion.motion import Motion
from engine.motion.skeleton import Skeleton

log = logging.getLogger(__name__)

TWIST_POLICIES = ("minimal",)
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
