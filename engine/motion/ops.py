"""Operations on motions that views and tools share: the root's floor path, equal-length joint stacks,
motion energy."""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from engine.errors import ConfigError
from engine.motion.motion import Motion


def root_floor_path(motion: Motion) -> np.ndarray:
    """(T, 2) float64 floor path (x, z) of the motion's root."""
    return motion.joints[:, motion.skeleton.root][:, [0, 2]].astype(np.float64)


def padded_joints(motions: Sequence[Motion], length: int | None = None) -> np.ndarray:
    """(n, length, J, 3) joints of ``motions``, each held at its last frame up to ``length`` frames
    (default: the longest motion's)."""
    if not motions:
        raise ConfigError("no motions to stack")
    length = max(m.n_frames for m in motions) if length is None else int(length)
    if length < max(m.n_frames for m in motions):
        raise ConfigError(
            f"length {length} is shorter than a motion of {max(m.n_frames for m in motions)} frames"
        )
    return np.stack(
        [np.concatenate([m.joints, np.repeat(m.joints[-1:], length - m.n_frames, 0)]) for m in motions]
    )


def motion_energy(joints: np.ndarray, fps: float) -> np.ndarray:
    """(B,) mean joint speed in m/s of motions ``joints`` (B, T, J, 3)."""
    if joints.shape[1] < 2:
        return np.zeros(len(joints))
    speed = np.linalg.norm(np.diff(joints, axis=1), axis=-1) * fps
    return speed.mean(axis=(1, 2))
