"""Trajectory-control metrics: end-point targets inside/outside the training range and their errors."""

from __future__ import annotations

import numpy as np

from engine.errors import ConfigError


def end_point_errors(trajectories: np.ndarray, targets: np.ndarray) -> np.ndarray:
    """(N,) distance in metres between each root path's displacement from its first frame to its last
    (trajectories (N, T, 3)) and the target end locations (N, 3), which are relative to the start (a clip
    lowered rigidly onto the floor keeps its end)."""
    traj = np.asarray(trajectories, dtype=np.float64)
    targets = np.asarray(targets, dtype=np.float64)
    if traj.ndim != 3 or traj.shape[2] != 3 or targets.shape != (len(traj), 3):
        raise ConfigError(
            f"need trajectories (N, T, 3) and targets (N, 3), got {traj.shape}, {targets.shape}"
        )
    return np.linalg.norm(traj[:, -1] - traj[:, 0] - targets, axis=1)


def root_travel(trajectories: np.ndarray) -> np.ndarray:
    """(N,) straight-line distance in metres from first to last root position of trajectories (N, T, 3)."""
    traj = np.asarray(trajectories, dtype=np.float64)
    if traj.ndim != 3 or traj.shape[2] != 3:
        raise ConfigError(f"need trajectories (N, T, 3), got {traj.shape}")
    return np.linalg.norm(traj[:, -1] - traj[:, 0], axis=1)


def control_targets(
    ends: np.ndarray,
    n_codes: int,
    rng: np.random.Generator,
    n_points: int = 10,
    outside_scale: float = 1.5,
) -> tuple[np.ndarray, np.ndarray]:
    """End-point targets (n_codes, n_points, 3) inside and outside one action's training end locations.

    Inside (the paper's protocol): per code, two random real end points and the points evenly spaced
    between them (both included). Outside: the same points pushed radially in the ground plane to
    ``outside_scale`` × the farthest training end distance, height kept.
    """
    ends = np.asarray(ends, dtype=np.float64)
    if ends.ndim != 2 or ends.shape[1] != 3 or len(ends) < 2:
        raise ConfigError(f"need at least two (3,) end locations, got {ends.shape}")
    pick = np.stack([rng.choice(len(ends), size=2, replace=False) for _ in range(n_codes)])
    s = np.linspace(0.0, 1.0, n_points)[None, :, None]
    inside = ends[pick[:, 0]][:, None] * (1.0 - s) + ends[pick[:, 1]][:, None] * s
    radius = outside_scale * max(float(np.linalg.norm(ends[:, [0, 2]], axis=1).max()), 0.1)
    ground = inside[..., [0, 2]]
    norm = np.linalg.norm(ground, axis=-1, keepdims=True)
    direction = np.where(norm > 1e-6, ground / np.maximum(norm, 1e-6), np.array([0.0, 1.0]))
    outside = inside.copy()
    outside[..., [0, 2]] = direction * radius
    return inside, outside
