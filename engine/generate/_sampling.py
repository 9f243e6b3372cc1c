"""Sampling per action, neighbourhoods of a code and interpolation between codes."""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from engine.errors import ConfigError
from engine.generate._decode import (
    action_index,
    as_codes,
    decode_array,
    generated_motion,
    resolve_ends,
)
from engine.latent.bank import LatentBank
from engine.latent.modes import ModeModel
from engine.modelio import LoadedModel
from engine.motion.motion import Motion

INTERPOLATIONS = ("linear", "slerp")


@dataclass(frozen=True, eq=False)
class Sample:
    """One generated motion and what produced it.

    Parameters
    ----------
    code : (D,) float32 latent code.
    action : action index.
    mode : mode index within the action (-1: conventional sampling or no mode model).
    end : (3,) float32 end location used, or None when the model takes none.
    motion : the decoded motion (meta holds the same facts).
    """

    code: np.ndarray
    action: int
    mode: int
    end: np.ndarray | None
    motion: Motion


def _bank(loaded: LoadedModel) -> LatentBank:
    if loaded.bank is None:
        raise ConfigError(f"{loaded.path}: the model has no latent bank (run `odmo bank`)")
    return loaded.bank


def _modes(loaded: LoadedModel, action: int) -> ModeModel:
    modes = _bank(loaded).modes.get(action)
    if modes is None:
        raise ConfigError(f"{loaded.path}: no modes for action {loaded.action_names[action]!r}")
    return modes


def _rng_and_seed(rng: np.random.Generator | int) -> tuple[np.random.Generator, int | None]:
    if isinstance(rng, np.random.Generator):
        return rng, None
    return np.random.default_rng(int(rng)), int(rng)


def _predicted_modes(loaded: LoadedModel, codes: np.ndarray, action: int) -> np.ndarray:
    """(B,) mode of each code under the action's mode model, -1 where there is none."""
    modes = None if loaded.bank is None else loaded.bank.modes.get(action)
    if modes is None:
        return np.full(len(codes), -1, dtype=np.int64)
    return np.asarray(modes.predict(codes), dtype=np.int64)


def _decode_samples(
    loaded: LoadedModel,
    codes: np.ndarray,
    action: int,
    modes: np.ndarray,
    end: np.ndarray | Sequence[float] | None,
    seed: int | None,
) -> list[Sample]:
    ends = resolve_ends(loaded, codes, action, end)
    joints, _ = decode_array(loaded, codes, np.full(len(codes), action), ends)
    samples = []
    for i, code in enumerate(codes):
        e = None if ends is None else ends[i]
        motion = generated_motion(loaded, joints[i], code, action, e, int(modes[i]), seed)
        samples.append(Sample(code, action, int(modes[i]), e, motion))
    return samples


def sample(
    loaded: LoadedModel,
    action: int | str,
    n: int,
    rng: np.random.Generator | int,
    strategy: str = "mode_preserving",
    mode: int | None = None,
    weights: np.ndarray | Sequence[float] | None = None,
    end: np.ndarray | Sequence[float] | None = None,
) -> list[Sample]:
    """Draw ``n`` codes of ``action`` from its mode model and decode them (``rng``: a Generator or a seed).

    Strategies: ``mode_preserving`` (modes in proportion to their size), ``conventional`` (one
    Gaussian per action), ``mode`` (only mode ``mode``), ``weights`` (modes in proportion to ``weights``).
    """
    if n < 1:
        raise ConfigError(f"n must be at least 1, got {n}")
    index = action_index(loaded, action)
    modes = _modes(loaded, index)
    generator, seed = _rng_and_seed(rng)
    codes, mode_ids = modes.sample(n, generator, strategy=strategy, mode=mode, weights=weights)
    return _decode_samples(loaded, as_codes(loaded, codes), index, mode_ids, end, seed)


def neighbours(
    loaded: LoadedModel,
    code: np.ndarray | Sequence[float],
    action: int | str,
    n: int,
    radius: float,
    rng: np.random.Generator | int,
    end: np.ndarray | Sequence[float] | None = None,
) -> list[Sample]:
    """Decode ``n`` codes drawn uniformly from the ball of ``radius`` around ``code`` (variations of it).

    Each neighbour's end location is predicted from its own code unless ``end`` is given.
    """
    index = action_index(loaded, action)
    generator, seed = _rng_and_seed(rng)
    codes = ball_codes(as_codes(loaded, code)[0], n, radius, generator)
    return _decode_samples(loaded, codes, index, _predicted_modes(loaded, codes, index), end, seed)


def ball_codes(centre: np.ndarray, n: int, radius: float, rng: np.random.Generator | int) -> np.ndarray:
    """(n, D) float32 codes drawn uniformly from the ball of ``radius`` around ``centre`` (D,)."""
    if n < 1 or not radius >= 0:
        raise ConfigError(f"need n >= 1 and radius >= 0, got n={n}, radius={radius}")
    generator, _ = _rng_and_seed(rng)
    centre = np.asarray(centre, dtype=np.float64).reshape(-1)
    direction = generator.standard_normal((n, centre.shape[0]))
    direction /= np.maximum(np.linalg.norm(direction, axis=1, keepdims=True), 1e-12)
    distance = radius * generator.random(n) ** (1.0 / centre.shape[0])
    return (centre + direction * distance[:, None]).astype(np.float32)


def interpolation_codes(
    code_a: np.ndarray, code_b: np.ndarray, steps: int, method: str, centre: np.ndarray
) -> np.ndarray:
    """(steps, D) codes from ``code_a`` to ``code_b`` inclusive, both endpoints exact.

    ``slerp`` turns the direction about ``centre`` along the great circle and blends the distance
    from ``centre`` linearly; ``linear`` is the straight segment.
    """
    t = np.linspace(0.0, 1.0, steps)[:, None]
    if method == "linear":
        codes = (1.0 - t) * code_a + t * code_b
    else:
        a, b = code_a - centre, code_b - centre
        ra, rb = np.linalg.norm(a), np.linalg.norm(b)
        ua, ub = a / max(ra, 1e-12), b / max(rb, 1e-12)
        omega = np.arccos(np.clip(ua @ ub, -1.0, 1.0))
        if omega < 1e-6:
            directions = (1.0 - t) * ua + t * ub
        else:
            directions = (np.sin((1.0 - t) * omega) * ua + np.sin(t * omega) * ub) / np.sin(omega)
        codes = centre + directions * ((1.0 - t) * ra + t * rb)
    codes = codes.astype(np.float32)
    codes[0], codes[-1] = code_a, code_b
    return codes


def interpolate(
    loaded: LoadedModel,
    code_a: np.ndarray | Sequence[float],
    code_b: np.ndarray | Sequence[float],
    action: int | str,
    steps: int,
    method: str = "linear",
    end_a: np.ndarray | Sequence[float] | None = None,
    end_b: np.ndarray | Sequence[float] | None = None,
) -> list[Sample]:
    """``steps`` motions from ``code_a`` to ``code_b`` within one action, end location blended linearly.

    Each step is decoded on its own, so the first and last motions equal ``decode`` of the endpoints
    bit for bit. ``slerp`` turns about the action's mean code (see :func:`interpolation_codes`).
    """
    if method not in INTERPOLATIONS:
        raise ConfigError(f"unknown interpolation {method!r}; choose from {', '.join(INTERPOLATIONS)}")
    if steps < 2:
        raise ConfigError(f"steps must be at least 2, got {steps}")
    index = action_index(loaded, action)
    a, b = as_codes(loaded, code_a)[0], as_codes(loaded, code_b)[0]
    mode_model = None if loaded.bank is None else loaded.bank.modes.get(index)
    centre = np.zeros_like(a) if mode_model is None else np.asarray(mode_model.conventional_mean_, np.float32)
    codes = interpolation_codes(a, b, steps, method, centre)
    ends_ab = [resolve_ends(loaded, c[None], index, e) for c, e in ((a, end_a), (b, end_b))]
    t = np.linspace(0.0, 1.0, steps, dtype=np.float32)[:, None]
    ends = None
    if ends_ab[0] is not None:
        ends = ((1.0 - t) * ends_ab[0] + t * ends_ab[1]).astype(np.float32)
        ends[0], ends[-1] = ends_ab[0][0], ends_ab[1][0]
    modes = _predicted_modes(loaded, codes, index)
    samples = []
    for i in range(steps):
        end_i = None if ends is None else ends[i : i + 1]
        samples += _decode_samples(loaded, codes[i : i + 1], index, modes[i : i + 1], end_i, None)
    return samples
