"""Quaternions (w, x, y, z), intrinsic Euler angles and forward kinematics, on top of scipy's Rotation."""

from __future__ import annotations

import warnings

import numpy as np
from scipy.spatial.transform import Rotation

from engine.errors import ConfigError
from engine.motion.skeleton import Skeleton


def _check_order(order: str) -> str:
    """``order`` upper-cased (scipy's intrinsic convention) after checking it names 1-3 axes."""
    upper = order.upper()
    if not 1 <= len(upper) <= 3 or any(c not in "XYZ" for c in upper):
        raise ConfigError(f"rotation order must be 1-3 of the axes X, Y, Z, got {order!r}")
    return upper


def _rotations(q: np.ndarray) -> Rotation:
    """scipy Rotation of (..., 4) quaternions (w, x, y, z)."""
    return Rotation.from_quat(np.asarray(q, dtype=np.float64), scalar_first=True)


def euler_to_quat(angles_deg: np.ndarray, order: str) -> np.ndarray:
    """(..., 4) quaternions (w, x, y, z) of (..., len(order)) intrinsic Euler angles in degrees."""
    angles = np.asarray(angles_deg, dtype=np.float64)
    rot = Rotation.from_euler(_check_order(order), angles, degrees=True)
    return rot.as_quat(scalar_first=True)


def quat_to_euler(quats: np.ndarray, order: str) -> np.ndarray:
    """(..., 3) intrinsic Euler angles in degrees of (..., 4) quaternions, unwrapped over time (axis 0)."""
    order = _check_order(order)
    if len(order) != 3:
        raise ConfigError(f"quat_to_euler needs three axes, got {order!r}")
    q = np.asarray(quats, dtype=np.float64)
    with warnings.catch_warnings():
        # At gimbal lock scipy sets the third angle to zero and warns; the rotation is still exact.
        warnings.filterwarnings("ignore", message="Gimbal lock detected")
        angles = _rotations(q).as_euler(order, degrees=True)
    if q.ndim >= 2:
        angles = np.unwrap(angles, period=360.0, axis=0)
    return angles


def quat_multiply(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Hamilton product ``a * b`` of broadcastable (..., 4) quaternions (apply ``b`` first)."""
    qa, qb = (np.array(x) for x in np.broadcast_arrays(np.asarray(a, np.float64), np.asarray(b, np.float64)))
    return (_rotations(qa) * _rotations(qb)).as_quat(scalar_first=True)


def quat_apply(q: np.ndarray, v: np.ndarray) -> np.ndarray:
    """(..., 3) vectors ``v`` rotated by broadcastable (..., 4) quaternions ``q``."""
    q = np.asarray(q, np.float64)
    v = np.asarray(v, np.float64)
    shape = np.broadcast_shapes(q.shape[:-1], v.shape[:-1])
    qs = np.array(np.broadcast_to(q, (*shape, 4))).reshape(-1, 4)
    vs = np.array(np.broadcast_to(v, (*shape, 3))).reshape(-1, 3)
    return _rotations(qs).apply(vs).reshape(*shape, 3)


def quat_inverse(q: np.ndarray) -> np.ndarray:
    """(..., 4) inverse (conjugate of the normalised) quaternions."""
    return _rotations(q).inv().as_quat(scalar_first=True)


def quat_continuity(q: np.ndarray) -> np.ndarray:
    """(T, ..., 4) quaternions with signs flipped along axis 0 so consecutive ones have dot >= 0."""
    q = np.array(q, dtype=np.float64)
    if q.shape[0] < 2:
        return q
    dots = np.sum(q[1:] * q[:-1], axis=-1)
    signs = np.cumprod(np.where(dots < 0, -1.0, 1.0), axis=0)
    q[1:] *= signs[..., None]
    return q


def forward_kinematics(
    skeleton: Skeleton,
    local_rotations: np.ndarray,
    root_translation: np.ndarray,
    local_translations: np.ndarray | None = None,
) -> np.ndarray:
    """(T, J, 3) joint positions from local rotations.

    Parameters
    ----------
    skeleton : topology and rest offsets (used where ``local_translations`` is None).
    local_rotations : (T, J, 4) quaternions (w, x, y, z), each joint relative to its parent.
    root_translation : (T, 3) root position; it places the root whatever ``local_translations`` holds.
    local_translations : optional (T, J, 3) per-frame offsets from the parent (BVH position channels).
    """
    rots = np.asarray(local_rotations, dtype=np.float64)
    T, J = rots.shape[:2]
    if rots.shape != (T, skeleton.n_joints, 4):
        raise ConfigError(f"local_rotations must be (T, {skeleton.n_joints}, 4), got {rots.shape}")
    root_t = np.asarray(root_translation, dtype=np.float64)
    if root_t.shape != (T, 3):
        raise ConfigError(f"root_translation must be ({T}, 3), got {root_t.shape}")
    if local_translations is None:
        offsets = np.broadcast_to(skeleton.offsets, (T, J, 3))
    else:
        offsets = np.asarray(local_translations, dtype=np.float64)
        if offsets.shape != (T, J, 3):
            raise ConfigError(f"local_translations must be ({T}, {J}, 3), got {offsets.shape}")
    local = _rotations(rots.reshape(-1, 4)).as_matrix().reshape(T, J, 3, 3)
    world = np.empty_like(local)
    pos = np.empty((T, J, 3))
    for j, p in enumerate(skeleton.parents):
        if p < 0:
            world[:, j] = local[:, j]
            pos[:, j] = root_t
        else:
            world[:, j] = world[:, p] @ local[:, j]
            pos[:, j] = pos[:, p] + np.einsum("tij,tj->ti", world[:, p], offsets[:, j])
    return pos
