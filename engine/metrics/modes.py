"""Mode metrics: homogeneity (ODMO Table 3) and purity of discovered modes against a metadata label."""

from __future__ import annotations

from collections.abc import Mapping, Sequence

import numpy as np
from sklearn.metrics import adjusted_rand_score, normalized_mutual_info_score

from engine.errors import ConfigError
from engine.metrics.apd import apd


def mode_apd(motions: np.ndarray, modes: np.ndarray) -> float:
    """Size-weighted mean APD within each mode; motions (N, T, J, 3), modes (N,) (singleton modes count 0)."""
    modes = np.asarray(modes).reshape(-1)
    if len(modes) != len(motions):
        raise ConfigError(f"{len(motions)} motions but {len(modes)} mode labels")
    total = 0.0
    for k in np.unique(modes):
        members = motions[modes == k]
        if len(members) >= 2:
            total += len(members) * apd(members)
    return total / len(modes)


def mode_homogeneity(motions: Mapping[int, np.ndarray], modes: Mapping[int, np.ndarray]) -> float:
    """100 × mean over actions of (APD − mode-APD) / APD: relative drop of APD when grouped by mode (%)."""
    drops = []
    for action, group in motions.items():
        whole = apd(group)
        drops.append((whole - mode_apd(group, modes[action])) / whole)
    if not drops:
        raise ConfigError("mode homogeneity needs at least one action")
    return float(100.0 * np.mean(drops))


def mode_purity(
    modes: Mapping[int, np.ndarray], labels: Mapping[int, Sequence[str] | np.ndarray]
) -> tuple[float, float]:
    """(NMI, adjusted Rand) between discovered modes and a label (e.g. style), each averaged over actions."""
    nmi, ari = [], []
    for action, mode in modes.items():
        truth = np.asarray(labels[action]).reshape(-1)
        if len(truth) != len(mode):
            raise ConfigError(f"action {action}: {len(mode)} modes but {len(truth)} labels")
        nmi.append(normalized_mutual_info_score(truth, mode))
        ari.append(adjusted_rand_score(truth, mode))
    if not nmi:
        raise ConfigError("mode purity needs at least one action")
    return float(np.mean(nmi)), float(np.mean(ari))
