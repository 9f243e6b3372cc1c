"""Plane geometry for the latent map: lasso hit-test, Gaussian ellipses and hulls, kNN blending."""

from __future__ import annotations

import numpy as np
from scipy.spatial import ConvexHull, QhullError, cKDTree

from engine.errors import ConfigError


def _as_points(values: np.ndarray, name: str, dim: int | None = None) -> np.ndarray:
    """``values`` as a float64 (N, dim) array, or ConfigError naming ``name``."""
    array = np.asarray(values, dtype=np.float64)
    if array.ndim != 2 or (dim is not None and array.shape[1] != dim):
        want = f"(N, {dim})" if dim is not None else "(N, D)"
        raise ConfigError(f"{name} must have shape {want}, got {array.shape}")
    if not np.all(np.isfinite(array)):
        raise ConfigError(f"{name} contains NaN or infinite values")
    return array


def points_in_polygon(points: np.ndarray, polygon: np.ndarray) -> np.ndarray:
    """Which points lie inside a polygon by the even-odd rule.

    Parameters
    ----------
    points : (N, 2) array
    polygon : (M, 2) array of vertices, open or closed, possibly concave or self-intersecting.

    Returns
    -------
    (N,) bool array. Edges are half-open (a point counts as inside when it is on a left or lower
    edge and outside on a right or upper one), so polygons sharing an edge never both claim a point.
    """
    pts = _as_points(points, "points", 2)
    poly = _as_points(polygon, "polygon", 2)
    inside = np.zeros(len(pts), dtype=bool)
    if len(poly) < 3 or len(pts) == 0:
        return inside
    x, y = pts[:, 0], pts[:, 1]
    (x0, y0), (x1, y1) = poly.min(axis=0), poly.max(axis=0)
    # Only points in the polygon's bounding box can be inside. Sorted by y, the points an edge spans
    # (min(yi, yj) <= y < max(yi, yj), i.e. (yi > y) != (yj > y)) are one run, found by bisection.
    box = np.flatnonzero((x >= x0) & (x <= x1) & (y >= y0) & (y <= y1))
    order = box[np.argsort(y[box])]
    xs, ys = x[order], y[order]
    odd = np.zeros(len(order), dtype=bool)
    for (xi, yi), (xj, yj) in zip(poly, np.roll(poly, 1, axis=0), strict=True):
        start, stop = np.searchsorted(ys, (min(yi, yj), max(yi, yj)))
        if start == stop:  # also every horizontal edge
            continue
        x_edge = xi + (ys[start:stop] - yi) * (xj - xi) / (yj - yi)  # the edge's x at each point's y
        odd[start:stop] ^= xs[start:stop] < x_edge
    inside[order] = odd
    return inside


def gaussian_ellipse(mean2: np.ndarray, cov2: np.ndarray, level: float = 0.5, n: int = 64) -> np.ndarray:
    """The contour of a 2D Gaussian where the density is ``level`` × its peak (default half-peak).

    Parameters
    ----------
    mean2 : (2,) array
    cov2 : (2, 2) symmetric positive semi-definite array
    level : density ratio in (0, 1); the contour is Mahalanobis² = −2 ln(level).
    n : number of vertices (≥ 3), at angles 2πi/n; the first is not repeated at the end.

    Returns
    -------
    (n, 2) array of contour points.
    """
    mean = np.asarray(mean2, dtype=np.float64)
    cov = np.asarray(cov2, dtype=np.float64)
    if mean.shape != (2,) or cov.shape != (2, 2):
        raise ConfigError(f"need mean (2,) and covariance (2, 2), got {mean.shape} and {cov.shape}")
    if not (0.0 < level < 1.0):
        raise ConfigError(f"level must be in (0, 1), got {level}")
    if n < 3:
        raise ConfigError(f"an ellipse needs at least 3 points, got {n}")
    if not np.allclose(cov, cov.T, rtol=1e-6, atol=1e-12):
        raise ConfigError("covariance must be symmetric")
    eigval, eigvec = np.linalg.eigh(cov)
    if eigval[0] < -1e-9 * max(1.0, abs(eigval[-1])):
        raise ConfigError("covariance must be positive semi-definite")
    radius = np.sqrt(-2.0 * np.log(level))
    angles = 2.0 * np.pi * np.arange(n) / n
    circle = radius * np.stack([np.cos(angles), np.sin(angles)], axis=1)
    return mean + (circle * np.sqrt(np.clip(eigval, 0.0, None))) @ eigvec.T


def project_gaussian(
    mean: np.ndarray, cov: np.ndarray, components: np.ndarray, center: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """The exact image of N(mean, cov) under p = components @ (x − center).

    Parameters
    ----------
    mean : (D,), cov : (D, D), components : (2, D), center : (D,)

    Returns
    -------
    mean2 : (2,), cov2 : (2, 2)
    """
    mean = np.asarray(mean, dtype=np.float64)
    cov = np.asarray(cov, dtype=np.float64)
    comps = np.asarray(components, dtype=np.float64)
    center = np.asarray(center, dtype=np.float64)
    d = mean.shape[0] if mean.ndim == 1 else -1
    if mean.ndim != 1 or cov.shape != (d, d) or comps.shape != (2, d) or center.shape != (d,):
        raise ConfigError(
            f"shapes disagree: mean {mean.shape}, cov {cov.shape}, components {comps.shape}, "
            f"center {center.shape}"
        )
    cov2 = comps @ cov @ comps.T
    return comps @ (mean - center), 0.5 * (cov2 + cov2.T)


def convex_hull(points: np.ndarray) -> np.ndarray:
    """The convex hull's vertices in counter-clockwise order (first not repeated).

    Parameters
    ----------
    points : (N, 2) array

    Returns
    -------
    (H, 2) array: H = 0 for no points, 1 for coincident points, 2 (the extremes) for collinear points.
    """
    pts = np.unique(_as_points(points, "points", 2), axis=0)
    if len(pts) <= 2:
        return pts
    try:
        return pts[ConvexHull(pts).vertices]
    except QhullError:
        centered = pts - pts.mean(axis=0)
        direction = np.linalg.svd(centered, full_matrices=False)[2][0]
        along = centered @ direction
        return pts[[int(np.argmin(along)), int(np.argmax(along))]]


class NeighbourBlend:
    """Blends ``values`` of the k nearest ``points`` to each query with continuous inverse-distance weights.

    The weights are Franke–Little's ((R − d) / (R d))², R being the distance to the (k+1)-th nearest
    point, so a neighbour's weight falls to zero before it leaves the set: the blend is continuous as
    the query moves, and exact (the point's own value) when the query coincides with a point. The k-d
    tree is built once, so repeated queries (drags) cost a lookup each.

    Parameters
    ----------
    points : (N, D), values : (N, V), k : neighbours (clipped to N).
    """

    def __init__(self, points: np.ndarray, values: np.ndarray, k: int = 8):
        pts = _as_points(points, "points")
        self.values = np.asarray(values, dtype=np.float64)
        if len(pts) == 0 or self.values.ndim != 2 or len(self.values) != len(pts):
            raise ConfigError(
                f"cannot blend: points {pts.shape} and values {self.values.shape} disagree or are empty"
            )
        if k < 1:
            raise ConfigError(f"k must be at least 1, got {k}")
        self.k = min(k, len(pts))
        self.tree = cKDTree(pts)

    def __call__(self, query: np.ndarray) -> np.ndarray:
        """(M, V) blended values at query points (M, D)."""
        q = _as_points(query, "query")
        if q.shape[1] != self.tree.m:
            raise ConfigError(f"query has {q.shape[1]} dimensions, the points {self.tree.m}")
        k = self.k
        if k < self.tree.n:
            dist, idx = self.tree.query(q, k=k + 1)
            reach = dist[:, k : k + 1]
            dist, idx = dist[:, :k], idx[:, :k]
        else:
            dist, idx = self.tree.query(q, k=k)
            dist, idx = dist.reshape(len(q), k), idx.reshape(len(q), k)
            reach = np.full((len(q), 1), np.inf)
        with np.errstate(divide="ignore", invalid="ignore"):
            weights = np.where(np.isinf(reach), 1.0 / dist, (reach - dist) / (reach * dist)) ** 2
        exact = dist == 0.0
        has_exact = exact.any(axis=1)
        weights[has_exact] = exact[has_exact]
        # All k neighbours as far as the (k+1)-th: no preferred neighbour, so blend them equally.
        flat = weights.sum(axis=1) <= 0.0
        weights[flat] = 1.0
        weights /= weights.sum(axis=1, keepdims=True)
        return np.einsum("mk,mkv->mv", weights, self.values[idx])


def idw_blend(query: np.ndarray, points: np.ndarray, values: np.ndarray, k: int = 8) -> np.ndarray:
    """One-off :class:`NeighbourBlend`: (M, V) blend at query (M, D) of values (N, V) at points (N, D)."""
    return NeighbourBlend(points, values, k)(query)
