"""Chain motions one after another on the floor, each starting where (and facing how) the last ended."""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
from scipy.spatial.transform import Rotation

from engine.errors import ConfigError
from engine.motion.motion import Motion
from engine.train.windows import canonicalize


def _yaw(frame: np.ndarray, motion: Motion) -> float:
    """Facing yaw (radians about +y) of one (J, 3) frame of ``motion``'s skeleton."""
    return canonicalize(frame[None], motion.skeleton)[1]


def chain_transforms(motions: Sequence[Motion]) -> list[np.ndarray]:
    """(4, 4) rigid floor transform of each motion that makes it start where the previous one ended.

    The first motion stays put. Each next one is turned about +y so that its first frame faces the way
    the previous (chained) motion's last frame faces, and moved on the floor (x, z) so that its first
    root position lands on that last root position; heights are kept.
    """
    if not motions:
        raise ConfigError("no motions to chain")
    transforms = [np.eye(4)]
    prev_end = np.zeros(3)
    for k, motion in enumerate(motions):
        root = motion.skeleton.root
        if k > 0:
            last = apply_transform(transforms[-1], motions[k - 1].joints[-1])
            turn = _yaw(last, motions[k - 1]) - _yaw(motion.joints[0], motion)
            rot = Rotation.from_euler("y", turn).as_matrix()
            start = motion.joints[0, root].astype(np.float64)
            target = np.array([prev_end[0], start[1], prev_end[2]])
            matrix = np.eye(4)
            matrix[:3, :3] = rot
            matrix[:3, 3] = target - rot @ start
            transforms.append(matrix)
        prev_end = apply_transform(transforms[-1], motion.joints[-1, root][None])[0]
    return transforms


def apply_transform(matrix: np.ndarray, points: np.ndarray) -> np.ndarray:
    """``points`` (..., 3) moved by the (4, 4) rigid transform ``matrix``."""
    pts = np.asarray(points, dtype=np.float64)
    return pts @ matrix[:3, :3].T + matrix[:3, 3]


def chain_motions(motions: Sequence[Motion]) -> tuple[Motion, list[np.ndarray]]:
    """The motions played one after another as one motion (see :func:`chain_transforms`), and the
    transform applied to each (to place what belongs to a step, e.g. its end location)."""
    transforms = chain_transforms(motions)
    joints = np.concatenate(
        [apply_transform(t, m.joints).astype(np.float32) for t, m in zip(transforms, motions, strict=True)]
    )
    meta = {"sequence": [m.meta for m in motions], "steps": [m.n_frames for m in motions]}
    return motions[0].with_joints(joints, meta=meta), transforms
