"""Search by clip name or metadata, nearest neighbours in the full latent space, and bookmarks.

A small companion of the controller: it owns the Find panel's wiring and calls the controller's
gestures (click a code, play a selection); the search itself is a pure function.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import TYPE_CHECKING, Any

import numpy as np
from PySide6.QtCore import QObject

from engine.errors import OdmoError
from explorer.bookmarks import Bookmark, load_bookmarks, new_bookmark, save_bookmarks
from explorer.decoding import map_codes
from explorer.state import Decoded

if TYPE_CHECKING:
    from explorer.controller import Controller

MAX_RESULTS = 200
NEIGHBOURS = 10


def search_bank(
    query: str,
    sources: Sequence[str],
    actions: np.ndarray,
    action_names: Sequence[str],
    meta: Sequence[dict[str, Any]],
) -> np.ndarray:
    """Indices of the codes matching every word of ``query`` (case-insensitive): a word matches a
    substring of the clip name, the action or any metadata value; ``key:value`` matches that key only;
    ``#12`` is bank index 12."""
    words = query.lower().split()
    hits = np.ones(len(sources), dtype=bool)
    if not words:
        return np.zeros(0, dtype=np.int64)
    for word in words:
        if word.startswith("#") and word[1:].isdigit():
            only = np.zeros(len(sources), dtype=bool)
            if int(word[1:]) < len(sources):
                only[int(word[1:])] = True
            hits &= only
            continue
        key, _, value = word.partition(":") if ":" in word else ("", "", word)
        row_hits = np.zeros(len(sources), dtype=bool)
        for i, source in enumerate(sources):
            if key:
                field = action_names[int(actions[i])] if key == "action" else meta[i].get(key)
                row_hits[i] = field is not None and value in str(field).lower()
            else:
                texts = [str(source), action_names[int(actions[i])], *map(str, meta[i].values())]
                row_hits[i] = any(word in t.lower() for t in texts)
        hits &= row_hits
    return np.flatnonzero(hits)


def describe(bank: Any, i: int) -> str:
    """One line for bank code ``i``: index, clip file name, action and style."""
    name = str(bank.sources[i]).replace("\\", "/").rsplit("/", 1)[-1]
    style = bank.meta[i].get("style")
    return f"#{i}  {name}  ·  {bank.action_names[int(bank.actions[i])]}" + (f" · {style}" if style else "")


class Finder(QObject):
    """Connects the Find panel to the controller: search, neighbours of what plays, bookmarks."""

    def __init__(self, controller: Controller) -> None:
        super().__init__(controller)
        self.c = controller
        self.panel = controller.window.find_panel
        self.marks: list[Bookmark] = []
        self.panel.searchChanged.connect(self.search)
        self.panel.resultChosen.connect(controller.gestures.click_point)
        self.panel.neighbourChosen.connect(controller.gestures.click_point)
        self.panel.bookmarkRequested.connect(self.bookmark_selection)
        self.panel.bookmarkChosen.connect(self.open_bookmark)
        controller.state.events.shown.connect(self._shown_changed)
        controller.modelLoaded.connect(self._model_loaded)

    def search(self, query: str) -> None:
        """List the bank codes matching ``query`` (see :func:`search_bank`)."""
        if self.c.state.model is None:
            return
        bank = self.c.bank
        hits = search_bank(query, bank.sources, bank.actions, bank.action_names, bank.meta)
        rows = [(describe(bank, int(i)), int(i)) for i in hits[:MAX_RESULTS]]
        more = f" (first {MAX_RESULTS} listed)" if len(hits) > MAX_RESULTS else ""
        self.panel.set_results(rows, f"{len(hits)} codes match{more}" if query.strip() else "")

    def _shown_changed(self, shown: tuple[Decoded, ...]) -> None:
        item = next((d for d in shown if d.code is not None), None)
        if item is None or self.c.state.model is None or self.c.gestures.drag_from is not None:
            return
        from engine.latent.neighbours import nearest

        bank = self.c.bank
        query = map_codes(self.c.generator, item.code[None])[0]  # a W+ code is looked up at its W point
        idx, dist = nearest(bank.codes, query, NEIGHBOURS, exclude=item.bank_index)
        what = f"#{item.bank_index}" if item.bank_index is not None else "the code playing"
        title = f"Nearest to {what} in the full {bank.codes.shape[1]}-D latent space"
        rows = [
            (
                f"{describe(bank, int(i))}  d={d:.2f}",
                int(i),
            )
            for i, d in zip(idx, dist, strict=True)
        ]
        self.panel.set_neighbours(title, rows)

    def _model_loaded(self, loaded: Any) -> None:
        self.marks = []
        try:
            self.marks = load_bookmarks(loaded.path, len(loaded.bank.codes))
        except Exception as exc:  # an unreadable bookmarks file must not stop the model from opening
            self.c.report_error("Bookmarks not loaded", exc)
        self._list_marks()

    def _list_marks(self) -> None:
        self.panel.set_bookmarks(
            [(f"{m.name}  ({len(m.indices)} codes)", k) for k, m in enumerate(self.marks)]
        )

    def bookmark_selection(self, name: str) -> None:
        """Save the selection as a bookmark in the model folder's bookmarks file."""
        sel = tuple(int(i) for i in self.c.state.selection)
        if self.c.state.model is None or not sel:
            self.c.report_error("Nothing to bookmark", "select codes first (click a point or draw a lasso)")
            return
        bank = self.c.bank
        mark = new_bookmark(name, sel, [str(bank.sources[i]) for i in sel], self.marks)
        try:
            path = save_bookmarks(self.c.generator.path, [*self.marks, mark])
        except (OSError, OdmoError) as exc:
            self.c.report_error("Bookmark not saved", exc)
            return
        self.marks.append(mark)
        self._list_marks()
        self.c.window.show_status(f"Bookmarked {len(sel)} codes as {mark.name!r} in {path}")

    def open_bookmark(self, k: int) -> None:
        """Select a bookmark's codes and play them."""
        if 0 <= k < len(self.marks):
            self.c.state.selection = self.marks[k].indices
            self.c.gestures.play_selection()
