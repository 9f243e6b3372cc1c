"""Shared motion operations, on motions whose answers are known."""

from __future__ import annotations

import numpy as np
import pytest

from engine.errors import ConfigError
from engine.motion.motion import Motion
from engine.motion.ops import motion_energy, padded_joints, root_floor_path
from engine.motion.skeleton import Skeleton


def _motion(n_frames: int, start: float) -> Motion:
    skeleton = Skeleton(["Hips", "Head"], np.array([-1, 0]), np.array([[0.0, 0.0, 0.0], [0.0, 0.5, 0.0]]))
    t = np.arange(n_frames, dtype=np.float32)
    joints = np.zeros((n_frames, 2, 3), np.float32)
    joints[:, 0] = np.stack([start + t, np.full_like(t, 0.9), -2 * t], axis=1)
    joints[:, 1] = joints[:, 0] + [0.0, 0.5, 0.0]
    return Motion(joints, 20.0, skeleton)


def test_root_floor_path_is_x_and_z_of_the_root() -> None:
    path = root_floor_path(_motion(4, 1.0))
    assert path.dtype == np.float64
    np.testing.assert_array_equal(path, [[1, 0], [2, -2], [3, -4], [4, -6]])


def test_padded_joints_hold_the_last_frame() -> None:
    short, long = _motion(2, 0.0), _motion(5, 10.0)
    stacked = padded_joints([short, long])
    assert stacked.shape == (2, 5, 2, 3)
    np.testing.assert_array_equal(stacked[0, 2:], np.repeat(short.joints[-1:], 3, axis=0))
    np.testing.assert_array_equal(stacked[1], long.joints)
    assert padded_joints([short], 3).shape == (1, 3, 2, 3)
    with pytest.raises(ConfigError, match="shorter"):
        padded_joints([long], 3)
    with pytest.raises(ConfigError, match="no motions"):
        padded_joints([])


def test_motion_energy_is_the_mean_joint_speed() -> None:
    moving = _motion(5, 0.0)  # both joints move by (1, 0, -2) a frame at 20 fps
    still = moving.with_joints(np.repeat(moving.joints[:1], 5, axis=0))
    energy = motion_energy(np.stack([moving.joints, still.joints]), 20.0)
    np.testing.assert_allclose(energy, [np.sqrt(5.0) * 20.0, 0.0], rtol=1e-6)
    assert motion_energy(moving.joints[None, :1], 20.0).tolist() == [0.0]
