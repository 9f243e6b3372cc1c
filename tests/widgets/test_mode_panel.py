"""ModePanel: plot of silhouette vs K, per-mode weight sliders, sample requests."""

from __future__ import annotations

import numpy as np
import pytest
from PySide6.QtCore import Qt

from widgets.mode_panel import ModePanel


@pytest.fixture
def panel(show) -> ModePanel:
    """A shown panel for an action with 3 modes chosen among K = 2..5."""
    widget = ModePanel()
    widget.set_action_modes("walk", [2, 3, 4, 5], [0.41, 0.58, 0.47, 0.39], 3, [40, 25, 12], [0.5, 0.3, 0.2])
    show(widget, 360, 480)
    return widget


def test_plot_marks_chosen_k(panel: ModePanel) -> None:
    x, y = panel._curve.getData()
    assert x.tolist() == [2, 3, 4, 5] and y.tolist() == [0.41, 0.58, 0.47, 0.39]
    assert panel._chosen.data["x"].tolist() == [3] and panel._chosen.data["y"].tolist() == [0.58]
    assert "3 modes" in panel.title.text()


def test_sliders_work_only_under_slider_weights(qtbot, panel: ModePanel) -> None:
    assert not panel.slider(0).isEnabled()
    qtbot.keyClick(panel.slider(2), Qt.Key.Key_End)
    np.testing.assert_allclose(panel.weights(), [0.5, 0.3, 0.2])
    panel.strategy_box.setCurrentIndex(panel.strategy_box.findData("weights"))
    assert all(panel.slider(k).isEnabled() for k in range(3))


def test_slider_emits_weights(qtbot, panel: ModePanel) -> None:
    panel.strategy_box.setCurrentIndex(panel.strategy_box.findData("weights"))
    np.testing.assert_allclose(panel.weights(), [0.5, 0.3, 0.2])
    with qtbot.waitSignal(panel.weightsChanged, timeout=1000) as blocker:
        panel.slider(2).setFocus()
        qtbot.keyClick(panel.slider(2), Qt.Key.Key_End)
    np.testing.assert_allclose(blocker.args[0], [0.5, 0.3, 1.0])


def test_sample_button_emits_strategy_n_and_mode(qtbot, panel: ModePanel) -> None:
    panel.n_box.setValue(25)
    with qtbot.waitSignal(panel.sampleRequested, timeout=1000) as blocker:
        qtbot.mouseClick(panel.sample_button, Qt.MouseButton.LeftButton)
    assert blocker.args == ["mode_preserving", 25, -1]
    panel.strategy_box.setCurrentIndex(panel.strategy_box.findData("one_mode"))
    assert panel.mode_box.isEnabled() and panel.mode_box.maximum() == 2
    panel.mode_box.setValue(2)
    with qtbot.waitSignal(panel.sampleRequested, timeout=1000) as blocker:
        qtbot.mouseClick(panel.sample_button, Qt.MouseButton.LeftButton)
    assert blocker.args == ["one_mode", 25, 2]


def test_new_action_rebuilds_sliders_and_rejects_bad_sizes(panel: ModePanel) -> None:
    panel.set_action_modes("run", [2, 3], [0.7, 0.5], 2, [30, 30], [1.0, 1.0])
    assert len(panel.weights()) == 2
    with pytest.raises(ValueError, match="sizes"):
        panel.set_action_modes("run", [2, 3], [0.7, 0.5], 2, [30], [1.0, 0.5])


def test_star_sits_on_the_chosen_k_and_the_kept_modes_are_listed(panel: ModePanel) -> None:
    note = "K = 4 chosen; 2 kept, 2 dropped for having too few clips"
    panel.set_action_modes("raise", [3, 4, 5], [0.3, 0.35, 0.5], 4, [40, 30], [1.0, 0.8], note)
    assert panel._chosen.data["x"].tolist() == [4] and panel._chosen.data["y"].tolist() == [0.35]
    assert "2 modes" in panel.title.text() and panel.note.text() == note
    assert len(panel.weights()) == 2 and panel.mode_box.maximum() == 1
    panel.set_action_modes("turn", [3, 4], [float("nan"), float("nan")], 1, [12], [1.0], "nothing scored")
    assert panel._chosen.data["x"].tolist() == [] and not panel._chosen_line.isVisible()
    assert "1 mode" in panel.title.text()
    axis = panel.plot.getPlotItem().getAxis("bottom")
    assert axis.autoSIPrefixScale == 1.0


def test_an_action_without_modes_says_why_and_resets_the_plot(panel: ModePanel) -> None:
    why = "No modes: the bank holds no code of this action (no training clip was labelled with it)."
    panel.set_action_modes("respond", [], [], 0, [], [], why)
    assert "0 modes" in panel.title.text() and panel.note.text() == why
    x, _ = panel._curve.getData()
    assert x is None or len(x) == 0
    assert panel.weights().size == 0 and not panel._chosen_line.isVisible()
    (x0, x1), (y0, y1) = panel.plot.getPlotItem().viewRange()
    assert x0 <= 1 and x1 >= 12 and y0 <= 0 and y1 >= 1, "the last action's (or the loading) range is gone"
