"""Explorer interaction timings: drag-to-pose latency, playback frame time, map redraw, cold start.

Run under X (or ``xvfb-run -a -s "-screen 0 1920x1080x24"``)::

    python bench/interaction.py --model DIR [--repeats 30]

- drag → pose: from a ``dragMoved`` event to the new pose set in the viewport (decode in the worker,
  result back on the GUI thread, state update, ``set_poses``), excluding the GPU draw; aim < 30 ms.
- playback frame: one timeline step (poses of every skeleton set) plus a synchronous render.
- map redraw: ``LatentMap.set_points`` of N random points plus a synchronous repaint.
- cold start: process start to the first paint of the map with the model's points, to the model being
  loaded (decoding enabled) and to the 3-D view being created, in fresh processes.
"""

from __future__ import annotations

import argparse
import statistics
import subprocess
import sys
import time
from pathlib import Path

import numpy as np

if __package__ in (None, ""):
    sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from PySide6.QtCore import QEventLoop, QSettings, QTimer
from PySide6.QtWidgets import QApplication

from explorer.app import DEFAULT_MODEL, create_explorer
from explorer.map_layers import category_colors, scalar_colors

_LOOP: list[QEventLoop] = []


def _wait(app: QApplication, condition, timeout: float = 60.0) -> None:
    """Process events until ``condition()`` holds.

    Uses ``QEventLoop.processEvents(flags) -> bool``: PySide6 6.12 on Python 3.11 drops a reference to
    None on every call of a void-returning method (``QApplication.processEvents`` included), which
    crashes a tight polling loop.
    """
    if not _LOOP:
        _LOOP.append(QEventLoop())
    deadline = time.perf_counter() + timeout
    while not condition():
        if time.perf_counter() > deadline:
            raise TimeoutError("condition not reached")
        _LOOP[0].processEvents(QEventLoop.ProcessEventsFlag.AllEvents)
        time.sleep(0.0005)


def _median_ms(samples: list[float]) -> float:
    return 1000.0 * statistics.median(samples)


def _settle(app: QApplication, seconds: float) -> None:
    """Process events for ``seconds`` (lets the previous update's draw finish, like the gap between
    two mouse-move events)."""
    end = time.perf_counter() + seconds
    _wait(app, lambda: time.perf_counter() > end)


def bench_drag(app: QApplication, explorer, repeats: int, gap_s: float = 0.03) -> dict:
    """Median ms from dragMoved to the new pose set in the viewport (moves ``gap_s`` apart, playing)."""
    c, lmap = explorer.controller, explorer.window.latent_map
    emb = c.state.embedding
    a, b = 0, int(np.argmax(np.linalg.norm(emb - emb[0], axis=1)))
    lmap.dragStarted.emit(a)
    times, decode = [], []
    for k in range(repeats):
        xy = emb[a] + (k + 0.5) / repeats * (emb[b] - emb[a])
        seen = []
        c.shownChanged.connect(lambda s=seen: s.append(time.perf_counter()))
        _settle(app, gap_s)
        start = time.perf_counter()
        lmap.dragMoved.emit(float(xy[0]), float(xy[1]))
        _wait(app, lambda s=seen: bool(s))
        times.append(seen[0] - start)
        decode.append(c.decoder.last_run_s)
        c.shownChanged.disconnect()
    lmap.dragFinished.emit(float(emb[a][0]), float(emb[a][1]))
    _wait(app, lambda: not c.tasks.active)
    c.decoder.wait_idle()
    app.processEvents()
    return {
        "measure": "drag → pose set (decode + update, no GPU draw)",
        "n": repeats,
        "median_ms": _median_ms(times),
        "decode_in_worker_ms": _median_ms(decode),
    }


def bench_playback(app: QApplication, explorer, n_skeletons: int, frames: int) -> dict:
    """Median ms of one playback step with ``n_skeletons`` skeletons, render included."""
    c, viewport = explorer.controller, explorer.window.viewport
    c.state.selection = tuple(range(n_skeletons))
    c.gestures.play_selection()
    _wait(app, lambda: len(c.state.shown) >= n_skeletons)
    explorer.window.timeline.pause()
    update, total = [], []
    for f in range(frames):
        start = time.perf_counter()
        c.state.frame = f % max(1, c.state.shown[0].motion.n_frames)
        mid = time.perf_counter()
        viewport.render_now()
        end = time.perf_counter()
        update.append(mid - start)
        total.append(end - start)
    return {
        "measure": f"playback step, {n_skeletons} skeleton(s)",
        "n": frames,
        "median_ms": _median_ms(total),
        "update_only_ms": _median_ms(update),
    }


def bench_map(app: QApplication, explorer, n_points: int, repeats: int, color_by: str) -> dict:
    """Median ms to set N points on the map, coloured as the app colours them, and repaint it.

    ``color_by`` "action": 12 categorical colours; "motion energy": the app's scalar colouring
    (``SCALAR_LEVELS`` steps). The widget renders one symbol image per distinct colour, so N
    distinct colours (e.g. random ones) cost ~0.4 s for 3k points.
    """
    lmap = explorer.window.latent_map
    rng = np.random.default_rng(0)
    xy = rng.standard_normal((n_points, 2))
    if color_by == "action":
        colors = category_colors(12)[rng.integers(0, 12, n_points)]
    else:
        colors = scalar_colors(rng.gamma(2.0, 0.5, n_points))
    ids = np.arange(n_points)
    times = []
    for _ in range(repeats):
        start = time.perf_counter()
        lmap.set_points(xy, colors, ids)
        lmap.plot.viewport().repaint()
        times.append(time.perf_counter() - start)
    explorer.controller.map.drawn = None
    explorer.controller.map.redraw_map(explorer.controller.state.embedding)
    return {
        "measure": f"map redraw, {n_points:,} points by {color_by}",
        "n": repeats,
        "median_ms": _median_ms(times),
    }


def cold_start_child(model: Path, spawned: float) -> None:
    """Child process: open the explorer as ``odmo-explorer`` does; print seconds since ``spawned`` at
    the first paint of the map with points on it, at the model being loaded, and at the 3-D view
    being created."""
    app = QApplication.instance() or QApplication(sys.argv[:1])
    explorer = create_explorer(model, None, QSettings("/dev/null", QSettings.Format.IniFormat))
    painted: list[float] = []
    loaded: list[float] = []
    viewport: list[float] = []
    explorer.window.mapPainted.connect(lambda: painted.append(time.time() - spawned))
    explorer.controller.modelLoaded.connect(lambda _m: loaded.append(time.time() - spawned))
    explorer.window.viewportCreated.connect(lambda: viewport.append(time.time() - spawned))
    explorer.window.show()
    _wait(app, lambda: bool(painted and loaded and viewport), timeout=120)
    print(f"{painted[0]:.3f} {loaded[0]:.3f} {viewport[0]:.3f}")
    explorer.close()
    QTimer.singleShot(0, app.quit)


def bench_cold_start(model: Path, repeats: int) -> list[dict]:
    """Median ms from process start to first map paint, to the model loaded and to the 3-D view created,
    over ``repeats`` processes."""
    paint, loaded, viewport = [], [], []
    for _ in range(repeats):
        out = subprocess.run(
            [sys.executable, __file__, "--model", str(model), "--cold-start-child", str(time.time())],
            check=True,
            capture_output=True,
            text=True,
        )
        first, ready, shown = (float(v) for v in out.stdout.strip().splitlines()[-1].split())
        paint.append(first)
        loaded.append(ready)
        viewport.append(shown)
    return [
        {"measure": "cold start → first map paint", "n": repeats, "median_ms": _median_ms(paint)},
        {"measure": "cold start → model loaded (decoding on)", "n": repeats, "median_ms": _median_ms(loaded)},
        {"measure": "cold start → 3-D view created", "n": repeats, "median_ms": _median_ms(viewport)},
    ]


def main() -> int:
    """Run every measurement and record them in docs/BENCHMARKS.md."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--model", type=Path, default=DEFAULT_MODEL)
    parser.add_argument("--repeats", type=int, default=30)
    parser.add_argument("--cold-starts", type=int, default=3)
    parser.add_argument("--map-sizes", type=int, nargs="+", default=[3_000, 30_000])
    parser.add_argument("--cold-start-child", type=float, help=argparse.SUPPRESS)
    parser.add_argument(
        "--only", nargs="+", choices=("drag", "playback", "map", "cold"), help="run only these measurements"
    )
    parser.add_argument("--no-record", action="store_true", help="print only")
    args = parser.parse_args()
    if args.cold_start_child is not None:
        cold_start_child(args.model, args.cold_start_child)
        return 0

    only = set(args.only or ("drag", "playback", "map", "cold"))
    rows: list[dict] = []
    if only - {"cold"}:
        import torch

        torch.set_num_threads(1)
        app = QApplication.instance() or QApplication(sys.argv[:1])
        explorer = create_explorer(args.model, None, QSettings("/dev/null", QSettings.Format.IniFormat))
        explorer.window.show()
        _wait(app, lambda: explorer.controller.state.embedding is not None, timeout=120)
        if "drag" in only:
            rows.append(bench_drag(app, explorer, args.repeats))
        if "playback" in only:
            rows += [bench_playback(app, explorer, n, args.repeats) for n in (1, 10)]
        if "map" in only:
            rows += [
                bench_map(app, explorer, n, max(3, args.repeats // 5), color_by)
                for n in args.map_sizes
                for color_by in ("action", "motion energy")
            ]
        explorer.close()
    if "cold" in only:
        rows += bench_cold_start(args.model, args.cold_starts)
    for row in rows:
        print(row)
    if not args.no_record:
        from bench._report import record

        sizes = " ".join(str(n) for n in args.map_sizes)
        command = (
            f"xvfb-run -a python bench/interaction.py --model {args.model} --map-sizes {sizes} "
            f"--cold-starts {args.cold_starts}"
        )
        record("Explorer interaction", rows, command)
    return 0


if __name__ == "__main__":
    sys.exit(main())
