"""The map's numpy rasterisers against plain per-point painting."""

from __future__ import annotations

import numpy as np

from widgets._raster import Grid, density, disc_offsets, discs, rings

GRID = Grid(x0=0.0, y0=0.0, px=1.0, py=1.0, width=23, height=17)


def _painted(xy: np.ndarray, rgba: np.ndarray, grid: Grid, diameter: float) -> np.ndarray:
    """Paint each point's disc in row order, clipped to the grid: what ``discs`` must draw."""
    image = np.zeros((grid.height, grid.width, 4), np.uint8)
    dc, dr = disc_offsets(diameter)
    col, row = grid.pixels(xy)
    for i in range(len(xy)):
        for oc, orow in zip(dc, dr, strict=True):
            c, r = col[i] + oc, row[i] + orow
            if 0 <= c < grid.width and 0 <= r < grid.height:
                image[r, c] = rgba[i]
    return image


def test_discs_match_painting_in_order_also_across_the_edges() -> None:
    rng = np.random.default_rng(0)
    xy = rng.uniform(-6, 29, size=(300, 2))  # many outside the grid, some with discs reaching in
    xy[:20] = np.floor(xy[:20])  # and some sharing a centre pixel
    xy[20:40] = xy[:20] + 0.3
    rgba = rng.integers(1, 256, size=(300, 4)).astype(np.uint8)
    for diameter in (1, 3, 6, 9):
        np.testing.assert_array_equal(discs(xy, rgba, GRID, diameter), _painted(xy, rgba, GRID, diameter))


def test_density_is_the_mean_colour_and_more_opaque_with_more_points() -> None:
    xy = np.array([[1.5, 1.5], [1.2, 1.8], [5.5, 2.5], [5.1, 2.1], [5.9, 2.9], [5.5, 2.2], [30.0, 1.0]])
    rgba = np.array([[255, 0, 0, 255], [0, 0, 255, 255], *[[0, 200, 0, 255]] * 4, [9, 9, 9, 255]], np.uint8)
    image = density(xy, rgba, GRID)
    assert image[1, 1, :3].tolist() == [128, 0, 128]  # (red + blue) / 2, rounded
    assert image[2, 5, :3].tolist() == [0, 200, 0]
    assert image[2, 5, 3] == 255 > image[1, 1, 3] > 90
    assert np.count_nonzero(image[..., 3]) == 2  # the point at x = 30 lies outside
    keep = np.array([True, False, True, True, True, True, True])
    assert density(xy, rgba, GRID, keep=keep)[1, 1].tolist() == [255, 0, 0, 90]


def test_rings_are_within_the_outer_radius_of_a_point_and_beyond_the_inner_of_all() -> None:
    rng = np.random.default_rng(1)
    xy = np.concatenate([rng.uniform(-9, 32, size=(25, 2)), [[4.5, 4.5], [6.5, 4.5]]])  # two overlap
    image = rings(xy, (255, 255, 255, 255), GRID, inner=2.0, outer=4.0)
    col, row = GRID.pixels(xy)
    rr, cc = np.mgrid[0 : GRID.height, 0 : GRID.width]
    d2 = (cc[..., None] - col) ** 2 + (rr[..., None] - row) ** 2
    expected = (d2.min(axis=-1) <= 16) & (d2.min(axis=-1) > 4)
    np.testing.assert_array_equal(image[..., 3] == 255, expected)
    assert expected[4, 9] and not expected[4, 5]  # on the pair's outline; between the two, inside
    assert np.all(image[expected] == 255) and np.all(image[~expected] == 0)
