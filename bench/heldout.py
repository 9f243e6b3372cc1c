"""The fixed held-out split of a dataset that every model in docs/RESULTS.md is evaluated on."""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from engine.motion.motion import Motion

HELDOUT_FRACTION = 0.15
SPLIT_SEED = 2022


def heldout_split(
    clips: Sequence[Motion], fraction: float = HELDOUT_FRACTION, seed: int = SPLIT_SEED
) -> tuple[list[Motion], list[Motion]]:
    """(train, held-out) clips, held out by clip and stratified by action and style, fixed by ``seed``."""
    rng = np.random.default_rng(seed)
    strata: dict[tuple[str, str], list[int]] = {}
    for i, clip in enumerate(clips):
        strata.setdefault((str(clip.action), str(clip.meta.get("style", ""))), []).append(i)
    held: set[int] = set()
    for key in sorted(strata):
        members = strata[key]
        n_held = round(fraction * len(members))
        held.update(int(i) for i in rng.permutation(members)[:n_held])
    train = [c for i, c in enumerate(clips) if i not in held]
    test = [c for i, c in enumerate(clips) if i in held]
    return train, test
