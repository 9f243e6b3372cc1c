"""The controller: the session (loaded generator, bank, maps, dataset, workers, errors) and the wiring of
widget signals and state events to the parts that act on them.

The parts, one concern each: ``MapPresenter`` (the map), ``Gestures`` (clicks, drags, lasso, selection),
``Generation`` (samples, variations, local mode, end location, paths) and ``Playback`` (the only writer
to the 3-D view, timeline and trajectory canvas); exports, search and clip encoding have theirs. Torch,
scikit-learn and scipy are imported where they are used: the window and the map's preview come up before
the model is loaded, and the model-loading task brings them in off the GUI thread.
"""

from __future__ import annotations

import logging
from collections.abc import Callable
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np
from PySide6.QtCore import QObject, Signal
from PySide6.QtWidgets import QFileDialog

from engine.errors import ConfigError, ModelFormatError, OdmoError
from engine.motion.motion import Motion
from explorer.capabilities import gate_tools
from explorer.generation import Generation
from explorer.gestures import Gestures
from explorer.main_window import MainWindow
from explorer.map_layers import META_PREFIX, category_colors, meta_keys, tooltip_texts
from explorer.map_presenter import MapPresenter
from explorer.model_menu import fill_model_menus, remember_model
from explorer.playback import Playback
from explorer.preview import BankPreview, read_preview
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
        self._model_task = None
        self.load_error = ""  # why the last model failed to load ("" when it did not)
        self._preview: BankPreview | None = None
        from explorer.encoding import ClipEncoder
        from explorer.exporting import Exporter
        from explorer.finding import Finder

        self.map = MapPresenter(self)
        self.gestures = Gestures(self)
        self.generation = Generation(self)
        self.playback = Playback(self)
        self._connect()
        self._fill_model_menus()
        self.exporter = Exporter(self)
        self.finder = Finder(self)
        self.encoder = ClipEncoder(self)
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
        w.open_model_action.triggered.connect(self._ask_model)
        w.open_data_action.triggered.connect(self._ask_data)
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

        ev.model.connect(self._model_changed)
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

    def show_preview(self, path: str | Path) -> bool:
        """Paint the map of ``path``'s latent bank now (numpy only), before its model is loaded.

        Only while no model is shown; clicks decode once the model is loaded. False when the folder
        has no readable bank with a stored map (the full load then reports why).
        """
        path = Path(path)
        if self.state.model is not None:
            return False
        if self._preview is not None and self._preview.path == path:
            return True
        preview = read_preview(path)
        if preview is None:
            return False
        name = self.state.projection if self.state.projection in preview.embeddings else None
        embedding = preview.embeddings[name or next(iter(preview.embeddings))]
        names = preview.action_names
        palette = category_colors(len(names))
        colors = palette[preview.actions]
        w = self.window
        w.latent_map.set_legend(names, [tuple(c) for c in palette])
        tips = tooltip_texts(preview.sources, preview.actions, names, preview.meta)
        w.latent_map.set_points(embedding, colors, np.arange(len(embedding)), tips)
        self._preview, self.map.drawn = preview, (embedding, colors)
        w.show_status(
            f"Loading model {path.name}… the map shows its {len(embedding)} bank codes; "
            "decoding starts once the model is loaded."
        )
        return True

    def open_model(self, path: str | Path) -> None:
        """Load a model folder in the background; the current one stays until the new one is ready."""
        path = Path(path)
        self.show_preview(path)

        def job(progress: Progress, _cancel: Cancel) -> Generator:
            progress(f"Loading {path.name}", 0.1)
            from engine.generators import open_generator

            progress(f"Loading {path.name}", 0.5)
            generator = open_generator(path)
            import engine.generate  # noqa: F401  (loaded here, off the GUI thread, before the first decode)

            if generator.bank is None:
                raise ModelFormatError(f"{path}: the model has no latent bank (latent_bank.npz)")
            return generator

        title = f"Loading model {path.name}"
        self.load_error = ""
        self._model_task = self.tasks.run(title, job, self._model_ready, self._model_failed)

    def _model_failed(self, exc: BaseException) -> None:
        """The model could not be loaded: say why, keep what is shown, remember it (``load_error``)."""
        self.load_error = str(exc) if isinstance(exc, OdmoError) else f"{type(exc).__name__}: {exc}"
        if self._preview is not None and self.state.model is None:  # the preview promised a model
            self.window.latent_map.set_points(np.zeros((0, 2)), np.zeros((0, 4)), np.zeros(0, dtype=np.int64))
            self._preview, self.map.drawn = None, None
        self.report_error("Cannot open the model", exc)

    def _model_ready(self, loaded: Generator) -> None:
        """Show a loaded model; a bank the app cannot show is reported like a failed load."""
        try:
            self._show_model(loaded)
        except Exception as exc:
            log.exception("showing %s failed", loaded.path)
            self.state.model = None
            self._model_failed(exc)
            return
        remember_model(self.window.settings, loaded.path)
        self._fill_model_menus()

    def _fill_model_menus(self) -> None:
        w = self.window
        fill_model_menus(w.recent_menu, w.bundled_menu, w.settings, self.open_model)

    def _show_model(self, loaded: Generator) -> None:
        self.projections = {k: v for k, v in loaded.bank.projections.items() if v.embedding_ is not None}
        self.map.reset()
        self.real_clips = {}
        self.state.selection = ()
        self.state.extra = None
        self.state.marker = None
        self.state.shown = ()
        if self.projections.get(self.state.projection) is None:
            self.state.embedding = None  # the old model's map must not stand for the new bank
        self.state.model = loaded
        self._preview = None
        if self.state.data_dir:
            self.open_data(self.state.data_dir)

    def open_data(self, path: str | Path) -> None:
        """Load a dataset folder in the background so real clips play beside their reconstructions."""
        path = Path(path)

        def job(progress: Progress, cancel: Cancel) -> tuple[str, dict[str, Motion], int]:
            from engine.motion.datasets import load_folder

            progress(f"Reading {path.name}", 0.05)
            dataset = load_folder(path)
            clips = {}
            for clip in dataset.clips:
                source = str(clip.meta.get("source", ""))
                clips[source] = clip
                clips.setdefault(Path(source).stem, clip)
            return str(path), clips, len(dataset.clips)

        def done(result: tuple[str, dict[str, Motion], int]) -> None:
            self.state.data_dir, self.real_clips, count = result
            self.window.show_status(
                f"Dataset {Path(result[0]).name}: {count} clips; click a code to play its clip beside it."
            )

        self.run_task(f"Loading dataset {path.name}", job, done)

    def _model_changed(self, loaded: Generator | None) -> None:
        w = self.window
        if loaded is None:
            return
        bank = loaded.bank
        names = list(loaded.action_names)
        w.action_combo.blockSignals(True)
        w.action_combo.clear()
        w.action_combo.addItems(names)
        w.action_combo.setCurrentIndex(0)
        w.action_combo.blockSignals(False)
        self._fill_color_combo(bank)
        gate_tools(w, loaded)
        w.viewport.set_skeletons(loaded.skeleton.parents, 1)
        self.playback.rig = None
        self.state.focus_action = 0
        # The legend first: set_legend redraws the points, so after set_points it would draw them twice.
        w.latent_map.set_legend(names, [tuple(c) for c in category_colors(len(names))])
        self.map.projection_changed(self.state.projection)
        self.map.focus_changed(self.state.focus_action)
        w.setWindowTitle(f"ODMO Explorer — {loaded.path.name}")
        w.show_status(
            f"Model {loaded.path.name}: {len(bank.codes)} bank codes, {len(names)} actions, "
            f"{loaded.kind} codes {loaded.code_space.name} of size {loaded.code_space.size}. "
            "Click a point to decode it."
        )
        self.modelLoaded.emit(loaded)

    def _fill_color_combo(self, bank: LatentBank) -> None:
        """Offer the fixed colourings and every metadata key of ``bank`` worth colouring by."""
        combo = self.window.color_combo
        combo.blockSignals(True)
        combo.clear()
        for name in ("action", "mode", "motion energy"):
            combo.addItem(name, name)
        for key in meta_keys(bank.meta):
            combo.addItem(key, META_PREFIX + key)
        combo.blockSignals(False)
        index = combo.findData(self.state.color_by)
        if index < 0:
            self.state.color_by = "action"
            index = 0
        combo.setCurrentIndex(index)
        if self.state.color_by == "motion energy" and self.map.energy is None:
            self.map.compute_energy()

    def decoding(self) -> bool:
        """True while a decode request has not been shown yet."""
        return self.decoder.newest > self.playback.shown_request

    def _ask_model(self) -> None:
        path = QFileDialog.getExistingDirectory(self.window, "Open model folder")
        if path:
            self.open_model(path)

    def _ask_data(self) -> None:
        path = QFileDialog.getExistingDirectory(self.window, "Open dataset folder")
        if path:
            self.open_data(path)

    def shutdown(self) -> None:
        """Stop the workers (cancel running tasks, drop pending decodes) and join their threads."""
        self.decoder.shutdown()
        self.tasks.shutdown()
