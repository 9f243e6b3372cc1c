"""Screenshots of the explorer's main states on a model folder, driven through the controller's gestures.

Run under X (or ``xvfb-run -a -s "-screen 0 1920x1080x24"``)::

    python bench/screenshots.py [--model DIR] [--out docs/screenshots]

Writes 01_click_decode.png (a clicked code playing beside the mode ellipses), 02_drag_interpolation_strip.png
(a drag between two modes of one action, released into a strip), 03_lasso_local_mode_samples.png (a lasso,
its local mode and samples around it), 04_tsne_energy_samples.png (t-SNE coloured by motion energy
with new samples placed on the map) and 05_walk_to_run_in_sequence.png (a drag from a walk onto a run,
decoded across the two actions and chained in sequence, with the Find panel's nearest neighbours).
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import numpy as np

if __package__ in (None, ""):
    sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from PySide6.QtCore import QEventLoop, QSettings
from PySide6.QtWidgets import QApplication

from explorer.app import DEFAULT_MODEL, Explorer, create_explorer, take_screenshot

REPO = Path(__file__).resolve().parents[1]
SIZE = (1600, 950)


def _settle(explorer: Explorer, seconds: float = 1.0, timeout: float = 120.0) -> None:
    """Process events until the model is loaded and no task or decode is pending, then ``seconds`` more."""
    loop = QEventLoop()
    flags = QEventLoop.ProcessEventsFlag.AllEvents
    deadline = time.perf_counter() + timeout
    c = explorer.controller
    while explorer.waiting or c.tasks.active or c.state.model is None:
        if time.perf_counter() > deadline:
            raise TimeoutError("the explorer did not become idle")
        loop.processEvents(flags)
        time.sleep(0.01)
    c.decoder.wait_idle(timeout)
    end = time.perf_counter() + seconds
    while time.perf_counter() < end:
        loop.processEvents(flags)
        time.sleep(0.01)


def _two_modes(explorer: Explorer, action: int) -> tuple[int, int]:
    """Bank indices of the codes nearest the means of ``action``'s two largest modes."""
    bank = explorer.controller.bank
    modes = bank.modes[action]
    members = bank.indices_of(action)
    a, b = np.argsort(modes.weights_)[::-1][:2]
    near = [members[np.argmin(np.linalg.norm(bank.codes[members] - modes.means_[m], axis=1))] for m in (a, b)]
    return int(near[0]), int(near[1])


def _drag(explorer: Explorer, start: int, target: int, steps: int, settle: float) -> None:
    """Drag on the map from code ``start`` to code ``target`` in ``steps`` moves, then release on it."""
    c = explorer.controller
    emb = c.state.embedding
    c.gestures.drag_start(start)
    for s in np.linspace(0.0, 1.0, steps)[1:]:
        xy = (1 - s) * emb[start] + s * emb[target]
        c.gestures.drag_move(float(xy[0]), float(xy[1]))
        _settle(explorer, 0.05)
    c.gestures.drag_finish(float(emb[target][0]), float(emb[target][1]))
    _settle(explorer, settle)


def main() -> int:
    """Drive the gestures and write the four screenshots."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--model", type=Path, default=DEFAULT_MODEL)
    parser.add_argument("--out", type=Path, default=REPO / "docs" / "screenshots")
    args = parser.parse_args()
    args.out.mkdir(parents=True, exist_ok=True)

    app = QApplication.instance() or QApplication(sys.argv[:1])
    app.setApplicationName("ODMO Explorer")
    explorer = create_explorer(args.model, None, QSettings("/dev/null", QSettings.Format.IniFormat))
    window, c = explorer.window, explorer.controller
    window.resize(*SIZE)
    window.show()
    _settle(explorer, 2.0)
    walk = c.generator.action_names.index("walk") if "walk" in c.generator.action_names else 0
    c.state.focus_action = walk
    first, second = _two_modes(explorer, walk)

    c.gestures.click_point(first)
    _settle(explorer, 1.5)
    take_screenshot(explorer, args.out / "01_click_decode.png")

    _drag(explorer, first, second, 8, 1.5)
    take_screenshot(explorer, args.out / "02_drag_interpolation_strip.png")

    emb = c.state.embedding
    members = c.bank.indices_of(walk)
    centre = emb[first]
    radius = 0.5 * float(np.median(np.linalg.norm(emb[members] - centre, axis=1)))
    angles = np.linspace(0.0, 2 * np.pi, 24, endpoint=False)
    c.gestures.lasso(centre + radius * np.stack([np.cos(angles), np.sin(angles)], axis=1))
    c.generation.fit_local_mode()
    _settle(explorer)
    c.generation.sample_variations()
    _settle(explorer, 1.5)
    take_screenshot(explorer, args.out / "03_lasso_local_mode_samples.png")

    c.gestures.clear_selection()
    c.state.projection = "tsne"
    c.state.color_by = "motion energy"
    _settle(explorer)
    c.generation.sample("mode_preserving", 10, 0)
    _settle(explorer, 1.5)
    take_screenshot(explorer, args.out / "04_tsne_energy_samples.png")

    c.gestures.clear_selection()
    c.state.projection = "pca"
    c.state.color_by = "action"
    _settle(explorer)
    names = c.generator.action_names
    run = names.index("run") if "run" in names else min(1, len(names) - 1)
    walk_code, run_code = _two_modes(explorer, walk)[0], _two_modes(explorer, run)[0]
    window.layout_combo.setCurrentIndex(window.layout_combo.findData("sequence"))
    window.find_dock.raise_()
    _drag(explorer, walk_code, run_code, 6, 2.0)
    take_screenshot(explorer, args.out / "05_walk_to_run_in_sequence.png")
    explorer.close()
    print(f"screenshots written to {args.out}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
