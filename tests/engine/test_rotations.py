"""Quaternion helpers and forward kinematics against known answers."""

from __future__ import annotations

import numpy as np
import pytest

from engine.errors import ConfigError
from engine.motion.rotations import (
    euler_to_quat,
    forward_kinematics,
    quat_apply,
    quat_continuity,
    quat_inverse,
    quat_multiply,
    quat_to_euler,
)
from engine.motion.skeleton import Skeleton

ORDERS = ["XYZ", "XZY", "YXZ", "YZX", "ZXY", "ZYX"]
S = np.sqrt(0.5)


def test_euler_to_quat_known_answers() -> None:
    assert np.allclose(euler_to_quat(np.array([90.0, 0, 0]), "ZXY"), [S, 0, 0, S])
    assert np.allclose(euler_to_quat(np.array([0.0, 90, 0]), "ZXY"), [S, S, 0, 0])
    # Intrinsic ZX: rotate about Z by 90, then about the new X (old Y) by 90.
    q = euler_to_quat(np.array([90.0, 90.0]), "ZX")
    assert np.allclose(quat_apply(q, np.array([0.0, 1, 0])), [0, 0, 1])
    assert np.allclose(quat_apply(q, np.array([1.0, 0, 0])), [0, 1, 0])


def test_bad_order_is_a_config_error() -> None:
    with pytest.raises(ConfigError):
        euler_to_quat(np.zeros(3), "ZQY")
    with pytest.raises(ConfigError):
        quat_to_euler(np.array([1.0, 0, 0, 0]), "ZX")


@pytest.mark.parametrize("order", ORDERS)
def test_euler_round_trip_every_order(order: str) -> None:
    rng = np.random.default_rng(0)
    angles = rng.uniform(-80, 80, size=(20, 5, 3))
    back = quat_to_euler(euler_to_quat(angles, order), order)
    assert np.allclose(back, angles, atol=1e-9)


def test_quat_to_euler_unwraps_over_time() -> None:
    z = np.linspace(0.0, 720.0, 145)
    angles = np.stack([z, np.zeros_like(z), np.zeros_like(z)], axis=1)
    q = euler_to_quat(angles, "ZXY")
    back = quat_to_euler(q, "ZXY")
    assert np.allclose(back, angles, atol=1e-9)
    assert np.max(np.abs(np.diff(back[:, 0]))) < 5.01


def test_quat_to_euler_at_gimbal_lock_does_not_warn_and_is_exact() -> None:
    q = euler_to_quat(np.array([[10.0, 90.0, 20.0]]), "ZXY")
    angles = quat_to_euler(q, "ZXY")
    assert np.allclose(np.abs(np.sum(q * euler_to_quat(angles, "ZXY"), axis=-1)), 1.0)


def test_multiply_apply_inverse_compose() -> None:
    rng = np.random.default_rng(1)
    a = euler_to_quat(rng.uniform(-180, 180, (6, 3)), "XYZ")
    b = euler_to_quat(rng.uniform(-180, 180, (6, 3)), "YZX")
    v = rng.normal(size=(6, 3))
    assert np.allclose(quat_apply(quat_multiply(a, b), v), quat_apply(a, quat_apply(b, v)))
    assert np.allclose(quat_apply(quat_inverse(a), quat_apply(a, v)), v)
    z90 = np.array([S, 0, 0, S])
    assert np.allclose(quat_apply(z90, np.array([[1.0, 0, 0], [0, 1, 0]])), [[0, 1, 0], [-1, 0, 0]])


def test_quat_continuity_flips_signs_only() -> None:
    rng = np.random.default_rng(2)
    q = euler_to_quat(np.cumsum(rng.uniform(-10, 10, (50, 3, 3)), axis=0), "ZXY")
    flipped = q * rng.choice([-1.0, 1.0], size=(50, 3, 1))
    fixed = quat_continuity(flipped)
    assert np.all(np.sum(fixed[1:] * fixed[:-1], axis=-1) >= 0)
    assert np.allclose(np.abs(fixed), np.abs(q))


def _chain() -> Skeleton:
    return Skeleton(("a", "b", "c"), np.array([-1, 0, 1]), np.array([[0.0, 1, 0], [1, 0, 0], [0, 1, 0]]))


def test_forward_kinematics_chain_by_hand() -> None:
    skel = _chain()
    rots = np.zeros((2, 3, 4))
    rots[..., 0] = 1
    rots[1, 0] = [S, 0, 0, S]  # root turns 90 degrees about z
    rots[1, 1] = [S, S, 0, 0]  # b turns 90 degrees about x
    root = np.array([[0.0, 1, 0], [2, 0, 0]])
    pos = forward_kinematics(skel, rots, root)
    assert np.allclose(pos[0], [[0, 1, 0], [1, 1, 0], [1, 2, 0]])
    # frame 1: b = root + Rz(1,0,0) = (2,1,0); c = b + Rz Rx (0,1,0) = b + Rz (0,0,1) = (2,1,1)
    assert np.allclose(pos[1], [[2, 0, 0], [2, 1, 0], [2, 1, 1]])


def test_forward_kinematics_local_translations_replace_offsets() -> None:
    skel = _chain()
    rots = np.zeros((1, 3, 4))
    rots[..., 0] = 1
    trans = np.array([[[9.0, 9, 9], [0, 0, 2], [0, 0, 3]]])
    pos = forward_kinematics(skel, rots, np.zeros((1, 3)), trans)
    assert np.allclose(pos[0], [[0, 0, 0], [0, 0, 2], [0, 0, 5]])


def test_forward_kinematics_rejects_wrong_shapes() -> None:
    with pytest.raises(ConfigError):
        forward_kinematics(_chain(), np.zeros((2, 2, 4)), np.zeros((2, 3)))
