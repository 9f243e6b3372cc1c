"""TrajectoryCanvas: a top-down x/z floor view to request an end location or draw a path."""

from __future__ import annotations

from collections.abc import Sequence
from typing import Literal

import numpy as np
import pyqtgraph as pg
from PySide6.QtCore import QPointF, Qt, Signal
from PySide6.QtWidgets import QButtonGroup, QHBoxLayout, QPushButton, QToolButton, QVBoxLayout, QWidget

from widgets._colors import FOREGROUND, GENERATED, GRID, REQUEST, configure_plot
from widgets.latent_map import GestureViewBox, PassiveScatter

Tool = Literal["end", "draw"]


class TrajectoryCanvas(QWidget):
    """Top-down floor view (x right, z down, metres): click for an end location, drag to draw a path.

    A drawn path emits ``pathDrawn`` then ``endRequested`` with its last point.
    """

    endRequested = Signal(float, float)  # noqa: N815
    pathDrawn = Signal(object)  # noqa: N815
    followPathRequested = Signal(object)  # noqa: N815

    def __init__(self, parent: QWidget | None = None, *, extent_m: float = 4.0) -> None:
        super().__init__(parent)
        self._tool: Tool = "end"
        self._stroke: list[tuple[float, float]] = []
        self._path: np.ndarray | None = None

        self.view_box = GestureViewBox(self._handle_click, self._handle_drag, lambda ev: None)
        self.view_box.setAspectLocked(True)
        self.view_box.invertY(True)
        self.plot = pg.PlotWidget(viewBox=self.view_box)
        configure_plot(self.plot)
        self.plot.showGrid(x=True, y=True, alpha=0.25)
        self.plot.getPlotItem().setLabel("bottom", "x (m)")
        self.plot.getPlotItem().setLabel("left", "z (m)")
        self.view_box.setRange(xRange=(-extent_m, extent_m), yRange=(-extent_m, extent_m), padding=0)

        self._origin = PassiveScatter(x=[0.0], y=[0.0], size=10, symbol="+", pen=pg.mkPen(GRID, width=2))
        self._request_curve = pg.PlotCurveItem(pen=pg.mkPen(REQUEST, width=2, style=Qt.PenStyle.DashLine))
        self._generated_curve = pg.PlotCurveItem(pen=pg.mkPen(GENERATED, width=2))
        self._end = PassiveScatter(size=14, symbol="o", brush=REQUEST, pen=pg.mkPen("w"))
        self._error_text = pg.TextItem(color=FOREGROUND, anchor=(0, 0))
        self._error_text.setParentItem(self.view_box)
        self._error_text.setPos(8, 8)
        for z, item in enumerate((self._origin, self._request_curve, self._generated_curve, self._end)):
            item.setZValue(10 + z)
            self.view_box.addItem(item)

        self._tool_group = QButtonGroup(self)
        tools = QHBoxLayout()
        for name, label, tip in (
            ("end", "End", "Click to set the end location"),
            ("draw", "Draw", "Press, drag and release to draw a path"),
        ):
            button = QToolButton(text=label, checkable=True, toolTip=tip)
            button.setObjectName(f"tool_{name}")
            button.setChecked(name == self._tool)
            button.toggled.connect(lambda on, n=name: on and self.set_tool(n))
            self._tool_group.addButton(button)
            tools.addWidget(button)
        tools.addStretch(1)
        self.follow_button = QPushButton("Follow path")
        self.follow_button.setEnabled(False)
        self.follow_button.clicked.connect(self._request_follow)
        tools.addWidget(self.follow_button)

        layout = QVBoxLayout(self)
        layout.setContentsMargins(0, 0, 0, 0)
        layout.addLayout(tools)
        layout.addWidget(self.plot, 1)

    def set_tool(self, tool: Tool) -> None:
        """Switch the mouse tool: "end" (click) or "draw" (drag a path)."""
        if tool not in ("end", "draw"):
            raise ValueError(f"unknown tool {tool!r}; expected 'end' or 'draw'")
        self._tool = tool
        for button in self._tool_group.buttons():
            button.setChecked(button.objectName() == f"tool_{tool}")

    def tool(self) -> Tool:
        """The current mouse tool."""
        return self._tool

    def set_request(self, request: np.ndarray | Sequence[float] | None) -> None:
        """Show the request: an end location (2,) x/z, a path (K, 2), or nothing (None)."""
        self._path = None
        if request is None:
            self._request_curve.setData([], [])
            self._end.setData(x=[], y=[])
        else:
            arr = np.asarray(request, dtype=np.float64)
            if arr.shape == (2,):
                self._request_curve.setData([], [])
                self._end.setData(x=[arr[0]], y=[arr[1]])
            elif arr.ndim == 2 and arr.shape[1] == 2 and len(arr) >= 2:
                self._path = arr
                self._request_curve.setData(arr[:, 0], arr[:, 1])
                self._end.setData(x=[arr[-1, 0]], y=[arr[-1, 1]])
            else:
                raise ValueError(f"a request is an end (2,) or a path (K>=2, 2), got shape {arr.shape}")
        self.follow_button.setEnabled(self._path is not None)

    def set_generated(self, traj_xz: np.ndarray | None, error_m: float | None = None) -> None:
        """Draw the generated root path ``traj_xz`` (T, 2) over the request, with its error in metres."""
        if traj_xz is None:
            self._generated_curve.setData([], [])
        else:
            pts = np.asarray(traj_xz, dtype=np.float64).reshape(-1, 2)
            self._generated_curve.setData(pts[:, 0], pts[:, 1])
        self._error_text.setText("" if error_m is None else f"error {error_m:.3f} m")

    def generated_path(self) -> np.ndarray:
        """(T, 2) generated root path as drawn (empty when none)."""
        x, y = self._generated_curve.getData()
        if x is None:
            return np.zeros((0, 2))
        return np.stack([np.asarray(x, float), np.asarray(y, float)], axis=1)

    def error_text(self) -> str:
        """The error label as shown."""
        return self._error_text.toPlainText()

    def data_to_widget(self, xz: Sequence[float]) -> QPointF:
        """Position of floor point ``xz`` in the plot viewport's pixel coordinates."""
        scene = self.view_box.mapViewToScene(QPointF(float(xz[0]), float(xz[1])))
        return QPointF(self.plot.mapFromScene(scene))

    def _handle_click(self, ev: object) -> bool:
        if ev.button() != Qt.MouseButton.LeftButton:  # type: ignore[attr-defined]
            return False
        ev.accept()  # type: ignore[attr-defined]
        pos = self.view_box.mapSceneToView(ev.scenePos())  # type: ignore[attr-defined]
        end = np.array([pos.x(), pos.y()])
        self.set_request(end)
        self.endRequested.emit(float(end[0]), float(end[1]))
        return True

    def _handle_drag(self, ev: object) -> bool:
        if ev.button() != Qt.MouseButton.LeftButton or self._tool != "draw":  # type: ignore[attr-defined]
            return False
        ev.accept()  # type: ignore[attr-defined]
        if ev.isStart():  # type: ignore[attr-defined]
            start = self.view_box.mapSceneToView(ev.buttonDownScenePos())  # type: ignore[attr-defined]
            self._stroke = [(start.x(), start.y())]
        pos = self.view_box.mapSceneToView(ev.scenePos())  # type: ignore[attr-defined]
        if (pos.x(), pos.y()) != self._stroke[-1]:
            self._stroke.append((pos.x(), pos.y()))
        stroke = np.asarray(self._stroke, dtype=np.float64)
        self._request_curve.setData(stroke[:, 0], stroke[:, 1])
        if ev.isFinish():  # type: ignore[attr-defined]
            self._stroke = []
            if len(stroke) < 2:
                self.set_request(None)
                return True
            self.set_request(stroke)
            self.pathDrawn.emit(stroke)
            self.endRequested.emit(float(stroke[-1, 0]), float(stroke[-1, 1]))
        return True

    def _request_follow(self) -> None:
        if self._path is not None:
            self.followPathRequested.emit(self._path.copy())
