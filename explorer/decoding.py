"""Decoding one code through the loaded generator, as every gesture of the app does."""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

if TYPE_CHECKING:
    from engine.generators.base import Generator
    from engine.motion.motion import Motion


def decode_one(
    generator: Generator, code: np.ndarray, action: int, end: np.ndarray | None, mode: int | None
) -> Motion:
    """One code of action index ``action`` decoded (``end`` only for kinds that take one), its mode
    recorded in the motion's meta."""
    rows = None
    if end is not None and "end" in generator.capabilities:
        rows = np.array(end, dtype=np.float32).reshape(1, -1)
    [motion] = generator.decode(np.array(code, dtype=np.float32)[None], condition(generator, action), rows)
    if mode is not None:
        motion.meta["mode"] = int(mode)
    return motion


def condition(generator: Generator, action: int) -> str | None:
    """The action a conditional kind decodes label index ``action`` as; None for an unconditional kind."""
    names = generator.action_names
    return None if names is None else names[action]


def map_codes(generator: Generator, codes: np.ndarray) -> np.ndarray:
    """(N, D) points of ``codes`` in the space the map projects: a kind with several code spaces (MoDi's
    W+) gives each code's point in the bank's space."""
    as_w = getattr(generator, "as_w", None)
    return np.asarray(codes, dtype=np.float32) if as_w is None else as_w(codes)


def full_end(
    generator: Generator, code: np.ndarray, action: int, end: np.ndarray | None
) -> np.ndarray | None:
    """(3,) end location for ``code`` (None for kinds that take none): ``end`` as given when (3,), a floor
    point (x, z) at the bank's predicted height when (2,), the bank's prediction when None."""
    if "end" not in generator.capabilities:
        return None
    return generator.full_end(code, generator.action_names[action], end)
