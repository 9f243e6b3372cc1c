"""Gestures on the map: click, click in empty space, drag, lasso, the selection; each becomes a decode
request for the session's worker."""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from engine.errors import ConfigError
from explorer.requests import BankDecode, CodeDecode, StripDecode, frozen_array

if TYPE_CHECKING:
    from engine.latent.bank import LatentBank
    from explorer.controller import Controller


MAX_PLAYED = 12  # motions played at once from a selection


class Gestures:
    """The map gestures of controller ``c``."""

    def __init__(self, c: Controller) -> None:
        self.c = c
        self.drag_from: int | None = None  # bank index a drag started on

    def bank_item(self, index: int) -> tuple[np.ndarray, int, np.ndarray | None]:
        """(code, action, end) of bank code ``index`` (copies: the bank's arrays are read-only; the end is
        None for kinds that take none)."""
        bank = self.c.bank
        end = bank.ends[index].copy() if self.c.can("end") else None
        return bank.codes[index].copy(), int(bank.actions[index]), end

    def select_index(self, index: int) -> None:
        """Click bank code ``index`` as the map would (``--select``); an index out of range is reported."""
        if self.c.state.model is None:
            return
        if not 0 <= index < len(self.c.bank.codes):
            self.c.report_error(
                "Cannot select", f"bank index {index} is out of range 0..{len(self.c.bank.codes) - 1}"
            )
            return
        self.click_point(index)

    def click_extra(self, k: int) -> None:
        """Decode and play marked point ``k`` (a sample, a variation or an encoded clip's window)."""
        extra = self.c.state.extra
        if self.c.state.model is None or extra is None or not 0 <= k < len(extra.codes):
            return
        self.c.state.marker = None
        code, action = extra.codes[k].copy(), int(extra.actions[k])
        label = f"marked point {k + 1}/{len(extra.codes)}"
        self.c.state.pick(code, label, action)
        self.decode_code(code, action, label)

    def click_point(self, index: int) -> None:
        """Select bank code ``index``, decode it (with the real clip beside it when data is loaded), play."""
        if self.c.state.model is None:
            return
        self.c.state.selection = (int(index),)
        self.c.state.marker = None
        self.c.state.extra = None  # the samples' diamonds belong to the samples, which no longer play
        bank = self.c.bank
        self.c.state.pick(bank.codes[index], f"#{index} {bank.sources[index]}", int(bank.actions[index]))
        self._decode_bank([int(index)], with_real=True)

    def _decode_bank(self, indices: Sequence[int], with_real: bool = False, note: str = "") -> None:
        bank, real = self.c.bank, self.c.real_clips
        clips = []
        for i in indices:
            source = str(bank.sources[i])  # the bank may name the clip from another root folder
            clips.append(real.get(source, real.get(Path(source).stem)) if with_real else None)
        request = BankDecode(self.c.generator, bank, tuple(int(i) for i in indices), tuple(clips), note)
        self.c.decoder.submit(request.run)

    def click_empty(self, x: float, y: float) -> None:
        """Decode the code under map position (x, y) for the nearest visible point's action; mark it."""
        if self.c.state.model is None or self.c.projection is None:
            return
        self.c.guard("Decoding failed", lambda: self._decode_at(np.array([x, y]), mark=True))

    def _code_at(self, xy: np.ndarray) -> tuple[np.ndarray, int]:
        """(code, action) under map point ``xy``: the projection's inverse, the nearest visible action."""
        code = self.c.projection.inverse_transform(xy[None])[0].astype(np.float32)
        visible = np.flatnonzero(~np.isin(self.c.bank.actions, list(self.c.state.hidden_actions)))
        if len(visible) == 0:
            raise ConfigError("every action is hidden; show one in the legend")
        nearest = visible[np.argmin(np.linalg.norm(self.c.state.embedding[visible] - xy, axis=1))]
        return code, int(self.c.bank.actions[nearest])

    def _decode_at(self, xy: np.ndarray, mark: bool) -> None:
        code, action = self._code_at(xy)
        label = f"map point ({xy[0]:.2f}, {xy[1]:.2f})"
        if mark:
            self.c.state.selection = ()
            self.c.state.marker = xy.astype(np.float64)
            self.c.state.pick(code, label, action)
        self.decode_code(code, action, label)

    def decode_code(
        self,
        code: np.ndarray | None,
        action: int,
        label: str,
        end: np.ndarray | None = None,
        xy: np.ndarray | None = None,
    ) -> int:
        """Decode ``code`` (or, when None, the inverse projection of map point ``xy``) in the worker."""
        c = self.c
        request = CodeDecode(
            c.generator,
            c.bank,
            c.projection,
            int(action),
            label,
            frozen_array(code),
            frozen_array(xy, np.float64),
            frozen_array(end),
        )
        return c.decoder.submit(request.run)

    def drag_start(self, index: int) -> None:
        """Start dragging from bank code ``index``."""
        if self.c.state.model is not None:
            self.drag_from = int(index)
            self.c.state.selection = (int(index),)

    def drag_move(self, x: float, y: float) -> None:
        """Live-decode the code under the cursor (only the newest request is decoded)."""
        if self.drag_from is None or self.c.projection is None:
            return
        xy = np.array([x, y])
        target = self._snap(xy)
        if target is not None:
            code, action, end = self.bank_item(target)
            self.decode_code(code, action, f"drag → #{target}", end)
        else:  # the inverse projection runs in the worker too
            action = int(self.c.bank.actions[self.drag_from])
            self.decode_code(None, action, f"drag → ({x:.2f}, {y:.2f})", xy=xy)
        self.c.playback.live_marker = (
            xy  # the map marker follows at the throttled rate (a repaint of every point)
        )
        self.c.playback.schedule_live()

    def drag_finish(self, x: float, y: float) -> None:
        """Leave an interpolation strip from the drag's start to the point (or position) released on."""
        start, self.drag_from = self.drag_from, None
        self.c.playback.live_marker = None
        if start is None or self.c.projection is None:
            return
        xy = np.array([x, y])
        target = self._snap(xy)
        # released on a code: both ends are selected (ringed); in empty space the star marks the end
        self.c.state.marker = None if target is not None else xy.astype(np.float64)
        code_a, action, end_a = self.bank_item(start)
        action_b = action
        if target is not None:
            code_b, action_b, end_b = self.bank_item(target)
            self.c.state.selection = (start, target)
            what = f"#{start} → #{target}"
        else:
            code_b = self._code_at(xy)[0]
            end_b = self.c.bank.end_location(code_b[None], action)[0] if self.c.can("end") else None
            what = f"#{start} → ({x:.2f}, {y:.2f})"
        self.interpolate(code_a, code_b, action, end_a, end_b, what, action_b)

    def _snap(self, xy: np.ndarray) -> int | None:
        """Bank index of the visible point drawn within a few pixels of map position ``xy``, else None."""
        embedding = self.c.state.embedding
        visible = np.flatnonzero(~np.isin(self.c.bank.actions, list(self.c.state.hidden_actions)))
        if embedding is None or len(visible) == 0:
            return None
        nearest = int(visible[np.argmin(np.linalg.norm(embedding[visible] - xy, axis=1))])
        to_px = self.c.window.latent_map.data_to_widget
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
        across = action_b is not None and action_b != action and self.c.generator.action_names is not None
        if self.c.refuse("interpolate_across" if across else "interpolate"):
            return
        request = StripDecode(
            self.c.generator,
            frozen_array(code_a),
            frozen_array(code_b),
            int(action),
            int(action if action_b is None else action_b),
            self.c.window.steps_spin.value(),
            what,
            frozen_array(end_a),  # None for kinds that take no end (see bank_item)
            frozen_array(end_b),
        )
        self.c.decoder.submit(request.run)

    def lasso(self, polygon: object) -> None:
        """Select the visible bank codes inside ``polygon`` (M, 2)."""
        if self.c.state.model is None or self.c.state.embedding is None:
            return
        from engine.latent.geometry import points_in_polygon

        inside = points_in_polygon(self.c.state.embedding, np.asarray(polygon, dtype=np.float64))
        inside &= ~np.isin(self.c.bank.actions, list(self.c.state.hidden_actions))
        self.c.state.selection = tuple(int(i) for i in np.flatnonzero(inside))
        self.c.state.marker = None
        self.c.window.show_status(
            f"Lasso selected {len(self.c.state.selection)} codes (Selection menu: play, …)."
        )

    def clear_selection(self) -> None:
        """Forget the selection, the samples on the map, the marker and the local mode."""
        self.c.state.selection = ()
        self.c.state.extra = None
        self.c.state.marker = None
        self.c.map.local_mode = None
        self.c.map.draw_overlays()

    def select_clip_windows(self) -> None:
        """Select the windows of the playing bank code's clip (a bank built with a stride holds several)."""
        index = next((d.bank_index for d in self.c.state.shown if d.bank_index is not None), None)
        if index is None:
            self.c.window.show_status("Play a code of the bank first: its clip's windows are then selected.")
            return
        windows = self.c.bank.windows_of(index)
        self.c.state.selection = tuple(int(i) for i in windows)
        self.c.window.show_status(
            f"{len(windows)} window(s) of {self.c.bank.sources[index]} selected; "
            "Selection ▸ Play selection plays them in time order."
        )

    def play_selection(self) -> None:
        """Decode up to ``MAX_PLAYED`` selected codes that cover the selection and play them together.

        The codes are spread over the selection in the full latent space, each action getting a share
        in proportion to its count (not the first codes by bank index); the status says which.
        """
        selection = np.asarray(self.c.state.selection, dtype=np.int64)
        if not len(selection):
            return
        from engine.latent.neighbours import spread_subset

        bank = self.c.bank
        picked = selection[spread_subset(bank.codes[selection], bank.actions[selection], MAX_PLAYED)]
        note = _selection_note(picked, selection, bank)
        self._decode_bank([int(i) for i in picked], with_real=len(selection) == 1, note=note)


def _selection_note(picked: np.ndarray, selection: np.ndarray, bank: LatentBank) -> str:
    """'playing 12 of 57 selected (8 walk, 4 run), spread over the selection' (or '' for all)."""
    if len(picked) == len(selection):
        return f"playing all {len(selection)} selected"
    counts = np.bincount(bank.actions[picked], minlength=len(bank.action_names))
    parts = ", ".join(f"{c} {bank.action_names[a]}" for a, c in enumerate(counts) if c)
    return f"playing {len(picked)} of {len(selection)} selected ({parts}), spread over the selection"
