"""LatentToolsPanel: truncation ψ, style mixing of two picked codes, a crowd around a code and clip
inversion, each in a box the application enables or disables as a whole."""

from __future__ import annotations

from PySide6.QtCore import Qt, Signal
from PySide6.QtWidgets import (
    QComboBox,
    QDoubleSpinBox,
    QFormLayout,
    QGroupBox,
    QLabel,
    QPushButton,
    QSlider,
    QSpinBox,
    QVBoxLayout,
    QWidget,
)

_PSI_STEPS = 100


class LatentToolsPanel(QWidget):
    """Controls of a style-based generator's latent operations.

    Signals: ``truncationChanged(float)`` ψ in [0, 1]; ``mixRequested(int)`` the level split (also on a
    change of the split); ``crowdRequested(int, float)`` n and σ; ``invertRequested(str, int)`` the code
    space ("W+" or "W") and the optimisation steps (0: the model's default).
    """

    truncationChanged = Signal(float)  # noqa: N815
    mixRequested = Signal(int)  # noqa: N815
    crowdRequested = Signal(int, float)  # noqa: N815
    invertRequested = Signal(str, int)  # noqa: N815

    def __init__(self, parent: QWidget | None = None) -> None:
        super().__init__(parent)
        self.truncate_box = QGroupBox("Truncation (sampling)")
        self.psi_slider = QSlider(Qt.Orientation.Horizontal)
        self.psi_slider.setRange(0, _PSI_STEPS)
        self.psi_slider.setValue(_PSI_STEPS)
        self.psi_slider.setToolTip("ψ: 1 samples the whole prior, 0 the mean code only")
        self.psi_label = QLabel()
        self.psi_slider.valueChanged.connect(self._psi_changed)
        row = QFormLayout(self.truncate_box)
        row.addRow(self.psi_label, self.psi_slider)

        self.mix_box = QGroupBox("Style mixing")
        self.mix_codes = QLabel("Click two codes on the map.")
        self.mix_codes.setWordWrap(True)
        self.split_spin = QSpinBox(minimum=0, maximum=0)
        self.split_spin.setToolTip("Skeleton levels (coarsest first) taken from A; the finer ones from B")
        self.mix_button = QPushButton("Mix A × B")
        self.mix_button.clicked.connect(lambda: self.mixRequested.emit(self.split_spin.value()))
        self.split_spin.valueChanged.connect(self._split_changed)
        form = QFormLayout(self.mix_box)
        form.addRow(self.mix_codes)
        form.addRow("Levels from A", self.split_spin)
        form.addRow(self.mix_button)

        self.crowd_box = QGroupBox("Crowd around the shown code")
        self.crowd_n = QSpinBox(minimum=1, maximum=64, value=6)
        self.crowd_sigma = QDoubleSpinBox(minimum=0.0, maximum=10.0, value=0.5, singleStep=0.1, decimals=2)
        self.crowd_sigma.setToolTip("Standard deviation σ of the codes drawn around the shown one")
        self.crowd_button = QPushButton("Sample crowd")
        self.crowd_button.clicked.connect(
            lambda: self.crowdRequested.emit(self.crowd_n.value(), self.crowd_sigma.value())
        )
        form = QFormLayout(self.crowd_box)
        form.addRow("N", self.crowd_n)
        form.addRow("σ", self.crowd_sigma)
        form.addRow(self.crowd_button)

        self.invert_box = QGroupBox("Invert a clip")
        self.space_combo = QComboBox()
        self.space_combo.addItems(["W+", "W"])
        self.space_combo.setToolTip("W+: one code per style layer (closer fit); W: one code for all")
        self.steps_spin = QSpinBox(minimum=0, maximum=20_000, value=0, singleStep=50)
        self.steps_spin.setSpecialValueText("model default")
        self.invert_button = QPushButton("Invert clip…")
        self.invert_button.setToolTip("Find the code of a motion file (or drop one on the map)")
        self.invert_button.clicked.connect(
            lambda: self.invertRequested.emit(self.space_combo.currentText(), self.steps_spin.value())
        )
        form = QFormLayout(self.invert_box)
        form.addRow("Space", self.space_combo)
        form.addRow("Steps", self.steps_spin)
        form.addRow(self.invert_button)

        layout = QVBoxLayout(self)
        for box in (self.truncate_box, self.mix_box, self.crowd_box, self.invert_box):
            layout.addWidget(box)
        layout.addStretch(1)
        self._psi_changed()

    @property
    def psi(self) -> float:
        """The slider's ψ in [0, 1]."""
        return self.psi_slider.value() / _PSI_STEPS

    def set_psi(self, psi: float) -> None:
        """Move the slider to ψ (clipped to [0, 1])."""
        self.psi_slider.setValue(round(min(max(float(psi), 0.0), 1.0) * _PSI_STEPS))

    def set_levels(self, n_levels: int) -> None:
        """Offer splits 0..``n_levels`` (0: every level from B; ``n_levels``: every level from A)."""
        self.split_spin.setMaximum(max(int(n_levels), 0))

    def set_mix_codes(self, a: str | None, b: str | None) -> None:
        """Name the two codes a mix takes (None: not picked yet)."""
        if a is None or b is None:
            self.mix_codes.setText(f"A: {a or '—'}\nB: {b or '—'}\nClick two codes on the map.")
        else:
            self.mix_codes.setText(f"A (coarse): {a}\nB (fine): {b}")

    def _psi_changed(self) -> None:
        self.psi_label.setText(f"ψ {self.psi:.2f}")
        self.truncationChanged.emit(self.psi)

    def _split_changed(self, split: int) -> None:
        if self.mix_box.isEnabled():
            self.mixRequested.emit(int(split))
