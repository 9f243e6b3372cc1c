"""LatentToolsPanel: truncation ψ, style mixing of two picked codes, a crowd around a code, clip
inversion and edit sliders (one per edit direction), each in a box the application enables or disables
as a whole."""

from __future__ import annotations

from PySide6.QtCore import Qt, Signal
from PySide6.QtWidgets import (
    QComboBox,
    QDoubleSpinBox,
    QFrame,
    QGridLayout,
    QGroupBox,
    QHBoxLayout,
    QLabel,
    QPushButton,
    QScrollArea,
    QSlider,
    QSpinBox,
    QVBoxLayout,
    QWidget,
)

_PSI_STEPS = 100
EDIT_STEPS = 10  # edit slider steps per spread
EDIT_SPREADS = 3  # an edit slider reaches this many spreads either way


class LatentToolsPanel(QWidget):
    """Controls of a style-based generator's latent operations.

    Signals: ``truncationChanged(float)`` ψ in [0, 1]; ``mixRequested(int)`` the level split (also on a
    change of the split); ``crowdRequested(int, float)`` n and σ; ``invertRequested(str, int)`` the code
    space ("W+" or "W") and the optimisation steps (0: the model's default); ``editChanged(str, float)``
    a direction's name and its slider's amount in spreads; ``editReset()`` the reset button.
    """

    truncationChanged = Signal(float)  # noqa: N815
    mixRequested = Signal(int)  # noqa: N815
    crowdRequested = Signal(int, float)  # noqa: N815
    invertRequested = Signal(str, int)  # noqa: N815
    editChanged = Signal(str, float)  # noqa: N815
    editReset = Signal()  # noqa: N815

    def __init__(self, parent: QWidget | None = None) -> None:
        super().__init__(parent)
        self.truncate_box = QGroupBox("Truncation ψ (sampling)")
        self.psi_slider = QSlider(Qt.Orientation.Horizontal)
        self.psi_slider.setRange(0, _PSI_STEPS)
        self.psi_slider.setValue(_PSI_STEPS)
        self.psi_slider.setToolTip("ψ: 1 samples the whole prior, 0 the mean code only")
        self.psi_label = QLabel()
        self.psi_slider.valueChanged.connect(self._psi_changed)
        _row(self.truncate_box, self.psi_label, self.psi_slider)

        self.mix_box = QGroupBox("Style mixing")
        self.mix_codes = QLabel()
        self.mix_codes.setWordWrap(True)
        self.split_spin = QSpinBox(minimum=0, maximum=0, prefix="levels from A: ")
        self.split_spin.setToolTip("Skeleton levels (coarsest first) taken from A; the finer ones from B")
        self.mix_button = QPushButton("Mix A × B")
        self.mix_button.clicked.connect(lambda: self.mixRequested.emit(self.split_spin.value()))
        self.split_spin.valueChanged.connect(self._split_changed)
        _row(self.mix_box, self.split_spin, self.mix_button).insertWidget(0, self.mix_codes)
        self.set_mix_codes(None, None)

        self.crowd_box = QGroupBox("Crowd around the shown code")
        self.crowd_n = QSpinBox(minimum=1, maximum=64, value=6, prefix="N ")
        self.crowd_sigma = QDoubleSpinBox(
            minimum=0.0, maximum=10.0, value=0.5, singleStep=0.1, decimals=2, prefix="σ "
        )
        self.crowd_sigma.setToolTip("Standard deviation σ of the codes drawn around the shown one")
        self.crowd_button = QPushButton("Sample crowd")
        self.crowd_button.clicked.connect(
            lambda: self.crowdRequested.emit(self.crowd_n.value(), self.crowd_sigma.value())
        )
        _row(self.crowd_box, self.crowd_n, self.crowd_sigma, self.crowd_button)

        self.invert_box = QGroupBox("Invert a clip (or drop files on the map)")
        self.space_combo = QComboBox()
        self.space_combo.addItems(["W+", "W"])
        self.space_combo.setToolTip("W+: one code per style layer (closer fit); W: one code for all")
        self.steps_spin = QSpinBox(minimum=0, maximum=20_000, value=0, singleStep=50, suffix=" steps")
        self.steps_spin.setSpecialValueText("default steps")
        self.steps_spin.setToolTip("Optimisation steps (the lowest value: the model's default)")
        self.invert_button = QPushButton("Invert clip…")
        self.invert_button.setToolTip("Find the code of a motion file by optimisation")
        self.invert_button.clicked.connect(
            lambda: self.invertRequested.emit(self.space_combo.currentText(), self.steps_spin.value())
        )
        _row(self.invert_box, self.space_combo, self.steps_spin, self.invert_button)

        self.edit_box = QGroupBox("Edit the last clicked code")
        self.edit_note = QLabel()
        self.edit_note.setWordWrap(True)
        self.edit_grid = QGridLayout()
        self.edit_reset = QPushButton("Reset")
        self.edit_reset.setToolTip("Every slider back to 0: the unedited code plays")
        self.edit_reset.clicked.connect(self.editReset.emit)
        self.edit_sliders: dict[str, QSlider] = {}
        self._edit_values: dict[str, QLabel] = {}
        edit_column = _row(self.edit_box, self.edit_reset)
        edit_column.insertLayout(0, self.edit_grid)
        edit_column.insertWidget(0, self.edit_note)
        self.set_directions([])
        self.edit_box.setEnabled(False)  # until a model that edits is loaded
        self.edit_box.setToolTip("Open a model with a latent bank to edit its codes")

        inner = QWidget()
        column = QVBoxLayout(inner)
        column.setContentsMargins(2, 2, 2, 2)
        for box in (self.edit_box, self.truncate_box, self.mix_box, self.crowd_box, self.invert_box):
            column.addWidget(box)
        column.addStretch(1)
        scroll = QScrollArea()  # a short dock scrolls instead of squeezing the boxes
        scroll.setWidgetResizable(True)
        scroll.setFrameShape(QFrame.Shape.NoFrame)
        scroll.setWidget(inner)
        layout = QVBoxLayout(self)
        layout.setContentsMargins(0, 0, 0, 0)
        layout.addWidget(scroll)
        self._psi_changed()

    @property
    def psi(self) -> float:
        """The slider's ψ in [0, 1]."""
        return self.psi_slider.value() / _PSI_STEPS

    def set_levels(self, n_levels: int) -> None:
        """Offer splits 0..``n_levels`` (0: every level from B; ``n_levels``: every level from A)."""
        self.split_spin.setMaximum(max(int(n_levels), 0))

    def set_mix_codes(self, a: str | None, b: str | None) -> None:
        """Name the two codes a mix takes (None: not picked yet)."""
        if a is None or b is None:
            self.mix_codes.setText(f"A: {a or '—'} · B: {b or '—'} (click two codes on the map)")
        else:
            self.mix_codes.setText(f"A (coarse): {a}\nB (fine): {b}")

    def set_edit_note(self, text: str) -> None:
        """Say above the edit sliders what they do (or why there are none yet)."""
        self.edit_note.setText(text)

    def set_directions(self, rows: list[tuple[str, str, str]]) -> None:
        """One slider per edit direction, at 0: ``rows`` of (name, score text, tooltip)."""
        while self.edit_grid.count():
            self.edit_grid.takeAt(0).widget().deleteLater()
        self.edit_sliders, self._edit_values = {}, {}
        for k, (name, score, tip) in enumerate(rows):
            label = QLabel(f"{name} ({score})")
            slider = QSlider(Qt.Orientation.Horizontal)
            slider.setRange(-EDIT_SPREADS * EDIT_STEPS, EDIT_SPREADS * EDIT_STEPS)
            value = QLabel()
            for widget in (label, slider, value):
                widget.setToolTip(tip)
            slider.valueChanged.connect(lambda v, n=name: self._edit_moved(n, v))
            value.setAlignment(Qt.AlignmentFlag.AlignRight)
            self.edit_sliders[name], self._edit_values[name] = slider, value
            self.edit_grid.addWidget(label, 2 * k, 0)  # name and amount over the slider: a narrow dock
            self.edit_grid.addWidget(value, 2 * k, 1)
            self.edit_grid.addWidget(slider, 2 * k + 1, 0, 1, 2)
            self._show_amount(name)
        self.edit_reset.setVisible(bool(rows))

    def set_amounts(self, amounts: dict[str, float]) -> None:
        """Put each slider at its amount in ``amounts`` (spreads; 0 when absent) without signalling."""
        for name, slider in self.edit_sliders.items():
            slider.blockSignals(True)
            slider.setValue(round(amounts.get(name, 0.0) * EDIT_STEPS))
            slider.blockSignals(False)
            self._show_amount(name)

    def edit_amount(self, name: str) -> float:
        """The amount (spreads) the slider of direction ``name`` is at."""
        return self.edit_sliders[name].value() / EDIT_STEPS

    def _show_amount(self, name: str) -> None:
        self._edit_values[name].setText(f"{self.edit_amount(name):+.1f}")

    def _edit_moved(self, name: str, _value: int) -> None:
        self._show_amount(name)
        self.editChanged.emit(name, self.edit_amount(name))

    def _psi_changed(self) -> None:
        self.psi_label.setText(f"ψ {self.psi:.2f}")
        self.truncationChanged.emit(self.psi)

    def _split_changed(self, split: int) -> None:
        if self.mix_box.isEnabled():
            self.mixRequested.emit(int(split))


def _row(box: QGroupBox, *widgets: QWidget) -> QVBoxLayout:
    """Lay ``widgets`` out in one row of ``box``; returns the box's column layout."""
    column = QVBoxLayout(box)
    column.setContentsMargins(6, 4, 6, 4)
    row = QHBoxLayout()
    for widget in widgets:
        row.addWidget(widget, 1 if isinstance(widget, QSlider) else 0)
    column.addLayout(row)
    return column
