"""Numpy rasterisers for the latent map: points as filled discs, or as a density image (mean colour,
opacity from the log of the count per pixel)."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy import ndimage


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


def _disc(radius: float) -> np.ndarray:
    """A boolean disc of ``radius`` pixels, as a structuring element."""
    dc, dr = disc_offsets(2 * radius)
    r = int(max(dc.max(), dr.max()))
    element = np.zeros((2 * r + 1, 2 * r + 1), dtype=bool)
    element[dr + r, dc + r] = True
    return element


def _packed(rgba: np.ndarray) -> np.ndarray:
    """(N,) uint32 view of ``rgba`` (N, 4) uint8, one word per colour."""
    return np.ascontiguousarray(rgba, dtype=np.uint8).view(np.uint32).reshape(-1)


def discs(xy: np.ndarray, rgba: np.ndarray, grid: Grid, diameter: float) -> np.ndarray:
    """(H, W, 4) uint8 image of points ``xy`` (N, 2) drawn as discs in ``rgba`` (N, 4), later rows on top."""
    h, w = grid.height, grid.width
    dc, dr = disc_offsets(diameter)
    r = int(max(dc.max(), dr.max()))
    col, row = grid.pixels(xy)
    rows = np.flatnonzero((col >= -r) & (col < w + r) & (row >= -r) & (row < h + r))  # discs reaching in
    # On a canvas padded by twice the radius every pixel of those discs lands inside: no bounds checks.
    pad = 2 * r
    wide = w + 2 * pad
    centre = (row[rows] + pad) * wide + (col[rows] + pad)
    # One point per centre pixel (the last row: it is drawn on top), so that within one disc offset no
    # two points write the same pixel and a gather-max-scatter keeps the topmost row exactly. The
    # centres' maxima stay on the canvas: the disc's own centre offset would write them again.
    order = np.arange(len(centre), dtype=np.int32)
    top = np.full((h + 2 * pad) * wide, -1, dtype=np.int32)
    np.maximum.at(top, centre, order)
    keep = np.flatnonzero(top[centre] == order)
    centre, order = centre[keep], order[keep]
    for offset in (dr * wide + dc).tolist():
        flat = centre + offset
        top[flat] = np.maximum(top[flat], order)
    visible = top.reshape(h + 2 * pad, wide)[pad : pad + h, pad : pad + w]
    table = np.concatenate([np.zeros(1, np.uint32), _packed(rgba)[rows]])
    return table[visible + 1].view(np.uint8).reshape(h, w, 4)


def density(
    xy: np.ndarray, rgba: np.ndarray, grid: Grid, keep: np.ndarray | None = None, min_alpha: int = 90
) -> np.ndarray:
    """(H, W, 4) uint8 image of points ``xy`` (N, 2) (those where ``keep`` (N,) bool is true): each pixel
    the mean colour of its points in ``rgba`` (N, 4), its opacity rising with log(count) from ``min_alpha``
    (one point) to 255 (the busiest pixel)."""
    h, w = grid.height, grid.width
    col, row = grid.pixels(xy)
    inside = (col >= 0) & (col < w) & (row >= 0) & (row < h)
    if keep is not None:
        inside &= keep
    flat = row * w + col
    channels = [rgba[:, c] for c in range(3)]
    if not inside.all():  # zoomed out, every point is inside: no copies
        flat = flat[inside]
        channels = [c[inside] for c in channels]
    count = np.bincount(flat, minlength=h * w)
    drawn = np.flatnonzero(count)
    image = np.zeros((h * w, 4), dtype=np.uint8)
    if not len(drawn):
        return image.reshape(h, w, 4)
    n = count[drawn]
    for c, values in enumerate(channels):
        total = np.bincount(flat, weights=values, minlength=h * w)[drawn]
        image[drawn, c] = np.rint(total / n).astype(np.uint8)
    peak = int(n.max())
    level = np.log(n) / np.log(peak) if peak > 1 else np.ones(len(n))
    image[drawn, 3] = np.rint(min_alpha + (255 - min_alpha) * level).astype(np.uint8)
    return image.reshape(h, w, 4)


def render(
    xy: np.ndarray, rgba: np.ndarray, visible: np.ndarray, grid: Grid, diameter: float, density_above: int
) -> np.ndarray:
    """(H, W, 4) uint8 image of the ``visible`` (N,) bool points of ``xy`` (N, 2) in ``rgba`` (N, 4): discs
    ``diameter`` pixels across, or a density image when more than ``density_above`` lie in the grid."""
    pad_x, pad_y = diameter * grid.px, diameter * grid.py  # discs reaching in from outside
    x, y = xy[:, 0], xy[:, 1]
    near = (
        visible
        & (x >= grid.x0 - pad_x)
        & (x <= grid.x0 + grid.width * grid.px + pad_x)
        & (y >= grid.y0 - pad_y)
        & (y <= grid.y0 + grid.height * grid.py + pad_y)
    )
    if np.count_nonzero(near) > density_above:
        return density(xy, rgba, grid, keep=visible)
    rows = np.flatnonzero(near)
    return discs(xy[rows], rgba[rows], grid, diameter)


def rings(
    xy: np.ndarray, rgba: tuple[int, int, int, int], grid: Grid, inner: float, outer: float
) -> np.ndarray:
    """(H, W, 4) uint8 image of rings around points ``xy`` (N, 2) in colour ``rgba``: the pixels within
    ``outer`` pixels of a point and beyond ``inner`` pixels of every point (where rings of nearby points
    overlap, the outline of the group)."""
    h, w = grid.height, grid.width
    pad = int(np.ceil(outer)) + 1
    col, row = grid.pixels(xy)
    near = (col >= -pad) & (col < w + pad) & (row >= -pad) & (row < h + pad)
    image = np.zeros((h, w, 4), dtype=np.uint8)
    if not near.any():
        return image
    col, row = col[near], row[near]
    # work on the points' bounding box (plus the ring) only: a lasso's selection is usually local
    c0, c1 = max(int(col.min()) - pad, -pad), min(int(col.max()) + pad + 1, w + pad)
    r0, r1 = max(int(row.min()) - pad, -pad), min(int(row.max()) + pad + 1, h + pad)
    hit = np.zeros((r1 - r0, c1 - c0), dtype=bool)
    hit[row - r0, col - c0] = True
    ring = ndimage.binary_dilation(hit, _disc(outer)) & ~ndimage.binary_dilation(hit, _disc(inner))
    ring = ring[max(-r0, 0) : ring.shape[0] - max(r1 - h, 0), max(-c0, 0) : ring.shape[1] - max(c1 - w, 0)]
    image[max(r0, 0) : max(r0, 0) + ring.shape[0], max(c0, 0) : max(c0, 0) + ring.shape[1]][ring] = rgba
    return image
