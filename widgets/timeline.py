"""Timeline: play / pause, scrub, step, speed and loop for a clip of T frames."""

from __future__ import annotations

from PySide6.QtCore import Qt, QTimer, Signal
from PySide6.QtGui import QAction, QCloseEvent, QKeySequence, QShortcut
from PySide6.QtWidgets import (
    QCheckBox,
    QComboBox,
    QHBoxLayout,
    QLabel,
    QSlider,
    QStyle,
    QToolButton,
    QWidget,
)

SPEEDS: tuple[float, ...] = (0.25, 0.5, 1.0, 2.0, 4.0)


class Timeline(QWidget):
    """Transport controls that emit ``frameChanged(int)``; a QTimer plays at fps × speed."""

    frameChanged = Signal(int)  # noqa: N815

    def __init__(self, parent: QWidget | None = None) -> None:
        super().__init__(parent)
        self._length = 1
        self._fps = 30.0
        self._speed = 1.0
        self.setFocusPolicy(Qt.FocusPolicy.StrongFocus)
        self._timer = QTimer(self)
        self._timer.setTimerType(Qt.TimerType.PreciseTimer)
        self._timer.timeout.connect(self._tick)

        self.play_button = QToolButton(toolTip="Play / pause (Space)")
        self._icons = {
            playing: self.style().standardIcon(
                QStyle.StandardPixmap.SP_MediaPause if playing else QStyle.StandardPixmap.SP_MediaPlay
            )
            for playing in (False, True)
        }
        self.play_button.setIcon(self._icons[False])
        self.play_button.setCheckable(True)
        self.play_button.toggled.connect(self._set_playing)
        self.slider = QSlider(Qt.Orientation.Horizontal)
        self.slider.setRange(0, 0)
        self.slider.valueChanged.connect(self._slider_moved)
        self.counter = QLabel()
        self.counter.setMinimumWidth(90)
        self.speed_box = QComboBox(toolTip="Playback speed")
        for speed in SPEEDS:
            self.speed_box.addItem(f"{speed:g}×", speed)
        self.speed_box.setCurrentIndex(SPEEDS.index(1.0))
        self.speed_box.currentIndexChanged.connect(lambda i: self.set_speed(SPEEDS[i]))
        self.loop_box = QCheckBox("Loop")
        self.loop_box.setChecked(True)

        self._layout = QHBoxLayout(self)
        self._layout.setContentsMargins(4, 2, 4, 2)
        for widget in (self.play_button, self.slider, self.counter, self.speed_box, self.loop_box):
            self._layout.addWidget(widget, 1 if widget is self.slider else 0)
        self.tool_buttons: list[QToolButton] = []

        context = Qt.ShortcutContext.WidgetWithChildrenShortcut
        for key, action in (
            (Qt.Key.Key_Space, self.toggle_play),
            (Qt.Key.Key_Left, lambda: self.step(-1)),
            (Qt.Key.Key_Right, lambda: self.step(1)),
            (Qt.Key.Key_Home, lambda: self.set_frame(0)),
            (Qt.Key.Key_End, lambda: self.set_frame(self._length - 1)),
        ):
            QShortcut(QKeySequence(key), self, action, context=context)
        self._update_counter()

    def set_length(self, n_frames: int, fps: float) -> None:
        """Set the clip length ``n_frames`` (T ≥ 1) and its frame rate; keeps the frame when it still fits."""
        if n_frames < 1 or fps <= 0:
            raise ValueError(f"need T >= 1 and fps > 0, got T={n_frames}, fps={fps}")
        self._length, self._fps = int(n_frames), float(fps)
        self.slider.setRange(0, self._length - 1)
        self._update_interval()
        self._update_counter()

    def add_tool_button(self, action: QAction) -> QToolButton:
        """A button after the transport controls that triggers ``action`` (and follows its text, tooltip and
        enabled state)."""
        button = QToolButton()
        button.setDefaultAction(action)
        button.setToolButtonStyle(Qt.ToolButtonStyle.ToolButtonTextOnly)
        self._layout.addWidget(button)
        self.tool_buttons.append(button)
        return button

    def frame(self) -> int:
        """The current frame index."""
        return self.slider.value()

    def set_frame(self, index: int) -> None:
        """Jump to frame ``index`` (clamped to the clip)."""
        self.slider.setValue(max(0, min(int(index), self._length - 1)))

    def step(self, delta: int) -> None:
        """Move ``delta`` frames (negative goes back) and pause."""
        self.pause()
        self.set_frame(self.frame() + delta)

    def play(self) -> None:
        """Start playback (from the start when at the last frame)."""
        self.play_button.setChecked(True)

    def pause(self) -> None:
        """Stop playback."""
        self.play_button.setChecked(False)

    def toggle_play(self) -> None:
        """Play when paused, pause when playing."""
        self.play_button.toggle()

    def is_playing(self) -> bool:
        """Whether playback is running."""
        return self._timer.isActive()

    def set_speed(self, speed: float) -> None:
        """Set the playback speed factor (0.25–4)."""
        if not SPEEDS[0] <= speed <= SPEEDS[-1]:
            raise ValueError(f"speed must lie in [{SPEEDS[0]}, {SPEEDS[-1]}], got {speed}")
        self._speed = float(speed)
        if speed in SPEEDS:
            self.speed_box.setCurrentIndex(SPEEDS.index(speed))
        self._update_interval()

    def set_loop(self, loop: bool) -> None:
        """Loop back to frame 0 at the end (else stop)."""
        self.loop_box.setChecked(loop)

    def interval_ms(self) -> int:
        """The playback timer interval in milliseconds."""
        return self._timer.interval()

    def _update_interval(self) -> None:
        self._timer.setInterval(max(1, round(1000.0 / (self._fps * self._speed))))

    def _set_playing(self, playing: bool) -> None:
        self.play_button.setIcon(self._icons[playing])
        if playing and self.frame() >= self._length - 1 and self._length > 1:
            self.set_frame(0)
        if playing:
            self._timer.start()
        else:
            self._timer.stop()

    def _tick(self) -> None:
        nxt = self.frame() + 1
        if nxt < self._length:
            self.set_frame(nxt)
        elif self.loop_box.isChecked():
            self.set_frame(0)
        else:
            self.pause()

    def _slider_moved(self, value: int) -> None:
        self._update_counter()
        self.frameChanged.emit(value)

    def _update_counter(self) -> None:
        self.counter.setText(f"{self.frame() + 1} / {self._length}  ({self.frame() / self._fps:.2f} s)")

    def closeEvent(self, event: QCloseEvent) -> None:  # noqa: N802
        """Stop playback when the widget closes."""
        self.pause()
        super().closeEvent(event)
