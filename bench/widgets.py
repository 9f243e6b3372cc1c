"""Widget timings: map redraw with 3k / 30k points, viewport pose update + render with 1 / 10 skeletons.

Run under an X server (software GL here): ``xvfb-run -a -s "-screen 0 1920x1080x24" python bench/widgets.py``.
The map is 900 x 700 px; a redraw is ``set_points`` (or ``set_visible_mask``) followed by a synchronous
repaint of the plot viewport. The viewport is 800 x 600 px; an update is ``set_poses`` of a 21-joint skeleton
followed by a synchronous ``Render()``.
"""

from __future__ import annotations

import argparse
import sys
from collections.abc import Callable
from pathlib import Path

import numpy as np

if __package__ in (None, ""):
    sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from bench._timing import timings_ms

# 21 joints: spine chain with head, two arms from the chest, two legs from the hips.
PARENTS = np.array([-1, 0, 1, 2, 3, 4, 3, 6, 7, 8, 3, 10, 11, 12, 0, 14, 15, 16, 0, 18, 19])


def _timings_ms(step: Callable[[int], None], repeats: int) -> tuple[float, float]:
    """Median and 90th percentile in ms of ``step(i)`` over ``repeats`` calls (after one warm-up)."""
    times = timings_ms(step, repeats)
    return float(np.median(times)), float(np.percentile(times, 90))


# Bone offsets from the parent (metres): a T-pose facing +z.
OFFSETS = np.array(
    [
        [0.0, 1.0, 0.0], [0.0, 0.12, 0.0], [0.0, 0.12, 0.0],
        [0.0, 0.14, 0.0], [0.0, 0.1, 0.0], [0.0, 0.12, 0.0],
        [0.08, 0.05, 0.0], [0.1, 0.0, 0.0], [0.27, 0.0, 0.0], [0.25, 0.0, 0.0],
        [-0.08, 0.05, 0.0], [-0.1, 0.0, 0.0], [-0.27, 0.0, 0.0], [-0.25, 0.0, 0.0],
        [0.1, 0.0, 0.0], [0.0, -0.45, 0.0], [0.0, -0.45, 0.0], [0.0, -0.08, 0.12],
        [-0.1, 0.0, 0.0], [0.0, -0.45, 0.0], [0.0, -0.45, 0.0],
    ]
)  # fmt: skip


def t_pose() -> np.ndarray:
    """Joint positions (J, 3) float32 of the T-pose."""
    pose = np.zeros_like(OFFSETS)
    for j, parent in enumerate(PARENTS):
        pose[j] = OFFSETS[j] + (pose[parent] if parent >= 0 else 0.0)
    return pose.astype(np.float32)


def bench_map(sizes: list[int], repeats: int, rng: np.random.Generator) -> list[dict[str, object]]:
    """Time map redraws for each number of points."""
    from PySide6.QtCore import Qt
    from PySide6.QtTest import QTest

    from widgets.latent_map import LatentMap

    rows: list[dict[str, object]] = []
    latent_map = LatentMap()
    latent_map.resize(900, 700)
    latent_map.show()
    QTest.qWaitForWindowExposed(latent_map)
    for n in sizes:
        xy = rng.normal(size=(n, 2))
        labels = rng.integers(0, 12, n)
        colors = (np.array([[(37 * k) % 256, (91 * k) % 256, (151 * k) % 256, 255] for k in range(12)]))[
            labels
        ]
        masks = rng.random((repeats + 1, n)) < 0.7

        def redraw(_: int, xy: np.ndarray = xy, colors: np.ndarray = colors) -> None:
            latent_map.set_points(xy, colors, np.arange(len(xy)), ["clip"] * len(xy))
            latent_map.plot.viewport().repaint()

        def remask(i: int, masks: np.ndarray = masks) -> None:
            latent_map.set_visible_mask(masks[i])
            latent_map.plot.viewport().repaint()

        def click(i: int, xy: np.ndarray = xy) -> None:
            pixel = latent_map.data_to_widget(xy[i % len(xy)]).toPoint()
            QTest.mouseClick(latent_map.plot.viewport(), Qt.MouseButton.LeftButton, pos=pixel)

        def select(i: int) -> None:
            latent_map.set_selection(np.arange(i + 1, i + 21))
            latent_map.plot.viewport().repaint()

        operations = (
            ("set_points + repaint", redraw),
            ("set_visible_mask + repaint", remask),
            ("click -> pointClicked", click),
            ("set_selection(20) + repaint", select),
        )
        for operation, step in operations:
            if operation == "click -> pointClicked":
                latent_map.set_visible_mask(np.ones(n, dtype=bool))
                latent_map.view_box.autoRange()
            median, p90 = _timings_ms(step, repeats)
            rows.append(
                {
                    "widget": "LatentMap",
                    "operation": operation,
                    "size": f"{n} points",
                    "median ms": median,
                    "p90 ms": p90,
                }
            )
    latent_map.close()
    return rows


def bench_viewport(counts: list[int], repeats: int, rng: np.random.Generator) -> list[dict[str, object]]:
    """Time in-place pose updates plus a synchronous render for each number of skeletons."""
    from PySide6.QtTest import QTest

    from widgets.viewport import SkeletonViewport

    rows: list[dict[str, object]] = []
    viewport = SkeletonViewport()
    viewport.resize(800, 600)
    viewport.show()
    QTest.qWaitForWindowExposed(viewport)
    for n in counts:
        viewport.set_skeletons(PARENTS, n)
        viewport.set_layout("side_by_side", spacing=1.0)
        base = np.repeat(t_pose()[None], n, axis=0)
        jitter = rng.normal(0.0, 0.02, (repeats + 1, *base.shape)).astype(np.float32)
        viewport.set_poses(base)
        viewport.reset_camera()

        def update(i: int, base: np.ndarray = base, jitter: np.ndarray = jitter) -> None:
            viewport.set_poses(base + jitter[i])
            viewport.render_now()

        median, p90 = _timings_ms(update, repeats)
        rows.append(
            {
                "widget": "SkeletonViewport",
                "operation": "set_poses + Render()",
                "size": f"{n} x {len(PARENTS)} joints",
                "median ms": median,
                "p90 ms": p90,
            }
        )
    viewport.close()
    return rows


def main(argv: list[str] | None = None) -> int:
    """Measure and record the widget benchmark."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--points", type=int, nargs="+", default=[3000, 30000])
    parser.add_argument("--skeletons", type=int, nargs="+", default=[1, 10])
    parser.add_argument("--repeats", type=int, default=30)
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument(
        "--no-record", action="store_true", help="print the table, do not touch BENCHMARKS.md"
    )
    args = parser.parse_args(argv)

    from PySide6.QtWidgets import QApplication

    from bench._report import publish

    app = QApplication.instance() or QApplication([])
    rng = np.random.default_rng(args.seed)
    rows = bench_map(args.points, args.repeats, rng) + bench_viewport(args.skeletons, args.repeats, rng)
    app.processEvents()
    command = (
        'xvfb-run -a -s "-screen 0 1920x1080x24" python bench/widgets.py'
        f" --points {' '.join(map(str, args.points))} --skeletons {' '.join(map(str, args.skeletons))}"
        f" --repeats {args.repeats}"
    )
    publish("widgets", rows, command, save=not args.no_record)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
