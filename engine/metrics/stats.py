"""Mean and 95 % confidence interval over repeated measurements."""

from __future__ import annotations

from collections.abc import Mapping, Sequence

import numpy as np


def mean_ci95(values: Sequence[float] | np.ndarray) -> tuple[float, float]:
    """Mean and half-width 1.96·s/√n (s: sample standard deviation; 0 for one value) of finite ``values``."""
    x = np.asarray(values, dtype=np.float64).reshape(-1)
    x = x[np.isfinite(x)]
    if x.size == 0:
        return float("nan"), float("nan")
    if x.size == 1:
        return float(x[0]), 0.0
    return float(x.mean()), float(1.96 * x.std(ddof=1) / np.sqrt(x.size))


def summarize(repeats: Sequence[Mapping[str, float]]) -> dict[str, dict[str, float]]:
    """``{metric: {"mean", "ci95"}}`` over per-repeat ``{metric: value}`` dicts (keys in first-seen order)."""
    names: dict[str, None] = {}
    for rep in repeats:
        names.update(dict.fromkeys(rep))
    out = {}
    for name in names:
        mean, ci = mean_ci95([rep[name] for rep in repeats if name in rep])
        out[name] = {"mean": mean, "ci95": ci}
    return out
