"""Diversity and multimodality: mean feature distance over random pairs (Action2Motion's definitions)."""

from __future__ import annotations

import numpy as np

from engine.errors import ConfigError


def _pair_distance(features: np.ndarray, n_pairs: int, rng: np.random.Generator) -> float:
    """Mean Euclidean distance over ``n_pairs`` random pairs of distinct rows of ``features`` (N, F)."""
    n = len(features)
    first = rng.integers(0, n, size=n_pairs)
    second = (first + rng.integers(1, n, size=n_pairs)) % n  # any other row, uniformly
    return float(np.linalg.norm(features[first] - features[second], axis=1).mean())


def diversity(features: np.ndarray, rng: np.random.Generator, n_pairs: int = 200) -> float:
    """Mean distance between ``n_pairs`` random pairs of features (N, F) drawn across all actions."""
    features = np.asarray(features, dtype=np.float64)
    if features.ndim != 2 or len(features) < 2:
        raise ConfigError(f"diversity needs (N>=2, F) features, got {features.shape}")
    return _pair_distance(features, n_pairs, rng)


def multimodality(
    features: np.ndarray, labels: np.ndarray, rng: np.random.Generator, n_pairs: int = 20
) -> float:
    """Mean over actions of mean distance of ``n_pairs`` same-action pairs; features (N, F), labels (N,)."""
    features = np.asarray(features, dtype=np.float64)
    labels = np.asarray(labels).reshape(-1)
    if features.ndim != 2 or len(features) != len(labels):
        raise ConfigError(f"features {features.shape} and labels {labels.shape} disagree")
    per_action = [
        _pair_distance(features[labels == a], n_pairs, rng)
        for a in np.unique(labels)
        if np.count_nonzero(labels == a) >= 2
    ]
    if not per_action:
        raise ConfigError("multimodality needs an action with at least two samples")
    return float(np.mean(per_action))
