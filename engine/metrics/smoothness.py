"""Frame-to-frame jumps: the largest per-joint displacement between consecutive frames."""

from __future__ import annotations

import numpy as np


def max_frame_jump(motions: np.ndarray, mask: np.ndarray | None = None) -> float:
    """Largest per-joint distance between consecutive frames over ``motions`` (N, T, J, 3).

    ``mask`` (N, T) marks real frames; a step counts only when both of its frames are real.
    """
    motions = np.asarray(motions, dtype=np.float64)
    steps = np.linalg.norm(np.diff(motions, axis=1), axis=-1).max(axis=-1)
    if mask is not None:
        mask = np.asarray(mask, dtype=bool)
        steps = np.where(mask[:, 1:] & mask[:, :-1], steps, 0.0)
    return float(steps.max()) if steps.size else 0.0
