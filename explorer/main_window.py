"""The main window: the latent map in the centre, dockable panels around it, menus, toolbar, status bar.

The window assembles views and exposes their controls; it holds no state and calls no engine code
(the controller connects both sides). The 3-D viewport (VTK, the slow part of opening the window) is
created on first use of :attr:`MainWindow.viewport`; the app asks for it right after the map's first
paint (``mapPainted``).
"""

from __future__ import annotations

from typing import TYPE_CHECKING

from PySide6.QtCore import QByteArray, QEvent, QObject, QSettings, Qt, QTimer, Signal
from PySide6.QtGui import QCloseEvent
from PySide6.QtOpenGLWidgets import QOpenGLWidget
from PySide6.QtWidgets import (
    QDockWidget,
    QLabel,
    QMainWindow,
    QMessageBox,
    QProgressBar,
    QToolButton,
    QWidget,
)

from explorer.window_actions import build_menus, build_toolbar
from widgets.find_panel import FindPanel
from widgets.latent_map import LatentMap
from widgets.latent_tools import LatentToolsPanel
from widgets.mode_panel import ModePanel
from widgets.timeline import Timeline
from widgets.trajectory_canvas import TrajectoryCanvas

if TYPE_CHECKING:
    from widgets.viewport import SkeletonViewport

SETTINGS_GEOMETRY = "window/geometry"
SETTINGS_STATE = "window/state"
_LAYOUT_VERSION = 3  # 2: the Find panel; 3: the latent tools


class MainWindow(QMainWindow):
    """ODMO Explorer's window; its dock layout is saved to and restored from ``settings``.

    Signals: ``mapPainted()`` once, after the first paint of the map with points on it;
    ``viewportCreated()`` once the 3-D viewport exists.
    """

    mapPainted = Signal()  # noqa: N815
    viewportCreated = Signal()  # noqa: N815

    def __init__(self, settings: QSettings, parent: QWidget | None = None) -> None:
        super().__init__(parent)
        self.settings = settings
        self.setWindowTitle("ODMO Explorer")
        self.setObjectName("OdmoExplorer")
        self.setDockNestingEnabled(True)
        self.resize(1500, 900)

        self.latent_map = LatentMap()
        self._viewport: SkeletonViewport | None = None
        self._viewport_placeholder = QLabel("Opening the 3-D view…")
        self._viewport_placeholder.setAlignment(Qt.AlignCenter)
        # Qt re-creates (unmaps and maps) a shown window when its first QOpenGLWidget arrives, which blacks
        # the screen out for a moment when the 3-D view opens; one hidden from the start prevents that.
        self._opengl_from_start = QOpenGLWidget(self)
        self._opengl_from_start.hide()
        self.timeline = Timeline()
        self.mode_panel = ModePanel()
        self.trajectory = TrajectoryCanvas()
        self.find_panel = FindPanel()
        self.latent_panel = LatentToolsPanel()
        self.setCentralWidget(self.latent_map)

        self.viewport_dock = self._dock(
            "Motion (3D)", "dock_viewport", self._viewport_placeholder, Qt.RightDockWidgetArea
        )
        self.timeline_dock = self._dock("Timeline", "dock_timeline", self.timeline, Qt.BottomDockWidgetArea)
        self.mode_dock = self._dock("Modes", "dock_modes", self.mode_panel, Qt.LeftDockWidgetArea)
        self.trajectory_dock = self._dock(
            "Trajectory (top view)", "dock_trajectory", self.trajectory, Qt.LeftDockWidgetArea
        )
        self.find_dock = self._dock("Find", "dock_find", self.find_panel, Qt.LeftDockWidgetArea)
        self.latent_dock = self._dock("Latent tools", "dock_latent", self.latent_panel, Qt.LeftDockWidgetArea)
        self.splitDockWidget(self.mode_dock, self.trajectory_dock, Qt.Vertical)
        self.tabifyDockWidget(self.mode_dock, self.find_dock)
        self.tabifyDockWidget(self.trajectory_dock, self.latent_dock)
        self.trajectory_dock.raise_()
        self.mode_dock.raise_()
        self.resizeDocks([self.viewport_dock], [560], Qt.Horizontal)
        self.resizeDocks([self.mode_dock], [330], Qt.Horizontal)
        self.resizeDocks([self.timeline_dock], [40], Qt.Vertical)

        build_toolbar(self)
        build_menus(self)
        for action in (self.complete_action, self.continue_action, self.keep_going_action):
            self.timeline.add_tool_button(action)
        self._build_status_bar()
        self._default_state = self.saveState(_LAYOUT_VERSION)
        self.restore_layout()
        self._paint_watch = _FirstPaint(self)
        self.latent_map.plot.viewport().installEventFilter(self._paint_watch)

    @property
    def viewport(self) -> SkeletonViewport:
        """The 3-D viewport, created (VTK loaded) on first use."""
        if self._viewport is None:
            from widgets.viewport import SkeletonViewport

            self._viewport = SkeletonViewport()
            self._viewport.setMinimumSize(240, 200)
            self.viewport_dock.setWidget(self._viewport)
            self._viewport_placeholder.deleteLater()
            self.viewportCreated.emit()
        return self._viewport

    def docks(self) -> tuple[QDockWidget, ...]:
        """Every dock panel of the window."""
        return (
            self.viewport_dock,
            self.timeline_dock,
            self.mode_dock,
            self.find_dock,
            self.trajectory_dock,
            self.latent_dock,
        )

    def has_viewport(self) -> bool:
        """True once the 3-D viewport exists."""
        return self._viewport is not None

    # -- construction ---------------------------------------------------------------------------------

    def _dock(self, title: str, name: str, widget: QWidget, area: Qt.DockWidgetArea) -> QDockWidget:
        dock = QDockWidget(title, self)
        dock.setObjectName(name)
        dock.setWidget(widget)
        if area != Qt.BottomDockWidgetArea:  # a shrunken window cannot squeeze a panel to a sliver
            widget.setMinimumSize(160, 120)
        dock.setFeatures(
            QDockWidget.DockWidgetMovable | QDockWidget.DockWidgetFloatable | QDockWidget.DockWidgetClosable
        )
        self.addDockWidget(area, dock)
        return dock

    def _build_status_bar(self) -> None:
        status = self.statusBar()
        self.status_label = QLabel("No model loaded.")
        self.status_label.setTextInteractionFlags(Qt.TextSelectableByMouse)
        status.addWidget(self.status_label, 1)
        self.hover_label = QLabel()
        self.hover_label.setObjectName("hover_label")
        status.addPermanentWidget(self.hover_label)
        self.progress_bar = QProgressBar()
        self.progress_bar.setMinimumWidth(320)
        self.progress_bar.setMaximumWidth(420)
        self.progress_bar.setRange(0, 1000)
        self.progress_bar.setTextVisible(True)
        self.progress_bar.hide()
        status.addPermanentWidget(self.progress_bar)
        self.cancel_button = QToolButton()
        self.cancel_button.setText("Cancel")
        self.cancel_button.hide()
        status.addPermanentWidget(self.cancel_button)

    # -- feedback ------------------------------------------------------------------------------------

    def show_status(self, text: str) -> None:
        """Show ``text`` (what was decoded, what is hovered) in the status bar."""
        self.status_label.setText(text)

    def show_hover(self, text: str) -> None:
        """Show what the mouse is over, beside the status text (which it does not replace)."""
        self.hover_label.setText(text)

    def show_progress(self, text: str, fraction: float | None) -> None:
        """Show a running task's progress (``fraction`` None: indeterminate)."""
        self.progress_bar.show()
        self.cancel_button.show()
        if fraction is None:
            self.progress_bar.setRange(0, 0)
        else:
            self.progress_bar.setRange(0, 1000)
            self.progress_bar.setValue(int(max(0.0, min(1.0, fraction)) * 1000))
        metrics = self.progress_bar.fontMetrics()
        room = max(self.progress_bar.width() - metrics.horizontalAdvance(" 100%") - 12, 40)
        short = metrics.elidedText(text, Qt.TextElideMode.ElideRight, room)
        self.progress_bar.setFormat(f"{short} %p%" if fraction is not None else short)
        self.progress_bar.setToolTip(text)

    def hide_progress(self) -> None:
        """Hide the progress bar and the Cancel button."""
        self.progress_bar.hide()
        self.cancel_button.hide()

    def show_error(self, title: str, text: str) -> None:
        """Tell the user that something failed (non-blocking message box); the app keeps running."""
        self.show_status(f"Error: {text}")
        box = QMessageBox(QMessageBox.Warning, title, text, QMessageBox.Ok, self)
        box.setAttribute(Qt.WA_DeleteOnClose)
        box.setObjectName("error_box")
        box.open()

    # -- layout persistence --------------------------------------------------------------------------

    def restore_layout(self) -> None:
        """Restore geometry and dock layout saved by a previous run, if any."""
        geometry = self.settings.value(SETTINGS_GEOMETRY)
        state = self.settings.value(SETTINGS_STATE)
        if isinstance(geometry, QByteArray):
            self.restoreGeometry(geometry)
        if isinstance(state, QByteArray):
            self.restoreState(state, _LAYOUT_VERSION)

    def save_layout(self) -> None:
        """Remember geometry and dock layout for the next run."""
        self.settings.setValue(SETTINGS_GEOMETRY, self.saveGeometry())
        self.settings.setValue(SETTINGS_STATE, self.saveState(_LAYOUT_VERSION))
        self.settings.sync()

    def reset_layout(self) -> None:
        """Put every panel back where it starts."""
        self.restoreState(self._default_state, _LAYOUT_VERSION)
        for dock in self.docks():
            dock.show()

    def closeEvent(self, event: QCloseEvent) -> None:  # noqa: N802
        """Save the layout, then close."""
        self.save_layout()
        super().closeEvent(event)


class _FirstPaint(QObject):
    """Event filter on the map's viewport: emits the window's ``mapPainted`` after the first paint with
    points drawn, then removes itself."""

    def __init__(self, window: MainWindow) -> None:
        super().__init__(window)
        self._window = window

    def eventFilter(self, watched: QObject, event: QEvent) -> bool:  # noqa: N802
        """Let the paint happen; once points were painted, report it from the next event-loop pass."""
        if event.type() == QEvent.Type.Paint and len(self._window.latent_map.visible_rows()):
            watched.removeEventFilter(self)
            QTimer.singleShot(0, self._window.mapPainted.emit)
        return False
