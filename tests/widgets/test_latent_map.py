"""LatentMap under real mouse events (clicks, drags, lasso, legend, hover) and the pixels it draws."""

from __future__ import annotations

import numpy as np
import pytest
from PySide6.QtCore import QPoint, Qt
from PySide6.QtWidgets import QToolTip

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


RED, BLUE, GREEN = (255, 0, 0), (0, 0, 255), (0, 255, 0)


def _pixel(widget: LatentMap, xy: tuple[float, float]) -> QPoint:
    return widget.data_to_widget(xy).toPoint()


def _drawn(qtbot, widget: LatentMap, xy: tuple[float, float] | np.ndarray) -> tuple[int, int, int]:
    """The RGB on screen at data point ``xy``, once the image follows the view."""
    qtbot.waitUntil(lambda: not widget.rendering(), timeout=5000)
    qtbot.wait(10)
    image = widget.plot.viewport().grab().toImage()
    return image.pixelColor(_pixel(widget, tuple(xy))).getRgb()[:3]


def _empty(qtbot, widget: LatentMap) -> tuple[int, int, int]:
    """The background's RGB as drawn (the screen may have fewer bits than the theme's colour)."""
    (x0, _), (_, y1) = widget.view_box.viewRange()
    sx, sy = widget.view_box.viewPixelSize()
    return _drawn(qtbot, widget, (x0 + 3 * sx, y1 - 3 * sy))


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
    empty = _empty(qtbot, latent_map)
    assert [_drawn(qtbot, latent_map, XY[row]) for row in (0, 1, 2, 3)] == [RED, RED, empty, empty]
    # a hidden point is no longer clickable
    with qtbot.waitSignal(latent_map.emptyClicked, timeout=1000):
        qtbot.mouseClick(latent_map.plot.viewport(), Qt.MouseButton.LeftButton, pos=_pixel(latent_map, XY[3]))
    qtbot.mouseClick(latent_map.legend_checkbox(1), Qt.MouseButton.LeftButton)
    assert [_drawn(qtbot, latent_map, XY[row]) for row in (2, 3)] == [BLUE, BLUE]


def test_visible_mask_and_selection(qtbot, latent_map: LatentMap) -> None:
    latent_map.set_visible_mask(np.array([True, False, True, False, True]))
    latent_map.set_selection([0, 1])
    assert latent_map.visible_rows().tolist() == [0, 2, 4]
    assert len(latent_map._highlight.data) == 1  # the hidden row 1 is not highlighted
    assert [_drawn(qtbot, latent_map, XY[row]) for row in (2, 3)] == [BLUE, _empty(qtbot, latent_map)]
    with qtbot.waitSignal(latent_map.emptyClicked, timeout=1000):
        qtbot.mouseClick(latent_map.plot.viewport(), Qt.MouseButton.LeftButton, pos=_pixel(latent_map, XY[3]))
    with pytest.raises(ValueError, match="mask"):
        latent_map.set_visible_mask(np.ones(3, dtype=bool))


def test_each_point_is_drawn_in_its_colour_later_ones_on_top(qtbot, latent_map: LatentMap) -> None:
    assert [_drawn(qtbot, latent_map, xy) for xy in XY] == [RED, RED, BLUE, BLUE, BLUE]
    assert _drawn(qtbot, latent_map, (0.25, 0.75)) == _empty(qtbot, latent_map)
    sx, _ = latent_map.view_box.viewPixelSize()
    pair = np.array([[0.5, 0.0], [0.5 + 2 * sx, 0.0]])  # discs overlapping by most of their width
    latent_map.set_points(pair, np.array([GREEN, RED]), np.arange(2))
    latent_map.view_box.setRange(xRange=(-0.5, 1.5), yRange=(-0.5, 1.5), padding=0)
    assert _drawn(qtbot, latent_map, pair[0]) == RED


def test_new_points_are_framed(qtbot, latent_map: LatentMap) -> None:
    far = np.array([[100.0, 100.0], [110.0, 120.0]])
    latent_map.set_points(far, np.array([RED, BLUE]), np.arange(2))
    (x0, x1), (y0, y1) = latent_map.view_box.viewRange()
    assert x0 < 100 and x1 > 110 and y0 < 100 and y1 > 120 and y1 - y0 < 30
    assert [_drawn(qtbot, latent_map, xy) for xy in far] == [RED, BLUE]


def test_set_colors_recolours_in_place(qtbot, latent_map: LatentMap) -> None:
    latent_map.set_visible_mask(np.array([True, True, True, True, False]))
    latent_map.set_selection([2])
    view = latent_map.view_box.viewRange()
    latent_map.set_colors(np.array([GREEN] * 5, dtype=np.uint8))
    assert latent_map.view_box.viewRange() == view
    empty = _empty(qtbot, latent_map)
    assert [_drawn(qtbot, latent_map, XY[row]) for row in (0, 2, 4)] == [GREEN, GREEN, empty]
    assert latent_map.visible_rows().tolist() == [0, 1, 2, 3]
    assert len(latent_map._highlight.data) == 1
    assert latent_map.point_colors()[:, :3].tolist() == [list(GREEN)] * 5


def test_a_large_selection_is_ringed_in_the_image_and_follows_the_view(qtbot, show) -> None:
    widget = show(LatentMap(rings_above=2))
    widget.set_points(XY, np.full((5, 3), 90, np.uint8), IDS)
    widget.view_box.setRange(xRange=(-0.5, 1.5), yRange=(-0.5, 1.5), padding=0)
    widget.set_selection([0, 1, 3])  # more than 2: rings in the image, no scatter
    assert len(widget._highlight.data) == 0

    def ring_at(row: int, offsets: range) -> bool:
        """Whether the selection colour is drawn at any of ``offsets`` pixels right of the row's point."""
        qtbot.waitUntil(lambda: not widget.rendering(), timeout=5000)
        qtbot.wait(10)
        image = widget.plot.viewport().grab().toImage()
        centre = _pixel(widget, XY[row])
        return any(image.pixelColor(centre + QPoint(dx, 0)).getRgb()[:3] == (255, 255, 255) for dx in offsets)

    ring, inside, beyond = range(6, 9), range(-4, 5), range(10, 14)  # a ring of radius 7, 2 px wide
    assert [ring_at(row, ring) for row in range(5)] == [True, True, False, True, False]
    assert not any(ring_at(row, inside) or ring_at(row, beyond) for row in range(5))
    widget.view_box.setRange(xRange=(-0.2, 0.3), yRange=(-0.2, 0.3), padding=0)  # 4 x zoom on row 0
    assert ring_at(0, ring) and ring_at(0, range(-8, -5)) and not ring_at(0, beyond)
    widget.set_selection([0])
    assert len(widget._highlight.data) == 1


def test_zooming_in_renders_again_at_the_new_scale(qtbot, latent_map: LatentMap) -> None:
    sx, _ = latent_map.view_box.viewPixelSize()
    pair = np.array([[0.5, 0.5], [0.5 + 0.3 * sx, 0.5]])  # both in one pixel
    latent_map.set_points(pair, np.array([RED, BLUE]), np.arange(2))
    latent_map.view_box.setRange(xRange=(-0.5, 1.5), yRange=(-0.5, 1.5), padding=0)
    assert _drawn(qtbot, latent_map, pair[0]) == BLUE
    half = 4 * sx  # 8 pixels across fill the view: the points are 15 pixels apart
    latent_map.view_box.setRange(xRange=(0.5 - half, 0.5 + half), yRange=(0.5 - half, 0.5 + half), padding=0)
    qtbot.wait(20)
    a, b = (latent_map.data_to_widget(tuple(xy)) for xy in pair)
    assert b.x() - a.x() > 12
    assert [_drawn(qtbot, latent_map, xy) for xy in pair] == [RED, BLUE]
    assert _drawn(qtbot, latent_map, pair[0] - (12 * sx / 50, 0)) == _empty(qtbot, latent_map)


def test_density_image_is_brighter_where_points_are_denser(qtbot, show) -> None:
    widget = show(LatentMap(density_above=10_000))
    rng = np.random.default_rng(0)
    # two squares filled uniformly, every pixel hit: one with 9 times the points of the other
    dense = rng.uniform(-0.2, 0.2, size=(180_000, 2))
    sparse = rng.uniform(-0.2, 0.2, size=(20_000, 2)) + np.array([3.0, 0.0])
    xy = np.concatenate([dense, sparse])
    widget.set_points(xy, np.full((len(xy), 3), 255, np.uint8), np.arange(len(xy)))
    widget.view_box.setRange(xRange=(-1.0, 4.0), yRange=(-1.0, 1.0), padding=0)
    qtbot.waitUntil(lambda: not widget.rendering(), timeout=5000)
    qtbot.wait(10)
    image = widget.plot.viewport().grab().toImage()

    def brightness(centre: tuple[float, float]) -> float:
        p = _pixel(widget, centre)
        patch = [image.pixelColor(p + QPoint(dx, dy)).value() for dx in range(-2, 3) for dy in range(-2, 3)]
        return float(np.mean(patch))

    empty = _empty(qtbot, widget)[2]
    assert brightness((0.0, 0.0)) > brightness((3.0, 0.0)) + 40
    assert brightness((3.0, 0.0)) > empty + 40  # the sparse square still shows
    assert brightness((1.5, 0.0)) == empty


def test_click_picks_the_nearest_visible_point_among_many(qtbot, show) -> None:
    widget = show(LatentMap())
    rng = np.random.default_rng(1)
    xy = rng.normal(size=(200_000, 2))
    widget.set_points(xy, np.full((len(xy), 3), 200, np.uint8), np.arange(len(xy)) + 7)
    mask = rng.random(len(xy)) < 0.5
    widget.set_visible_mask(mask)
    widget.view_box.setRange(xRange=(-0.2, 0.2), yRange=(-0.2, 0.2), padding=0)
    qtbot.wait(20)
    clicked: list[int] = []
    widget.pointClicked.connect(clicked.append)
    widget.emptyClicked.connect(lambda *_: clicked.append(-1))
    viewport, vb = widget.plot.viewport(), widget.view_box
    sx, sy = vb.viewPixelSize()
    expected = []
    for pixel in rng.integers(100, 350, size=(25, 2)):
        pos = QPoint(int(pixel[0]), int(pixel[1]))
        at = vb.mapSceneToView(widget.plot.mapToScene(pos))
        d2 = ((xy[:, 0] - at.x()) / sx) ** 2 + ((xy[:, 1] - at.y()) / sy) ** 2
        d2[~mask] = np.inf
        best = int(np.argmin(d2))
        expected.append(best + 7 if d2[best] <= 8.0**2 else -1)
        qtbot.mouseClick(viewport, Qt.MouseButton.LeftButton, pos=pos)
    assert clicked == expected
    assert set(expected) != {-1}
    assert not any(not mask[i - 7] for i in expected if i >= 0)


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


def test_tooltips_may_be_a_function_of_the_row(qtbot, latent_map: LatentMap) -> None:
    latent_map.set_points(XY, np.full((5, 3), 255, np.uint8), IDS, lambda row: f"row {row}")
    latent_map.view_box.setRange(xRange=(-0.5, 1.5), yRange=(-0.5, 1.5), padding=0)
    qtbot.mouseMove(latent_map.plot.viewport(), _pixel(latent_map, (0.25, 0.25)))
    qtbot.wait(25)
    qtbot.mouseMove(latent_map.plot.viewport(), _pixel(latent_map, XY[2]))
    qtbot.waitUntil(lambda: QToolTip.text() == "row 2", timeout=1000)


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
