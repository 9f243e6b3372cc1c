"""Interpolation between codes of two actions: each step decoded as the action its code is likelier under."""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
from scipy.special import logsumexp

from engine.errors import ConfigError
from engine.generate._decode import action_index, as_codes, decode, resolve_ends
from engine.generate._sampling import Sample, interpolation_codes
from engine.modelio import LoadedModel

RULE = "each step is decoded as the action under whose modes its code is likelier"


def step_actions(loaded: LoadedModel, codes: np.ndarray, action_a: int, action_b: int) -> np.ndarray:
    """(S,) action of each interpolation step (S, D): ``action_a`` or ``action_b``, whichever mode
    mixture gives the code the higher density; the first step keeps ``action_a``, the last ``action_b``."""
    bank = loaded.bank
    if bank is None or action_a not in bank.modes or action_b not in bank.modes:
        raise ConfigError(f"{loaded.path}: interpolating across actions needs both actions' modes")
    x = as_codes(loaded, codes)
    score_a = logsumexp(bank.modes[action_a].log_responsibilities(x), axis=1)
    score_b = logsumexp(bank.modes[action_b].log_responsibilities(x), axis=1)
    actions = np.where(score_b > score_a, action_b, action_a).astype(np.int64)
    actions[0], actions[-1] = action_a, action_b
    return actions


def interpolate_across(
    loaded: LoadedModel,
    code_a: np.ndarray | Sequence[float],
    action_a: int | str,
    code_b: np.ndarray | Sequence[float],
    action_b: int | str,
    steps: int,
    end_a: np.ndarray | Sequence[float] | None = None,
    end_b: np.ndarray | Sequence[float] | None = None,
) -> list[Sample]:
    """``steps`` motions on the straight segment from ``code_a`` (of ``action_a``) to ``code_b`` (of
    ``action_b``); the action condition is not blended (the model takes one action): see :data:`RULE`.

    End locations are blended linearly; the first and last motions equal ``decode`` of the endpoints.
    """
    if steps < 2:
        raise ConfigError(f"steps must be at least 2, got {steps}")
    ia, ib = action_index(loaded, action_a), action_index(loaded, action_b)
    a, b = as_codes(loaded, code_a)[0], as_codes(loaded, code_b)[0]
    codes = interpolation_codes(a, b, steps, "linear", np.zeros_like(a))
    actions = step_actions(loaded, codes, ia, ib)
    ends_ab = [resolve_ends(loaded, c[None], i, e) for c, i, e in ((a, ia, end_a), (b, ib, end_b))]
    samples = []
    for k, (code, action) in enumerate(zip(codes, actions, strict=True)):
        t = k / (steps - 1)
        end = None
        if ends_ab[0] is not None:
            end = ends_ab[0][0] if k == 0 else ends_ab[1][0] if k == steps - 1 else None
            if end is None:
                end = ((1.0 - t) * ends_ab[0][0] + t * ends_ab[1][0]).astype(np.float32)
        modes = loaded.bank.modes[int(action)]
        mode = int(modes.predict(code[None])[0])
        motion = decode(loaded, code, int(action), None if end is None else end[None], mode=mode)
        samples.append(Sample(code, int(action), mode, None if end is None else np.asarray(end), motion))
    return samples
