"""LatentMap: a 2-D map of latent codes with picking, dragging, lasso, overlays and a legend.

The codes are drawn as one image rasterised with numpy (``widgets._raster``): discs when few lie in the
rendered region, a density image when many do. Pan and zoom move that image; once the view leaves its
margin or the zoom changes its pixel size by more than ``RERENDER_ZOOM`` it is rendered again on a worker
thread, the old image staying until the new one is ready. New points, colours or masks render at once.
Picking goes through a k-d tree built on that thread once per ``set_points``.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from concurrent.futures import Future, ThreadPoolExecutor
from functools import partial
from typing import Literal

import numpy as np
import pyqtgraph as pg
from PySide6.QtCore import QEvent, QObject, QPointF, QRectF, Qt, QTimer, Signal
from PySide6.QtGui import QImage, QPixmap
from PySide6.QtWidgets import (
    QButtonGroup,
    QCheckBox,
    QHBoxLayout,
    QLabel,
    QScrollArea,
    QToolButton,
    QToolTip,
    QVBoxLayout,
    QWidget,
)
from scipy.spatial import cKDTree

from widgets._colors import FOREGROUND, SELECTION, brushes_for, configure_plot, qcolor, to_rgba8
from widgets._raster import Grid, render, rings

Tool = Literal["pick", "lasso"]
Tooltips = Sequence[str] | Callable[[int], str]

MARGIN = 0.25  # the image covers the view and this fraction of its size on every side
RERENDER_ZOOM = 1.5  # render again once the pixel size differs from the image's by this factor
MAX_SIDE = 8192  # pixels: a cap on the image for odd view sizes


class PassiveScatter(pg.ScatterPlotItem):
    """A scatter item that lets clicks through to the view box (which does its own picking)."""

    def mouseClickEvent(self, ev: object) -> None:  # noqa: N802
        """Ignore the click so the view box receives it."""
        ev.ignore()  # type: ignore[attr-defined]


class PointsImage(pg.ImageItem):
    """The map's points as one image in data coordinates; auto-range frames the points, not the image."""

    def __init__(self) -> None:
        super().__init__(axisOrder="row-major")
        self.bounds: tuple[tuple[float, float], tuple[float, float]] | None = None
        self.padding_px = 0.0

    def dataBounds(self, ax: int, frac: float = 1.0, orthoRange: object = None) -> tuple[float, float] | None:  # noqa: N802
        """The (min, max) along axis ``ax`` of the shown points in the image's coordinates (None: none)."""
        if self.bounds is None:
            return None
        (x0, x1), (y0, y1) = self.bounds
        rect = self.transform().inverted()[0].mapRect(QRectF(x0, y0, x1 - x0, y1 - y0))
        return (rect.left(), rect.right()) if ax == 0 else (rect.top(), rect.bottom())

    def pixelPadding(self) -> float:  # noqa: N802
        """Pixels beyond the points' centres that auto-range keeps in view."""
        return self.padding_px

    def mouseClickEvent(self, ev: object) -> None:  # noqa: N802
        """Ignore the click so the view box receives it."""
        ev.ignore()  # type: ignore[attr-defined]


class GestureViewBox(pg.ViewBox):
    """A view box that hands clicks, drags and hovers to callbacks before its default pan/zoom."""

    def __init__(
        self,
        on_click: Callable[[object], bool],
        on_drag: Callable[[object], bool],
        on_hover: Callable[[object], None],
    ) -> None:
        super().__init__()
        self._on_click = on_click
        self._on_drag = on_drag
        self._on_hover = on_hover

    def mouseClickEvent(self, ev: object) -> None:  # noqa: N802
        """Forward the click; fall back to the default (context menu) when unhandled."""
        if not self._on_click(ev):
            super().mouseClickEvent(ev)

    def mouseDragEvent(self, ev: object, axis: int | None = None) -> None:  # noqa: N802
        """Forward the drag; fall back to the default pan when unhandled."""
        if not self._on_drag(ev):
            super().mouseDragEvent(ev, axis)

    def hoverEvent(self, ev: object) -> None:  # noqa: N802
        """Forward the hover."""
        self._on_hover(ev)


class _FileDrops(QObject):
    """Event filter on the plot's viewport: accepts dragged local files and reports their paths."""

    def __init__(self, on_drop: Callable[[list[str]], None], parent: QObject) -> None:
        super().__init__(parent)
        self._on_drop = on_drop

    def eventFilter(self, watched: QObject, event: QEvent) -> bool:  # noqa: N802
        """Accept drags that carry local files; on drop hand their paths over."""
        kind = event.type()
        if kind in (QEvent.Type.DragEnter, QEvent.Type.DragMove, QEvent.Type.Drop):
            urls = (
                [u for u in event.mimeData().urls() if u.isLocalFile()] if event.mimeData().hasUrls() else []
            )
            if not urls:
                return False
            event.acceptProposedAction()
            if kind == QEvent.Type.Drop:
                self._on_drop([u.toLocalFile() for u in urls])
            return True
        return False


class LatentMap(QWidget):
    """A 2-D map of points (one rasterised image) that reports clicks, drags, lassos and hovers.

    Point positions passed to ``set_visible_mask`` / ``set_selection`` are row indices into the
    arrays given to ``set_points``; signals report the per-point ``ids``. More than ``density_above``
    shown points in the rendered region are drawn as a density image instead of discs; more than
    ``rings_above`` selected points are ringed in an image (where rings overlap, the group's outline)
    instead of by a scatter item.
    """

    pointClicked = Signal(int)  # noqa: N815
    emptyClicked = Signal(float, float)  # noqa: N815
    dragStarted = Signal(int)  # noqa: N815
    dragMoved = Signal(float, float)  # noqa: N815
    dragFinished = Signal(float, float)  # noqa: N815
    lassoFinished = Signal(object)  # noqa: N815
    hovered = Signal(int)
    legendToggled = Signal(int, bool)  # noqa: N815
    filesDropped = Signal(list)  # noqa: N815
    extraClicked = Signal(int)  # noqa: N815

    def __init__(
        self,
        parent: QWidget | None = None,
        *,
        point_size: float = 6.0,
        pick_tolerance_px: float = 8.0,
        density_above: int = 50_000,
        rings_above: int = 2000,
    ) -> None:
        super().__init__(parent)
        self._tolerance_px = float(pick_tolerance_px)
        self._point_size = float(point_size)
        self._density_above = int(density_above)
        self._rings_above = int(rings_above)
        ring = (point_size + 8) / 2  # the selection ring's radius, 2 px wide
        self._ring_radii = (ring - 1, ring + 1)
        self._ring_rows: np.ndarray | None = None  # selected rows ringed in the image, when many
        self._tool: Tool = "pick"
        self._xy = np.zeros((0, 2))
        self._ids = np.zeros(0, dtype=np.int64)
        self._rgba = np.zeros((0, 4), dtype=np.uint8)
        self._tree: Future[cKDTree] | None = None  # built on the worker thread
        self._tooltips: Tooltips = []
        self._mask = np.zeros(0, dtype=bool)
        self._visible = np.zeros(0, dtype=bool)
        self._grid: Grid | None = None  # where the image was rendered
        self._generation = 0  # counts the data changes: a background render of older data is dropped
        self._worker: ThreadPoolExecutor | None = None  # renders views and builds the k-d tree
        self._pending: tuple[int, Grid, Future[tuple[np.ndarray, np.ndarray | None]]] | None = None
        self._groups: np.ndarray | None = None
        self._hidden_groups: set[int] = set()
        self._shown = np.zeros(0, dtype=np.int64)
        self._selection = np.zeros(0, dtype=np.int64)
        self._hover_row = -1
        self._dragging = False
        self._lasso: list[tuple[float, float]] = []

        self.view_box = GestureViewBox(self._handle_click, self._handle_drag, self._handle_hover)
        self.plot = pg.PlotWidget(viewBox=self.view_box)
        configure_plot(self.plot)
        self.plot.viewport().setAcceptDrops(True)
        self._drops = _FileDrops(self.filesDropped.emit, self)
        self.plot.viewport().installEventFilter(self._drops)
        self.view_box.setAspectLocked(True)  # one map unit is as long across as up
        self.points_image = PointsImage()
        self.points_image.padding_px = (self._point_size + 1) * 0.7072  # as a scatter of such discs pads
        self._rings_image = PointsImage()
        self._rings_image.setZValue(10.5)
        self.view_box.addItem(self._rings_image)
        self._render_timer = QTimer(self, singleShot=True, interval=0)
        self._render_timer.timeout.connect(self._render_in_background)
        self._collect_timer = QTimer(self, interval=4)
        self._collect_timer.timeout.connect(self._collect)
        self.view_box.sigRangeChanged.connect(self._view_changed)
        self.view_box.sigResized.connect(self._view_changed)
        self._highlight = PassiveScatter(
            pxMode=True, size=point_size + 8, pen=pg.mkPen(SELECTION, width=2), brush=None, symbol="o"
        )
        self._extra = PassiveScatter(pxMode=True, size=point_size + 5, pen=pg.mkPen("w"), symbol="d")
        self._marker = PassiveScatter(pxMode=True, size=20, pen=pg.mkPen("k"), brush=SELECTION, symbol="star")
        self._lasso_curve = pg.PlotCurveItem(pen=pg.mkPen(SELECTION, width=1.5, style=Qt.PenStyle.DashLine))
        self._overlays: list[pg.PlotCurveItem] = []
        self._paths: list[pg.PlotCurveItem] = []
        self._halos: list[pg.PlotCurveItem] = []
        layers = (self.points_image, self._highlight, self._extra, self._marker, self._lasso_curve)
        for z, item in enumerate(layers):
            item.setZValue(10 + z)
            self.view_box.addItem(item)

        self._legend_box = QWidget()
        self._legend_layout = QVBoxLayout(self._legend_box)
        self._legend_layout.setContentsMargins(4, 4, 4, 4)
        self._legend_checks: list[QCheckBox] = []
        legend_scroll = QScrollArea()
        legend_scroll.setWidgetResizable(True)
        legend_scroll.setWidget(self._legend_box)
        legend_scroll.setMaximumWidth(200)
        self._legend_scroll = legend_scroll
        legend_scroll.hide()
        self.key_label = QLabel()  # what the colours mean when they are not the actions
        self.key_label.setObjectName("colour_key")
        self.key_label.setTextFormat(Qt.TextFormat.RichText)
        self.key_label.setWordWrap(True)
        self.key_label.setMaximumWidth(200)
        self.key_label.hide()
        side = QVBoxLayout()
        side.addWidget(self.key_label)
        side.addWidget(legend_scroll, 1)

        self._tool_group = QButtonGroup(self)
        tools = QHBoxLayout()
        for name, tip in (("pick", "Click a point, drag from a point"), ("lasso", "Draw a lasso to select")):
            button = QToolButton(text=name.capitalize(), checkable=True, toolTip=tip)
            button.setObjectName(f"tool_{name}")
            button.setChecked(name == self._tool)
            button.toggled.connect(lambda on, n=name: on and self.set_tool(n))
            self._tool_group.addButton(button)
            tools.addWidget(button)
        tools.addStretch(1)

        body = QHBoxLayout()
        body.addWidget(self.plot, 1)
        body.addLayout(side)
        layout = QVBoxLayout(self)
        layout.setContentsMargins(0, 0, 0, 0)
        layout.addLayout(tools)
        layout.addLayout(body, 1)

    # ----- data ---------------------------------------------------------------------------------
    def set_points(
        self, xy: np.ndarray, colors: np.ndarray, ids: np.ndarray, tooltips: Tooltips | None = None
    ) -> None:
        """Show points ``xy`` (N, 2) coloured by ``colors`` (N, 3|4) and identified by ``ids`` (N,) int.

        ``tooltips`` are N hover texts, or a function of the row giving its text (no list of N strings
        to build for a large map).
        """
        xy = np.asarray(xy, dtype=np.float64)
        if xy.ndim != 2 or xy.shape[1] != 2:
            raise ValueError(f"xy must have shape (N, 2), got {xy.shape}")
        n = len(xy)
        ids = np.asarray(ids, dtype=np.int64).reshape(-1)
        if ids.shape != (n,):
            raise ValueError(f"ids must have shape ({n},), got {ids.shape}")
        if tooltips is None:
            tooltips = [""] * n
        elif not callable(tooltips) and len(tooltips) != n:
            raise ValueError(f"expected {n} tooltips, got {len(tooltips)}")
        self._rgba = to_rgba8(colors, n)
        self._xy, self._ids, self._tooltips = xy, ids, tooltips
        # an unbalanced tree builds in half the time and answers a pick as fast; a pick waits for it
        self._tree = self._background(cKDTree, xy, balanced_tree=False, compact_nodes=False) if n else None
        self._mask = np.ones(n, dtype=bool)
        self._groups = None
        self._hidden_groups.clear()
        self._selection = np.zeros(0, dtype=np.int64)
        self._hover_row = -1
        self._update_shown()
        self.view_box.autoRange(items=[self.points_image])  # frame the points, not stale overlays
        self._render()

    def set_colors(self, colors: np.ndarray) -> None:
        """Recolour the points with ``colors`` (N, 3|4), keeping the view, the mask and the selection."""
        self._rgba = to_rgba8(colors, len(self._xy))
        self._render()

    def set_visible_mask(self, mask: np.ndarray) -> None:
        """Show only the points where ``mask`` (N,) bool is true."""
        mask = np.asarray(mask, dtype=bool).reshape(-1)
        if mask.shape != self._mask.shape:
            raise ValueError(f"mask must have shape {self._mask.shape}, got {mask.shape}")
        self._mask = mask
        self._refresh_points()

    def set_selection(self, indices: Sequence[int] | np.ndarray) -> None:
        """Highlight the points at row ``indices``."""
        rows = np.asarray(indices, dtype=np.int64).reshape(-1)
        if rows.size and (rows.min() < 0 or rows.max() >= len(self._xy)):
            raise ValueError(f"selection indices must lie in [0, {len(self._xy)})")
        self._selection = rows
        self._generation += 1  # a background render of the old rings is not shown
        self._refresh_selection()
        self._draw_rings()

    def set_marker(self, xy: Sequence[float] | np.ndarray | None) -> None:
        """Mark one position (a decoded point), or remove the marker with None."""
        if xy is None:
            self._marker.setData(x=[], y=[])
            return
        x, y = np.asarray(xy, dtype=np.float64).reshape(2)
        self._marker.setData(x=[x], y=[y])

    def set_extra_points(self, xy: np.ndarray | None, colors: np.ndarray | None = None) -> None:
        """Show extra points ``xy`` (K, 2) (e.g. samples) with ``colors`` (K, 3|4); None clears them."""
        if xy is None or len(xy) == 0:
            self._extra.setData(x=[], y=[])
            return
        pts = np.asarray(xy, dtype=np.float64).reshape(-1, 2)
        rgba = to_rgba8(colors, len(pts)) if colors is not None else np.full((len(pts), 4), 255, np.uint8)
        self._extra.setData(x=pts[:, 0], y=pts[:, 1], brush=brushes_for(rgba))

    def set_overlays(self, curves: Sequence[np.ndarray], colors: Sequence[object] | None = None) -> None:
        """Draw closed polylines ``curves`` (each (M, 2)), e.g. mode ellipses or hulls, in ``colors``."""
        for item in self._overlays + self._halos:
            self.view_box.removeItem(item)
        self._overlays, self._halos = [], []
        for i, curve in enumerate(curves):
            pts = np.asarray(curve, dtype=np.float64).reshape(-1, 2)
            closed = np.vstack([pts, pts[:1]])
            color = colors[i] if colors is not None else FOREGROUND
            # a dark halo under the coloured line keeps it visible on points of the same colour
            halo = pg.PlotCurveItem(closed[:, 0], closed[:, 1], pen=pg.mkPen("#000000", width=5))
            item = pg.PlotCurveItem(closed[:, 0], closed[:, 1], pen=pg.mkPen(qcolor(color), width=2))
            halo.setZValue(4.5)
            item.setZValue(5)
            self.view_box.addItem(halo)
            self.view_box.addItem(item)
            self._halos.append(halo)
            self._overlays.append(item)

    def set_paths(self, curves: Sequence[np.ndarray], colors: Sequence[object] | None = None) -> None:
        """Draw open polylines ``curves`` (each (M, 2)), e.g. a long clip's windows in order; [] clears."""
        for item in self._paths:
            self.view_box.removeItem(item)
        self._paths = []
        for i, curve in enumerate(curves):
            pts = np.asarray(curve, dtype=np.float64).reshape(-1, 2)
            color = colors[i] if colors is not None else SELECTION
            item = pg.PlotCurveItem(pts[:, 0], pts[:, 1], pen=pg.mkPen(qcolor(color), width=1.5))
            item.setZValue(11.5)
            self.view_box.addItem(item)
            self._paths.append(item)

    def paths(self) -> list[np.ndarray]:
        """The polylines drawn by ``set_paths``, each (M, 2)."""
        return [np.stack([np.asarray(a) for a in item.getData()], axis=1) for item in self._paths]

    def point_colors(self) -> np.ndarray:
        """(N, 4) uint8 RGBA of the points as drawn (before hover, selection or hiding)."""
        return self._rgba.copy()

    def extra_points(self) -> np.ndarray:
        """(K, 2) positions of the extra points drawn."""
        x, y = self._extra.getData()
        return (
            np.stack([np.asarray(x, float), np.asarray(y, float)], axis=1)
            if x is not None
            else np.zeros((0, 2))
        )

    def render_plot(self, width: int | None = None) -> QImage:
        """The plot alone (points, overlays, axes with their names; no tool buttons, legend or key) as an
        image ``width`` pixels wide (default: its size on screen), height in proportion."""
        from pyqtgraph.exporters import ImageExporter

        if self.rendering():
            self._render()
        exporter = ImageExporter(self.plot.getPlotItem())
        if width is not None:
            exporter.parameters()["width"] = int(width)
        return exporter.export(toBytes=True)

    def set_axis_names(self, x: str, y: str) -> None:
        """Name the map's axes (e.g. "PCA 1", "PCA 2")."""
        item = self.plot.getPlotItem()
        item.setLabel("bottom", x)
        item.setLabel("left", y)

    def axis_names(self) -> tuple[str, str]:
        """The axis names shown."""
        item = self.plot.getPlotItem()
        return item.getAxis("bottom").labelText, item.getAxis("left").labelText

    def set_legend(
        self, names: Sequence[str], colors: Sequence[object], groups: np.ndarray | None = None
    ) -> None:
        """Show a legend with checkboxes; given ``groups`` (N,) int, unchecking entry k hides group k."""
        for check in self._legend_checks:
            self._legend_layout.removeWidget(check)
            check.deleteLater()
        self._legend_checks = []
        while self._legend_layout.count():
            self._legend_layout.takeAt(0)
        if groups is not None:
            groups = np.asarray(groups, dtype=np.int64).reshape(-1)
            if groups.shape != self._xy[:, 0].shape:
                raise ValueError(f"groups must have shape ({len(self._xy)},), got {groups.shape}")
        self._groups = groups
        self._hidden_groups.clear()
        for i, (name, color) in enumerate(zip(names, colors, strict=True)):
            check = QCheckBox(name)
            check.setChecked(True)
            pixmap = QPixmap(12, 12)
            pixmap.fill(qcolor(color))
            check.setIcon(pixmap)
            check.toggled.connect(lambda on, k=i: self._legend_toggled(k, on))
            self._legend_layout.addWidget(check)
            self._legend_checks.append(check)
        self._legend_layout.addStretch(1)
        self._legend_scroll.setVisible(bool(self._legend_checks))
        self._refresh_points()

    def set_key(self, title: str, names: Sequence[str], colors: Sequence[object]) -> None:
        """Show a colour key (``title``, one swatch per name) above the legend; an empty title hides it."""
        if not title:
            self.key_label.clear()
            self.key_label.hide()
            return
        rows = [f"<b>{title}</b>"]
        for name, color in zip(names, colors, strict=True):
            rows.append(f'<span style="color:{qcolor(color).name()}">&#9632;</span> {name}')
        self.key_label.setText("<br>".join(rows))
        self.key_label.show()

    def key_text(self) -> str:
        """The colour key as plain text ("" when hidden)."""
        if self.key_label.isHidden():
            return ""
        from PySide6.QtGui import QTextDocument

        doc = QTextDocument()
        doc.setHtml(self.key_label.text())
        return doc.toPlainText()

    def legend_checkbox(self, index: int) -> QCheckBox:
        """The legend checkbox of entry ``index``."""
        return self._legend_checks[index]

    def set_tool(self, tool: Tool) -> None:
        """Switch the mouse tool: "pick" (click / drag from a point) or "lasso"."""
        if tool not in ("pick", "lasso"):
            raise ValueError(f"unknown tool {tool!r}; expected 'pick' or 'lasso'")
        self._tool = tool
        for button in self._tool_group.buttons():
            button.setChecked(button.objectName() == f"tool_{tool}")

    def tool(self) -> Tool:
        """The current mouse tool."""
        return self._tool

    def rendering(self) -> bool:
        """Whether the image of the points is being rendered again for the current view."""
        return self._render_timer.isActive() or self._pending is not None or self._stale()

    def visible_rows(self) -> np.ndarray:
        """Row indices of the points currently drawn, (V,) int."""
        return self._shown.copy()

    def data_to_widget(self, xy: Sequence[float]) -> QPointF:
        """Position of data point ``xy`` in the plot viewport's pixel coordinates."""
        scene = self.view_box.mapViewToScene(QPointF(float(xy[0]), float(xy[1])))
        return QPointF(self.plot.mapFromScene(scene))

    # ----- internals ----------------------------------------------------------------------------
    def _legend_toggled(self, index: int, on: bool) -> None:
        if on:
            self._hidden_groups.discard(index)
        else:
            self._hidden_groups.add(index)
        self._refresh_points()
        self.legendToggled.emit(index, on)

    def _refresh_points(self) -> None:
        self._update_shown()
        self._render()

    def _update_shown(self) -> None:
        """Which rows are shown (mask and legend), their bounds, and the selection ring."""
        visible = self._mask
        if self._groups is not None and self._hidden_groups:
            visible = visible & ~np.isin(self._groups, list(self._hidden_groups))
        self._visible = visible
        self._shown = np.flatnonzero(visible)
        self.points_image.bounds = (
            tuple(
                (
                    float(np.min(v, where=visible, initial=np.inf)),
                    float(np.max(v, where=visible, initial=-np.inf)),
                )
                for v in self._xy.T
            )
            if self._shown.size
            else None
        )
        self._refresh_selection()

    def _refresh_selection(self) -> None:
        """Ring the shown selected rows: by the scatter item when few, else in the rings image."""
        rows = self._selection[self._visible[self._selection]]
        many = len(rows) > self._rings_above
        self._ring_rows = rows if many else None
        pts = self._xy[rows[:0] if many else rows]
        self._highlight.setData(x=pts[:, 0], y=pts[:, 1])

    def _ring_job(self, grid: Grid) -> Callable[[], np.ndarray] | None:
        """The rendering of the rings image over ``grid`` (None: no rings image)."""
        if self._ring_rows is None:
            return None
        return partial(rings, self._xy[self._ring_rows], qcolor(SELECTION).getRgb(), grid, *self._ring_radii)

    def _draw_rings(self) -> None:
        job = self._ring_job(self._grid) if self._grid is not None else None
        self._place(self._rings_image, None if job is None else job(), self._grid)

    def _view_grid(self) -> Grid:
        """The raster for the current view: its pixel size, over the view and ``MARGIN`` around it."""
        (x0, x1), (y0, y1) = self.view_box.viewRange()
        sx, sy = (abs(float(v)) for v in self.view_box.viewPixelSize())
        if not (np.isfinite(sx) and np.isfinite(sy) and sx > 0 and sy > 0):  # no size yet
            sx, sy = (x1 - x0) / 640 or 1.0, (y1 - y0) / 480 or 1.0
        mx, my = MARGIN * (x1 - x0), MARGIN * (y1 - y0)
        width = min(int(np.ceil((x1 - x0 + 2 * mx) / sx)), MAX_SIDE)
        height = min(int(np.ceil((y1 - y0 + 2 * my) / sy)), MAX_SIDE)
        return Grid(x0 - mx, y0 - my, sx, sy, max(width, 1), max(height, 1))

    def _stale(self) -> bool:
        """Whether the image no longer covers the view or the zoom changed its pixel size too much."""
        grid = self._grid
        if grid is None or not self._shown.size:
            return False
        (x0, x1), (y0, y1) = self.view_box.viewRange()
        sx = abs(float(self.view_box.viewPixelSize()[0]))
        zoom = grid.px / sx if sx > 0 else np.inf
        return not grid.covers(x0, x1, y0, y1) or not (1 / RERENDER_ZOOM <= zoom <= RERENDER_ZOOM)

    def _view_changed(self) -> None:
        """Schedule a background render when the view outgrew the image (one at a time)."""
        if self._pending is None and self._stale():
            self._render_timer.start()

    def _render_job(self) -> tuple[Grid, Callable[[], tuple[np.ndarray, np.ndarray | None]]]:
        """The grid of the current view and the rendering of the points and rings images over it."""
        grid = self._view_grid()
        points = partial(
            render, self._xy, self._rgba, self._visible, grid, self._point_size, self._density_above
        )
        ring = self._ring_job(grid)
        return grid, lambda: (points(), None if ring is None else ring())

    def _render(self) -> None:
        """Rasterise the shown points over the current view now (a background render still running is
        dropped when it ends)."""
        self._render_timer.stop()
        self._generation += 1
        if not self._shown.size:
            self._grid = None
            self.points_image.clear()
            self._rings_image.clear()
            return
        grid, job = self._render_job()
        self._show(*job(), grid)

    def _render_in_background(self) -> None:
        if self._pending is not None or not self._shown.size:
            return
        grid, job = self._render_job()
        self._pending = (self._generation, grid, self._background(job))
        self._collect_timer.start()

    def _background(self, function: Callable[..., object], *args: object, **kwargs: object) -> Future:
        """``function(*args, **kwargs)`` run on the map's worker thread."""
        if self._worker is None:
            self._worker = ThreadPoolExecutor(max_workers=1, thread_name_prefix="latent-map")
        return self._worker.submit(function, *args, **kwargs)

    def _collect(self) -> None:
        """Show a finished background render (unless the data changed meanwhile); render again if the
        view moved on."""
        if self._pending is None or not self._pending[2].done():
            return
        generation, grid, future = self._pending
        self._pending = None
        self._collect_timer.stop()
        if generation == self._generation:
            self._show(*future.result(), grid)
        self._view_changed()

    def _show(self, points: np.ndarray, ring_image: np.ndarray | None, grid: Grid) -> None:
        self._place(self.points_image, points, grid)
        self._place(self._rings_image, ring_image, grid)
        self._grid = grid

    @staticmethod
    def _place(item: pg.ImageItem, image: np.ndarray | None, grid: Grid | None) -> None:
        """Show ``image`` in ``item`` over ``grid``'s rectangle (None: show nothing)."""
        if image is None or grid is None:
            item.clear()
            return
        item.setImage(image, autoLevels=False)
        item.setRect(QRectF(grid.x0, grid.y0, grid.width * grid.px, grid.height * grid.py))

    def _nearest(self, scene_pos: QPointF) -> int:
        """Row of the shown point nearest ``scene_pos`` within the pixel tolerance, or -1."""
        if self._tree is None or self._shown.size == 0:
            return -1
        pos = self.view_box.mapSceneToView(scene_pos)
        sx, sy = (abs(float(v)) for v in self.view_box.viewPixelSize())
        reach = self._tolerance_px * max(sx, sy)
        tree = self._tree.result()
        near = np.asarray(tree.query_ball_point((pos.x(), pos.y()), reach), dtype=np.intp)
        near = np.sort(near[self._visible[near]])  # ties go to the lowest row, as over all points
        if near.size == 0:
            return -1
        pts = self._xy[near]
        d2 = ((pts[:, 0] - pos.x()) / sx) ** 2 + ((pts[:, 1] - pos.y()) / sy) ** 2
        best = int(np.argmin(d2))
        return int(near[best]) if d2[best] <= self._tolerance_px**2 else -1

    def _nearest_extra(self, scene_pos: QPointF) -> int:
        """Index of the extra point drawn within the pixel tolerance of ``scene_pos``, or -1."""
        pts = self.extra_points()
        if not len(pts):
            return -1
        pos = self.view_box.mapSceneToView(scene_pos)
        sx, sy = self.view_box.viewPixelSize()
        d2 = ((pts[:, 0] - pos.x()) / sx) ** 2 + ((pts[:, 1] - pos.y()) / sy) ** 2
        best = int(np.argmin(d2))
        return best if d2[best] <= self._tolerance_px**2 else -1

    def _handle_click(self, ev: object) -> bool:
        if ev.button() != Qt.MouseButton.LeftButton or self._tool != "pick":  # type: ignore[attr-defined]
            return False
        ev.accept()  # type: ignore[attr-defined]
        extra = self._nearest_extra(ev.scenePos())  # type: ignore[attr-defined]
        row = self._nearest(ev.scenePos()) if extra < 0 else -1  # type: ignore[attr-defined]
        if extra >= 0:  # the marked points (samples, encoded clips) lie on top of the bank's
            self.extraClicked.emit(extra)
        elif row >= 0:
            self.pointClicked.emit(int(self._ids[row]))
        else:
            pos = self.view_box.mapSceneToView(ev.scenePos())  # type: ignore[attr-defined]
            self.emptyClicked.emit(float(pos.x()), float(pos.y()))
        return True

    def _handle_drag(self, ev: object) -> bool:
        if ev.button() != Qt.MouseButton.LeftButton:  # type: ignore[attr-defined]
            return False
        pos = self.view_box.mapSceneToView(ev.scenePos())  # type: ignore[attr-defined]
        if self._tool == "lasso":
            self._lasso_step(ev, (float(pos.x()), float(pos.y())))
            return True
        if ev.isStart():  # type: ignore[attr-defined]
            row = self._nearest(ev.buttonDownScenePos())  # type: ignore[attr-defined]
            self._dragging = row >= 0
            if self._dragging:
                self.dragStarted.emit(int(self._ids[row]))
        if not self._dragging:
            return False
        ev.accept()  # type: ignore[attr-defined]
        if ev.isFinish():  # type: ignore[attr-defined]
            self._dragging = False
            self.dragFinished.emit(float(pos.x()), float(pos.y()))
        else:
            self.dragMoved.emit(float(pos.x()), float(pos.y()))
        return True

    def _lasso_step(self, ev: object, point: tuple[float, float]) -> None:
        ev.accept()  # type: ignore[attr-defined]
        if ev.isStart():  # type: ignore[attr-defined]
            start = self.view_box.mapSceneToView(ev.buttonDownScenePos())  # type: ignore[attr-defined]
            self._lasso = [(float(start.x()), float(start.y()))]
        self._lasso.append(point)
        path = np.asarray(self._lasso + self._lasso[:1])
        self._lasso_curve.setData(path[:, 0], path[:, 1])
        if ev.isFinish():  # type: ignore[attr-defined]
            polygon = np.asarray(self._lasso, dtype=np.float64)
            self._lasso = []
            self._lasso_curve.setData([], [])
            if len(polygon) >= 3:
                self.lassoFinished.emit(polygon)

    def _handle_hover(self, ev: object) -> None:
        row = -1 if ev.isExit() else self._nearest(ev.scenePos())  # type: ignore[attr-defined]
        if row == self._hover_row:
            return
        self._hover_row = row
        text = "" if row < 0 else self._tooltips(row) if callable(self._tooltips) else self._tooltips[row]
        if text:
            widget_pos = self.plot.mapFromScene(ev.scenePos())  # type: ignore[attr-defined]
            QToolTip.showText(self.plot.viewport().mapToGlobal(widget_pos), text, self.plot)
        else:
            QToolTip.hideText()
        self.hovered.emit(int(self._ids[row]) if row >= 0 else -1)
