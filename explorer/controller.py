"""The controller: the session (loaded generator, bank, maps, dataset, workers, errors) and the wiring of
widget signals and state events to the parts that act on them.

The parts, one concern each: ``MapPresenter`` (the map), ``Gestures`` (clicks, drags, lasso, selection),
``Generation`` (samples, variations, local mode, end location, paths), ``LatentTools`` (truncation,
style mixing, crowds, inversion), ``Editing`` (edit sliders), ``Continuation`` (futures of a prefix,
longer motions) and ``Playback`` (the only writer
to the 3-D view, timeline and trajectory canvas); exports, search and clip encoding have theirs. Torch,
scikit-learn and scipy are imported where they are used: the window and the map's preview come up before
the model is loaded, and the model-loading task brings them in off the GUI thread.
"""

from __future__ import annotations

import logging
from collections.abc import Callable
from typing import TYPE_CHECKING, Any

import numpy as np
from PySide6.QtCore import QObject, Signal

from engine.errors import ConfigError, ModelFormatError, OdmoError
from engine.motion.motion import Motion
from explorer.generation import Generation
from explorer.gestures import Gestures
from explorer.main_window import MainWindow
from explorer.map_presenter import MapPresenter
from explorer.playback import Playback
from explorer.state import AppState
from explorer.workers import Cancel, LatestRunner, Progress, TaskRunner

if TYPE_CHECKING:
    from engine.generators.base import Generator
    from engine.latent.bank import LatentBank
    from engine.latent.projection import Projection

log = logging.getLogger(__name__)


class Controller(QObject):
    """Wires a :class:`MainWindow` to an :class:`AppState`, the loaded generator and the parts.

    Signals: ``modelLoaded(object)`` after a model is shown, ``errorOccurred(str)`` for every error
    shown to the user, ``shownChanged()`` once new motions are in the viewport.
    """

    modelLoaded = Signal(object)  # noqa: N815
    errorOccurred = Signal(str)  # noqa: N815
    shownChanged = Signal()  # noqa: N815

    def __init__(self, window: MainWindow, state: AppState | None = None, seed: int = 0) -> None:
        super().__init__(window)
        self.window = window
        self.state = state if state is not None else AppState()
        self.decoder = LatestRunner("decode", self)
        self.tasks = TaskRunner(2, self)
        self._seeds = np.random.SeedSequence(seed)
        self.projections: dict[str, Projection] = {}
        self.real_clips: dict[str, Motion] = {}  # the loaded dataset's clips by source name
        from explorer.continuing import Continuation
        from explorer.editing import Editing
        from explorer.encoding import ClipEncoder
        from explorer.exporting import Exporter
        from explorer.finding import Finder
        from explorer.latent_tools import LatentTools
        from explorer.loading import Loader

        self.loader = Loader(self)
        self.map = MapPresenter(self)
        self.gestures = Gestures(self)
        self.generation = Generation(self)
        self.playback = Playback(self)
        self._connect()
        self.loader.fill_model_menus()
        self.exporter = Exporter(self)
        self.finder = Finder(self)
        self.encoder = ClipEncoder(self)
        self.latent = LatentTools(self)
        self.editing = Editing(self)
        self.continuation = Continuation(self)
        self.state.events.embedding.connect(lambda _e: self.encoder.show())

    def _connect(self) -> None:
        w, ev = self.window, self.state.events
        w.latent_map.pointClicked.connect(self.gestures.click_point)
        w.latent_map.emptyClicked.connect(self.gestures.click_empty)
        w.latent_map.extraClicked.connect(self.gestures.click_extra)
        w.latent_map.dragStarted.connect(self.gestures.drag_start)
        w.latent_map.dragMoved.connect(self.gestures.drag_move)
        w.latent_map.dragFinished.connect(self.gestures.drag_finish)
        w.latent_map.lassoFinished.connect(self.gestures.lasso)
        w.latent_map.hovered.connect(self.map.hover)
        w.latent_map.legendToggled.connect(self.map.legend_toggled)
        w.mode_panel.weightsChanged.connect(self.map.weights_changed)
        w.mode_panel.sampleRequested.connect(self.generation.sample)
        w.timeline.frameChanged.connect(lambda f: setattr(self.state, "frame", int(f)))
        w.trajectory.endRequested.connect(self.generation.set_end)
        w.trajectory.followPathRequested.connect(self.generation.follow_path)

        w.projection_combo.currentIndexChanged.connect(
            lambda _i: setattr(self.state, "projection", w.projection_combo.currentData())
        )
        w.color_combo.currentIndexChanged.connect(
            lambda _i: setattr(self.state, "color_by", w.color_combo.currentData())
        )
        w.action_combo.currentIndexChanged.connect(
            lambda i: i >= 0 and setattr(self.state, "focus_action", int(i))
        )
        w.layout_combo.currentIndexChanged.connect(
            lambda _i: setattr(self.state, "layout", w.layout_combo.currentData())
        )
        w.open_model_action.triggered.connect(self.loader.ask_model)
        w.open_data_action.triggered.connect(self.loader.ask_data)
        w.select_clip_action.triggered.connect(self.gestures.select_clip_windows)
        w.play_selection_action.triggered.connect(self.gestures.play_selection)
        w.variations_action.triggered.connect(self.generation.sample_variations)
        w.fit_mode_action.triggered.connect(self.generation.fit_local_mode)
        w.clear_selection_action.triggered.connect(self.gestures.clear_selection)
        w.reset_camera_action.triggered.connect(self.playback.reset_camera)
        w.follow_camera_action.toggled.connect(self.playback.follow_camera)
        w.labels_action.toggled.connect(lambda _on: self.playback.show_motions(self.state.shown))
        w.ghosts_spin.valueChanged.connect(
            lambda _n: self.playback.show_details(self.state.shown, restart=False)
        )
        w.cancel_button.clicked.connect(self.tasks.cancel_all)

        self.decoder.finished.connect(self.playback.decoded)
        self.decoder.failed.connect(self._decode_failed)
        self.tasks.started.connect(self._task_started)
        self.tasks.ended.connect(self._task_ended)

        ev.model.connect(self.loader.model_changed)
        w.viewportCreated.connect(self.loader.rig_viewport)
        ev.projection.connect(self.map.projection_changed)
        ev.embedding.connect(self.map.redraw_map)
        ev.color_by.connect(self.map.color_by_changed)
        ev.hidden_actions.connect(self.map.apply_visibility)
        ev.selection.connect(self.map.apply_selection)
        ev.focus_action.connect(self.map.focus_changed)
        ev.extra.connect(self.map.draw_extra)
        ev.marker.connect(lambda m: self.window.latent_map.set_marker(m))
        ev.shown.connect(self.playback.show_motions)
        ev.layout.connect(lambda _l: self.playback.show_motions(self.state.shown))
        ev.frame.connect(self.playback.set_frame)

    @property
    def generator(self) -> Generator:
        """The loaded generator, of any kind; ConfigError when none is."""
        if self.state.model is None:
            raise ConfigError("no model is loaded (File ▸ Open model folder…)")
        return self.state.model

    @property
    def bank(self) -> LatentBank:
        """The loaded model's latent bank."""
        bank = self.generator.bank
        if bank is None:
            raise ModelFormatError(f"{self.generator.path}: the model has no latent bank (run `odmo bank`)")
        return bank

    def can(self, capability: str) -> bool:
        """True when the loaded generator declares ``capability``."""
        return self.state.model is not None and capability in self.generator.capabilities

    def refuse(self, capability: str, asked: str | None = None) -> bool:
        """Say in the status bar that the loaded kind lacks ``capability``; True when it does (or when
        no model is loaded)."""
        if self.state.model is None:
            return True
        if self.can(capability):
            return False
        from engine.generators.base import refusal

        self.window.show_status(str(refusal(self.generator, capability, asked)))
        return True

    @property
    def projection(self) -> Projection | None:
        """The fitted projection the map shows, or None while it is being computed."""
        return self.projections.get(self.state.projection)

    def new_seed(self) -> int:
        return int(self._seeds.spawn(1)[0].generate_state(1)[0])

    def report_error(self, title: str, exc: BaseException | str) -> None:
        """Show an error to the user (message box + status bar) and emit ``errorOccurred``."""
        text = str(exc) if isinstance(exc, OdmoError | str) else f"{type(exc).__name__}: {exc}"
        log.warning("%s: %s", title, text)
        self.window.show_error(title, text)
        self.errorOccurred.emit(text)

    def guard(self, title: str, fn: Callable[[], Any]) -> Any:
        try:
            return fn()
        except (OdmoError, OSError, ValueError) as exc:
            self.report_error(title, exc)
            return None

    def run_task(self, title: str, fn: Callable[[Progress, Cancel], Any], on_done: Callable[[Any], None]):
        return self.tasks.run(title, fn, on_done, lambda exc: self.report_error(title, exc))

    def _decode_failed(self, request: int, exc: BaseException) -> None:
        self.playback.shown_request = max(self.playback.shown_request, request)
        self.report_error("Decoding failed", exc)

    def _task_started(self, task: Any) -> None:
        self.state.busy = task.title
        self.window.show_progress(task.title, None)
        task.progress.connect(lambda text, frac: self.window.show_progress(text or task.title, frac))

    def _task_ended(self, _task: Any) -> None:
        active = self.tasks.active
        self.state.busy = active[-1].title if active else ""
        if not active:
            self.window.hide_progress()

    def decoding(self) -> bool:
        """True while a decode request has not been shown yet."""
        return self.decoder.newest > self.playback.shown_request

    def shutdown(self) -> None:
        """Stop the workers (cancel running tasks, drop pending decodes) and join their threads."""
        self.decoder.shutdown()
        self.tasks.shutdown()
