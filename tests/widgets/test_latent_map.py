"""LatentMap under real mouse events: clicks, drags, lasso, legend, hover."""

from __future__ import annotations

import numpy as np
import pytest
from PySide6.QtCore import QPoint, Qt

from widgets.latent_map import LatentMap

XY = np.array([[0.0, 0.0], [1.0, 0.0], [0.0, 1.0], [1.0, 1.0], [0.5, 0.5]])
IDS = np.array([10, 11, 12, 13, 14])
GROUPS = np.array([0, 0, 1, 1, 1])


@pytest.fixture
def latent_map(show) -> LatentMap:
    """A shown map with five known points in two legend groups."""
    widget = LatentMap()
    colors = np.array([[255, 0, 0, 255]] * 2 + [[0, 0, 255, 255]] * 3, dtype=np.uint8)
    widget.set_points(XY, colors, IDS, [f"clip {i}" for i in IDS])
    widget.set_legend(["walk", "run"], ["#ff0000", "#0000ff"], groups=GROUPS)
    show(widget)
    widget.view_box.setRange(xRange=(-0.5, 1.5), yRange=(-0.5, 1.5), padding=0)
    return widget


def _pixel(widget: LatentMap, xy: tuple[float, float]) -> QPoint:
    return widget.data_to_widget(xy).toPoint()


def _drag(qtbot, widget: LatentMap, path: list[tuple[float, float]]) -> None:
    """Press at the first data point of ``path``, move through the rest with the button held, release."""
    viewport = widget.plot.viewport()
    qtbot.mousePress(viewport, Qt.MouseButton.LeftButton, pos=_pixel(widget, path[0]))
    for xy in path[1:]:
        qtbot.wait(25)  # pyqtgraph drops move events closer than its rate limit
        qtbot.mouseMove(viewport, _pixel(widget, xy))
    qtbot.wait(25)
    qtbot.mouseRelease(viewport, Qt.MouseButton.LeftButton, pos=_pixel(widget, path[-1]))


def test_click_on_point_emits_its_id(qtbot, latent_map: LatentMap) -> None:
    for row in (1, 2, 4):
        with qtbot.waitSignal(latent_map.pointClicked, timeout=1000) as blocker:
            qtbot.mouseClick(
                latent_map.plot.viewport(), Qt.MouseButton.LeftButton, pos=_pixel(latent_map, XY[row])
            )
        assert blocker.args == [IDS[row]]


def test_click_near_point_within_tolerance_picks_it(qtbot, latent_map: LatentMap) -> None:
    pos = _pixel(latent_map, XY[3]) + QPoint(4, -3)
    with qtbot.waitSignal(latent_map.pointClicked, timeout=1000) as blocker:
        qtbot.mouseClick(latent_map.plot.viewport(), Qt.MouseButton.LeftButton, pos=pos)
    assert blocker.args == [13]


def test_click_on_empty_space_emits_data_coords(qtbot, latent_map: LatentMap) -> None:
    target = (0.25, 0.8)
    with qtbot.waitSignal(latent_map.emptyClicked, timeout=1000) as blocker:
        qtbot.mouseClick(
            latent_map.plot.viewport(), Qt.MouseButton.LeftButton, pos=_pixel(latent_map, target)
        )
    sx, sy = latent_map.view_box.viewPixelSize()
    assert blocker.args[0] == pytest.approx(target[0], abs=1.5 * sx)
    assert blocker.args[1] == pytest.approx(target[1], abs=1.5 * sy)


def test_drag_from_point_reports_path(qtbot, latent_map: LatentMap) -> None:
    started, moved, finished = [], [], []
    latent_map.dragStarted.connect(started.append)
    latent_map.dragMoved.connect(lambda x, y: moved.append((x, y)))
    latent_map.dragFinished.connect(lambda x, y: finished.append((x, y)))
    path = [(0.0, 0.0), (0.2, 0.1), (0.4, 0.2), (0.6, 0.3), (0.8, 0.4)]
    _drag(qtbot, latent_map, path)
    assert started == [10]
    assert len(moved) >= 3
    moved_arr = np.asarray(moved)
    assert np.all(np.diff(moved_arr[:, 0]) > 0), "x grows along the drag"
    # every reported point lies on the line y = x / 2 that the drag followed
    sx, sy = latent_map.view_box.viewPixelSize()
    assert np.allclose(moved_arr[:, 1], moved_arr[:, 0] / 2, atol=2 * max(sx, sy))
    assert finished and finished[0] == pytest.approx((0.8, 0.4), abs=2 * max(sx, sy))


def test_drag_from_empty_space_pans_instead(qtbot, latent_map: LatentMap) -> None:
    started: list[int] = []
    latent_map.dragStarted.connect(started.append)
    before = latent_map.view_box.viewRange()[0][0]
    _drag(qtbot, latent_map, [(0.25, 0.75), (0.35, 0.75), (0.45, 0.75), (0.55, 0.75)])
    assert started == []
    assert latent_map.view_box.viewRange()[0][0] < before - 0.2


def test_lasso_emits_polygon_in_data_coords(qtbot, latent_map: LatentMap) -> None:
    latent_map.set_tool("lasso")
    corners = [(-0.2, -0.2), (0.7, -0.2), (0.7, 0.7), (-0.2, 0.7), (-0.2, -0.1)]
    with qtbot.waitSignal(latent_map.lassoFinished, timeout=2000) as blocker:
        _drag(qtbot, latent_map, corners)
    polygon = blocker.args[0]
    assert isinstance(polygon, np.ndarray) and polygon.ndim == 2 and polygon.shape[1] == 2
    sx, _ = latent_map.view_box.viewPixelSize()
    for corner in corners[:4]:
        assert np.min(np.linalg.norm(polygon - corner, axis=1)) < 3 * sx
    assert latent_map.tool() == "lasso"


def test_legend_toggle_hides_and_restores_points(qtbot, latent_map: LatentMap) -> None:
    with qtbot.waitSignal(latent_map.legendToggled, timeout=1000) as blocker:
        qtbot.mouseClick(latent_map.legend_checkbox(1), Qt.MouseButton.LeftButton)
    assert blocker.args == [1, False]
    assert latent_map.visible_rows().tolist() == [0, 1]
    assert len(latent_map.scatter.data) == 2
    # a hidden point is no longer clickable
    with qtbot.waitSignal(latent_map.emptyClicked, timeout=1000):
        qtbot.mouseClick(latent_map.plot.viewport(), Qt.MouseButton.LeftButton, pos=_pixel(latent_map, XY[3]))
    qtbot.mouseClick(latent_map.legend_checkbox(1), Qt.MouseButton.LeftButton)
    assert len(latent_map.scatter.data) == 5


def test_visible_mask_and_selection(latent_map: LatentMap) -> None:
    latent_map.set_visible_mask(np.array([True, False, True, False, True]))
    latent_map.set_selection([0, 1])
    assert latent_map.visible_rows().tolist() == [0, 2, 4]
    assert len(latent_map._highlight.data) == 1  # the hidden row 1 is not highlighted
    with pytest.raises(ValueError, match="mask"):
        latent_map.set_visible_mask(np.ones(3, dtype=bool))


def test_hover_emits_id_and_leaves(qtbot, latent_map: LatentMap) -> None:
    hovered: list[int] = []
    latent_map.hovered.connect(hovered.append)
    viewport = latent_map.plot.viewport()
    qtbot.mouseMove(viewport, _pixel(latent_map, (0.25, 0.25)))
    qtbot.wait(25)
    qtbot.mouseMove(viewport, _pixel(latent_map, XY[4]))
    qtbot.wait(25)
    qtbot.mouseMove(viewport, _pixel(latent_map, (0.25, 0.75)))
    qtbot.wait(25)
    assert hovered[-2:] == [14, -1]


def test_overlays_extra_points_and_marker(latent_map: LatentMap) -> None:
    circle = np.c_[np.cos(np.linspace(0, 2 * np.pi, 20)), np.sin(np.linspace(0, 2 * np.pi, 20))]
    latent_map.set_overlays([circle, circle * 0.5], [(255, 0, 0), "#00ff00"])
    latent_map.set_extra_points(np.array([[0.3, 0.3], [0.6, 0.6]]), np.array([[1.0, 0, 0], [0, 1.0, 0]]))
    latent_map.set_marker((0.5, 0.25))
    assert len(latent_map._overlays) == 2
    x, _ = latent_map._overlays[0].getData()
    assert len(x) == 21 and x[0] == x[-1]  # closed
    assert len(latent_map._extra.data) == 2
    assert latent_map._marker.data["x"].tolist() == [0.5]
    latent_map.set_overlays([])
    latent_map.set_marker(None)
    assert latent_map._overlays == [] and len(latent_map._marker.data) == 0
