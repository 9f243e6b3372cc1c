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


def palette_rgb(n: int) -> np.ndarray:
    """Return ``n`` categorical colours, shape (n, 3) uint8, cycling the palette."""
    base = np.asarray(PALETTE, dtype=np.uint8)
    return base[np.arange(n) % len(base)]


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
