"""Latent map at scale: draw, pan, zoom, hover, click, lasso, recolour and masking of 10k to 1M codes.

Run under an X server (software GL here):
``xvfb-run -a -s "-screen 0 1920x1080x24" python bench/map_scale.py --sizes 10000 100000 1000000``.
The codes are a mixture of 10 Gaussians, one colour each, on a 900 x 700 px LatentMap with its legend. A
frame is the operation, a synchronous repaint of the plot viewport, then the events queued. A view that
leaves the image's margin is rendered again on a worker thread while frames go on (the "until its image
is shown" row times that). Reference rows time, in the same run, the map
as it was (one pyqtgraph ScatterPlotItem with a QBrush per point) and that item with a single brush.
"""

from __future__ import annotations

import argparse
import sys
import time
from collections.abc import Callable
from pathlib import Path

import numpy as np

if __package__ in (None, ""):
    sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from bench._timing import timings_ms

TARGETS_MS = {"frame": 16.0, "hover": 16.0, "pick": 16.0, "lasso": 100.0, "colour": 100.0}
REDRAW_TARGET_MS = 16.0  # the 30k redraw


def _row(
    item: str, operation: str, n: int, times: list[float], target: float | None, note: str = ""
) -> dict[str, object]:
    """One table row: median, p90 and max ms of ``times``, the p90 against the target (if any)."""
    p90 = float(np.percentile(times, 90))
    return {
        "item": item,
        "operation": operation,
        "codes": n,
        "median ms": float(np.median(times)),
        "p90 ms": p90,
        "max ms": float(np.max(times)),
        "target ms": "" if target is None else target,
        "met": "" if target is None else ("yes" if p90 <= target else "no"),
        "note": note,
    }


def mixture(n: int, rng: np.random.Generator) -> tuple[np.ndarray, np.ndarray]:
    """``n`` points (n, 2) from 10 Gaussians and their group (n,) int."""
    centres = rng.normal(scale=4.0, size=(10, 2))
    groups = rng.integers(0, 10, n)
    return centres[groups] + rng.normal(size=(n, 2)), groups


def lasso_polygon(centre: np.ndarray, radius: float) -> np.ndarray:
    """A 120-vertex wobbly loop around ``centre``, like one drawn by hand."""
    t = np.linspace(0.0, 2.0 * np.pi, 120, endpoint=False)
    return centre + radius * np.c_[np.cos(t) + 0.15 * np.cos(5 * t), np.sin(t)]


class Frames:
    """Frame steps on a plot widget: an operation, a synchronous repaint, then the queued events."""

    def __init__(self, plot: object, view_box: object) -> None:
        from PySide6.QtWidgets import QApplication

        self.plot, self.view_box, self.app = plot, view_box, QApplication.instance()

    def repaint(self) -> None:
        """Repaint the viewport now, then run the queued events (a deferred re-render and its paint)."""
        self.plot.viewport().repaint()  # type: ignore[attr-defined]
        self.app.processEvents()  # type: ignore[union-attr]

    def pan(self, fraction: float, turn: int) -> Callable[[int], None]:
        """A step shifting the view by ``fraction`` of its width: right for ``turn`` steps, then left."""

        def step(i: int) -> None:
            (x0, x1), (y0, y1) = self.view_box.viewRange()  # type: ignore[attr-defined]
            shift = fraction * (x1 - x0) * (1 if (i // turn) % 2 == 0 else -1)
            self.view_box.setRange(xRange=(x0 + shift, x1 + shift), yRange=(y0, y1), padding=0)  # type: ignore[attr-defined]
            self.repaint()

        return step

    def zoom(self, factor: float) -> Callable[[int], None]:
        """A step zooming by ``factor`` about the view's centre: in for 40 steps, then out for 40."""

        def step(i: int) -> None:
            (x0, x1), (y0, y1) = self.view_box.viewRange()  # type: ignore[attr-defined]
            f = factor if (i // 40) % 2 == 0 else 1.0 / factor
            cx, cy, hx, hy = (x0 + x1) / 2, (y0 + y1) / 2, (x1 - x0) / 2 * f, (y1 - y0) / 2 * f
            self.view_box.setRange(xRange=(cx - hx, cx + hx), yRange=(cy - hy, cy + hy), padding=0)  # type: ignore[attr-defined]
            self.repaint()

        return step


class MapBench:
    """The LatentMap's operations on one bank of codes (a mixture of 10 Gaussians) in one shown widget."""

    def __init__(self, latent_map: object, n: int, repeats: int, rng: np.random.Generator) -> None:
        from widgets._colors import palette_rgb

        self.map, self.n, self.repeats, self.rng = latent_map, n, repeats, rng
        self.frames = Frames(latent_map.plot, latent_map.view_box)  # type: ignore[attr-defined]
        self.viewport = latent_map.plot.viewport()  # type: ignore[attr-defined]
        palette = palette_rgb(10)
        self.xy, self.groups = mixture(n, rng)
        self.colors, self.other = palette[self.groups], palette[(self.groups + 3) % 10]
        self.masks = rng.random((repeats + 1, n)) < 0.7
        self.targets = self.xy[rng.choice(n, repeats + 1, replace=False)]
        self.polygon = lasso_polygon(self.xy.mean(axis=0), 0.35 * float(np.ptp(self.xy[:, 0])))
        self.rows: list[dict[str, object]] = []

    def add(self, operation: str, step: Callable[[int], None], target: float | None, times: int = 0) -> None:
        """Time ``step`` (``times`` calls, default the repeats) into a row."""
        timings = timings_ms(step, times or self.repeats)
        self.rows.append(_row("LatentMap (raster)", operation, self.n, timings, target))

    def first_draw(self, _: int) -> None:
        self.map.set_points(self.xy, self.colors, np.arange(self.n))  # type: ignore[attr-defined]
        self.frames.repaint()

    def first_pick(self, i: int) -> None:
        """New points, then at once a click on one (it waits for the k-d tree built on the worker)."""
        self.first_draw(i)
        self.click(i)

    def recolour(self, i: int) -> None:
        self.map.set_colors(self.other if i % 2 == 0 else self.colors)  # type: ignore[attr-defined]
        self.frames.repaint()

    def remask(self, i: int) -> None:
        self.map.set_visible_mask(self.masks[i])  # type: ignore[attr-defined]
        self.frames.repaint()

    def click(self, i: int) -> None:
        from PySide6.QtCore import Qt
        from PySide6.QtTest import QTest

        pixel = self.map.data_to_widget(self.targets[i]).toPoint()  # type: ignore[attr-defined]
        QTest.mouseClick(self.viewport, Qt.MouseButton.LeftButton, pos=pixel)

    def lasso(self, _: int) -> None:
        from engine.latent.geometry import points_in_polygon

        inside = points_in_polygon(self.xy, self.polygon)  # as explorer.gestures.Gestures.lasso does
        inside &= ~np.isin(self.groups, [2, 7])

    def rerender(self, i: int) -> None:
        """A 40% pan, then the event loop until the image rendered for the new view is shown."""
        self.frames.pan(0.4, 1)(i)
        while self.map.rendering():  # type: ignore[attr-defined]
            time.sleep(0.002)  # as an idle event loop would, leaving the worker the CPU
            self.frames.repaint()

    def select(self, i: int) -> None:
        self.map.set_selection(np.arange(i + 1, i + 21))  # type: ignore[attr-defined]
        self.frames.repaint()

    def select_lasso(self, i: int) -> None:
        """A selection of 10% of the codes, as a lasso makes (over 2000 rows: ringed in an image)."""
        self.map.set_selection(np.arange(i % 2, self.n, 10))  # type: ignore[attr-defined]
        self.frames.repaint()

    def hover(self) -> None:
        """Moves onto codes, each from off the plot, until ``hovered`` arrives (the waits between moves
        that pyqtgraph's rate limit needs are not timed)."""
        from PySide6.QtCore import QPoint
        from PySide6.QtTest import QTest

        hovered: list[int] = []
        self.map.hovered.connect(hovered.append)  # type: ignore[attr-defined]
        times, missed = [], 0

        def wait_for(hover: Callable[[], bool], start: float, limit: float) -> None:
            while not hover() and time.perf_counter() - start < limit:
                self.frames.app.processEvents()  # type: ignore[union-attr]

        for i in range(-1, self.repeats):
            time.sleep(0.03)  # pyqtgraph drops moves closer than its rate limit
            hovered.clear()
            QTest.mouseMove(self.viewport, QPoint(3, 3))  # the X server delivers moves a little later
            wait_for(lambda: -1 in hovered, time.perf_counter(), 0.2)
            time.sleep(0.03)
            hovered.clear()
            start = time.perf_counter()
            QTest.mouseMove(self.viewport, self.map.data_to_widget(self.targets[i]).toPoint())  # type: ignore[attr-defined]
            wait_for(lambda: any(h >= 0 for h in hovered), start, 0.5)
            if i >= 0:
                times.append((time.perf_counter() - start) * 1e3)
                missed += not any(h >= 0 for h in hovered)
        self.map.hovered.disconnect(hovered.append)  # type: ignore[attr-defined]
        note = f"{self.repeats - missed} of {self.repeats} moves hovered a code"
        self.rows.append(
            _row("LatentMap (raster)", "hover -> hovered", self.n, times, TARGETS_MS["hover"], note)
        )

    def redraws(self, target: float | None) -> None:
        """First draw, recolour and re-mask."""
        few = max(3, self.repeats // 4) if self.n >= 100_000 else self.repeats
        self.add("set_points + repaint (first draw)", self.first_draw, target, few)
        self.add("set_points + repaint + first click", self.first_pick, None, few)
        self.add("set_colors + repaint", self.recolour, TARGETS_MS["colour"], few)
        self.add("set_visible_mask + repaint", self.remask, target, few)
        self.map.set_visible_mask(np.ones(self.n, dtype=bool))  # type: ignore[attr-defined]

    def interaction(self, frames: int) -> None:
        """Pan and zoom frames, hover, click, lasso and selection over the whole bank in view."""
        for operation, step, times in (
            ("pan frame (1% of the view, 50 right then 50 left)", self.frames.pan(0.01, 50), frames),
            ("pan frame past the margin (40% back and forth)", self.frames.pan(0.4, 1), self.repeats),
            ("zoom frame (2%, 40 in then 40 out)", self.frames.zoom(0.98), frames),
        ):
            self.map.view_box.autoRange()  # type: ignore[attr-defined]
            self.frames.repaint()
            self.add(operation, step, TARGETS_MS["frame"], times)
        self.map.view_box.autoRange()  # type: ignore[attr-defined]
        self.frames.repaint()
        self.add("40% pan until its image is shown (background render)", self.rerender, None)
        self.map.view_box.autoRange()  # type: ignore[attr-defined]
        self.frames.repaint()
        self.hover()
        self.add("click -> pointClicked", self.click, TARGETS_MS["pick"])
        self.add("lasso hit-test (120 vertices)", self.lasso, TARGETS_MS["lasso"])
        self.add("set_selection(20) + repaint", self.select, None)
        self.add("set_selection(10% of the codes) + repaint", self.select_lasso, None, 5)
        self.add("pan frame with 10% selected", self.frames.pan(0.01, 50), TARGETS_MS["frame"])
        self.map.set_selection([])  # type: ignore[attr-defined]


def bench_latent_map(
    sizes: list[int], redraw: int, repeats: int, frames: int, rng: np.random.Generator
) -> list[dict[str, object]]:
    """Time the LatentMap's operations for each number of codes (only the redraws at ``redraw`` codes)."""
    from PySide6.QtTest import QTest

    from widgets._colors import palette_rgb
    from widgets.latent_map import LatentMap

    latent_map = LatentMap()
    latent_map.resize(900, 700)
    latent_map.set_legend([f"group {k}" for k in range(10)], [tuple(c) for c in palette_rgb(10)])
    latent_map.show()
    QTest.qWaitForWindowExposed(latent_map)
    rows: list[dict[str, object]] = []
    for n in sorted({*sizes, redraw}):
        bench = MapBench(latent_map, n, repeats, rng)
        bench.redraws(REDRAW_TARGET_MS if n == redraw else None)
        if n in sizes:
            bench.interaction(frames)
        rows += bench.rows
    latent_map.close()
    return rows


def bench_scatter(
    cases: list[tuple[str, int]], repeats: int, rng: np.random.Generator
) -> list[dict[str, object]]:
    """Reference: one pyqtgraph ScatterPlotItem with a QBrush per point (the map as it was), or one brush."""
    import pyqtgraph as pg
    from PySide6.QtTest import QTest

    from widgets._colors import brushes_for, configure_plot, palette_rgb, to_rgba8

    palette = palette_rgb(10)
    rows: list[dict[str, object]] = []
    plot = pg.PlotWidget()
    configure_plot(plot)
    plot.resize(700, 680)  # the LatentMap's plot area at 900 x 700 with its legend
    plot.show()
    QTest.qWaitForWindowExposed(plot)
    view_box = plot.getPlotItem().getViewBox()
    view_box.setAspectLocked(True)
    frames = Frames(plot, view_box)
    one = pg.mkBrush(*(int(c) for c in palette[0]))
    for kind, n in cases:
        xy, groups = mixture(n, rng)
        scatter = pg.ScatterPlotItem(pxMode=True, size=6, pen=None, symbol="o")
        view_box.addItem(scatter)
        rgba = to_rgba8(palette[groups], n)
        brush = (lambda rgba=rgba: brushes_for(rgba)) if kind == "per-point brushes" else (lambda: one)

        def draw(_: int, xy: np.ndarray = xy, scatter: object = scatter, brush: Callable = brush) -> None:
            scatter.setData(x=xy[:, 0], y=xy[:, 1], brush=brush())  # type: ignore[attr-defined]
            frames.repaint()

        item = f"reference: ScatterPlotItem, {kind}"
        target = REDRAW_TARGET_MS if n == 30_000 else None
        rows.append(
            _row(item, "setData + repaint (first draw)", n, timings_ms(draw, max(3, repeats // 4)), target)
        )
        view_box.autoRange()
        frames.repaint()
        timings = timings_ms(frames.pan(0.01, 50), repeats)
        rows.append(
            _row(item, "pan frame (1% of the view, 50 right then 50 left)", n, timings, TARGETS_MS["frame"])
        )
        view_box.removeItem(scatter)
    plot.close()
    return rows


def main(argv: list[str] | None = None) -> int:
    """Measure and record the map-at-scale benchmark."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--sizes", type=int, nargs="+", default=[10_000, 100_000, 1_000_000])
    parser.add_argument("--redraw", type=int, default=30_000, help="codes of the redraw rows")
    parser.add_argument("--repeats", type=int, default=20)
    parser.add_argument("--frames", type=int, default=100, help="frames of the pan and zoom rows")
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--no-reference", action="store_true", help="skip the ScatterPlotItem rows")
    parser.add_argument(
        "--no-record", action="store_true", help="print the table, do not touch BENCHMARKS.md"
    )
    args = parser.parse_args(argv)

    from PySide6.QtWidgets import QApplication

    from bench._report import publish

    app = QApplication.instance() or QApplication([])
    rng = np.random.default_rng(args.seed)
    rows = bench_latent_map(args.sizes, args.redraw, args.repeats, args.frames, rng)
    if not args.no_reference:
        references = [("per-point brushes", 10_000), ("per-point brushes", 30_000), ("one brush", 100_000)]
        rows += bench_scatter(references, args.repeats, rng)
    app.processEvents()
    command = (
        'xvfb-run -a -s "-screen 0 1920x1080x24" python bench/map_scale.py'
        f" --sizes {' '.join(map(str, args.sizes))} --redraw {args.redraw} --repeats {args.repeats}"
        f" --frames {args.frames}" + (" --no-reference" if args.no_reference else "")
    )
    publish("map at scale", rows, command, save=not args.no_record)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
