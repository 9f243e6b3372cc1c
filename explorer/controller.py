"""The controller: the one place that connects widget signals, the app state and engine calls.

Torch, scikit-learn and scipy (``engine.generate``, ``engine.modelio``, ``engine.latent``) are imported
where they are used, not here: the window and the map's preview come up before the model is loaded,
and the model-loading task brings them in off the GUI thread.
"""

from __future__ import annotations

import logging
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np
from PySide6.QtCore import QObject, QTimer, Signal
from PySide6.QtWidgets import QFileDialog

from engine.errors import ConfigError, ModelFormatError, OdmoError
from engine.motion.motion import Motion
from explorer.capabilities import gate_tools
from explorer.decoding import decode_one, full_end
from explorer.main_window import MainWindow
from explorer.map_layers import (
    META_PREFIX,
    category_colors,
    color_key,
    gaussian_outline,
    meta_keys,
    mode_labels,
    mode_note,
    mode_overlays,
    motion_energy,
    point_colors,
    tooltip_texts,
    tooltips,
)
from explorer.model_menu import fill_model_menus, remember_model
from explorer.preview import BankPreview, read_preview
from explorer.scene import build_scene
from explorer.state import AppState, Decoded, ExtraPoints
from explorer.workers import Cancel, LatestRunner, Progress, TaskRunner

if TYPE_CHECKING:
    from engine import generate
    from engine.generators.base import Generator
    from engine.latent.bank import LatentBank
    from engine.latent.modes import ModeModel
    from engine.latent.projection import Projection

log = logging.getLogger(__name__)

MAX_PLAYED = 12  # motions played at once from a selection
VARIATIONS = 8
LOCAL_MODE_SAMPLES = 6
LIVE_INTERVAL_MS = (
    150  # during a drag: marker, root path, ghosts, canvas, timeline, status at most this often
)
PANEL_STRATEGIES = {"one_mode": "mode"}  # mode panel key -> engine strategy


class Controller(QObject):
    """Wires a :class:`MainWindow` to an :class:`AppState` and the engine.

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
        self._projections: dict[str, Projection] = {}
        self._energy: np.ndarray | None = None
        self._real: dict[str, Motion] = {}
        self._weights: dict[int, np.ndarray] = {}
        self._local_mode: tuple[ModeModel, np.ndarray] | None = None
        self._drag_from: int | None = None
        self._played: list[Motion] = []
        self._rig: tuple[bytes, int, str] | None = None
        self._model_task = None
        self.load_error = ""  # why the last model failed to load ("" when it did not)
        self._shown_request = 0
        self._preview: BankPreview | None = None
        self._drawn: tuple[np.ndarray, np.ndarray] | None = None  # (embedding, colours) on the map
        self._tips: tuple[object, list[str]] | None = None  # (bank, its tooltips)
        # During a drag only the poses follow every decode; the rest is throttled (see _flush_live).
        self._live = QTimer(self)
        self._live.setSingleShot(True)
        self._live.setInterval(LIVE_INTERVAL_MS)
        self._live.timeout.connect(self._flush_live)
        self._live_marker: np.ndarray | None = None
        self._live_details = False
        self._connect()
        self._fill_model_menus()
        from explorer.encoding import ClipEncoder
        from explorer.exporting import Exporter
        from explorer.finding import Finder

        self.exporter = Exporter(self)
        self.finder = Finder(self)
        self.encoder = ClipEncoder(self)
        self.state.events.embedding.connect(lambda _e: self.encoder.show())

    # -- wiring --------------------------------------------------------------------------------------

    def _connect(self) -> None:
        w, ev = self.window, self.state.events
        w.latent_map.pointClicked.connect(self.click_point)
        w.latent_map.emptyClicked.connect(self.click_empty)
        w.latent_map.extraClicked.connect(self.click_extra)
        w.latent_map.dragStarted.connect(self.drag_start)
        w.latent_map.dragMoved.connect(self.drag_move)
        w.latent_map.dragFinished.connect(self.drag_finish)
        w.latent_map.lassoFinished.connect(self.lasso)
        w.latent_map.hovered.connect(self._hover)
        w.latent_map.legendToggled.connect(self._legend_toggled)
        w.mode_panel.weightsChanged.connect(self._weights_changed)
        w.mode_panel.sampleRequested.connect(self.sample)
        w.timeline.frameChanged.connect(lambda f: setattr(self.state, "frame", int(f)))
        w.trajectory.endRequested.connect(self.set_end)
        w.trajectory.followPathRequested.connect(self.follow_path)

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
        w.select_clip_action.triggered.connect(self.select_clip_windows)
        w.play_selection_action.triggered.connect(self.play_selection)
        w.variations_action.triggered.connect(self.sample_variations)
        w.fit_mode_action.triggered.connect(self.fit_local_mode)
        w.clear_selection_action.triggered.connect(self.clear_selection)
        w.reset_camera_action.triggered.connect(self.reset_camera)
        w.follow_camera_action.toggled.connect(self._follow_camera)
        w.labels_action.toggled.connect(lambda _on: self._show_motions(self.state.shown))
        w.ghosts_spin.valueChanged.connect(lambda _n: self._show_details(self.state.shown, restart=False))
        w.cancel_button.clicked.connect(self.tasks.cancel_all)

        self.decoder.finished.connect(self._decoded)
        self.decoder.failed.connect(self._decode_failed)
        self.tasks.started.connect(self._task_started)
        self.tasks.ended.connect(self._task_ended)

        ev.model.connect(self._model_changed)
        ev.projection.connect(self._projection_changed)
        ev.embedding.connect(self._redraw_map)
        ev.color_by.connect(self._color_by_changed)
        ev.hidden_actions.connect(self._apply_visibility)
        ev.selection.connect(self._apply_selection)
        ev.focus_action.connect(self._focus_changed)
        ev.extra.connect(self._draw_extra)
        ev.marker.connect(lambda m: self.window.latent_map.set_marker(m))
        ev.shown.connect(self._show_motions)
        ev.layout.connect(lambda _l: self._show_motions(self.state.shown))
        ev.frame.connect(self._set_frame)

    # -- helpers -------------------------------------------------------------------------------------

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
        return self._projections.get(self.state.projection)

    def _new_seed(self) -> int:
        return int(self._seeds.spawn(1)[0].generate_state(1)[0])

    def report_error(self, title: str, exc: BaseException | str) -> None:
        """Show an error to the user (message box + status bar) and emit ``errorOccurred``."""
        text = str(exc) if isinstance(exc, OdmoError | str) else f"{type(exc).__name__}: {exc}"
        log.warning("%s: %s", title, text)
        self.window.show_error(title, text)
        self.errorOccurred.emit(text)

    def _guard(self, title: str, fn: Callable[[], Any]) -> Any:
        try:
            return fn()
        except (OdmoError, OSError, ValueError) as exc:
            self.report_error(title, exc)
            return None

    def _run_task(self, title: str, fn: Callable[[Progress, Cancel], Any], on_done: Callable[[Any], None]):
        return self.tasks.run(title, fn, on_done, lambda exc: self.report_error(title, exc))

    def _decode_failed(self, request: int, exc: BaseException) -> None:
        self._shown_request = max(self._shown_request, request)
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

    # -- model and data ------------------------------------------------------------------------------

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
        self._preview, self._drawn = preview, (embedding, colors)
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
            self._preview, self._drawn = None, None
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
        self._projections = {k: v for k, v in loaded.bank.projections.items() if v.embedding_ is not None}
        self._energy = None
        self._weights = {}
        self._local_mode = None
        self._real = {}
        self.state.selection = ()
        self.state.extra = None
        self.state.marker = None
        self.state.shown = ()
        if self._projections.get(self.state.projection) is None:
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
            self.state.data_dir, self._real, count = result
            self.window.show_status(
                f"Dataset {Path(result[0]).name}: {count} clips; click a code to play its clip beside it."
            )

        self._run_task(f"Loading dataset {path.name}", job, done)

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
        self._rig = None
        self.state.focus_action = 0
        # The legend first: set_legend redraws the points, so after set_points it would draw them twice.
        w.latent_map.set_legend(names, [tuple(c) for c in category_colors(len(names))])
        self._projection_changed(self.state.projection)
        self._focus_changed(self.state.focus_action)
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
        if self.state.color_by == "motion energy" and self._energy is None:
            self._compute_energy()

    # -- map -----------------------------------------------------------------------------------------

    def _projection_changed(self, name: str) -> None:
        index = self.window.projection_combo.findData(name)
        if index >= 0 and index != self.window.projection_combo.currentIndex():
            self.window.projection_combo.setCurrentIndex(index)
        label = {"pca": "PCA", "tsne": "t-SNE", "umap": "UMAP"}.get(name, name)
        self.window.latent_map.set_axis_names(f"{label} 1", f"{label} 2")
        if self.state.model is None:
            return
        self.state.marker = None
        projection = self._projections.get(name)
        if projection is not None:
            self.state.embedding = projection.embedding_
            return
        codes = self.bank.codes

        def job(progress: Progress, _cancel: Cancel) -> Projection:
            from engine.latent.projection import make_projection

            progress(f"Computing {name} map of {len(codes)} codes", 0.0)
            return make_projection(name, seed=0).fit(codes)

        def done(fitted: Projection) -> None:
            self._projections[name] = fitted
            if self.state.projection == name:
                self.state.embedding = fitted.embedding_

        self._run_task(f"Computing {name.upper()} projection", job, done)

    def _redraw_map(self, embedding: np.ndarray | None) -> None:
        if self.state.model is None:
            return
        lmap = self.window.latent_map
        if embedding is None:
            if self._drawn is not None:
                lmap.set_points(np.zeros((0, 2)), np.zeros((0, 4)), np.zeros(0, dtype=np.int64))
                self._drawn = None
            return
        bank = self.bank
        colors = point_colors(bank, self.state.color_by, self._energy)
        drawn = self._drawn
        if drawn is None or not (np.array_equal(drawn[0], embedding) and np.array_equal(drawn[1], colors)):
            # (the preview painted at start-up usually is this very map: then nothing is redrawn)
            lmap.set_points(embedding, colors, np.arange(len(bank.codes)), self._tooltips(bank))
            self._drawn = (embedding, colors)
        if self.state.hidden_actions:  # set_points shows every point
            self._apply_visibility(self.state.hidden_actions)
        if self.state.selection or drawn is not None:
            self._apply_selection(self.state.selection)
        self._reproject_extra()
        self._draw_overlays()
        self.window.latent_map.set_marker(self.state.marker)
        lmap.set_key(*color_key(bank, self.state.color_by, self._energy))

    def _tooltips(self, bank: LatentBank) -> list[str]:
        """Hover texts of ``bank``'s codes (built once per bank)."""
        if self._tips is None or self._tips[0] is not bank:
            self._tips = (bank, tooltips(bank))
        return self._tips[1]

    def _color_by_changed(self, color_by: str) -> None:
        index = self.window.color_combo.findData(color_by)
        if index >= 0 and index != self.window.color_combo.currentIndex():
            self.window.color_combo.setCurrentIndex(index)
        if color_by == "motion energy" and self._energy is None and self.state.model is not None:
            self._compute_energy()
        self._recolor()

    def _recolor(self) -> None:
        if self.state.embedding is None or self.state.model is None:
            return
        self._redraw_map(self.state.embedding)

    def _compute_energy(self) -> None:
        loaded, bank, with_end = self.generator, self.bank, self.can("end")

        def job(progress: Progress, cancel: Cancel) -> np.ndarray:
            energy = np.zeros(len(bank.codes))
            done, chunk = 0, 256
            for action in range(len(bank.action_names)):
                idx = bank.indices_of(action)
                for start in range(0, len(idx), chunk):
                    if cancel():
                        return energy
                    part = idx[start : start + chunk]
                    ends = bank.ends[part].copy() if with_end else None
                    motions = loaded.decode(bank.codes[part].copy(), bank.action_names[action], ends)
                    energy[part] = motion_energy(np.stack([m.joints for m in motions]), loaded.fps)
                    done += len(part)
                    progress("Decoding bank codes for motion energy", done / len(bank.codes))
            return energy

        def finished(energy: np.ndarray) -> None:
            if self.state.model is loaded:
                self._energy = energy
                self._recolor()

        self._run_task("Motion energy of every bank code", job, finished)

    def _apply_visibility(self, hidden: frozenset[int]) -> None:
        if self.state.model is None or self.state.embedding is None:
            return
        visible = ~np.isin(self.bank.actions, list(hidden))
        self.window.latent_map.set_visible_mask(visible)

    def _legend_toggled(self, action: int, on: bool) -> None:
        hidden = set(self.state.hidden_actions)
        (hidden.discard if on else hidden.add)(int(action))
        self.state.hidden_actions = frozenset(hidden)

    def _apply_selection(self, selection: tuple[int, ...]) -> None:
        if self.state.embedding is not None:
            self.window.latent_map.set_selection(np.asarray(selection, dtype=np.int64))

    def _draw_overlays(self) -> None:
        projection, embedding = self.projection, self.state.embedding
        if self.state.model is None or projection is None or embedding is None:
            return
        curves, colors = mode_overlays(self.bank, self.state.focus_action, projection, embedding)
        colors = [tuple(c) for c in colors]
        if self._local_mode is not None:
            mode, members = self._local_mode
            curves.append(
                gaussian_outline(mode.means[0], mode.covariances[0], projection, embedding[members])
            )
            colors.append((1.0, 0.8, 0.2, 1.0))
        self.window.latent_map.set_overlays(curves, colors)

    def _draw_extra(self, extra: ExtraPoints | None) -> None:
        if extra is None:
            self.window.latent_map.set_extra_points(None)
            return
        colors = category_colors(len(self.generator.action_names))[extra.actions]
        self.window.latent_map.set_extra_points(extra.xy, colors)

    def _reproject_extra(self) -> None:
        extra, projection = self.state.extra, self.projection
        if extra is not None and projection is not None:
            self.state.extra = ExtraPoints(extra.codes, extra.actions, projection.transform(extra.codes))

    def _focus_changed(self, action: int) -> None:
        w = self.window
        if w.action_combo.currentIndex() != action:
            w.action_combo.setCurrentIndex(action)
        if self.state.model is None:
            return
        modes = self.bank.modes.get(action)
        name = self.generator.action_names[action]
        note = mode_note(modes, len(self.bank.indices_of(action)))
        if modes is None:
            w.mode_panel.set_action_modes(name, [], [], 0, [], [], note)
        else:
            ks = sorted(modes.silhouette)
            weights = self._weights.get(action, modes.weights / max(float(np.max(modes.weights)), 1e-12))
            w.mode_panel.set_action_modes(
                name,
                ks,
                [float(modes.silhouette[k]) for k in ks],
                int(modes.k_chosen),
                [int(s) for s in modes.sizes()],
                [float(v) for v in weights],
                note,
            )
        self._draw_overlays()

    def _weights_changed(self, weights: object) -> None:
        self._weights[self.state.focus_action] = np.asarray(weights, dtype=np.float64)

    def _hover(self, index: int) -> None:
        if index < 0 or self.state.model is None:
            return
        bank = self.bank
        action = bank.action_names[int(bank.actions[index])]
        self.window.show_hover(f"#{index}  {bank.sources[index]}  ·  {action}")

    # -- gestures ------------------------------------------------------------------------------------

    def bank_item(self, index: int) -> tuple[np.ndarray, int, np.ndarray]:
        """(code, action, end) of bank code ``index`` (copies: the bank's arrays are read-only)."""
        bank = self.bank
        return bank.codes[index].copy(), int(bank.actions[index]), bank.ends[index].copy()

    def select_index(self, index: int) -> None:
        """Click bank code ``index`` as the map would (``--select``); an index out of range is reported."""
        if self.state.model is None:
            return
        if not 0 <= index < len(self.bank.codes):
            self.report_error(
                "Cannot select", f"bank index {index} is out of range 0..{len(self.bank.codes) - 1}"
            )
            return
        self.click_point(index)

    def decoding(self) -> bool:
        """True while a decode request has not been shown yet."""
        return self.decoder.newest > self._shown_request

    def click_extra(self, k: int) -> None:
        """Decode and play marked point ``k`` (a sample, a variation or an encoded clip's window)."""
        extra = self.state.extra
        if self.state.model is None or extra is None or not 0 <= k < len(extra.codes):
            return
        self.state.marker = None
        code, action = extra.codes[k].copy(), int(extra.actions[k])
        self._decode_code(code, action, f"marked point {k + 1}/{len(extra.codes)}")

    def click_point(self, index: int) -> None:
        """Select bank code ``index``, decode it (with the real clip beside it when data is loaded), play."""
        if self.state.model is None:
            return
        self.state.selection = (int(index),)
        self.state.marker = None
        self.state.extra = None  # the samples' diamonds belong to the samples, which no longer play
        self._decode_bank([int(index)], with_real=True)

    def _decode_bank(self, indices: Sequence[int], with_real: bool = False, note: str = "") -> None:
        bank, real, generator = self.bank, self._real, self.generator

        def job() -> tuple[Decoded, ...]:
            items = []
            labels = mode_labels(bank)
            for i in indices:
                code, action, end = self.bank_item(i)
                mode = None if labels[i] < 0 else int(labels[i])
                motion = decode_one(generator, code, action, end, mode)
                name = f"#{i} {bank.sources[i]}"
                items.append(Decoded(motion, f"{name} (decoded)", code, action, end, mode, None, i, note))
                source = str(bank.sources[i])  # the bank may name the clip from another root folder
                clip = real.get(source, real.get(Path(source).stem)) if with_real else None
                if clip is not None:  # the window the code encodes, placed and turned as the decode is
                    start = bank.meta[i].get("window_start") if "window_stride" in bank.meta[i] else None
                    window = generator.real_window(clip, start)
                    items.append(Decoded(window, f"{name} (real clip)", None, action))
            return tuple(items)

        self.decoder.submit(job)

    def click_empty(self, x: float, y: float) -> None:
        """Decode the code under map position (x, y) for the nearest visible point's action; mark it."""
        if self.state.model is None or self.projection is None:
            return
        self._guard("Decoding failed", lambda: self._decode_at(np.array([x, y]), mark=True))

    def _code_at(self, xy: np.ndarray) -> tuple[np.ndarray, int]:
        """(code, action) under map point ``xy``: the projection's inverse, the nearest visible action."""
        code = self.projection.inverse_transform(xy[None])[0].astype(np.float32)
        visible = np.flatnonzero(~np.isin(self.bank.actions, list(self.state.hidden_actions)))
        if len(visible) == 0:
            raise ConfigError("every action is hidden; show one in the legend")
        nearest = visible[np.argmin(np.linalg.norm(self.state.embedding[visible] - xy, axis=1))]
        return code, int(self.bank.actions[nearest])

    def _decode_at(self, xy: np.ndarray, mark: bool) -> None:
        code, action = self._code_at(xy)
        if mark:
            self.state.selection = ()
            self.state.marker = xy.astype(np.float64)
        self._decode_code(code, action, f"map point ({xy[0]:.2f}, {xy[1]:.2f})")

    def _decode_code(
        self,
        code: np.ndarray | None,
        action: int,
        label: str,
        end: np.ndarray | None = None,
        xy: np.ndarray | None = None,
    ) -> int:
        """Decode ``code`` (or, when None, the inverse projection of map point ``xy``) in the worker."""
        loaded, bank, projection = self.generator, self.bank, self.projection

        def job() -> tuple[Decoded, ...]:
            nonlocal code
            if code is None:
                code = projection.inverse_transform(np.asarray(xy, np.float64)[None])[0].astype(np.float32)
            e = full_end(loaded, code, action, end)
            modes = bank.modes.get(action)
            mode = None if modes is None else int(modes.predict(code[None])[0])
            motion = decode_one(loaded, code, action, e, mode)
            return (Decoded(motion, label, code, action, e, mode),)

        return self.decoder.submit(job)

    def drag_start(self, index: int) -> None:
        """Start dragging from bank code ``index``."""
        if self.state.model is not None:
            self._drag_from = int(index)
            self.state.selection = (int(index),)

    def drag_move(self, x: float, y: float) -> None:
        """Live-decode the code under the cursor (only the newest request is decoded)."""
        if self._drag_from is None or self.projection is None:
            return
        xy = np.array([x, y])
        target = self._snap(xy)
        if target is not None:
            code, action, end = self.bank_item(target)
            self._decode_code(code, action, f"drag → #{target}", end)
        else:  # the inverse projection runs in the worker too
            action = int(self.bank.actions[self._drag_from])
            self._decode_code(None, action, f"drag → ({x:.2f}, {y:.2f})", xy=xy)
        self._live_marker = xy  # the map marker follows at the throttled rate (a repaint of every point)
        self._schedule_live()

    def drag_finish(self, x: float, y: float) -> None:
        """Leave an interpolation strip from the drag's start to the point (or position) released on."""
        start, self._drag_from = self._drag_from, None
        self._live_marker = None
        if start is None or self.projection is None:
            return
        xy = np.array([x, y])
        target = self._snap(xy)
        # released on a code: both ends are selected (ringed); in empty space the star marks the end
        self.state.marker = None if target is not None else xy.astype(np.float64)
        code_a, action, end_a = self.bank_item(start)
        action_b = action
        if target is not None:
            code_b, action_b, end_b = self.bank_item(target)
            self.state.selection = (start, target)
            what = f"#{start} → #{target}"
        else:
            code_b = self._code_at(xy)[0]
            end_b = self.bank.end_location(code_b[None], action)[0]
            what = f"#{start} → ({x:.2f}, {y:.2f})"
        self.interpolate(code_a, code_b, action, end_a, end_b, what, action_b)

    def _snap(self, xy: np.ndarray) -> int | None:
        """Bank index of the visible point drawn within a few pixels of map position ``xy``, else None."""
        embedding = self.state.embedding
        visible = np.flatnonzero(~np.isin(self.bank.actions, list(self.state.hidden_actions)))
        if embedding is None or len(visible) == 0:
            return None
        nearest = int(visible[np.argmin(np.linalg.norm(embedding[visible] - xy, axis=1))])
        to_px = self.window.latent_map.data_to_widget
        a, b = to_px(embedding[nearest]), to_px(xy)
        return nearest if np.hypot(a.x() - b.x(), a.y() - b.y()) <= 10.0 else None

    def interpolate(
        self,
        code_a: np.ndarray,
        code_b: np.ndarray,
        action: int,
        end_a: np.ndarray | None,
        end_b: np.ndarray | None,
        what: str,
        action_b: int | None = None,
    ) -> None:
        """Decode the strip of ``steps`` codes from ``code_a`` to ``code_b`` and show them.

        Between two actions (``action_b`` given and different) the engine's cross-action rule is used
        and the status bar says so: each step is decoded as the likelier of the two actions.
        """
        loaded, steps = self.generator, self.window.steps_spin.value()
        across = action_b is not None and action_b != action
        names = loaded.action_names
        if self.refuse("interpolate_across" if across else "interpolate"):
            return
        ends = {"end_a": end_a, "end_b": end_b} if self.can("end") else {}

        def job() -> tuple[Decoded, ...]:
            from engine import generate

            if across:
                pair = (code_a, names[action], code_b, names[action_b])
                samples = loaded.interpolate_across(*pair, steps, **ends)
            else:
                samples = loaded.interpolate(code_a, code_b, names[action], steps, **ends)
            note = f"{names[action]} → {names[action_b]}: {generate.ACROSS_RULE}" if across else ""
            return tuple(
                Decoded(
                    s.motion,
                    f"{what} step {k + 1}/{steps} {names[s.action]}",
                    s.code,
                    s.action,
                    s.end,
                    s.mode,
                    note=note,
                )
                for k, s in enumerate(samples)
            )

        self.decoder.submit(job)

    def lasso(self, polygon: object) -> None:
        """Select the visible bank codes inside ``polygon`` (M, 2)."""
        if self.state.model is None or self.state.embedding is None:
            return
        from engine.latent.geometry import points_in_polygon

        inside = points_in_polygon(self.state.embedding, np.asarray(polygon, dtype=np.float64))
        inside &= ~np.isin(self.bank.actions, list(self.state.hidden_actions))
        self.state.selection = tuple(int(i) for i in np.flatnonzero(inside))
        self.state.marker = None
        self.window.show_status(
            f"Lasso selected {len(self.state.selection)} codes (Selection menu: play, …)."
        )

    def clear_selection(self) -> None:
        """Forget the selection, the samples on the map, the marker and the local mode."""
        self.state.selection = ()
        self.state.extra = None
        self.state.marker = None
        self._local_mode = None
        self._draw_overlays()

    def select_clip_windows(self) -> None:
        """Select the windows of the playing bank code's clip (a bank built with a stride holds several)."""
        index = next((d.bank_index for d in self.state.shown if d.bank_index is not None), None)
        if index is None:
            self.window.show_status("Play a code of the bank first: its clip's windows are then selected.")
            return
        windows = self.bank.windows_of(index)
        self.state.selection = tuple(int(i) for i in windows)
        self.window.show_status(
            f"{len(windows)} window(s) of {self.bank.sources[index]} selected; "
            "Selection ▸ Play selection plays them in time order."
        )

    def play_selection(self) -> None:
        """Decode up to ``MAX_PLAYED`` selected codes that cover the selection and play them together.

        The codes are spread over the selection in the full latent space, each action getting a share
        in proportion to its count (not the first codes by bank index); the status says which.
        """
        selection = np.asarray(self.state.selection, dtype=np.int64)
        if not len(selection):
            return
        from engine.latent.neighbours import spread_subset

        bank = self.bank
        picked = selection[spread_subset(bank.codes[selection], bank.actions[selection], MAX_PLAYED)]
        note = _selection_note(picked, selection, bank)
        self._decode_bank([int(i) for i in picked], with_real=len(selection) == 1, note=note)

    def _selection_summary(self) -> tuple[np.ndarray, int, float]:
        """(centroid code, majority action, radius) of the selection."""
        sel = np.asarray(self.state.selection, dtype=np.int64)
        if len(sel) == 0:
            raise ConfigError("select codes first (click a point or draw a lasso)")
        bank = self.bank
        codes = bank.codes[sel].astype(np.float64)
        centre = codes.mean(axis=0)
        action = int(np.bincount(bank.actions[sel]).argmax())
        spread = float(np.linalg.norm(codes - centre, axis=1).mean())
        if spread == 0.0:
            same = bank.codes[bank.indices_of(action)]
            spread = 0.25 * float(np.median(np.linalg.norm(same - same.mean(axis=0), axis=1)))
        return centre.astype(np.float32), action, spread

    def sample_variations(self) -> None:
        """Decode variations around the selection (the engine's ``neighbours``) and put them on the map."""
        summary = self._guard("Cannot sample variations", self._selection_summary)
        if summary is None:
            return
        centre, action, radius = summary
        loaded, seed = self.generator, self._new_seed()
        name = loaded.action_names[action]
        self._run_task(
            "Sampling variations",
            lambda _p, _c: loaded.vary(centre, name, VARIATIONS, radius, seed),
            lambda samples: self._samples_ready(samples, seed, "variation"),
        )

    def fit_local_mode(self) -> None:
        """Fit one Gaussian to the selected codes, outline it on the map and sample from it."""
        sel = np.asarray(self.state.selection, dtype=np.int64)
        if len(sel) < 3:
            self.report_error("Cannot fit a local mode", "select at least 3 codes with the lasso")
            return
        from engine import generate
        from engine.latent.modes import ModeModel

        loaded, bank, with_end = self.generator, self.bank, self.can("end")
        action = int(np.bincount(bank.actions[sel]).argmax())
        codes = bank.codes[sel].astype(np.float64)
        mean = codes.mean(axis=0)
        cov = np.cov(codes, rowvar=False) + 1e-6 * np.eye(codes.shape[1])
        local = ModeModel(
            weights=np.ones(1),
            means=mean[None],
            covariances=cov[None],
            labels=np.zeros(len(sel), dtype=np.int64),
            silhouette={},
            k_chosen=1,
            conventional_mean=mean,
            conventional_cov=cov,
        )
        self._local_mode = (local, sel)
        self._draw_overlays()
        seed = self._new_seed()

        def job(_p: Progress, _c: Cancel) -> list[generate.Sample]:
            codes, _ = local.sample(LOCAL_MODE_SAMPLES, np.random.default_rng(seed), strategy="mode", mode=0)
            motions = loaded.decode(codes, loaded.action_names[action])
            ends = bank.end_location(codes, action) if with_end else [None] * len(codes)
            return [
                generate.Sample(c.astype(np.float32), action, -1, e, m)
                for c, e, m in zip(codes, ends, motions, strict=True)
            ]

        self._run_task("Sampling the local mode", job, lambda s: self._samples_ready(s, seed, "local mode"))

    def sample(self, strategy: str, n: int, mode: int) -> None:
        """Draw ``n`` samples of the focused action (mode panel's Sample buttons) and show them."""
        if self.state.model is None or self.refuse("sample"):
            return
        loaded, action, seed = self.generator, self.state.focus_action, self._new_seed()
        strategy = PANEL_STRATEGIES.get(strategy, strategy)
        weights = self._weights.get(action) if strategy == "weights" else None
        from engine.generators.base import SampleRequest

        request = SampleRequest(
            loaded.action_names[action],
            int(n),
            seed,
            strategy,
            None if mode < 0 else int(mode),
            weights=None if weights is None else tuple(float(w) for w in weights),
        )

        def job(_p: Progress, _c: Cancel) -> list[generate.Sample]:
            return loaded.sample(request)

        self._run_task(
            f"Sampling {n} × {loaded.action_names[action]}",
            job,
            lambda s: self._samples_ready(s, seed, strategy.replace("_", "-")),
        )

    def _samples_ready(self, samples: list[generate.Sample], seed: int, what: str) -> None:
        if not samples:
            return
        codes = np.stack([s.code for s in samples]).astype(np.float32)
        actions = np.array([s.action for s in samples], dtype=np.int64)
        xy = self.projection.transform(codes) if self.projection is not None else np.zeros((len(codes), 2))
        self.state.extra = ExtraPoints(codes, actions, xy)
        names = self.generator.action_names
        self.state.shown = tuple(
            Decoded(
                s.motion,
                f"{what} {k + 1}/{len(samples)} {names[s.action]}"
                + (f" mode {s.mode}" if s.mode >= 0 else ""),
                s.code,
                s.action,
                s.end,
                s.mode if s.mode >= 0 else None,
                seed,
            )
            for k, s in enumerate(samples)
        )

    def set_end(self, x: float, z: float) -> None:
        """Re-decode the current code with its end location moved to floor point (x, z)."""
        current = next((d for d in self.state.shown if d.code is not None), None)
        if self.refuse("end") or current is None:
            return
        label = current.label.split(" · end (")[0]
        self._decode_code(current.code, current.action, f"{label} · end ({x:.2f}, {z:.2f})", np.array([x, z]))

    def follow_path(self, path: object) -> None:
        """Ask the engine for the code of the focused action whose root path follows ``path`` (K, 2)."""
        if self.state.model is None or self.refuse("follow_path"):
            return
        shown = next((d for d in self.state.shown if d.code is not None), None)
        loaded = self.generator
        action = shown.action if shown is not None else self.state.focus_action  # the motion playing
        path_xz = np.asarray(path, dtype=np.float64)
        length = float(np.linalg.norm(np.diff(path_xz, axis=0), axis=1).sum())

        def job(progress: Progress, _c: Cancel) -> generate.PathResult:
            progress("Optimising a code to follow the path", 0.0)
            return loaded.follow_path(path_xz, loaded.action_names[action])

        def done(result: generate.PathResult) -> None:
            share = result.path_error_m / max(length, 1e-9)
            label = (
                f"follow path · {loaded.action_names[action]} · error {result.path_error_m:.3f} m "
                f"({share:.0%} of {length:.1f} m)"
            )
            item = Decoded(result.motion, label, result.code, action, result.end)
            self.state.shown = (item,)
            self.window.trajectory.set_generated(_root_xz(result.motion), result.path_error_m)

        self._run_task("Following the path", job, done)

    # -- showing motions -----------------------------------------------------------------------------

    def _decoded(self, request: int, items: tuple[Decoded, ...]) -> None:
        self._shown_request = max(self._shown_request, request)
        self.state.shown = items

    def _show_motions(self, shown: tuple[Decoded, ...]) -> None:
        """Put ``shown`` in the viewport: the poses and end marker at once; during a drag, the rest
        (root path, ghosts, trajectory canvas, timeline, status) at most every ``DETAILS_INTERVAL_MS``."""
        w = self.window
        if not shown:
            return
        loaded = self.generator
        scene = build_scene(shown, self.state.layout, loaded.root_height, loaded.action_names)
        played = scene.played
        self._played = played
        live = self._drag_from is not None
        rig = (played[0].skeleton.parents.tobytes(), len(played), self.state.layout)
        if rig != self._rig:  # rebuilding the actors is the slow part of an update: only when needed
            self._rig, live = rig, False
            w.viewport.set_skeletons(played[0].skeleton.parents, len(played))
            w.viewport.set_layout("overlay" if self.state.layout == "overlay" else "side_by_side", 1.0)
        w.viewport.set_colors(_skeleton_colors(shown, len(played), len(loaded.action_names)))
        lead = w.viewport.offsets[0]  # the end marker and root path belong to the first skeleton
        w.viewport.set_end_marker(None if scene.end is None else scene.end + lead)
        w.viewport.set_labels(scene.labels if w.labels_action.isChecked() else None)
        if live:  # keep playing from the current frame; the timeline catches up with the details
            self._set_frame(self.state.frame)
            self._live_details = True
            self._schedule_live()
        else:
            self._live_details = False
            self._show_details(shown, restart=True)
            if shown[0].code is not None:  # the Action box and the mode panel follow what plays
                self.state.focus_action = int(shown[0].action)
        self.shownChanged.emit()

    def reset_camera(self) -> None:
        """Aim the camera at the whole of what plays (every frame), as after a decode."""
        played = self._played
        if played:
            length = max(m.n_frames for m in played)
            self.window.viewport.frame_motion(padded_frames(played, length))
        else:
            self.window.viewport.reset_camera()

    def _follow_camera(self, on: bool) -> None:
        self.window.viewport.set_follow(on)
        if not on:
            self.reset_camera()

    def _schedule_live(self) -> None:
        """Flush the throttled part of a drag's updates within ``LIVE_INTERVAL_MS`` (at most that often)."""
        if not self._live.isActive():
            self._live.start()

    def _flush_live(self) -> None:
        """The throttled part of a drag: the map marker and the details of the motion shown."""
        if self._live_marker is not None:
            self.state.marker, self._live_marker = self._live_marker, None
        if self._live_details:
            self._live_details = False
            self._show_details(self.state.shown, restart=False)

    def _show_details(self, shown: tuple[Decoded, ...], restart: bool) -> None:
        """Root path, ghost trail, trajectory canvas, timeline and status text of ``shown``;
        ``restart`` plays from frame 0."""
        w, played = self.window, self._played
        if not shown or not played:
            return
        first = played[0]
        w.viewport.set_trajectory(first.joints[:, first.skeleton.root] + w.viewport.offsets[0])
        count = w.ghosts_spin.value()
        ghosts = first.joints[np.unique(np.linspace(0, first.n_frames - 1, count).round().astype(int))]
        w.viewport.set_ghosts(ghosts if len(played) == 1 and count > 0 else None)
        w.trajectory.set_generated(_root_xz(first), None)
        length = max(m.n_frames for m in played)
        frame = 0 if restart else min(self.state.frame, length - 1)
        w.timeline.set_length(length, first.fps)
        if restart:
            w.timeline.set_frame(0)
            if not w.viewport.follow:
                w.viewport.frame_motion(padded_frames(played, length))
        else:  # during a drag: re-aim only when the new motion leaves the view
            w.viewport.keep_in_view(padded_frames(played, length))
        self.state.frame = frame
        self._set_frame(frame)
        if restart or not w.timeline.is_playing():
            w.timeline.play()
        head = shown[0]
        more = f" (+{len(shown) - 1} more)" if len(shown) > 1 else ""
        mode = "" if head.mode is None else f" · mode {head.mode}"
        end = "" if head.end is None else " · end ({:.2f}, {:.2f}, {:.2f}) m".format(*np.ravel(head.end))
        note = f" · {head.note}" if head.note else ""
        w.show_status(
            f"Playing {head.label}{more} · {head.motion.action}{mode}{end} · "
            f"{first.n_frames} frames @ {first.fps:g} fps{note}"
        )

    def _set_frame(self, frame: int) -> None:
        played = self._played
        if not played:
            return
        poses = np.stack([m.joints[min(frame, m.n_frames - 1)] for m in played])
        self.window.viewport.set_poses(poses)

    def _ask_model(self) -> None:
        path = QFileDialog.getExistingDirectory(self.window, "Open model folder")
        if path:
            self.open_model(path)

    def _ask_data(self) -> None:
        path = QFileDialog.getExistingDirectory(self.window, "Open dataset folder")
        if path:
            self.open_data(path)

    # -- lifetime ------------------------------------------------------------------------------------

    def shutdown(self) -> None:
        """Stop the workers (cancel running tasks, drop pending decodes) and join their threads."""
        self.decoder.shutdown()
        self.tasks.shutdown()


def _selection_note(picked: np.ndarray, selection: np.ndarray, bank: LatentBank) -> str:
    """'playing 12 of 57 selected (8 walk, 4 run), spread over the selection' (or '' for all)."""
    if len(picked) == len(selection):
        return f"playing all {len(selection)} selected"
    counts = np.bincount(bank.actions[picked], minlength=len(bank.action_names))
    parts = ", ".join(f"{c} {bank.action_names[a]}" for a, c in enumerate(counts) if c)
    return f"playing {len(picked)} of {len(selection)} selected ({parts}), spread over the selection"


def _skeleton_colors(shown: Sequence[Decoded], n: int, n_actions: int) -> np.ndarray:
    """(n, 3) uint8 skeleton colours: each motion's action colour (as on the map), in lighter to darker
    shades when several share an action; real clips are light grey."""
    from widgets._colors import palette_rgb, shades

    palette = palette_rgb(max(n_actions, 1))
    rows = np.zeros((len(shown), 3), dtype=np.uint8)
    actions = np.array([d.action for d in shown])
    for action in np.unique(actions):
        same = [k for k, d in enumerate(shown) if d.action == action and d.code is not None]
        if same:
            rows[same] = shades(palette[int(action) % len(palette)], len(same))
    rows[[k for k, d in enumerate(shown) if d.code is None]] = (205, 205, 205)
    return rows[:n]


def padded_frames(motions: Sequence[Motion], length: int) -> np.ndarray:
    """(n, length, J, 3) joints of ``motions``, each padded with its last frame (for framing the view)."""
    return np.stack(
        [np.concatenate([m.joints, np.repeat(m.joints[-1:], length - m.n_frames, 0)]) for m in motions]
    )


def _root_xz(motion: Motion) -> np.ndarray:
    """(T, 2) floor path (x, z) of the motion's root."""
    return motion.joints[:, motion.skeleton.root][:, [0, 2]].astype(np.float64)
