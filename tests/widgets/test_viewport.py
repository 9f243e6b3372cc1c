"""SkeletonViewport: pixels move when poses change, layouts, decorations, clean close."""

from __future__ import annotations

import numpy as np
import pytest
import pyvista as pv
from PySide6.QtWidgets import QApplication

from widgets.viewport import SkeletonViewport

PARENTS = np.array([-1, 0, 1, 0, 0, 1])
POSE = np.array(
    [[0.0, 1.0, 0.0], [0.0, 1.5, 0.0], [0.0, 1.8, 0.0], [-0.2, 0.0, 0.0], [0.2, 0.0, 0.0], [0.5, 1.4, 0.0]],
    dtype=np.float32,
)


@pytest.fixture
def viewport(show) -> SkeletonViewport:
    """A shown viewport with one skeleton in the rest pose."""
    widget = SkeletonViewport()
    widget.set_skeletons(PARENTS, 1)
    widget.set_poses(POSE[None])
    show(widget, 480, 400)
    widget.reset_camera()
    widget.render_now()
    return widget


def _screenshot(widget: SkeletonViewport) -> np.ndarray:
    widget.render_now()
    return np.asarray(widget.plotter.screenshot(return_img=True), dtype=np.int16)


def test_set_poses_moves_rendered_skeleton(viewport: SkeletonViewport) -> None:
    before = _screenshot(viewport)
    assert before.std() > 5, "the view shows structure (skeleton, floor), not a flat colour"
    viewport.set_poses((POSE + np.array([0.6, 0.0, 0.0], dtype=np.float32))[None])
    after = _screenshot(viewport)
    changed = np.any(np.abs(after - before) > 30, axis=2)
    assert changed.mean() > 0.002, "the skeleton's pixels moved"
    np.testing.assert_allclose(viewport.skeleton_points()[0, 0], [0.6, 1.0, 0.0], atol=1e-6)


def test_widget_grab_includes_the_3d_view(viewport: SkeletonViewport) -> None:
    QApplication.processEvents()
    image = viewport.grab().toImage()
    pixels = np.array(
        [
            [image.pixelColor(x, y).value() for x in range(0, image.width(), 4)]
            for y in range(0, image.height(), 4)
        ]
    )
    assert pixels.std() > 5 and len(np.unique(pixels)) > 10


def test_side_by_side_layout_offsets_skeletons(viewport: SkeletonViewport) -> None:
    viewport.set_skeletons(PARENTS, 3)
    viewport.set_poses(np.repeat(POSE[None], 3, axis=0))
    viewport.set_layout("side_by_side", spacing=1.5)
    np.testing.assert_allclose(viewport.skeleton_points()[:, 0, 0], [-1.5, 0.0, 1.5], atol=1e-6)
    viewport.set_layout("overlay")
    np.testing.assert_allclose(viewport.skeleton_points()[:, 0, 0], [0.0, 0.0, 0.0], atol=1e-6)
    with pytest.raises(ValueError, match="shape"):
        viewport.set_poses(POSE[None])


def test_follow_moves_camera_with_root(viewport: SkeletonViewport) -> None:
    np.testing.assert_allclose(viewport.plotter.camera.up, [0.0, 1.0, 0.0], atol=1e-9)
    viewport.set_follow(True)
    viewport.set_poses(POSE[None])
    focal = np.asarray(viewport.plotter.camera.focal_point)
    viewport.set_poses((POSE + np.array([1.0, 0.3, -2.0], dtype=np.float32))[None])
    np.testing.assert_allclose(
        np.asarray(viewport.plotter.camera.focal_point) - focal, [1.0, 0.0, -2.0], atol=1e-6
    )
    viewport.set_follow(False)
    viewport.set_poses(POSE[None])
    np.testing.assert_allclose(
        np.asarray(viewport.plotter.camera.focal_point) - focal, [1.0, 0.0, -2.0], atol=1e-6
    )


def _in_view(viewport: SkeletonViewport, points: np.ndarray) -> np.ndarray:
    """Whether each world point (N, 3) projects inside the rendered viewport (VTK's own transform)."""
    renderer = viewport.plotter.renderer
    inside = []
    for p in points:
        renderer.SetWorldPoint(*p, 1.0)
        renderer.WorldToDisplay()
        x, y, _ = renderer.GetDisplayPoint()
        width, height = renderer.GetSize()
        inside.append(0 <= x <= width and 0 <= y <= height)
    return np.array(inside)


def test_frame_motion_keeps_a_whole_walk_in_view(viewport: SkeletonViewport) -> None:
    walk = POSE[None] + np.linspace(0.0, 6.0, 30)[:, None, None] * np.array([0.3, 0.0, 1.0], np.float32)
    ends = np.stack([walk[0], walk[-1]]).reshape(-1, 3)
    viewport.reset_camera()
    assert not _in_view(viewport, ends).all(), "the test walk must leave the default view"
    viewport.frame_motion(walk[None])
    viewport.render_now()
    assert _in_view(viewport, ends).all()
    with pytest.raises(ValueError, match="frames must be"):
        viewport.frame_motion(walk)


def test_decorations_draw_and_clear(viewport: SkeletonViewport) -> None:
    before = _screenshot(viewport)
    path = np.c_[np.linspace(0, 1.5, 20), np.zeros(20), np.linspace(0, 1.0, 20)]
    viewport.set_trajectory(path)
    viewport.set_end_marker((1.5, 0.0, 1.0))
    viewport.set_ghosts(np.stack([POSE + np.array([dx, 0.0, 0.0]) for dx in (-0.8, -0.4)]).astype(np.float32))
    decorated = _screenshot(viewport)
    assert np.any(np.abs(decorated - before) > 30, axis=2).mean() > 0.002
    viewport.set_trajectory(None)
    viewport.set_end_marker(None)
    viewport.set_ghosts(None)
    cleared = _screenshot(viewport)
    assert np.abs(cleared - before).max() <= 2
    with pytest.raises(ValueError, match="ghost"):
        viewport.set_ghosts(np.zeros((2, 3, 3)))


def test_close_finalises_plotter_without_leaks(qtbot) -> None:
    open_before = len(pv.plotting.plotter._ALL_PLOTTERS)
    widget = SkeletonViewport()
    qtbot.addWidget(widget)
    widget.set_skeletons(PARENTS, 2)
    widget.show()
    qtbot.waitExposed(widget)
    assert len(pv.plotting.plotter._ALL_PLOTTERS) == open_before + 1
    widget.close()
    QApplication.processEvents()
    assert widget.plotter._closed
    assert len(pv.plotting.plotter._ALL_PLOTTERS) == open_before
    assert not any(w.isVisible() for w in QApplication.topLevelWidgets())


def test_bad_parents_rejected(viewport: SkeletonViewport) -> None:
    with pytest.raises(ValueError, match="tree"):
        viewport.set_skeletons([0, 0, 1], 1)


def test_updates_in_one_event_pass_share_one_render(qtbot, viewport: SkeletonViewport) -> None:
    renders: list[str] = []
    viewport.plotter.ren_win.AddObserver("EndEvent", lambda *_: renders.append("render"))
    for dx in np.linspace(0.0, 0.5, 5, dtype=np.float32):
        viewport.set_poses((POSE + np.array([dx, 0.0, 0.0], dtype=np.float32))[None])
    viewport.set_end_marker((1.0, 0.0, 1.0))
    assert renders == []
    qtbot.wait(50)
    assert len(renders) == 1


def test_labels_follow_the_heads_and_can_be_retexted(viewport: SkeletonViewport) -> None:
    viewport.set_labels(["walk 1/1"])
    [pos] = viewport.label_positions()
    assert pos[1] > POSE[:, 1].max() and viewport.labels() == ["walk 1/1"]
    viewport.set_poses((POSE + np.array([2.0, 0.0, 0.0], dtype=np.float32))[None])
    assert viewport.label_positions()[0, 0] == pytest.approx(pos[0] + 2.0)
    viewport.set_labels(["run 1/1"])
    assert viewport.labels() == ["run 1/1"] and len(viewport.label_positions()) == 1
    viewport.render_now()  # the 2-D label sits just above where the head is drawn
    renderer = viewport.plotter.renderer
    head = viewport.skeleton_points()[0, np.argmax(POSE[:, 1])]
    renderer.SetWorldPoint(*head.astype(float), 1.0)
    renderer.WorldToDisplay()
    hx, hy, _ = renderer.GetDisplayPoint()
    x, y = viewport._label_actors[0].GetPosition()
    assert abs(x - hx) < 20 and hy < y < hy + 120
    with pytest.raises(ValueError, match="labels"):
        viewport.set_labels(["a", "b"])
    viewport.set_labels(None)
    assert viewport.labels() == [] and len(viewport.label_positions()) == 0


def test_framing_keeps_a_long_walk_in_view_at_any_aspect(show, viewport: SkeletonViewport) -> None:
    walk = np.stack([POSE + np.array([0.0, 0.0, 0.15 * t], dtype=np.float32) for t in range(60)])[None]
    for size in ((480, 400), (260, 600), (900, 240)):
        viewport.resize(*size)
        QApplication.processEvents()
        viewport.frame_motion(walk)
        assert viewport.in_view(walk.reshape(-1, 3))
        ndc = viewport.project(walk.reshape(-1, 3))
        assert np.abs(ndc).max() > 0.6, "framed tightly, not from far away"
    viewport.set_poses(walk[:, 0])
    assert not viewport.keep_in_view(walk), "already in view: the camera stays"
    far = walk + np.array([6.0, 0.0, 0.0], dtype=np.float32)
    assert viewport.keep_in_view(far) and viewport.in_view(far.reshape(-1, 3))
