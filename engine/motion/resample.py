"""Change a motion's frame rate: linear interpolation of positions, slerp of rotations."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
from scipy.spatial.transform import Rotation

from engine.errors import ConfigError
from engine.motion.motion import Motion


def resample_motion(motion: Motion, fps: float) -> Motion:
    """``motion`` sampled at ``fps`` over the same duration.

    The new clip has ``round(duration * fps) + 1`` frames at times ``k / fps`` (the last one clamped to
    the end), positions and root translation interpolated linearly, local rotations by slerp.
    ``meta["resampled_from_fps"]`` records the source rate; action and other meta are kept.
    """
    fps = float(fps)
    if not (np.isfinite(fps) and fps > 0):
        raise ConfigError(f"fps must be a positive number, got {fps}")
    n_new = round(motion.duration * fps) + 1
    src = np.minimum(np.arange(n_new) / fps, motion.duration) * motion.fps
    lo = np.minimum(np.floor(src).astype(np.int64), motion.n_frames - 1)
    hi = np.minimum(lo + 1, motion.n_frames - 1)
    frac = src - lo

    def lerp(x: np.ndarray) -> np.ndarray:
        w = frac.reshape(-1, *([1] * (x.ndim - 1)))
        return x[lo] * (1.0 - w) + x[hi] * w

    joints = lerp(motion.joints.astype(np.float64))
    rotations = root = None
    if motion.local_rotations is not None:
        q0 = Rotation.from_quat(motion.local_rotations[lo], scalar_first=True)
        q1 = Rotation.from_quat(motion.local_rotations[hi], scalar_first=True)
        step = (q0.inv() * q1).as_rotvec() * frac[:, None, None]
        rotations = (q0 * Rotation.from_rotvec(step)).as_quat(scalar_first=True)
    if motion.root_translation is not None:
        root = lerp(motion.root_translation)
    meta = {**motion.meta, "resampled_from_fps": motion.fps}
    return replace(
        motion, joints=joints, fps=fps, local_rotations=rotations, root_translation=root, meta=meta
    )
