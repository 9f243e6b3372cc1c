"""Neighbours in the full latent space, small subsets that cover a selection, and its summary (numpy
only)."""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

from engine.errors import ConfigError

if TYPE_CHECKING:
    from engine.latent.bank import LatentBank


def nearest(
    codes: np.ndarray, query: np.ndarray, k: int, exclude: int | None = None
) -> tuple[np.ndarray, np.ndarray]:
    """Indices (k,) of the ``k`` codes (N, D) nearest ``query`` (D,) by Euclidean distance in the full
    latent space (not on a 2-D map), nearest first, and their distances (k,); ``exclude`` is skipped."""
    codes = np.asarray(codes, dtype=np.float64)
    q = np.asarray(query, dtype=np.float64).reshape(-1)
    if codes.ndim != 2 or q.shape != (codes.shape[1],):
        raise ConfigError(f"need codes (N, D) and a query (D,), got {codes.shape} and {np.shape(query)}")
    if k < 1:
        raise ConfigError(f"k must be at least 1, got {k}")
    d = np.linalg.norm(codes - q, axis=1)
    if exclude is not None and 0 <= exclude < len(d):
        d[exclude] = np.inf
    order = np.argsort(d, kind="stable")[: min(k, int(np.isfinite(d).sum()))]
    return order.astype(np.int64), d[order]


def _allot(counts: np.ndarray, k: int) -> np.ndarray:
    """How many of ``k`` picks each group (sizes ``counts``) gets: proportional (largest remainder),
    at least one per group while picks last, never more than the group holds."""
    share = np.zeros(len(counts), dtype=np.int64)
    order = np.argsort(-counts, kind="stable")
    for g in order[: min(k, len(counts))]:
        share[g] = 1
    left = k - int(share.sum())
    while left > 0 and np.any(share < counts):
        room = np.where(share < counts, counts * k / counts.sum() - share, -np.inf)
        g = int(np.argmax(room))
        share[g] += 1
        left -= 1
    return share


def _farthest_points(codes: np.ndarray, k: int) -> np.ndarray:
    """``k`` row indices of ``codes`` (M, D) by farthest-point sampling from the code nearest their mean."""
    first = int(np.argmin(np.linalg.norm(codes - codes.mean(axis=0), axis=1)))
    picked = [first]
    d = np.linalg.norm(codes - codes[first], axis=1)
    while len(picked) < k:
        nxt = int(np.argmax(d))
        picked.append(nxt)
        d = np.minimum(d, np.linalg.norm(codes - codes[nxt], axis=1))
    return np.array(picked, dtype=np.int64)


def spread_subset(codes: np.ndarray, groups: np.ndarray, k: int) -> np.ndarray:
    """Indices of at most ``k`` of ``codes`` (N, D) that cover them: each group of ``groups`` (N,)
    (e.g. the action) gets picks in proportion to its size, spread by farthest-point sampling."""
    codes = np.asarray(codes, dtype=np.float64)
    groups = np.asarray(groups).reshape(-1)
    if len(codes) != len(groups):
        raise ConfigError(f"{len(codes)} codes but {len(groups)} group labels")
    if len(codes) <= k:
        return np.arange(len(codes), dtype=np.int64)
    labels, inverse = np.unique(groups, return_inverse=True)
    counts = np.bincount(inverse, minlength=len(labels))
    picks = []
    for g, share in enumerate(_allot(counts, k)):
        if share:
            members = np.flatnonzero(inverse == g)
            picks.append(members[_farthest_points(codes[members], int(share))])
    return np.sort(np.concatenate(picks))


def selection_summary(bank: LatentBank, indices: np.ndarray) -> tuple[np.ndarray, int, float]:
    """(centroid code, majority action, radius) of bank codes ``indices``: the radius is their mean
    distance to the centroid, or a quarter of the action's median spread for a single code."""
    sel = np.asarray(indices, dtype=np.int64).reshape(-1)
    if len(sel) == 0:
        raise ConfigError("select codes first (click a point or draw a lasso)")
    codes = bank.codes[sel].astype(np.float64)
    centre = codes.mean(axis=0)
    action = int(np.bincount(bank.actions[sel]).argmax())
    spread = float(np.linalg.norm(codes - centre, axis=1).mean())
    if spread == 0.0:
        same = bank.codes[bank.indices_of(action)]
        spread = 0.25 * float(np.median(np.linalg.norm(same - same.mean(axis=0), axis=1)))
    return centre.astype(np.float32), action, spread
