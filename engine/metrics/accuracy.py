"""Recognition accuracy of a classifier's predictions."""

from __future__ import annotations

import numpy as np

from engine.errors import ConfigError


def recognition_accuracy(predicted: np.ndarray, labels: np.ndarray) -> float:
    """Fraction (0..1) of ``predicted`` (N,) class indices equal to ``labels`` (N,)."""
    predicted = np.asarray(predicted).reshape(-1)
    labels = np.asarray(labels).reshape(-1)
    if predicted.shape != labels.shape or predicted.size == 0:
        raise ConfigError(
            f"need equal, non-empty predictions and labels, got {predicted.shape} and {labels.shape}"
        )
    return float(np.mean(predicted == labels))
