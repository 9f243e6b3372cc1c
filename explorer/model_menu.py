"""File ▸ Open recent and File ▸ Bundled models: the model folders a user can open in one click."""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path

from PySide6.QtCore import QSettings
from PySide6.QtWidgets import QMenu

MODELS_DIR = Path(__file__).resolve().parents[1] / "resources" / "models"
RECENT_KEY = "models/recent"
MAX_RECENT = 8


def bundled_models(root: Path = MODELS_DIR) -> list[Path]:
    """The model folders shipped in ``resources/models`` (each with a ``model.json``), by name."""
    return sorted(p for p in root.iterdir() if (p / "model.json").is_file()) if root.is_dir() else []


def recent_models(settings: QSettings) -> list[Path]:
    """The model folders opened last (newest first) that still exist."""
    value = settings.value(RECENT_KEY, [])
    paths = [value] if isinstance(value, str) else list(value or [])
    return [Path(p) for p in paths if Path(p).is_dir()]


def remember_model(settings: QSettings, path: Path) -> None:
    """Put ``path`` first in the recent models (at most ``MAX_RECENT``)."""
    path = Path(path).resolve()
    kept = [p for p in recent_models(settings) if p.resolve() != path]
    settings.setValue(RECENT_KEY, [str(p) for p in [path, *kept][:MAX_RECENT]])


def fill_model_menus(recent: QMenu, bundled: QMenu, settings: QSettings, open_model: Callable[[Path], None]):
    """Fill the two menus from ``settings`` and ``resources/models``; choosing an entry opens it."""
    for menu, paths in ((recent, recent_models(settings)), (bundled, bundled_models())):
        menu.clear()
        for path in paths:
            menu.addAction(path.name if menu is bundled else str(path)).triggered.connect(
                lambda _on=False, p=path: open_model(p)
            )
        menu.setEnabled(bool(paths))
