"""Timeline: playback emits increasing frames, loops or stops, keys and scrubbing."""

from __future__ import annotations

import pytest
from PySide6.QtCore import Qt

from widgets.timeline import Timeline


@pytest.fixture
def timeline(show) -> Timeline:
    """A shown timeline of 10 frames at 100 fps."""
    widget = Timeline()
    widget.set_length(10, 100.0)
    show(widget, 600, 40)
    return widget


def test_plays_increasing_frames_then_loops(qtbot, timeline: Timeline) -> None:
    frames: list[int] = []
    timeline.frameChanged.connect(frames.append)
    timeline.play()
    qtbot.waitUntil(lambda: frames.count(0) >= 1 and len(frames) > 12, timeout=3000)
    timeline.pause()
    assert frames[:9] == list(range(1, 10))
    wrap = frames.index(0)
    assert frames[wrap - 1] == 9 and frames[wrap + 1] == 1


def test_stops_at_end_without_loop(qtbot, timeline: Timeline) -> None:
    timeline.set_loop(False)
    timeline.set_frame(7)
    timeline.play()
    qtbot.waitUntil(lambda: not timeline.is_playing(), timeout=2000)
    assert timeline.frame() == 9
    timeline.play()  # playing again from the end restarts at 0
    assert timeline.frame() == 0 and timeline.is_playing()
    timeline.close()
    assert not timeline.is_playing()


def test_speed_sets_timer_interval(timeline: Timeline) -> None:
    assert timeline.interval_ms() == 10
    timeline.set_speed(0.25)
    assert timeline.interval_ms() == 40
    timeline.set_speed(4.0)
    assert timeline.interval_ms() == 2  # 1000 / 400 rounded
    with pytest.raises(ValueError, match="speed"):
        timeline.set_speed(8.0)


def test_keyboard_shortcuts(qtbot, timeline: Timeline) -> None:
    timeline.activateWindow()
    qtbot.waitActive(timeline)
    timeline.setFocus()
    qtbot.waitUntil(timeline.hasFocus, timeout=1000)
    qtbot.keyClick(timeline, Qt.Key.Key_Right)
    qtbot.keyClick(timeline, Qt.Key.Key_Right)
    assert timeline.frame() == 2
    qtbot.keyClick(timeline, Qt.Key.Key_Left)
    assert timeline.frame() == 1
    qtbot.keyClick(timeline, Qt.Key.Key_End)
    assert timeline.frame() == 9
    qtbot.keyClick(timeline, Qt.Key.Key_Home)
    assert timeline.frame() == 0
    qtbot.keyClick(timeline, Qt.Key.Key_Space)
    assert timeline.is_playing()
    qtbot.keyClick(timeline, Qt.Key.Key_Space)
    assert not timeline.is_playing()


def test_scrub_slider_emits_frame_and_updates_counter(qtbot, timeline: Timeline) -> None:
    with qtbot.waitSignal(timeline.frameChanged, timeout=1000) as blocker:
        timeline.slider.setValue(5)
    assert blocker.args == [5]
    assert timeline.counter.text().startswith("6 / 10")
    timeline.set_length(4, 30.0)
    assert timeline.frame() == 3
    with pytest.raises(ValueError):
        timeline.set_length(0, 30.0)
