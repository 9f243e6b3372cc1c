"""Reconstruction error: mean per-joint position error (MPJPE) in metres."""

from __future__ import annotations

import numpy as np

from engine.errors import ConfigError


def mpjpe(predicted: np.ndarray, truth: np.ndarray, mask: np.ndarray | None = None) -> float:
    """Mean Euclidean joint distance of (N, T, J, 3) arrays, over frames where ``mask`` (N, T) is true."""
    predicted = np.asarray(predicted, dtype=np.float64)
    truth = np.asarray(truth, dtype=np.float64)
    if predicted.shape != truth.shape or predicted.shape[-1] != 3:
        raise ConfigError(f"shapes differ or are not (..., 3): {predicted.shape} vs {truth.shape}")
    dist = np.linalg.norm(predicted - truth, axis=-1)  # (N, T, J)
    if mask is not None:
        dist = dist[np.asarray(mask, dtype=bool)]
    if dist.size == 0:
        raise ConfigError("no frames to compare")
    return float(dist.mean())
