"""Clip-level validation split, class-balanced sampling and contrastive partners (training split only)."""

from __future__ import annotations

import numpy as np

from engine.errors import DataError


def split_clips(actions: np.ndarray, val_fraction: float, seed: int) -> tuple[np.ndarray, np.ndarray]:
    """Training and validation clip indices, stratified by action and fixed by ``seed``.

    Each action with at least two clips gives ``round(val_fraction · n)`` clips (at least one when
    ``val_fraction`` > 0, never all of them) to validation.
    """
    if not 0.0 <= val_fraction < 1.0:
        raise DataError(f"val_fraction must lie in [0, 1), got {val_fraction}")
    rng = np.random.default_rng([seed, 0x5B17])
    actions = np.asarray(actions)
    val: list[np.ndarray] = []
    for a in np.unique(actions):
        members = rng.permutation(np.flatnonzero(actions == a))
        n_val = 0 if val_fraction == 0 or len(members) < 2 else max(1, round(val_fraction * len(members)))
        val.append(members[: min(n_val, len(members) - 1)])
    val_idx = np.sort(np.concatenate(val)).astype(np.int64)
    train_idx = np.setdiff1d(np.arange(len(actions)), val_idx).astype(np.int64)
    return train_idx, val_idx


class PairSampler:
    """Draws class-balanced anchors and their contrastive partners from a fixed set of clips."""

    def __init__(self, actions: np.ndarray, indices: np.ndarray):
        indices = np.asarray(indices, dtype=np.int64)
        if len(indices) == 0:
            raise DataError("no clips to sample from")
        acts = np.asarray(actions)[indices]
        order = np.argsort(acts, kind="stable")
        self._pool = indices[order]
        self.actions, first, self._counts = np.unique(acts[order], return_index=True, return_counts=True)
        self._first = first.astype(np.int64)

    def _clips_of(self, slot: np.ndarray, rng: np.random.Generator) -> np.ndarray:
        """One random clip of each action slot (positions in ``self.actions``)."""
        return self._pool[self._first[slot] + rng.integers(0, self._counts[slot])]

    def anchors(self, n: int, rng: np.random.Generator) -> tuple[np.ndarray, np.ndarray]:
        """``n`` clip indices, action uniform then clip uniform; also their action slots."""
        slot = rng.integers(0, len(self.actions), size=n)
        return self._clips_of(slot, rng), slot

    def partners(self, slot: np.ndarray, rng: np.random.Generator) -> tuple[np.ndarray, np.ndarray]:
        """A partner clip per anchor slot: same action with probability 1/2, else another action uniformly.

        Returns partner clip indices (n,) and ``same`` (n,) bool.
        """
        n_act = len(self.actions)
        if n_act == 1:
            return self._clips_of(slot, rng), np.ones(len(slot), dtype=bool)
        same = rng.random(len(slot)) < 0.5
        other = rng.integers(0, n_act - 1, size=len(slot))
        other += other >= slot
        partner_slot = np.where(same, slot, other)
        return self._clips_of(partner_slot, rng), same
