"""Fixtures for the widget tests: real widgets, shown under Xvfb, closed afterwards."""

from __future__ import annotations

from collections.abc import Callable, Iterator

import pytest
from PySide6.QtWidgets import QApplication, QWidget


@pytest.fixture
def show(qtbot) -> Iterator[Callable[[QWidget, int, int], QWidget]]:
    """Show a widget at a given size and wait until it is exposed; close it after the test."""
    shown: list[QWidget] = []

    def _show(widget: QWidget, width: int = 640, height: int = 480) -> QWidget:
        qtbot.addWidget(widget)
        widget.resize(width, height)
        widget.show()
        qtbot.waitExposed(widget)
        shown.append(widget)
        return widget

    yield _show
    for widget in shown:
        widget.close()
    QApplication.processEvents()
