"""Bookmarks: named selections of bank codes saved in a JSON file next to the model (pure, no Qt)."""

from __future__ import annotations

import json
import time
from dataclasses import dataclass
from pathlib import Path

from engine.errors import DataError
from engine.fileio import atomic_write_text

BOOKMARKS_FILE = "bookmarks.json"
FORMAT = "odmo-bookmarks"


@dataclass(frozen=True)
class Bookmark:
    """A saved selection: its name, bank indices, the clips they came from and when it was saved."""

    name: str
    indices: tuple[int, ...]
    sources: tuple[str, ...]
    created: str


def bookmarks_path(model_dir: str | Path) -> Path:
    """The bookmarks file of a model folder."""
    return Path(model_dir) / BOOKMARKS_FILE


def _bookmark(entry: dict) -> Bookmark:
    """One bookmark from its JSON entry."""
    indices = tuple(int(i) for i in entry["indices"])
    sources = tuple(str(s) for s in entry["sources"])
    return Bookmark(str(entry["name"]), indices, sources, str(entry.get("created", "")))


def load_bookmarks(model_dir: str | Path, n_codes: int) -> list[Bookmark]:
    """The bookmarks saved for a model ([] when none); DataError naming the file when it is unreadable
    or points outside a bank of ``n_codes`` codes."""
    path = bookmarks_path(model_dir)
    if not path.is_file():
        return []
    try:
        data = json.loads(path.read_text(encoding="utf-8"))
        if data.get("format") != FORMAT:
            raise ValueError(f"not an {FORMAT} file")
        marks = [_bookmark(b) for b in data["bookmarks"]]
    except (OSError, ValueError, KeyError, TypeError) as exc:
        raise DataError(f"{path}: cannot read bookmarks ({exc})") from exc
    for mark in marks:
        if any(not 0 <= i < n_codes for i in mark.indices):
            raise DataError(f"{path}: bookmark {mark.name!r} points outside the bank's {n_codes} codes")
    return marks


def save_bookmarks(model_dir: str | Path, marks: list[Bookmark]) -> Path:
    """Write ``marks`` to the model folder's bookmarks file, atomically."""
    path = bookmarks_path(model_dir)
    payload = {
        "format": FORMAT,
        "version": 1,
        "bookmarks": [
            {"name": m.name, "indices": list(m.indices), "sources": list(m.sources), "created": m.created}
            for m in marks
        ],
    }
    atomic_write_text(path, json.dumps(payload, indent=1) + "\n")
    return path


def new_bookmark(
    name: str, indices: tuple[int, ...], sources: list[str], existing: list[Bookmark]
) -> Bookmark:
    """A bookmark of ``indices``; an empty name becomes "selection N"."""
    name = name or f"selection {len(existing) + 1}"
    return Bookmark(name, indices, tuple(sources), time.strftime("%Y-%m-%d %H:%M:%S"))
