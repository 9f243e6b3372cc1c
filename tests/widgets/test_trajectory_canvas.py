"""TrajectoryCanvas under real mouse events: end clicks, drawn paths, follow, generated overlay."""

from __future__ import annotations

import numpy as np
import pytest
from PySide6.QtCore import QPoint, Qt

from widgets.trajectory_canvas import TrajectoryCanvas


@pytest.fixture
def canvas(show) -> TrajectoryCanvas:
    """A shown canvas over a 4 m x 4 m floor."""
    widget = TrajectoryCanvas(extent_m=2.0)
    show(widget, 500, 500)
    return widget


def _pixel(widget: TrajectoryCanvas, xz: tuple[float, float]) -> QPoint:
    return widget.data_to_widget(xz).toPoint()


def test_click_emits_end_location(qtbot, canvas: TrajectoryCanvas) -> None:
    with qtbot.waitSignal(canvas.endRequested, timeout=1000) as blocker:
        qtbot.mouseClick(canvas.plot.viewport(), Qt.MouseButton.LeftButton, pos=_pixel(canvas, (1.0, -0.5)))
    sx, sz = canvas.view_box.viewPixelSize()
    assert blocker.args[0] == pytest.approx(1.0, abs=1.5 * sx)
    assert blocker.args[1] == pytest.approx(-0.5, abs=1.5 * sz)
    assert not canvas.follow_button.isEnabled()


def test_z_axis_points_down_in_top_view(canvas: TrajectoryCanvas) -> None:
    assert _pixel(canvas, (0.0, 1.0)).y() > _pixel(canvas, (0.0, -1.0)).y()
    assert _pixel(canvas, (1.0, 0.0)).x() > _pixel(canvas, (-1.0, 0.0)).x()


def test_draw_emits_path_then_end_and_follow(qtbot, canvas: TrajectoryCanvas) -> None:
    canvas.set_tool("draw")
    paths, ends = [], []
    canvas.pathDrawn.connect(paths.append)
    canvas.endRequested.connect(lambda x, z: ends.append((x, z)))
    stroke = [(0.0, 0.0), (0.3, 0.2), (0.6, 0.4), (0.9, 0.6), (1.2, 0.8)]
    viewport = canvas.plot.viewport()
    qtbot.mousePress(viewport, Qt.MouseButton.LeftButton, pos=_pixel(canvas, stroke[0]))
    for xz in stroke[1:]:
        qtbot.wait(25)
        qtbot.mouseMove(viewport, _pixel(canvas, xz))
    qtbot.wait(25)
    qtbot.mouseRelease(viewport, Qt.MouseButton.LeftButton, pos=_pixel(canvas, stroke[-1]))
    assert len(paths) == 1
    path = paths[0]
    sx, _ = canvas.view_box.viewPixelSize()
    assert path.shape[1] == 2 and len(path) >= 4
    np.testing.assert_allclose(path[0], stroke[0], atol=2 * sx)
    np.testing.assert_allclose(path[-1], stroke[-1], atol=2 * sx)
    np.testing.assert_allclose(path[:, 1], path[:, 0] * 2 / 3, atol=3 * sx)  # along the drawn line
    assert ends == [tuple(path[-1])]
    assert canvas.follow_button.isEnabled()
    with qtbot.waitSignal(canvas.followPathRequested, timeout=1000) as blocker:
        qtbot.mouseClick(canvas.follow_button, Qt.MouseButton.LeftButton)
    np.testing.assert_array_equal(blocker.args[0], path)


def test_generated_trajectory_and_error_text(canvas: TrajectoryCanvas) -> None:
    canvas.set_request(np.array([[0.0, 0.0], [1.0, 1.0]]))
    traj = np.c_[np.linspace(0, 0.9, 30), np.linspace(0, 1.1, 30)]
    canvas.set_generated(traj, 0.1414)
    x, z = canvas._generated_curve.getData()
    np.testing.assert_allclose(np.c_[x, z], traj)
    assert canvas.error_text() == "error 0.141 m"
    canvas.set_generated(None, None)
    assert canvas.error_text() == ""
    with pytest.raises(ValueError, match="request"):
        canvas.set_request(np.zeros((3, 3)))
