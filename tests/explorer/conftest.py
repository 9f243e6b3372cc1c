"""Fixtures for the explorer tests: a real window on the tiny model, closed and checked for leaks."""

from __future__ import annotations

import threading
from collections.abc import Callable, Iterator
from dataclasses import dataclass
from pathlib import Path

import pytest
import shiboken6
from PySide6.QtCore import QCoreApplication, QEvent, QSettings
from PySide6.QtWidgets import QApplication, QMessageBox

from explorer.app import Explorer, create_explorer


@dataclass
class Opened:
    """A shown explorer and the settings file it uses."""

    explorer: Explorer
    settings: Path

    @property
    def window(self):
        """The main window."""
        return self.explorer.window

    @property
    def controller(self):
        """The controller."""
        return self.explorer.controller


def worker_threads() -> list[threading.Thread]:
    """Live threads started by the explorer's workers."""
    return [t for t in threading.enumerate() if t.name.startswith("odmo-")]


def close_message_boxes() -> list[str]:
    """Close every open message box; returns their texts."""
    texts = []
    for widget in QApplication.topLevelWidgets():
        if isinstance(widget, QMessageBox) and widget.isVisible():
            texts.append(widget.text())
            widget.close()
    return texts


@pytest.fixture
def open_explorer(qtbot, tmp_path_factory) -> Iterator[Callable[..., Opened]]:
    """Open explorers (temp settings file); on teardown close them and check nothing leaked."""
    opened: list[Opened] = []

    def _open(
        model: Path | None,
        settings: Path | None = None,
        wait: bool = True,
        before_show: Callable[[object], None] | None = None,
    ) -> Opened:
        settings = settings or tmp_path_factory.mktemp("qt-settings") / "settings.ini"  # not in tmp_path
        explorer = create_explorer(model, None, QSettings(str(settings), QSettings.Format.IniFormat))
        if before_show is not None:
            before_show(explorer.window)
        explorer.window.show()
        qtbot.waitExposed(explorer.window)
        item = Opened(explorer, settings)
        opened.append(item)
        if wait and model is not None:
            qtbot.waitUntil(lambda: explorer.controller.state.embedding is not None, timeout=60_000)
        return item

    yield _open
    watched = []
    for item in opened:
        close_message_boxes()
        item.explorer.close()
        watched += [item.window, item.window.viewport, item.window.latent_map, item.controller]
        item.window.deleteLater()
    QCoreApplication.sendPostedEvents(None, QEvent.Type.DeferredDelete)
    QApplication.processEvents()
    assert worker_threads() == [], "worker threads outlived the window"
    assert not any(shiboken6.isValid(obj) for obj in watched), "widgets outlived the window"


@pytest.fixture
def explorer(open_explorer, tiny_model_dir: Path) -> Opened:
    """An explorer showing the tiny fixture model's bank under PCA."""
    return open_explorer(tiny_model_dir)
