"""Opening model folders and datasets: the map's preview at once, the generator and the dataset in the
background, File ▸ Open, recent and bundled models; what changes in the window when a model arrives."""

from __future__ import annotations

import logging
from collections.abc import Callable
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np
from PySide6.QtWidgets import QFileDialog

from engine.errors import ModelFormatError, OdmoError
from engine.motion.motion import Motion
from explorer.capabilities import PANEL_TOOLS, gate_tools
from explorer.generation import panel_strategies
from explorer.map_layers import META_PREFIX, category_colors, meta_keys, tooltip_texts
from explorer.model_menu import fill_model_menus, remember_model
from explorer.preview import BankPreview, read_preview
from explorer.workers import Cancel, Progress

if TYPE_CHECKING:
    from engine.generators.base import Generator
    from engine.latent.bank import LatentBank
    from explorer.controller import Controller

log = logging.getLogger(__name__)


class Loader:
    """Loads models and datasets for controller ``c`` and shows a loaded model in its window."""

    def __init__(self, c: Controller) -> None:
        self.c = c
        self._model_task = None
        self.load_error = ""  # why the last model failed to load ("" when it did not)
        self._preview: BankPreview | None = None

    def show_preview(self, path: str | Path) -> bool:
        """Paint the map of ``path``'s latent bank now (numpy only), before its model is loaded.

        Only while no model is shown; clicks decode once the model is loaded. False when the folder
        has no readable bank with a stored map (the full load then reports why).
        """
        path = Path(path)
        if self.c.state.model is not None:
            return False
        if self._preview is not None and self._preview.path == path:
            return True
        preview = read_preview(path)
        if preview is None:
            return False
        name = self.c.state.projection if self.c.state.projection in preview.embeddings else None
        embedding = preview.embeddings[name or next(iter(preview.embeddings))]
        names = preview.action_names
        palette = category_colors(len(names))
        colors = palette[preview.actions]
        w = self.c.window
        w.latent_map.set_legend(names, [tuple(c) for c in palette])
        tips = tooltip_texts(preview.sources, preview.actions, names, preview.meta)
        w.latent_map.set_points(embedding, colors, np.arange(len(embedding)), tips)
        self._preview, self.c.map.drawn = preview, (embedding, colors)
        w.show_status(
            f"Loading model {path.name}… the map shows its {len(embedding)} bank codes; "
            "decoding starts once the model is loaded."
        )
        return True

    def open_model(self, path: str | Path, then: Callable[[], None] | None = None) -> None:
        """Load a model folder in the background; the current one stays until the new one is ready.
        ``then()`` runs on the GUI thread after the model is shown or its failure reported."""
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

        def after(report: Callable[[Any], None]) -> Callable[[Any], None]:
            return lambda result: (report(result), then and then())

        self._model_task = self.c.tasks.run(title, job, after(self._model_ready), after(self._model_failed))

    def _model_failed(self, exc: BaseException) -> None:
        """The model could not be loaded: say why, keep what is shown, remember it (``load_error``)."""
        self.load_error = str(exc) if isinstance(exc, OdmoError) else f"{type(exc).__name__}: {exc}"
        if self._preview is not None and self.c.state.model is None:  # the preview promised a model
            self.c.window.latent_map.set_points(
                np.zeros((0, 2)), np.zeros((0, 4)), np.zeros(0, dtype=np.int64)
            )
            self._preview, self.c.map.drawn = None, None
        self.c.report_error("Cannot open the model", exc)

    def _model_ready(self, loaded: Generator) -> None:
        """Show a loaded model; a bank the app cannot show is reported like a failed load."""
        try:
            self._show_model(loaded)
        except Exception as exc:
            log.exception("showing %s failed", loaded.path)
            self.c.state.model = None
            self.c.state.shown = ()  # nothing of either model keeps playing
            self._model_failed(exc)
            return
        remember_model(self.c.window.settings, loaded.path)
        self.fill_model_menus()

    def fill_model_menus(self) -> None:
        w = self.c.window
        fill_model_menus(w.recent_menu, w.bundled_menu, w.settings, self.open_model)

    def _show_model(self, loaded: Generator) -> None:
        self.c.projections = {k: v for k, v in loaded.bank.projections.items() if v.embedding_ is not None}
        self.c.map.reset()
        self.c.real_clips = {}
        self.c.state.selection = ()
        self.c.state.extra = None
        self.c.state.marker = None
        self.c.state.shown = ()
        if self.c.projections.get(self.c.state.projection) is None:
            self.c.state.embedding = None  # the old model's map must not stand for the new bank
        self.c.state.model = loaded
        self._preview = None
        if self.c.state.data_dir:
            self.open_data(self.c.state.data_dir)

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
            self.c.state.data_dir, self.c.real_clips, count = result
            self.c.window.show_status(
                f"Dataset {Path(result[0]).name}: {count} clips; click a code to play its clip beside it."
            )

        self.c.run_task(f"Loading dataset {path.name}", job, done)

    def model_changed(self, loaded: Generator | None) -> None:
        w = self.c.window
        if loaded is None:
            return
        bank = loaded.bank
        names = list(loaded.label_names)
        w.action_combo.blockSignals(True)
        w.action_combo.clear()
        w.action_combo.addItems(names)
        w.action_combo.setCurrentIndex(0)
        w.action_combo.blockSignals(False)
        self._fill_color_combo(bank)
        w.mode_panel.set_strategies(panel_strategies(loaded))
        gate_tools(w, loaded)
        if set(PANEL_TOOLS.values()) & loaded.capabilities and "end" not in loaded.capabilities:
            w.latent_dock.raise_()  # a kind that sets end locations keeps its trajectory tab in front
        self.rig_viewport()
        self.c.playback.rig = None
        self.c.state.focus_action = 0
        # The legend first: set_legend redraws the points, so after set_points it would draw them twice.
        w.latent_map.set_legend(names, [tuple(c) for c in category_colors(len(names))])
        self.c.map.projection_changed(self.c.state.projection)
        self.c.map.focus_changed(self.c.state.focus_action)
        w.setWindowTitle(f"ODMO Explorer — {loaded.path.name}")
        w.show_status(
            f"Model {loaded.path.name}: {len(bank.codes)} bank codes, {len(names)} actions"
            f"{' (labels: the model is unconditional)' if loaded.action_names is None else ''}, "
            f"{loaded.kind} codes {loaded.code_space.name} of size {loaded.code_space.size}. "
            "Click a point to decode it."
        )
        self.c.modelLoaded.emit(loaded)

    def rig_viewport(self) -> None:
        """Give the 3-D view, once it exists, the loaded model's skeleton (one, until a motion plays)."""
        loaded = self.c.state.model
        if loaded is not None and self.c.window.has_viewport():
            self.c.window.viewport.set_skeletons(loaded.skeleton.parents, 1)

    def _fill_color_combo(self, bank: LatentBank) -> None:
        """Offer the fixed colourings and every metadata key of ``bank`` worth colouring by."""
        combo = self.c.window.color_combo
        combo.blockSignals(True)
        combo.clear()
        for name in ("action", "mode", "motion energy"):
            combo.addItem(name, name)
        for key in meta_keys(bank.meta):
            combo.addItem(key, META_PREFIX + key)
        combo.blockSignals(False)
        index = combo.findData(self.c.state.color_by)
        if index < 0:
            self.c.state.color_by = "action"
            index = 0
        combo.setCurrentIndex(index)
        if self.c.state.color_by == "motion energy" and self.c.map.energy is None:
            self.c.map.compute_energy()

    def ask_model(self) -> None:
        path = QFileDialog.getExistingDirectory(self.c.window, "Open model folder")
        if path:
            self.open_model(path)

    def ask_data(self) -> None:
        path = QFileDialog.getExistingDirectory(self.c.window, "Open dataset folder")
        if path:
            self.open_data(path)
