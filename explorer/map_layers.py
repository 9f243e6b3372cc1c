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
        labels[bank.indices_of(action)] = np.asarray(modes.labels, dtype=np.int64)
    return labels


def motion_energy(joints: np.ndarray, fps: float) -> np.ndarray:
    """(B,) mean joint speed in m/s of motions ``joints`` (B, T, J, 3)."""
    if joints.shape[1] < 2:
        return np.zeros(len(joints))
    speed = np.linalg.norm(np.diff(joints, axis=1), axis=-1) * fps
    return speed.mean(axis=(1, 2))


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


def point_colors(bank: LatentBank, color_by: str, energy: np.ndarray | None) -> np.ndarray:
    """(N, 4) float RGBA colour of each bank code by action, mode or motion energy (grey until known)."""
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
    non-linear maps, the convex hull of the mode's member codes is drawn.
    """
    from engine.latent.geometry import convex_hull, gaussian_ellipse, project_gaussian
    from engine.latent.projection import PCAProjection

    modes = bank.modes.get(action)
    if modes is None:
        return [], np.zeros((0, 4))
    curves: list[np.ndarray] = []
    if isinstance(projection, PCAProjection):
        for mean, cov in zip(modes.means, modes.covariances, strict=True):
            mean2, cov2 = project_gaussian(mean, cov, projection.components_, projection.mean_)
            curves.append(gaussian_ellipse(mean2, cov2, level=0.5))
    else:
        members = bank.indices_of(action)
        labels = np.asarray(modes.labels)
        for k in range(modes.n_modes):
            curves.append(convex_hull(embedding[members[labels == k]]))
    return curves, category_colors(modes.n_modes)


def gaussian_outline(
    mean: np.ndarray, cov: np.ndarray, projection: Projection, members_xy: np.ndarray
) -> np.ndarray:
    """Outline of one fitted Gaussian: its exact half-peak ellipse under PCA, else its members' hull."""
    from engine.latent.geometry import convex_hull, gaussian_ellipse, project_gaussian
    from engine.latent.projection import PCAProjection

    if isinstance(projection, PCAProjection):
        mean2, cov2 = project_gaussian(mean, cov, projection.components_, projection.mean_)
        return gaussian_ellipse(mean2, cov2, level=0.5)
    return convex_hull(members_xy)
