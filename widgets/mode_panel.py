"""ModePanel: the modes of one action (silhouette vs K, sizes, weights) and the sampling controls."""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
import pyqtgraph as pg
from PySide6.QtCore import Qt, Signal
from PySide6.QtWidgets import (
    QComboBox,
    QFormLayout,
    QGridLayout,
    QHBoxLayout,
    QLabel,
    QPushButton,
    QSlider,
    QSpinBox,
    QVBoxLayout,
    QWidget,
)

from widgets._colors import ACCENT, FOREGROUND, configure_plot, palette_rgb

STRATEGIES: tuple[tuple[str, str], ...] = (
    ("mode_preserving", "Mode-preserving"),
    ("conventional", "Conventional"),
    ("one_mode", "One mode"),
    ("weights", "Slider weights"),
)
PRIOR = ("prior", "Prior")  # a generator's own sampling (an unconditional one's: of any action)
_SLIDER_STEPS = 100


class ModePanel(QWidget):
    """Shows an action's mode search and emits sampling-weight changes and sample requests.

    ``weightsChanged`` carries the (K,) slider weights in [0, 1] (not normalised);
    ``sampleRequested`` carries (strategy key, n, mode), mode being -1 unless the strategy is "one_mode".
    """

    weightsChanged = Signal(object)  # noqa: N815
    sampleRequested = Signal(str, int, int)  # noqa: N815

    def __init__(self, parent: QWidget | None = None) -> None:
        super().__init__(parent)
        self.title = QLabel()
        self.plot = pg.PlotWidget()
        configure_plot(self.plot)
        self.plot.setMinimumHeight(120)
        self.plot.setMouseEnabled(x=False, y=False)
        self.plot.setMenuEnabled(False)
        item = self.plot.getPlotItem()
        item.setLabel("bottom", "K")
        item.setLabel("left", "silhouette")
        item.getAxis("left").enableAutoSIPrefix(False)
        item.getAxis("bottom").enableAutoSIPrefix(False)
        item.hideButtons()
        item.setRange(xRange=(1, 12), yRange=(0, 1), padding=0.05)
        item.enableAutoRange(False)
        self._curve = item.plot(pen=pg.mkPen(FOREGROUND, width=2), symbol="o", symbolSize=6)
        self._chosen = pg.ScatterPlotItem(size=14, symbol="star", brush=ACCENT, pen=pg.mkPen("k"))
        self._chosen_line = pg.InfiniteLine(angle=90, pen=pg.mkPen(ACCENT, style=Qt.PenStyle.DashLine))
        item.addItem(self._chosen)
        item.addItem(self._chosen_line)

        self._modes_box = QWidget()
        self._modes_layout = QGridLayout(self._modes_box)
        self._modes_layout.setContentsMargins(0, 0, 0, 0)
        self._sliders: list[QSlider] = []

        self.strategy_box = QComboBox()
        self.strategy_box.currentIndexChanged.connect(self._strategy_changed)
        self.n_box = QSpinBox(minimum=1, maximum=10_000, value=10)
        self.mode_box = QSpinBox(minimum=0, maximum=0)
        self.sample_button = QPushButton("Sample")
        self.sample_button.clicked.connect(self._request_sample)
        form = QFormLayout()
        form.addRow("Strategy", self.strategy_box)
        form.addRow("N", self.n_box)
        form.addRow("Mode", self.mode_box)
        buttons = QHBoxLayout()
        buttons.addStretch(1)
        buttons.addWidget(self.sample_button)

        layout = QVBoxLayout(self)
        layout.addWidget(self.title)
        self.note = QLabel()
        self.note.setWordWrap(True)
        self.note.setStyleSheet("color: #a0a0a0;")
        layout.addWidget(self.note)
        layout.addWidget(self.plot, 1)
        layout.addWidget(self._modes_box)
        layout.addLayout(form)
        layout.addLayout(buttons)
        self.set_strategies(None)

    def set_action_modes(
        self,
        action_name: str,
        ks: Sequence[int],
        scores: Sequence[float],
        chosen_k: int,
        sizes: Sequence[int],
        weights: Sequence[float],
        note: str = "",
    ) -> None:
        """Show the silhouette ``scores`` per candidate ``ks``, the ``chosen_k`` (starred where it was
        scored) and one row per kept mode (``sizes``, ``weights``: fewer than K when modes were dropped);
        ``note`` explains the choice in words."""
        if len(ks) != len(scores):
            raise ValueError(f"{len(ks)} candidate K values but {len(scores)} scores")
        if len(sizes) != len(weights):
            raise ValueError(f"{len(sizes)} sizes but {len(weights)} weights")
        kept = len(sizes)
        self.title.setText(f"<b>{action_name}</b>: {kept} mode{'s' if kept != 1 else ''}")
        self.title.setToolTip(note)
        self.note.setText(note)
        x, y = np.asarray(ks, dtype=float), np.asarray(scores, dtype=float)
        scored = np.isfinite(y)  # a K that could not be scored is not drawn
        self._curve.setData(x[scored], y[scored])
        chosen = [float(s) for k, s in zip(ks, scores, strict=True) if k == chosen_k and np.isfinite(s)]
        self._chosen.setData(x=[chosen_k] * len(chosen), y=chosen)
        self._chosen_line.setVisible(bool(chosen))
        self._chosen_line.setValue(chosen_k)
        plot = self.plot.getPlotItem()
        if scored.any():
            lo, hi = float(y[scored].min()), float(y[scored].max())
            pad = max(0.05 * (hi - lo), 0.01)
            plot.setRange(xRange=(x.min() - 0.5, x.max() + 0.5), yRange=(lo - pad, hi + pad), padding=0)
        else:
            plot.setRange(xRange=(1, 12), yRange=(0, 1), padding=0)
        self._rebuild_modes(sizes, weights)
        self.mode_box.setMaximum(max(kept - 1, 0))
        self._strategy_changed()

    def set_strategies(self, keys: Sequence[str] | None) -> None:
        """Offer the sampling strategies ``keys`` (of ``STRATEGIES`` and ``PRIOR``), the first selected;
        None offers ``STRATEGIES``."""
        known = dict((PRIOR, *STRATEGIES))
        keys = [key for key, _ in STRATEGIES] if keys is None else list(keys)
        if unknown := [k for k in keys if k not in known]:
            raise ValueError(f"unknown sampling strategies {unknown}")
        self.strategy_box.blockSignals(True)
        self.strategy_box.clear()
        for key in keys:
            self.strategy_box.addItem(known[key], key)
        self.strategy_box.setCurrentIndex(0)
        self.strategy_box.blockSignals(False)
        self._strategy_changed()

    def weights(self) -> np.ndarray:
        """The slider weights, (K,) float in [0, 1]."""
        return np.array([s.value() / _SLIDER_STEPS for s in self._sliders], dtype=np.float64)

    def slider(self, mode: int) -> QSlider:
        """The weight slider of ``mode``."""
        return self._sliders[mode]

    def _rebuild_modes(self, sizes: Sequence[int], weights: Sequence[float]) -> None:
        while self._modes_layout.count():
            widget = self._modes_layout.takeAt(0).widget()
            if widget is not None:  # hidden now: a grab before the deferred delete must not show it
                widget.hide()
                widget.deleteLater()
        self._sliders = []
        for mode, (size, weight, rgb) in enumerate(zip(sizes, weights, palette_rgb(len(sizes)), strict=True)):
            swatch = QLabel(f"mode {mode}")
            swatch.setStyleSheet(f"color: rgb({rgb[0]}, {rgb[1]}, {rgb[2]}); font-weight: bold;")
            slider = QSlider(Qt.Orientation.Horizontal)
            slider.setRange(0, _SLIDER_STEPS)
            slider.setValue(round(float(np.clip(weight, 0.0, 1.0)) * _SLIDER_STEPS))
            slider.valueChanged.connect(self._emit_weights)
            self._modes_layout.addWidget(swatch, mode, 0)
            self._modes_layout.addWidget(QLabel(f"{int(size)} clips"), mode, 1)
            self._modes_layout.addWidget(slider, mode, 2)
            self._sliders.append(slider)

    def _emit_weights(self) -> None:
        self.weightsChanged.emit(self.weights())

    def _strategy_changed(self) -> None:
        strategy = self.strategy_box.currentData()
        self.mode_box.setEnabled(strategy == "one_mode")
        for slider in self._sliders:  # the weights only matter when sampling by them
            slider.setEnabled(strategy == "weights")
            slider.setToolTip(
                "Sampling weight of this mode"
                if strategy == "weights"
                else "Used by the 'Slider weights' strategy"
            )

    def _request_sample(self) -> None:
        strategy = str(self.strategy_box.currentData())
        mode = self.mode_box.value() if strategy == "one_mode" else -1
        self.sampleRequested.emit(strategy, self.n_box.value(), mode)
