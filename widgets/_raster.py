"""Numpy rasterisers for the latent map: points as filled discs, or as a density image (mean colour,
opacity from the log of the count per pixel)."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True)
class Grid:
    """A raster over the plane: pixel (row 0, column 0) has its lower-left corner at ``(x0, y0)``.

    Rows grow with y and columns with x; each pixel is ``px`` by ``py`` data units.
    """

    x0: float
    y0: float
    px: float
    py: float
    width: int
    height: int

    def pixels(self, xy: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Column and row (each (N,) intp) of the pixel under each point of ``xy`` (N, 2)."""
        col = np.floor((xy[:, 0] - self.x0) / self.px).astype(np.intp)
        row = np.floor((xy[:, 1] - self.y0) / self.py).astype(np.intp)
        return col, row

    def covers(self, x0: float, x1: float, y0: float, y1: float) -> bool:
        """Whether the rectangle [x0, x1] × [y0, y1] lies inside the raster."""
        return (
            x0 >= self.x0
            and y0 >= self.y0
            and x1 <= self.x0 + self.width * self.px
            and y1 <= self.y0 + self.height * self.py
        )


def disc_offsets(diameter: float) -> tuple[np.ndarray, np.ndarray]:
    """Column and row offsets of the pixels of a filled disc ``diameter`` pixels across."""
    r = max(float(diameter) / 2.0, 0.5)
    span = np.arange(-int(np.ceil(r)), int(np.ceil(r)) + 1)
    dc, dr = np.meshgrid(span, span)
    inside = dc**2 + dr**2 <= r * r
    return dc[inside], dr[inside]


def discs(xy: np.ndarray, rgba: np.ndarray, grid: Grid, diameter: float) -> np.ndarray:
    """(H, W, 4) uint8 image of points ``xy`` (N, 2) drawn as discs in ``rgba`` (N, 4), later rows on top."""
    h, w = grid.height, grid.width
    col, row = grid.pixels(xy)
    dc, dr = disc_offsets(diameter)
    near = (col >= -dc.max()) & (col < w + dc.max()) & (row >= -dr.max()) & (row < h + dr.max())
    rows = np.flatnonzero(near)
    col, row = col[rows], row[rows]
    # One point per centre pixel (the last row: it is drawn on top), so that within one disc offset no
    # two points write the same pixel and a gather-max-scatter keeps the topmost row exactly.
    centre = (row + dr.max()) * (w + 2 * dc.max()) + (col + dc.max())
    _, last = np.unique(centre[::-1], return_index=True)
    keep = len(centre) - 1 - last
    rows, col, row = rows[keep], col[keep], row[keep]
    top = np.full(h * w, -1, dtype=np.intp)
    for oc, orow in zip(dc, dr, strict=True):
        c, r = col + oc, row + orow
        ok = (c >= 0) & (c < w) & (r >= 0) & (r < h)
        flat = r[ok] * w + c[ok]
        top[flat] = np.maximum(top[flat], rows[ok])
    image = np.zeros((h * w, 4), dtype=np.uint8)
    drawn = top >= 0
    image[drawn] = rgba[top[drawn]]
    return image.reshape(h, w, 4)


def density(xy: np.ndarray, rgba: np.ndarray, grid: Grid, min_alpha: int = 90) -> np.ndarray:
    """(H, W, 4) uint8 image of points ``xy`` (N, 2): each pixel the mean colour of its points in ``rgba``
    (N, 4), its opacity rising from ``min_alpha`` (one point) to 255 (the busiest pixel) with log(count)."""
    h, w = grid.height, grid.width
    col, row = grid.pixels(xy)
    inside = (col >= 0) & (col < w) & (row >= 0) & (row < h)
    flat = row[inside] * w + col[inside]
    colors = rgba[inside]
    count = np.bincount(flat, minlength=h * w)
    image = np.zeros((h * w, 4), dtype=np.uint8)
    drawn = count > 0
    if not drawn.any():
        return image.reshape(h, w, 4)
    n = count[drawn]
    for channel in range(3):
        total = np.bincount(flat, weights=colors[:, channel], minlength=h * w)[drawn]
        image[drawn, channel] = np.rint(total / n).astype(np.uint8)
    level = np.log1p(n) / np.log1p(n.max())
    image[drawn, 3] = np.rint(min_alpha + (255 - min_alpha) * level).astype(np.uint8)
    return image.reshape(h, w, 4)
