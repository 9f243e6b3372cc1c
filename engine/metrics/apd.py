"""Average pairwise distance (APD) of motions and its normalised form n-APD (ODMO, Sec. 4.2.2)."""

from __future__ import annotations

from collections.abc import Mapping

import numpy as np
from scipy.spatial.distance import pdist

from engine.errors import ConfigError


def apd(motions: np.ndarray) -> float:
    """Mean over ordered pairs i≠j of (Σ_t ‖m_t^i − m_t^j‖²)^½ for motions (N, T, J, 3) (or (N, T, F))."""
    m = np.asarray(motions, dtype=np.float64)
    if m.ndim < 2 or len(m) < 2:
        raise ConfigError(f"APD needs at least two motions, got shape {m.shape}")
    return float(pdist(m.reshape(len(m), -1)).mean())


def n_apd(generated: Mapping[int, np.ndarray], real: Mapping[int, np.ndarray]) -> float:
    """Mean over actions of APD(generated[a]) / APD(real[a]); values are (N, T, J, 3) motions."""
    ratios = [apd(generated[a]) / apd(real[a]) for a in generated if a in real]
    if not ratios:
        raise ConfigError("n-APD needs at least one action present in both sets")
    return float(np.mean(ratios))
