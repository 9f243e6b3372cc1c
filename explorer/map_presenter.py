"""The map presenter: the latent map's points, colours, key, mode outlines, marked points and hover text,
and the mode panel of the focused action."""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

from explorer.decoding import condition, map_codes
from explorer.map_layers import (
    category_colors,
    color_key,
    gaussian_outline,
    mode_note,
    mode_overlays,
    point_colors,
    tooltips,
)
from explorer.state import ExtraPoints
from explorer.window_actions import PROJECTION_LABELS
from explorer.workers import Cancel, Progress

if TYPE_CHECKING:
    from engine.latent.bank import LatentBank
    from engine.latent.modes import ModeModel
    from engine.latent.projection import Projection
    from explorer.controller import Controller


class MapPresenter:
    """Draws the loaded bank on the latent map for controller ``c`` (it reads the session's state)."""

    def __init__(self, c: Controller) -> None:
        self.c = c
        self.energy: np.ndarray | None = None  # motion energy of every bank code, once computed
        self.weights: dict[int, np.ndarray] = {}  # action -> the mode panel's slider weights
        self.local_mode: tuple[ModeModel, np.ndarray] | None = None  # (fitted mode, its members)
        self.drawn: tuple[np.ndarray, np.ndarray] | None = None  # (embedding, colours) on the map
        self.tips: tuple[object, list[str]] | None = None  # (bank, its tooltips)

    def reset(self) -> None:
        """Forget what belonged to the previous model."""
        self.energy, self.weights, self.local_mode = None, {}, None

    def projection_changed(self, name: str) -> None:
        index = self.c.window.projection_combo.findData(name)
        if index >= 0 and index != self.c.window.projection_combo.currentIndex():
            self.c.window.projection_combo.setCurrentIndex(index)
        label = PROJECTION_LABELS.get(name, name)
        self.c.window.latent_map.set_axis_names(f"{label} 1", f"{label} 2")
        if self.c.state.model is None:
            return
        self.c.state.marker = None
        projection = self.c.projections.get(name)
        if projection is not None:
            self.c.state.embedding = projection.embedding_
            return
        codes = self.c.bank.codes

        def job(progress: Progress, _cancel: Cancel) -> Projection:
            from engine.latent.projection import make_projection

            progress(f"Computing {name} map of {len(codes)} codes", 0.0)
            return make_projection(name, seed=0).fit(codes)

        def done(fitted: Projection) -> None:
            self.c.projections[name] = fitted
            if self.c.state.projection == name:
                self.c.state.embedding = fitted.embedding_

        self.c.run_task(f"Computing {name.upper()} projection", job, done)

    def redraw_map(self, embedding: np.ndarray | None) -> None:
        if self.c.state.model is None:
            return
        lmap = self.c.window.latent_map
        if embedding is None:
            if self.drawn is not None:
                lmap.set_points(np.zeros((0, 2)), np.zeros((0, 4)), np.zeros(0, dtype=np.int64))
                self.drawn = None
            return
        bank = self.c.bank
        colors = point_colors(bank, self.c.state.color_by, self.energy)
        drawn = self.drawn
        # (the preview painted at start-up usually is this very map: then nothing is redrawn)
        if drawn is None or not np.array_equal(drawn[0], embedding):
            lmap.set_points(embedding, colors, np.arange(len(bank.codes)), self._tooltips(bank))
        elif not np.array_equal(drawn[1], colors):
            lmap.set_colors(colors)  # a new colouring keeps the view
        self.drawn = (embedding, colors)
        if self.c.state.hidden_actions:  # set_points shows every point
            self.apply_visibility(self.c.state.hidden_actions)
        if self.c.state.selection or drawn is not None:
            self.apply_selection(self.c.state.selection)
        self._reproject_extra()
        self.draw_overlays()
        self.c.window.latent_map.set_marker(self.c.state.marker)
        lmap.set_key(*color_key(bank, self.c.state.color_by, self.energy))

    def _tooltips(self, bank: LatentBank) -> list[str]:
        """Hover texts of ``bank``'s codes (built once per bank)."""
        if self.tips is None or self.tips[0] is not bank:
            self.tips = (bank, tooltips(bank))
        return self.tips[1]

    def color_by_changed(self, color_by: str) -> None:
        index = self.c.window.color_combo.findData(color_by)
        if index >= 0 and index != self.c.window.color_combo.currentIndex():
            self.c.window.color_combo.setCurrentIndex(index)
        if color_by == "motion energy" and self.energy is None and self.c.state.model is not None:
            self.compute_energy()
        self._recolor()

    def _recolor(self) -> None:
        if self.c.state.embedding is None or self.c.state.model is None:
            return
        self.redraw_map(self.c.state.embedding)

    def compute_energy(self) -> None:
        loaded, bank, with_end = self.c.generator, self.c.bank, self.c.can("end")

        def job(progress: Progress, cancel: Cancel) -> np.ndarray:
            from engine.motion.ops import motion_energy

            energy = np.zeros(len(bank.codes))
            done, chunk = 0, 256
            for action in range(len(bank.action_names)):
                idx = bank.indices_of(action)
                for start in range(0, len(idx), chunk):
                    if cancel():
                        return energy
                    part = idx[start : start + chunk]
                    ends = bank.ends[part].copy() if with_end else None
                    motions = loaded.decode(bank.codes[part].copy(), condition(loaded, action), ends)
                    energy[part] = motion_energy(np.stack([m.joints for m in motions]), loaded.fps)
                    done += len(part)
                    progress("Decoding bank codes for motion energy", done / len(bank.codes))
            return energy

        def finished(energy: np.ndarray) -> None:
            if self.c.state.model is loaded:
                self.energy = energy
                self._recolor()

        self.c.run_task("Motion energy of every bank code", job, finished)

    def apply_visibility(self, hidden: frozenset[int]) -> None:
        if self.c.state.model is None or self.c.state.embedding is None:
            return
        visible = ~np.isin(self.c.bank.actions, list(hidden))
        self.c.window.latent_map.set_visible_mask(visible)

    def legend_toggled(self, action: int, on: bool) -> None:
        hidden = set(self.c.state.hidden_actions)
        (hidden.discard if on else hidden.add)(int(action))
        self.c.state.hidden_actions = frozenset(hidden)

    def apply_selection(self, selection: tuple[int, ...]) -> None:
        if self.c.state.embedding is not None:
            self.c.window.latent_map.set_selection(np.asarray(selection, dtype=np.int64))

    def draw_overlays(self) -> None:
        projection, embedding = self.c.projection, self.c.state.embedding
        if self.c.state.model is None or projection is None or embedding is None:
            return
        curves, colors = mode_overlays(self.c.bank, self.c.state.focus_action, projection, embedding)
        colors = [tuple(c) for c in colors]
        if self.local_mode is not None:
            mode, members = self.local_mode
            curves.append(
                gaussian_outline(mode.means_[0], mode.covariances_[0], projection, embedding[members])
            )
            colors.append((1.0, 0.8, 0.2, 1.0))
        self.c.window.latent_map.set_overlays(curves, colors)

    def draw_extra(self, extra: ExtraPoints | None) -> None:
        if extra is None:
            self.c.window.latent_map.set_extra_points(None)
            return
        colors = category_colors(len(self.c.generator.label_names))[extra.actions]
        self.c.window.latent_map.set_extra_points(extra.xy, colors)

    def _reproject_extra(self) -> None:
        extra, projection = self.c.state.extra, self.c.projection
        if extra is not None and projection is not None:
            xy = projection.transform(map_codes(self.c.generator, extra.codes))
            self.c.state.extra = ExtraPoints(extra.codes, extra.actions, xy)

    def focus_changed(self, action: int) -> None:
        w = self.c.window
        if w.action_combo.currentIndex() != action:
            w.action_combo.setCurrentIndex(action)
        if self.c.state.model is None:
            return
        modes = self.c.bank.modes.get(action)
        name = self.c.generator.label_names[action]
        note = mode_note(modes, len(self.c.bank.indices_of(action)))
        if modes is None:
            w.mode_panel.set_action_modes(name, [], [], 0, [], [], note)
        else:
            ks = sorted(modes.silhouette_)
            weights = self.weights.get(action, modes.weights_ / max(float(np.max(modes.weights_)), 1e-12))
            w.mode_panel.set_action_modes(
                name,
                ks,
                [float(modes.silhouette_[k]) for k in ks],
                int(modes.k_chosen_),
                [int(s) for s in modes.sizes()],
                [float(v) for v in weights],
                note,
            )
        self.draw_overlays()

    def weights_changed(self, weights: object) -> None:
        self.weights[self.c.state.focus_action] = np.asarray(weights, dtype=np.float64)

    def hover(self, index: int) -> None:
        if index < 0 or self.c.state.model is None:
            return
        bank = self.c.bank
        action = bank.action_names[int(bank.actions[index])]
        self.c.window.show_hover(f"#{index}  {bank.sources[index]}  ·  {action}")
