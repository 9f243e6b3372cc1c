"""Shared dark-theme colours and colour-array helpers for the widgets."""

from __future__ import annotations

import numpy as np
import pyqtgraph as pg
from PySide6.QtGui import QBrush, QColor

BACKGROUND = "#1e1f22"
FOREGROUND = "#d0d0d0"
GRID = "#4a4d53"
GHOST = "#6b6e75"
ACCENT = "#ffcc33"
REQUEST = "#4fc3f7"
GENERATED = "#ff7043"

# Tableau-10: distinguishable on a dark background, reused for skeletons and categories.
PALETTE: tuple[tuple[int, int, int], ...] = (
    (78, 121, 167),
    (242, 142, 43),
    (225, 87, 89),
    (118, 183, 178),
    (89, 161, 79),
    (237, 201, 72),
    (176, 122, 161),
    (255, 157, 167),
    (156, 117, 95),
    (186, 176, 172),
)


SELECTION = "#ffffff"  # selection ring and map marker: no category uses white


def palette_rgb(n: int) -> np.ndarray:
    """Return ``n`` distinct categorical colours, shape (n, 3) uint8: the palette, then hues spaced by
    the golden angle (so the 11th action does not reuse the 1st's colour)."""
    base = np.asarray(PALETTE, dtype=np.uint8)
    if n <= len(base):
        return base[:n].copy()
    extra = []
    for k in range(n - len(base)):
        color = QColor.fromHsvF((0.07 + k * 0.381966) % 1.0, 0.55 if k % 2 else 0.75, 0.95 if k % 3 else 0.8)
        extra.append((color.red(), color.green(), color.blue()))
    return np.concatenate([base, np.asarray(extra, dtype=np.uint8)])


def shades(rgb: np.ndarray, n: int) -> np.ndarray:
    """(n, 3) uint8 shades of one colour ``rgb`` (3,), from lighter to darker (n = 1: the colour)."""
    if n == 1:
        return np.asarray(rgb, dtype=np.uint8).reshape(1, 3)
    t = np.linspace(-0.35, 0.35, n)[:, None]
    rgb = np.asarray(rgb, dtype=np.float64).reshape(1, 3)
    out = np.where(t < 0, rgb + (255 - rgb) * -t, rgb * (1 - t))
    return np.clip(np.rint(out), 0, 255).astype(np.uint8)


def to_rgba8(colors: np.ndarray, n: int) -> np.ndarray:
    """Return ``colors`` ((n, 3|4) uint8 or float in [0, 1]) as (n, 4) uint8 RGBA."""
    arr = np.asarray(colors)
    if arr.ndim != 2 or arr.shape[0] != n or arr.shape[1] not in (3, 4):
        raise ValueError(f"colours must have shape ({n}, 3|4), got {arr.shape}")
    if np.issubdtype(arr.dtype, np.floating):
        arr = np.rint(np.clip(arr, 0.0, 1.0) * 255.0)
    rgba = np.full((n, 4), 255, dtype=np.uint8)
    rgba[:, : arr.shape[1]] = arr.astype(np.uint8)
    return rgba


def brushes_for(rgba: np.ndarray) -> np.ndarray:
    """Return an object array of QBrush, one per row of ``rgba`` (N, 4) uint8, shared per distinct colour."""
    packed = np.ascontiguousarray(rgba, dtype=np.uint8).view(np.uint32).reshape(-1)
    unique, first, inverse = np.unique(packed, return_index=True, return_inverse=True)
    table = np.empty(len(unique), dtype=object)
    table[:] = [QBrush(pg.mkColor(*(int(c) for c in rgba[i]))) for i in first]
    return table[inverse]


def configure_plot(plot: pg.PlotWidget) -> None:
    """Apply the dark theme to a pyqtgraph plot widget."""
    plot.setBackground(BACKGROUND)
    item = plot.getPlotItem()
    for name in ("left", "bottom"):
        axis = item.getAxis(name)
        axis.setPen(pg.mkPen(GRID))
        axis.setTextPen(pg.mkPen(FOREGROUND))


def qcolor(color: object) -> QColor:
    """A QColor from a name, a QColor, or an RGB(A) tuple of 0–255 ints or of 0–1 floats."""
    if isinstance(color, str | QColor):
        return QColor(color)
    arr = np.asarray(color)
    if np.issubdtype(arr.dtype, np.floating):
        arr = np.rint(np.clip(arr, 0.0, 1.0) * 255)
    return QColor(*(int(c) for c in arr.reshape(-1)))
