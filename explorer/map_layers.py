"""What the latent map draws for a bank: point colours, tooltips, mode overlays (pure functions, no Qt).

Imports only numpy and the widgets' palette at module level, so the map can be painted at start-up
before scikit-learn, scipy and torch are loaded; the geometry helpers are imported where they are used.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import TYPE_CHECKING, Any

import numpy as np

from widgets._colors import palette_rgb

if TYPE_CHECKING:
    from engine.latent.bank import LatentBank
    from engine.latent.projection import Projection


def category_colors(n: int) -> np.ndarray:
    """(n, 4) float RGBA categorical colours (the widgets' palette)."""
    rgb = palette_rgb(max(n, 1))[:n].astype(np.float64) / 255.0
    return np.concatenate([rgb, np.ones((n, 1))], axis=1)


def mode_labels(bank: LatentBank) -> np.ndarray:
    """(N,) mode index of every bank code within its action (-1 where the action has no modes)."""
    labels = np.full(len(bank.codes), -1, dtype=np.int64)
    for action, modes in bank.modes.items():
        labels[bank.indices_of(action)] = np.asarray(modes.labels_, dtype=np.int64)
    return labels


SCALAR_LEVELS = 64  # distinct colours of a scalar colouring: the map draws one symbol image per colour


def scalar_colors(values: np.ndarray, levels: int = SCALAR_LEVELS) -> np.ndarray:
    """(N, 4) float RGBA viridis colours of ``values`` scaled between their 2nd and 98th percentiles,
    in ``levels`` steps (N distinct colours make the scatter render N symbol images: 3k take ~0.4 s)."""
    values = np.asarray(values, dtype=np.float64)
    from pyqtgraph import colormap

    lo, hi = np.percentile(values, [2, 98]) if len(values) else (0.0, 1.0)
    scaled = np.clip((values - lo) / max(hi - lo, 1e-12), 0.0, 1.0)
    scaled = np.round(scaled * (levels - 1)) / (levels - 1)
    return np.asarray(colormap.get("viridis").map(scaled, mode="float"), dtype=np.float64)


META_PREFIX = "meta:"  # colour-by entries for a metadata key of the bank, e.g. "meta:style"
MAX_META_VALUES = 40  # a metadata key with more distinct values than this is not offered as a colouring
GREY = (0.5, 0.5, 0.5, 1.0)


def meta_keys(meta: Sequence[dict[str, Any]]) -> list[str]:
    """Metadata keys of the bank's clips worth colouring by: text values, 2..MAX_META_VALUES distinct."""
    keys: dict[str, set[str]] = {}
    for m in meta:
        for key, value in m.items():
            if isinstance(value, str) and key not in ("source", "path"):
                keys.setdefault(key, set()).add(value)
    return sorted(k for k, v in keys.items() if 2 <= len(v) <= MAX_META_VALUES)


def meta_values(meta: Sequence[dict[str, Any]], key: str) -> tuple[list[str], np.ndarray]:
    """The distinct values of ``key`` (sorted) and each clip's index among them (-1: missing)."""
    raw = [m.get(key) for m in meta]
    values = sorted({str(v) for v in raw if v is not None})
    index = {v: i for i, v in enumerate(values)}
    return values, np.array([index.get(str(v), -1) if v is not None else -1 for v in raw], dtype=np.int64)


def energy_key(energy: np.ndarray, steps: int = 5) -> tuple[list[str], np.ndarray]:
    """Labels and colours (steps, 4) of a colour key for motion energy (m/s) as ``scalar_colors`` maps it."""
    lo, hi = np.percentile(energy, [2, 98])
    values = np.linspace(lo, hi, steps)
    colors = scalar_colors(np.concatenate([values, [lo, hi]]))[:steps]
    labels = [
        f"{v:.2f} m/s" + (" or less" if k == 0 else " or more" if k == steps - 1 else "")
        for k, v in enumerate(values)
    ]
    return labels, colors


def color_key(bank: LatentBank, color_by: str, energy: np.ndarray | None) -> tuple[str, list[str], list]:
    """(title, names, colours) of the key for ``color_by`` ("" title for action: the legend says it)."""
    if color_by == "mode":
        labels = mode_labels(bank)
        n = max(int(labels.max()) + 1, 1)
        names = [f"mode {k}" for k in range(n)]
        colors = [tuple(c) for c in category_colors(n)]
        if np.any(labels < 0):
            names.append("no modes")
            colors.append(GREY)
        return "Mode (within its action)", names, colors
    if color_by == "motion energy":
        if energy is None:
            return "Motion energy: computing…", [], []
        names, colors = energy_key(energy)
        return "Mean joint speed", names, [tuple(c) for c in colors]
    if color_by.startswith(META_PREFIX):
        key = color_by[len(META_PREFIX) :]
        values, _ = meta_values(bank.meta, key)
        colors = [tuple(c) for c in category_colors(len(values))]
        return key.capitalize(), values, colors
    return "", [], []


def point_colors(bank: LatentBank, color_by: str, energy: np.ndarray | None) -> np.ndarray:
    """(N, 4) float RGBA colour of each bank code by action, mode, motion energy (grey until known) or
    a metadata key (``META_PREFIX`` + key; grey where a clip has none)."""
    if color_by.startswith(META_PREFIX):
        values, index = meta_values(bank.meta, color_by[len(META_PREFIX) :])
        colors = category_colors(max(len(values), 1))[np.maximum(index, 0)]
        colors[index < 0] = GREY
        return colors
    if color_by == "mode":
        labels = mode_labels(bank)
        colors = category_colors(max(int(labels.max()) + 1, 1))[np.maximum(labels, 0)]
        colors[labels < 0] = (0.5, 0.5, 0.5, 1.0)
        return colors
    if color_by == "motion energy":
        if energy is None:
            return np.tile((0.5, 0.5, 0.5, 1.0), (len(bank.codes), 1))
        return scalar_colors(energy)
    return category_colors(len(bank.action_names))[np.asarray(bank.actions, dtype=np.int64)]


def tooltips(bank: LatentBank) -> list[str]:
    """One hover text per bank code: clip name, action and style when known."""
    return tooltip_texts(bank.sources, bank.actions, bank.action_names, bank.meta)


def tooltip_texts(
    sources: Sequence[str], actions: np.ndarray, action_names: Sequence[str], meta: Sequence[dict[str, Any]]
) -> list[str]:
    """One hover text per code from its source (N,), action (N,) and meta dicts: clip, action, style."""
    texts = []
    for i, source in enumerate(sources):
        style = meta[i].get("style") if i < len(meta) else None
        extra = f" · {style}" if style else ""
        texts.append(f"{source}\n{action_names[int(actions[i])]}{extra} · #{i}")
    return texts


def mode_overlays(
    bank: LatentBank, action: int, projection: Projection, embedding: np.ndarray
) -> tuple[list[np.ndarray], np.ndarray]:
    """Outlines of ``action``'s modes on the map and their colours (N_modes, 4).

    Under PCA each mode's Gaussian is projected exactly and drawn as its half-peak ellipse; under the
    non-linear maps, the half-peak ellipse of a Gaussian fitted to its member codes' map positions.
    """
    from engine.latent.geometry import gaussian_ellipse, project_gaussian
    from engine.latent.projection import PCAProjection

    modes = bank.modes.get(action)
    if modes is None:
        return [], np.zeros((0, 4))
    curves: list[np.ndarray] = []
    if isinstance(projection, PCAProjection):
        for mean, cov in zip(modes.means_, modes.covariances_, strict=True):
            mean2, cov2 = project_gaussian(mean, cov, projection.components_, projection.mean_)
            curves.append(gaussian_ellipse(mean2, cov2, level=0.5))
    else:
        members = bank.indices_of(action)
        labels = np.asarray(modes.labels_)
        for k in range(modes.n_modes_):
            curve = members_ellipse(embedding[members[labels == k]])
            if curve is not None:
                curves.append(curve)
    return curves, category_colors(modes.n_modes_)[: len(curves)]


def members_ellipse(xy: np.ndarray) -> np.ndarray | None:
    """Half-peak ellipse (64, 2) of a Gaussian fitted to map positions ``xy`` (M, 2); None under 3 points."""
    from engine.latent.geometry import gaussian_ellipse

    xy = np.asarray(xy, dtype=np.float64).reshape(-1, 2)
    if len(xy) < 3:
        return None
    cov = np.cov(xy, rowvar=False) + 1e-9 * np.eye(2)
    return gaussian_ellipse(xy.mean(axis=0), cov, level=0.5)


def gaussian_outline(
    mean: np.ndarray, cov: np.ndarray, projection: Projection, members_xy: np.ndarray
) -> np.ndarray:
    """Outline of one fitted Gaussian: its exact half-peak ellipse under PCA, else its members' ellipse."""
    from engine.latent.geometry import convex_hull, gaussian_ellipse, project_gaussian
    from engine.latent.projection import PCAProjection

    if isinstance(projection, PCAProjection):
        mean2, cov2 = project_gaussian(mean, cov, projection.components_, projection.mean_)
        return gaussian_ellipse(mean2, cov2, level=0.5)
    curve = members_ellipse(members_xy)
    return curve if curve is not None else convex_hull(members_xy)


def mode_note(modes: Any, n_codes: int, ratio: float = 0.95) -> str:
    """Why the action has the modes shown: which K the silhouette rule chose, and what was dropped.

    ``modes`` is the action's ``ModeModel`` or None; ``n_codes`` its number of bank codes.
    """
    if modes is None:
        if n_codes == 0:
            return "No modes: the bank holds no code of this action (no training clip was labelled with it)."
        return f"No modes: the bank has {n_codes} codes of this action but no mode model for it."
    scores = {int(k): float(v) for k, v in modes.silhouette_.items()}
    scored = {k: v for k, v in scores.items() if np.isfinite(v)}
    if not scored:
        span = f"{min(scores)}–{max(scores)}" if scores else "the range searched"
        return f"1 mode (the action's single Gaussian): no K in {span} could be scored on {n_codes} codes."
    k = int(modes.k_chosen_)
    best = max(scored, key=scored.get)
    if k == best:
        why = "the best silhouette"
    else:
        why = f"the first K scoring above {ratio:.0%} of K + 1's (a smaller K is preferred)"
    text = f"K = {k} chosen: {why}."
    if modes.n_modes_ < k:
        dropped = k - modes.n_modes_
        text += f" {modes.n_modes_} kept; {dropped} dropped for having too few clips."
    return text
