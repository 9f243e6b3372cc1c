"""Fréchet distance between two feature sets (FID on the evaluation classifier's features)."""

from __future__ import annotations

import numpy as np
import scipy.linalg

from engine.errors import ConfigError


def frechet_distance(mu1: np.ndarray, cov1: np.ndarray, mu2: np.ndarray, cov2: np.ndarray) -> float:
    """‖μ1 − μ2‖² + Tr(Σ1 + Σ2 − 2·(Σ1·Σ2)^½) of two Gaussians, means (F,), covariances (F, F)."""
    mu1, mu2 = np.asarray(mu1, np.float64), np.asarray(mu2, np.float64)
    cov1, cov2 = np.atleast_2d(np.asarray(cov1, np.float64)), np.atleast_2d(np.asarray(cov2, np.float64))
    if mu1.shape != mu2.shape or cov1.shape != cov2.shape or cov1.shape != (mu1.size, mu1.size):
        raise ConfigError(f"mismatched Gaussian shapes {mu1.shape}, {cov1.shape}, {mu2.shape}, {cov2.shape}")
    covmean = scipy.linalg.sqrtm(cov1 @ cov2)
    if not np.all(np.isfinite(covmean)):
        # Near-singular product: regularise both covariances slightly, as the reference FID code does.
        eps = np.eye(mu1.size) * 1e-6
        covmean = scipy.linalg.sqrtm((cov1 + eps) @ (cov2 + eps))
    diff = mu1 - mu2
    trace = np.trace(cov1) + np.trace(cov2) - 2.0 * np.trace(np.real(covmean))
    return float(max(diff @ diff + trace, 0.0))


def fid(features_a: np.ndarray, features_b: np.ndarray) -> float:
    """Fréchet distance between the Gaussians fitted to features ``(N, F)`` and ``(M, F)``."""
    a, b = np.asarray(features_a, np.float64), np.asarray(features_b, np.float64)
    if a.ndim != 2 or b.ndim != 2 or a.shape[1] != b.shape[1] or min(len(a), len(b)) < 2:
        raise ConfigError(f"need two (N>=2, F) feature sets of equal width, got {a.shape} and {b.shape}")
    return frechet_distance(a.mean(0), np.cov(a, rowvar=False), b.mean(0), np.cov(b, rowvar=False))
