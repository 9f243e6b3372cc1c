"""Motions as the evaluation classifier sees them: canonical windows of fixed length."""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from engine.errors import ConfigError
from engine.motion.motion import Motion
from engine.train.windows import canonicalize


def canonical_windows(motions: Sequence[Motion], window: int) -> np.ndarray:
    """(N, T, J, 3) float32: each motion's ``window`` frames, frame-0 root at the origin, facing +z."""
    out = []
    for motion in motions:
        if motion.n_frames != window:
            raise ConfigError(f"a motion has {motion.n_frames} frames, the classifier reads {window}")
        joints, _ = canonicalize(motion.joints, motion.skeleton)
        out.append(np.asarray(joints, dtype=np.float32))
    if not out:
        raise ConfigError("no motions given")
    return np.stack(out)


def root_heights(motions: Sequence[Motion]) -> np.ndarray:
    """(N,) float32 frame-0 root height of each motion (what ``canonical_windows`` subtracts from y)."""
    return np.array([m.joints[0, m.skeleton.root, 1] for m in motions], dtype=np.float32)
