"""FindPanel: search box with results, a nearest-neighbour list and saved selections (bookmarks)."""

from __future__ import annotations

from collections.abc import Sequence

from PySide6.QtCore import Qt, Signal
from PySide6.QtWidgets import (
    QHBoxLayout,
    QLabel,
    QLineEdit,
    QListWidget,
    QListWidgetItem,
    QPushButton,
    QVBoxLayout,
    QWidget,
)

_ID = Qt.ItemDataRole.UserRole


def _fill(widget: QListWidget, rows: Sequence[tuple[str, int]]) -> None:
    widget.clear()
    for text, ident in rows:
        item = QListWidgetItem(text)
        item.setData(_ID, int(ident))
        widget.addItem(item)


def _ids(widget: QListWidget) -> list[int]:
    return [int(widget.item(i).data(_ID)) for i in range(widget.count())]


class FindPanel(QWidget):
    """Three lists with ids: search results, nearest neighbours, bookmarks.

    Signals: ``searchChanged(str)`` as the query is typed (Enter too); ``resultChosen(int)``,
    ``neighbourChosen(int)``, ``bookmarkChosen(int)`` with the id of a clicked row;
    ``bookmarkRequested(str)`` with the name typed when "Bookmark selection" is pressed.
    """

    searchChanged = Signal(str)  # noqa: N815
    resultChosen = Signal(int)  # noqa: N815
    neighbourChosen = Signal(int)  # noqa: N815
    bookmarkChosen = Signal(int)  # noqa: N815
    bookmarkRequested = Signal(str)  # noqa: N815

    def __init__(self, parent: QWidget | None = None) -> None:
        super().__init__(parent)
        self.search_box = QLineEdit(placeholderText="Search clip name, action, style, key:value …")
        self.search_box.setClearButtonEnabled(True)
        self.search_box.textChanged.connect(self.searchChanged)
        self.search_box.returnPressed.connect(lambda: self.searchChanged.emit(self.search_box.text()))
        self.results = QListWidget()
        self.results_label = QLabel()
        self.neighbours_label = QLabel("Nearest neighbours: click a code")
        self.neighbours_label.setWordWrap(True)
        self.neighbours = QListWidget()
        self.bookmark_name = QLineEdit(placeholderText="bookmark name")
        self.bookmark_button = QPushButton("Bookmark selection")
        self.bookmark_button.clicked.connect(
            lambda: self.bookmarkRequested.emit(self.bookmark_name.text().strip())
        )
        self.bookmarks = QListWidget()
        for widget, signal in (
            (self.results, self.resultChosen),
            (self.neighbours, self.neighbourChosen),
            (self.bookmarks, self.bookmarkChosen),
        ):
            widget.itemClicked.connect(lambda item, s=signal: s.emit(int(item.data(_ID))))
            widget.itemActivated.connect(lambda item, s=signal: s.emit(int(item.data(_ID))))

        save = QHBoxLayout()
        save.addWidget(self.bookmark_name, 1)
        save.addWidget(self.bookmark_button)
        layout = QVBoxLayout(self)
        layout.setContentsMargins(4, 4, 4, 4)
        layout.addWidget(self.search_box)
        layout.addWidget(self.results_label)
        layout.addWidget(self.results, 2)
        layout.addWidget(self.neighbours_label)
        layout.addWidget(self.neighbours, 2)
        layout.addWidget(QLabel("Bookmarks"))
        layout.addLayout(save)
        layout.addWidget(self.bookmarks, 1)

    def set_results(self, rows: Sequence[tuple[str, int]], summary: str = "") -> None:
        """Show search results: (text, id) rows and a one-line summary."""
        _fill(self.results, rows)
        self.results_label.setText(summary)

    def set_neighbours(self, title: str, rows: Sequence[tuple[str, int]]) -> None:
        """Show the nearest neighbours of a code: a title and (text, id) rows, nearest first."""
        self.neighbours_label.setText(title)
        _fill(self.neighbours, rows)

    def set_bookmarks(self, rows: Sequence[tuple[str, int]]) -> None:
        """Show the saved bookmarks as (text, id) rows."""
        _fill(self.bookmarks, rows)

    def result_ids(self) -> list[int]:
        """Ids of the search results shown, in order."""
        return _ids(self.results)

    def neighbour_ids(self) -> list[int]:
        """Ids of the neighbours shown, nearest first."""
        return _ids(self.neighbours)

    def bookmark_ids(self) -> list[int]:
        """Ids of the bookmarks shown."""
        return _ids(self.bookmarks)
