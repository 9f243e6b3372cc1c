"""Real mouse gestures on the explorer's window and checks of what the 3-D view shows."""

from __future__ import annotations

from collections.abc import Callable

import numpy as np
from PySide6.QtCore import QPoint, Qt

from tests.explorer.conftest import Opened


def map_pixel(opened: Opened, xy: np.ndarray) -> QPoint:
    """Pixel of map position ``xy`` in the map's plot viewport."""
    return opened.window.latent_map.data_to_widget(xy).toPoint()


def click_map(qtbot, opened: Opened, xy: np.ndarray) -> None:
    """Left-click the map at data position ``xy``."""
    viewport = opened.window.latent_map.plot.viewport()
    qtbot.mouseClick(viewport, Qt.MouseButton.LeftButton, pos=map_pixel(opened, xy))


def drag(qtbot, widget, pixels: list[QPoint], between: Callable[[], None] | None = None) -> None:
    """Press at the first pixel, move through the others (25 ms apart), release at the last."""
    qtbot.mouseMove(widget, pixels[0])
    qtbot.mousePress(widget, Qt.MouseButton.LeftButton, pos=pixels[0])
    for pixel in pixels[1:]:
        qtbot.wait(25)
        qtbot.mouseMove(widget, pixel)
        if between is not None:
            between()
    qtbot.wait(25)
    qtbot.mouseRelease(widget, Qt.MouseButton.LeftButton, pos=pixels[-1])


def drag_map(qtbot, opened: Opened, path: list[np.ndarray], between: Callable[[], None] | None = None):
    """Drag on the map through data positions ``path``."""
    viewport = opened.window.latent_map.plot.viewport()
    drag(qtbot, viewport, [map_pixel(opened, xy) for xy in path], between)


def isolated_points(embedding: np.ndarray, count: int, among: np.ndarray | None = None) -> list[int]:
    """Indices of ``count`` points (of ``among``, default all) far from every other point."""
    d = np.linalg.norm(embedding[:, None] - embedding[None], axis=-1)
    np.fill_diagonal(d, np.inf)
    lonely = np.argsort(-d.min(axis=1))
    if among is not None:
        lonely = lonely[np.isin(lonely, among)]
    return [int(i) for i in lonely[:count]]


def click_canvas(qtbot, opened: Opened, xz: tuple[float, float]) -> None:
    """Left-click the trajectory canvas at floor point ``xz``."""
    canvas = opened.window.trajectory
    pos = canvas.data_to_widget(xz).toPoint()
    qtbot.mouseClick(canvas.plot.viewport(), Qt.MouseButton.LeftButton, pos=pos)


def display_points(viewport, points: np.ndarray) -> np.ndarray:
    """(N, 2) display pixels of world points through VTK's own renderer (independent of the widget's
    projection helper)."""
    renderer = viewport.plotter.renderer
    out = []
    for p in np.asarray(points, dtype=np.float64).reshape(-1, 3):
        renderer.SetWorldPoint(float(p[0]), float(p[1]), float(p[2]), 1.0)
        renderer.WorldToDisplay()
        out.append(renderer.GetDisplayPoint()[:2])
    return np.asarray(out)


def outside_view(viewport, points: np.ndarray) -> int:
    """How many world points fall outside the rendered 3-D view."""
    viewport.render_now()
    width, height = viewport.plotter.renderer.GetSize()
    px = display_points(viewport, points)
    inside = (px[:, 0] >= 0) & (px[:, 0] <= width) & (px[:, 1] >= 0) & (px[:, 1] <= height)
    return int((~inside).sum())


def played_points(opened: Opened, every: int = 6) -> np.ndarray:
    """World positions of every ``every``-th frame of each motion played, layout offsets included."""
    c, viewport = opened.controller, opened.window.viewport
    pts = [m.joints[::every] + viewport.offsets[k] for k, m in enumerate(c.playback.played)]
    return np.concatenate([p.reshape(-1, 3) for p in pts])
