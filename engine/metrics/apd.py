"""Average pairwise distance (APD) of motions and its normalised form n-APD (ODMO, Sec. 4.2.2)."""

from __future__ import annotations

import logging
from collections.abc import Mapping

import numpy as np
from scipy.spatial.distance import pdist

from engine.errors import ConfigError

log = logging.getLogger(__name__)


def apd(motions: np.ndarray) -> float:
    """Mean over ordered pairs i≠j of (Σ_t ‖m_t^i − m_t^j‖²)^½ for motions (N, T, J, 3) (or (N, T, F))."""
    m = np.asarray(motions, dtype=np.float64)
    if m.ndim < 2 or len(m) < 2:
        raise ConfigError(f"APD needs at least two motions, got shape {m.shape}")
    return float(pdist(m.reshape(len(m), -1)).mean())


def n_apd(generated: Mapping[int, np.ndarray], real: Mapping[int, np.ndarray]) -> float:
    """Mean over actions of APD(generated[a]) / APD(real[a]); values are (N, T, J, 3) motions.

    Actions whose real motions do not differ (APD 0, e.g. one real clip drawn repeatedly) have no
    spread to normalise by and are left out; NaN when no action is left.
    """
    shared = [a for a in generated if a in real]
    if not shared:
        raise ConfigError("n-APD needs at least one action present in both sets")
    ratios = []
    for a in shared:
        spread = apd(real[a])
        if spread > 0:
            ratios.append(apd(generated[a]) / spread)
        else:
            log.info("n-APD: the real motions of action %s are identical; left out", a)
    return float(np.mean(ratios)) if ratios else float("nan")
