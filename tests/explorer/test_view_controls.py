"""Issue 12 view controls on the real window: follow camera, labels, ghost count, follow path."""

from __future__ import annotations

import numpy as np
from PySide6.QtCore import Qt

from tests.explorer.conftest import Opened, close_message_boxes
from tests.explorer.gestures import drag, outside_view, played_points


def _walker(c) -> int:
    return int(np.argmax(np.linalg.norm(c.bank.ends[:, [0, 2]], axis=1)))


def _play(qtbot, opened: Opened, index: int) -> None:
    with qtbot.waitSignal(opened.controller.shownChanged, timeout=20_000):
        opened.controller.gestures.click_point(index)


def test_follow_camera_keeps_the_walker_centred(qtbot, explorer: Opened) -> None:
    c, w = explorer.controller, explorer.window
    _play(qtbot, explorer, _walker(c))
    w.follow_camera_action.trigger()
    assert w.viewport.follow
    motion = c.playback.played[0]
    root = motion.skeleton.root
    for frame in (0, motion.n_frames // 2, motion.n_frames - 1, 3):
        w.timeline.set_frame(frame)
        focal = np.asarray(w.viewport.plotter.camera.focal_point)
        np.testing.assert_allclose(w.viewport.skeleton_points()[0, root, [0, 2]], focal[[0, 2]], atol=1e-4)
    w.follow_camera_action.trigger()  # off again: the whole motion is framed
    assert not w.viewport.follow
    assert outside_view(w.viewport, played_points(explorer, every=3)) == 0


def test_labels_sit_over_each_skeleton_and_can_be_hidden(qtbot, explorer: Opened) -> None:
    c, w = explorer.controller, explorer.window
    w.mode_panel.n_box.setValue(3)
    with qtbot.waitSignal(c.shownChanged, timeout=30_000):
        qtbot.mouseClick(w.mode_panel.sample_button, Qt.MouseButton.LeftButton)
    labels = w.viewport.labels()
    name = c.bank.action_names[c.state.focus_action]
    assert len(labels) == 3 and all(name in text for text in labels)
    heads = w.viewport.skeleton_points().max(axis=1)[:, 1]
    positions = w.viewport.label_positions()
    assert np.all(positions[:, 1] > heads)
    np.testing.assert_allclose(positions[:, 0], w.viewport.skeleton_points()[:, :, 0].mean(axis=1), atol=0.6)
    w.labels_action.trigger()
    assert w.viewport.labels() == []


def test_ghost_count_follows_the_spin_box(qtbot, explorer: Opened) -> None:
    c, w = explorer.controller, explorer.window
    _play(qtbot, explorer, _walker(c))
    for count in (8, 0, 2):
        w.ghosts_spin.setValue(count)
        assert len(w.viewport.ghost_frames()) == count
    np.testing.assert_allclose(w.viewport.ghost_frames()[-1], c.playback.played[0].joints[-1], atol=1e-5)


def test_follow_path_button_follows_a_drawn_path_and_refuses_an_unreachable_one(
    qtbot, explorer: Opened
) -> None:
    c, w = explorer.controller, explorer.window
    index = _walker(c)
    _play(qtbot, explorer, index)
    canvas = w.trajectory
    canvas.set_tool("draw")
    reach = float(np.linalg.norm(c.bank.ends[index, [0, 2]]))
    arc = [(-0.3 * reach * t**2, -reach * t) for t in np.linspace(0, 1, 7)]  # drawn away from +z
    with qtbot.waitSignal(c.shownChanged, timeout=20_000):
        drag(qtbot, canvas.plot.viewport(), [canvas.data_to_widget(p).toPoint() for p in arc])
    with qtbot.waitSignal(c.shownChanged, timeout=60_000):
        qtbot.mouseClick(canvas.follow_button, Qt.MouseButton.LeftButton)
    item = c.state.shown[0]
    assert item.label.startswith("follow path") and "error" in canvas.error_text()
    assert item.action == int(c.bank.actions[index])
    root = item.motion.joints[:, item.motion.skeleton.root][:, [0, 2]]
    np.testing.assert_allclose(w.trajectory.generated_path(), root, atol=1e-5)
    far = [(0.0, 10.0 * reach * t + 0.01) for t in np.linspace(0, 1, 7)]
    canvas.view_box.setRange(xRange=(-12 * reach, 12 * reach), yRange=(-1, 12 * reach))
    with qtbot.waitSignal(c.shownChanged, timeout=20_000):
        drag(qtbot, canvas.plot.viewport(), [canvas.data_to_widget(p).toPoint() for p in far])
    with qtbot.waitSignal(c.errorOccurred, timeout=30_000) as blocker:
        qtbot.mouseClick(canvas.follow_button, Qt.MouseButton.LeftButton)
    assert "unreachable" in blocker.args[0]
    assert close_message_boxes() and w.isVisible()
