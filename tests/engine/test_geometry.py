"""Lasso hit-test, Gaussian ellipses and projections, hulls and neighbour blends against known answers."""

from __future__ import annotations

import numpy as np
import pytest
from matplotlib.path import Path as MplPath
from scipy.stats import multivariate_normal

from engine.errors import ConfigError
from engine.latent.geometry import (
    convex_hull,
    gaussian_ellipse,
    idw_blend,
    points_in_polygon,
    project_gaussian,
)

STAR = np.array([[np.cos(a), np.sin(a)] for a in np.pi / 2 + 4 * np.pi / 5 * np.arange(5)])  # self-crossing
U_SHAPE = np.array([[0, 0], [3, 0], [3, 3], [2, 3], [2, 1], [1, 1], [1, 3], [0, 3]], dtype=float)
ZIGZAG = np.array([[0, 0], [4, 0], [4, 4], [3, 1], [2, 4], [1, 1], [0, 4]], dtype=float)


@pytest.mark.parametrize("polygon", [U_SHAPE, ZIGZAG, STAR, np.random.default_rng(3).uniform(-1, 1, (12, 2))])
def test_points_in_polygon_matches_matplotlib(polygon: np.ndarray) -> None:
    points = np.random.default_rng(0).uniform(-1.5, 4.5, (5000, 2))
    expected = MplPath(polygon).contains_points(points)
    assert np.array_equal(points_in_polygon(points, polygon), expected)
    assert 0 < expected.sum() < len(points)


def test_points_in_polygon_hand_cases() -> None:
    inside_u = points_in_polygon(np.array([[0.5, 2.0], [2.5, 2.0], [1.5, 2.0], [1.5, 0.5]]), U_SHAPE)
    assert inside_u.tolist() == [True, True, False, True]
    # Even-odd: the pentagram's centre is covered twice, hence outside; its tips once, hence inside.
    assert points_in_polygon(np.array([[0.0, 0.0], [0.0, 0.8]]), STAR).tolist() == [False, True]
    closed = np.vstack([U_SHAPE, U_SHAPE[:1]])
    pts = np.random.default_rng(1).uniform(-1, 4, (500, 2))
    assert np.array_equal(points_in_polygon(pts, closed), points_in_polygon(pts, U_SHAPE))


def test_points_in_a_staircase_lasso_of_many_vertices() -> None:
    """200 steps under a known height profile: the points inside are exactly the cells under it."""
    steps, rows = 200, 50
    heights = np.random.default_rng(2).integers(1, rows, steps)
    top = [(x, h) for i, h in enumerate(heights) for x in (i, i + 1)]
    polygon = np.array([(0, 0), *top, (steps, 0)], dtype=float)
    cx, cy = np.meshgrid(np.arange(steps) + 0.5, np.arange(rows) + 0.5, indexing="ij")
    inside = points_in_polygon(np.c_[cx.ravel(), cy.ravel()], polygon).reshape(steps, rows)
    assert np.array_equal(inside, np.arange(rows)[None, :] < heights[:, None])


def test_points_on_shared_edges_belong_to_exactly_one_cell() -> None:
    cells = [
        np.array([[x, y], [x + 1, y], [x + 1, y + 1], [x, y + 1]], float) for x in range(3) for y in range(3)
    ]
    grid = np.stack(np.meshgrid(np.arange(0.5, 2.51, 0.25), np.arange(0.5, 2.51, 0.25)), -1).reshape(-1, 2)
    hits = np.sum([points_in_polygon(grid, cell) for cell in cells], axis=0)
    assert np.all(hits == 1)


def test_points_in_polygon_degenerate_and_bad_input() -> None:
    pts = np.zeros((3, 2))
    assert not points_in_polygon(pts, np.array([[0.0, 0.0], [1.0, 1.0]])).any()
    assert points_in_polygon(np.zeros((0, 2)), U_SHAPE).shape == (0,)
    with pytest.raises(ConfigError):
        points_in_polygon(np.zeros((3, 3)), U_SHAPE)
    with pytest.raises(ConfigError):
        points_in_polygon(pts, np.array([[0.0, np.nan], [1, 0], [0, 1]]))


@pytest.mark.parametrize("level", [0.5, 0.1, 0.9])
def test_gaussian_ellipse_is_a_density_contour(level: float) -> None:
    mean, cov = np.array([1.0, -2.0]), np.array([[2.0, 0.8], [0.8, 0.5]])
    ring = gaussian_ellipse(mean, cov, level=level, n=50)
    density = multivariate_normal(mean, cov)
    assert ring.shape == (50, 2)
    np.testing.assert_allclose(density.pdf(ring) / density.pdf(mean), level, rtol=1e-9)
    assert points_in_polygon(mean[None], ring)[0]


def test_gaussian_ellipse_rejects_bad_input() -> None:
    with pytest.raises(ConfigError):
        gaussian_ellipse(np.zeros(2), np.eye(2), level=1.0)
    with pytest.raises(ConfigError):
        gaussian_ellipse(np.zeros(2), np.array([[1.0, 0.0], [0.0, -1.0]]))
    with pytest.raises(ConfigError):
        gaussian_ellipse(np.zeros(3), np.eye(3))
    flat = gaussian_ellipse(np.zeros(2), np.array([[1.0, 0.0], [0.0, 0.0]]), n=8)
    assert np.allclose(flat[:, 1], 0.0)


def test_project_gaussian_matches_monte_carlo() -> None:
    rng = np.random.default_rng(0)
    d = 6
    a = rng.normal(size=(d, d))
    mean, cov = rng.normal(size=d), a @ a.T + 0.1 * np.eye(d)
    components = np.linalg.qr(rng.normal(size=(d, 2)))[0].T
    center = rng.normal(size=d)
    mean2, cov2 = project_gaussian(mean, cov, components, center)
    projected = (rng.multivariate_normal(mean, cov, size=200_000) - center) @ components.T
    np.testing.assert_allclose(mean2, projected.mean(axis=0), atol=0.03)
    np.testing.assert_allclose(cov2, np.cov(projected, rowvar=False), rtol=0.03, atol=0.03)
    with pytest.raises(ConfigError):
        project_gaussian(mean, cov, components[:, :3], center)


def test_convex_hull_vertices_and_orientation() -> None:
    rng = np.random.default_rng(2)
    square = np.array([[0, 0], [1, 0], [1, 1], [0, 1]], dtype=float)
    hull = convex_hull(np.vstack([rng.uniform(0.05, 0.95, (100, 2)), square]))
    assert {tuple(p) for p in hull} == {tuple(p) for p in square}
    x, y = hull[:, 0], hull[:, 1]
    assert 0.5 * np.sum(x * np.roll(y, -1) - np.roll(x, -1) * y) == pytest.approx(1.0)  # counter-clockwise
    cloud = rng.normal(size=(300, 2))
    inside = rng.normal(scale=0.3, size=(200, 2))
    assert points_in_polygon(inside, convex_hull(cloud)).all()


def test_convex_hull_degenerate_inputs() -> None:
    assert convex_hull(np.zeros((0, 2))).shape == (0, 2)
    assert convex_hull(np.ones((5, 2))).tolist() == [[1.0, 1.0]]
    line = np.array([[0.0, 0.0], [1.0, 1.0], [3.0, 3.0], [2.0, 2.0]])
    assert {tuple(p) for p in convex_hull(line)} == {(0.0, 0.0), (3.0, 3.0)}


def test_idw_blend_exact_at_points_and_continuous() -> None:
    rng = np.random.default_rng(4)
    points, values = rng.normal(size=(200, 5)), rng.normal(size=(200, 3))
    np.testing.assert_array_equal(idw_blend(points[:10], points, values, k=8), values[:10])
    path = points[0] + np.linspace(0, 1, 2001)[:, None] * (points[1] - points[0])
    blended = idw_blend(path, points, values, k=8)
    nearest = values[np.argmin(((path[:, None] - points[None]) ** 2).sum(-1), axis=1)]
    max_step = np.abs(np.diff(blended, axis=0)).max()
    assert max_step < 0.05 * np.abs(np.diff(nearest, axis=0)).max()
    np.testing.assert_allclose(blended[[0, -1]], values[:2])


def test_idw_blend_with_fewer_points_than_k() -> None:
    points, values = np.array([[0.0], [1.0]]), np.array([[0.0], [1.0]])
    mid = idw_blend(np.array([[0.5], [0.25]]), points, values, k=8)
    np.testing.assert_allclose(mid[:, 0], [0.5, 0.1])  # weights 1/d²: (1/0.75²) / (1/0.25² + 1/0.75²)
    with pytest.raises(ConfigError):
        idw_blend(np.zeros((1, 2)), points, values)
