"""The explorer on a DVGAN model: futures of the motion shown from the timeline's frame ("Complete from
here"), longer motions that keep going while they play ("Continue", "Keep going") and their exports; the
tools off, saying why, on a kind that lacks them."""

from __future__ import annotations

from itertools import combinations
from pathlib import Path

import numpy as np
import pytest
from PySide6.QtCore import Qt

from engine.generators import open_generator
from engine.generators.dvgan import DvganGenerator
from engine.motion.formats import read_motion, write_motion
from engine.motion.motion import Motion
from engine.motion.resample import resample_motion
from engine.motion.skeleton import Skeleton
from explorer.continuing import FUTURES, frames_ahead
from tests.explorer.conftest import Opened, close_message_boxes
from tests.explorer.gestures import click_map, isolated_points, outside_view, played_points

pytestmark = pytest.mark.usefixtures("torch_single_thread")

SCREENSHOT = Path("/tmp/dvgan_complete.png")


@pytest.fixture(scope="module")
def dvgan(tiny_dvgan_dir) -> DvganGenerator:
    generator = open_generator(tiny_dvgan_dir)
    assert isinstance(generator, DvganGenerator)
    return generator


@pytest.fixture
def opened(qtbot, open_explorer, tiny_dvgan_dir) -> Opened:
    opened = open_explorer(tiny_dvgan_dir)
    qtbot.waitUntil(lambda: opened.controller.state.model is not None, timeout=60_000)
    return opened


def button(opened: Opened, action) -> object:
    """The timeline's button of ``action``."""
    [found] = [b for b in opened.window.timeline.tool_buttons if b.defaultAction() is action]
    return found


def press(qtbot, opened: Opened, action, timeout: int = 60_000) -> None:
    """Click the timeline's button of ``action`` and wait for the motions it shows."""
    with qtbot.waitSignal(opened.controller.shownChanged, timeout=timeout):
        qtbot.mouseClick(button(opened, action), Qt.MouseButton.LeftButton)


def stop_at(qtbot, opened: Opened, frame: int) -> None:
    """Pause the timeline and scrub it to ``frame``."""
    timeline = opened.window.timeline
    timeline.pause()
    timeline.set_frame(frame)
    qtbot.waitUntil(lambda: opened.controller.state.frame == frame, timeout=5_000)


def play_file(qtbot, opened: Opened, clip, tmp_path: Path) -> Path:
    """Drop ``clip`` saved as NPZ on the map (a DVGAN neither encodes nor inverts: it plays as recorded)."""
    path = tmp_path / "clip.npz"
    write_motion(clip, path)
    with qtbot.waitSignal(opened.controller.shownChanged, timeout=30_000):
        opened.window.latent_map.filesDropped.emit([str(path)])
    return path


def test_complete_from_here_plays_futures_that_start_with_the_clip(
    qtbot, opened: Opened, dvgan, procedural_clips, tmp_path
) -> None:
    window, c = opened.window, opened.controller
    assert window.complete_action.isEnabled() and button(opened, window.complete_action).isEnabled()
    assert "futures" in button(opened, window.complete_action).toolTip()
    clip = procedural_clips[0]
    play_file(qtbot, opened, clip, tmp_path)
    [shown] = c.state.shown
    assert shown.real and shown.label == "clip.npz (file)"
    assert "Complete from here" in window.status_label.text()
    np.testing.assert_allclose(shown.motion.joints, clip.joints, atol=1e-6)

    k = 30
    stop_at(qtbot, opened, k)
    press(qtbot, opened, window.complete_action)
    futures = c.state.shown
    ahead = frames_ahead(dvgan)
    assert len(futures) == FUTURES and ahead == 2 * dvgan.window
    for d in futures:
        assert d.motion.n_frames == k + 1 + ahead and d.motion.meta["prefix_frames"] == k + 1
        gap = np.linalg.norm(d.motion.joints[: k + 1] - clip.joints[: k + 1], axis=-1)
        assert gap.max() < 0.03, gap.max()  # the clip up to the timeline's frame, within a few cm
        assert not d.real and d.label.startswith(f"future {futures.index(d) + 1}/{FUTURES} · from frame 31")
    for a, b in combinations(futures, 2):  # and then each its own way (the tiny model's noise is weak)
        apart = np.linalg.norm(a.motion.joints[k + 1 :] - b.motion.joints[k + 1 :], axis=-1).mean(axis=1)
        assert apart[-1] > apart[0] and apart.mean() > 1e-3, apart
    # the engine's own call with the seed recorded
    expected = dvgan.complete(clip.with_joints(clip.joints[: k + 1]), ahead, FUTURES, futures[0].seed, "walk")
    for d, e in zip(futures, expected, strict=True):
        np.testing.assert_allclose(d.motion.joints, e.joints, atol=1e-5)

    # side by side in the view, in the action's colour (not the real clip's grey), all in view, playing
    viewport = window.viewport
    assert len(viewport.offsets) == FUTURES and np.ptp(viewport.offsets[:, 0]) > 1.0
    assert not (viewport.colors() == 205).all(axis=1).any()
    assert viewport.labels() == [f"walk {j + 1}/{FUTURES}" for j in range(FUTURES)]
    assert window.timeline.is_playing() and f"{k + 1 + ahead} frames" in window.status_label.text()
    assert outside_view(viewport, played_points(opened)) == 0
    stop_at(qtbot, opened, k + ahead)
    viewport.render_now()
    window.grab().save(str(SCREENSHOT))
    assert SCREENSHOT.stat().st_size > 10_000

    # a decoded motion completes the same way, from its own frames
    index = isolated_points(c.state.embedding, 1)[0]
    with qtbot.waitSignal(c.shownChanged, timeout=30_000):
        click_map(qtbot, opened, c.state.embedding[index])
    decoded = c.state.shown[0].motion
    stop_at(qtbot, opened, 7)
    press(qtbot, opened, window.complete_action)
    assert len(c.state.shown) == FUTURES
    for d in c.state.shown:
        assert np.linalg.norm(d.motion.joints[:8] - decoded.joints[:8], axis=-1).max() < 0.03
        assert f"of #{index} " in d.label


def test_continue_extends_what_plays_and_keep_going_makes_a_long_motion_that_exports(
    qtbot, opened: Opened, dvgan, tmp_path
) -> None:
    window, c = opened.window, opened.controller
    index = isolated_points(c.state.embedding, 1)[0]
    with qtbot.waitSignal(c.shownChanged, timeout=30_000):
        click_map(qtbot, opened, c.state.embedding[index])
    first = c.state.shown[0].motion
    assert first.n_frames == dvgan.window

    stop_at(qtbot, opened, 10)
    press(qtbot, opened, window.continue_action)
    [longer] = c.state.shown
    assert longer.motion.n_frames == dvgan.window + frames_ahead(dvgan)
    assert np.linalg.norm(longer.motion.joints[: first.n_frames] - first.joints, axis=-1).max() < 0.03
    assert longer.bank_index == index and "continued to 48 frames" in longer.label
    # playback goes on from where it was, over the new length
    assert window.timeline.is_playing() and window.timeline.slider.maximum() == longer.motion.n_frames - 1
    assert window.timeline.frame() >= 10

    # Keep going: extended whenever playback nears the end, with no seam in what came before
    window.timeline.set_speed(4.0)
    window.keep_going_action.trigger()
    assert window.keep_going_action.isChecked()
    qtbot.waitUntil(lambda: c.state.shown[0].motion.n_frames >= 250, timeout=120_000)
    window.keep_going_action.trigger()
    qtbot.waitUntil(lambda: not c.tasks.active, timeout=30_000)
    long = c.state.shown[0]
    assert np.linalg.norm(long.motion.joints[:48] - longer.motion.joints, axis=-1).max() < 0.03
    assert window.timeline.slider.maximum() == long.motion.n_frames - 1
    assert max(m.n_frames for m in c.playback.played) == long.motion.n_frames

    # the long motion exports whole: BVH, NPZ and every frame of the 3-D view as video
    for name in ("long.bvh", "long.npz"):
        [path] = c.exporter.export_shown(tmp_path / name)
        back = read_motion(path)
        assert back.n_frames == long.motion.n_frames, name
        assert np.linalg.norm(back.joints - long.motion.joints, axis=-1).max() < 0.02, name
    import imageio_ffmpeg

    video = c.exporter.export_video(tmp_path / "long.mp4")
    frames, _seconds = imageio_ffmpeg.count_frames_and_secs(str(video))
    assert frames == long.motion.n_frames


def test_a_completion_that_fails_says_why_and_the_app_keeps_running(
    qtbot, opened: Opened, procedural_clips, tmp_path
) -> None:
    window, c = opened.window, opened.controller
    clip = resample_motion(procedural_clips[1], 6 * procedural_clips[1].fps)  # 6 file frames a model frame
    play_file(qtbot, opened, clip, tmp_path)
    stop_at(qtbot, opened, 0)
    qtbot.mouseClick(button(opened, window.complete_action), Qt.MouseButton.LeftButton)
    assert "past the first frame" in window.status_label.text()  # nothing asked of the model
    stop_at(qtbot, opened, 1)  # two file frames: one at the model's rate
    with qtbot.waitSignal(c.errorOccurred, timeout=30_000) as error:
        qtbot.mouseClick(button(opened, window.complete_action), Qt.MouseButton.LeftButton)
    assert "at least 2 frames" in error.args[0]
    assert close_message_boxes()
    assert c.state.shown[0].motion.n_frames == clip.n_frames and window.isVisible()
    assert not window.keep_going_action.isChecked()


def test_a_file_plays_on_the_models_joints_and_another_rig_is_refused_by_name(
    qtbot, opened: Opened, procedural_clips, tmp_path
) -> None:
    window, c = opened.window, opened.controller
    clip = procedural_clips[1]
    skel = clip.skeleton
    # A Bandai-style ground-projected root above the model's root joint, as the raw dataset files have.
    grounded = Motion(
        np.concatenate([clip.joints[:, :1] * np.float32([1, 0, 1]), clip.joints], axis=1),
        clip.fps,
        Skeleton(
            ("Ground", *skel.names),
            np.concatenate([[-1], np.where(skel.parents < 0, 0, skel.parents + 1)]),
            np.concatenate([np.zeros((1, 3)), skel.offsets]),
        ),
    )
    play_file(qtbot, opened, grounded, tmp_path)
    [shown] = c.state.shown
    assert shown.motion.skeleton.names == skel.names
    np.testing.assert_allclose(shown.motion.joints, clip.joints, atol=1e-5)
    assert "unlabelled (real)" in window.viewport.labels() and "None" not in window.status_label.text()

    other = clip.without_joints([skel.names[-1]])
    path = tmp_path / "other_rig.npz"
    write_motion(other, path)
    with qtbot.waitSignal(c.errorOccurred, timeout=30_000) as error:
        window.latent_map.filesDropped.emit([str(path)])
    assert "other_rig.npz" in error.args[0] and "skeleton does not match" in error.args[0]
    assert close_message_boxes()
    assert c.state.shown == (shown,)  # what played before plays on


def test_an_odmo_model_has_complete_and_continue_off_with_the_reason(
    qtbot, open_explorer, tiny_model_dir
) -> None:
    opened = open_explorer(tiny_model_dir)
    window, c = opened.window, opened.controller
    qtbot.waitUntil(lambda: c.state.model is not None, timeout=60_000)
    reasons = {
        window.complete_action: "cannot complete a motion from a prefix",
        window.continue_action: "cannot extend a motion past its window",
        window.keep_going_action: "cannot extend a motion past its window",
    }
    for action, why in reasons.items():
        assert not action.isEnabled() and why in action.toolTip(), action.text()
        tool = button(opened, action)
        assert not tool.isEnabled() and why in tool.toolTip(), action.text()
    with qtbot.waitSignal(c.shownChanged, timeout=30_000):
        c.gestures.click_point(0)
    shown = c.state.shown
    c.continuation.continue_shown()  # reached anyway (a shortcut, a script): refused in words, not run
    assert "cannot extend a motion past its window" in window.status_label.text()
    c.continuation.complete_here()
    assert "cannot complete a motion from a prefix" in window.status_label.text()
    assert c.state.shown is shown, [t.title for t in c.tasks.active]
    assert not any(t.title.startswith(("Complet", "Continu")) for t in c.tasks.active)
