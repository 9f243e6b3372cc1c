"""Entry point of ``odmo-explorer``: parse arguments, build the window and controller, run Qt."""

from __future__ import annotations

import argparse
import logging
import sys
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from pathlib import Path

from PySide6.QtCore import QSettings, QTimer
from PySide6.QtWidgets import QApplication

DEFAULT_MODEL = Path(__file__).resolve().parents[1] / "resources" / "models" / "bandai2-odmo"
SCREENSHOT_IDLE_TIMEOUT_S = 120.0
START_FALLBACK_MS = 1000  # start loading even if the map has not been painted by then

log = logging.getLogger(__name__)


def build_parser() -> argparse.ArgumentParser:
    """The argument parser of ``odmo-explorer``."""
    parser = argparse.ArgumentParser(
        prog="odmo-explorer", description="Explore the latent space of an ODMO motion model."
    )
    parser.add_argument(
        "--model", type=Path, help=f"model folder (default: the bundled {DEFAULT_MODEL.name})"
    )
    parser.add_argument(
        "--data", type=Path, help="dataset folder: real clips play beside their reconstructions"
    )
    parser.add_argument(
        "--screenshot", type=Path, metavar="FILE.png", help="render the window to FILE and exit"
    )
    parser.add_argument(
        "--after", type=float, default=3.0, metavar="SECONDS", help="wait this long before --screenshot"
    )
    parser.add_argument("--projection", choices=("pca", "tsne", "umap"), default="pca", help="initial map")
    parser.add_argument(
        "--select", type=int, metavar="INDEX", help="click bank code INDEX once the model is loaded"
    )
    parser.add_argument(
        "--color-by",
        default="action",
        metavar="WHAT",
        help="colour the map by action, mode, 'motion energy' or a metadata key (meta:KEY, e.g. meta:style)",
    )
    parser.add_argument("--settings", type=Path, help="settings file (default: the user's Qt settings)")
    parser.add_argument("-v", "--verbose", action="store_true", help="log details")
    return parser


@dataclass
class Explorer:
    """A running explorer: the window, its controller, and the work waiting for the map's first paint."""

    window: object
    controller: object
    pending: list[Callable[[], None]] = field(default_factory=list)
    closed: bool = False

    def load_viewport(self) -> None:
        """Import VTK off the GUI thread, then create the 3-D view there (the window still open)."""

        def job(progress: Callable[[str, float], None], _cancel: Callable[[], bool]) -> None:
            progress("Loading the 3-D view", 0.5)
            import widgets.viewport  # noqa: F401

        def create(_result: None) -> None:
            if not self.closed and self.window.isVisible():
                _ = self.window.viewport

        self.controller.run_task("Loading the 3-D view", job, create)

    @property
    def waiting(self) -> bool:
        """True until the work deferred to after the first paint has been started."""
        return bool(self.pending)

    def start_deferred(self) -> None:
        """Start the work deferred to after the map's first paint (model and data loading, 3-D view)."""
        jobs, self.pending = self.pending, []
        if not self.closed:
            for job in jobs:
                job()

    def close(self) -> None:
        """Stop the workers and close the window (saving its layout)."""
        self.closed = True
        self.pending = []
        self.controller.shutdown()
        self.window.close()


def open_settings(path: Path | None) -> QSettings:
    """Qt settings in ``path`` (INI) or the user's default location."""
    if path is not None:
        return QSettings(str(path), QSettings.Format.IniFormat)
    return QSettings("ODMO", "ODMO Explorer")


def create_explorer(
    model: Path | None,
    data: Path | None,
    settings: QSettings,
    projection: str = "pca",
    color_by: str = "action",
    select: int | None = None,
) -> Explorer:
    """Build the window and controller, paint ``model``'s (or the bundled one's) map, then load it.

    Start-up order, so that the map shows within a second and decoding starts within two: the window,
    the controller and the map (the bank's stored projection, read with numpy) come first; after the
    map's first paint (or ``START_FALLBACK_MS`` at the latest) torch and the model are loaded in a
    worker, then VTK is imported in a worker and the 3-D viewport created. Imports hold Python's lock,
    so the two run one after the other rather than slowing each other down, and the GUI thread stays
    free for the map. A motion decoded before the viewport exists creates it at once.
    """
    from explorer.controller import Controller
    from explorer.main_window import MainWindow

    window = MainWindow(settings)
    controller = Controller(window)
    controller.state.projection = projection
    controller.state.color_by = color_by
    if select is not None:
        controller.modelLoaded.connect(lambda _m: controller.gestures.select_index(select))
    explorer = Explorer(window, controller)
    target = model if model is not None else DEFAULT_MODEL
    if model is None and not DEFAULT_MODEL.is_dir():
        window.show_status(
            f"The bundled model ({DEFAULT_MODEL.name}) is not installed yet: open a model folder with "
            "File ▸ Open model folder… or start with --model DIR."
        )
        explorer.pending.append(explorer.load_viewport)
    else:
        controller.loader.show_preview(target)
        explorer.pending.append(lambda: controller.loader.open_model(target, then=explorer.load_viewport))
    if data is not None:
        explorer.pending.append(lambda: controller.loader.open_data(data))
    window.mapPainted.connect(explorer.start_deferred)
    QTimer.singleShot(START_FALLBACK_MS, window, explorer.start_deferred)
    return explorer


def take_screenshot(explorer: Explorer, path: Path) -> None:
    """Render the whole window (3-D view included) to ``path`` as a PNG."""
    from explorer.export import save_png

    window = explorer.window
    QApplication.processEvents()  # widgets shown or laid out by the last update (e.g. new mode rows)
    window.viewport.render_now()
    state = explorer.controller.state
    meta = {
        "model": str(state.model.path) if state.model else None,
        "projection": state.projection,
        "color_by": state.color_by,
        "selection": list(state.selection),
    }
    save_png(window.grab().toImage(), path, meta)


def _schedule_screenshot(
    app: QApplication, explorer: Explorer, path: Path, after: float, codes: list[int]
) -> None:
    """After ``after`` seconds and once no task is running, save the screenshot and quit."""
    deadline = time.monotonic() + after + SCREENSHOT_IDLE_TIMEOUT_S

    def attempt() -> None:
        c = explorer.controller
        busy = explorer.waiting or c.tasks.active or (c.state.model is not None and c.decoding())
        if busy and time.monotonic() < deadline:
            QTimer.singleShot(200, attempt)
            return
        if c.loader.load_error or c.state.model is None:
            why = c.loader.load_error or "no model was loaded"
            print(f"odmo-explorer: error: {why}; no screenshot written", file=sys.stderr)
            codes.append(2)
            app.quit()
            return
        try:
            take_screenshot(explorer, path)
            print(f"odmo-explorer: screenshot written to {path}", file=sys.stderr)
        except OSError as exc:
            print(f"odmo-explorer: error: cannot write {path}: {exc}", file=sys.stderr)
            codes.append(1)
        app.quit()

    QTimer.singleShot(int(after * 1000), attempt)


def main(argv: Sequence[str] | None = None) -> int:
    """Run ``odmo-explorer``; returns the exit code."""
    args = build_parser().parse_args(argv)
    logging.basicConfig(level=logging.INFO if args.verbose else logging.WARNING, format="%(message)s")
    app = QApplication.instance() or QApplication(sys.argv[:1])
    app.setApplicationName("ODMO Explorer")
    app.setOrganizationName("ODMO")
    explorer = create_explorer(
        args.model, args.data, open_settings(args.settings), args.projection, args.color_by, args.select
    )
    explorer.window.show()
    codes: list[int] = []
    if args.screenshot is not None:
        _schedule_screenshot(app, explorer, args.screenshot, args.after, codes)
    app.exec()
    explorer.close()
    return codes[0] if codes else 0


if __name__ == "__main__":
    sys.exit(main())
