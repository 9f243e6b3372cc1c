"""Every widget closes cleanly: no visible windows and no live VTK plotters left behind."""

from __future__ import annotations

import gc

import numpy as np
import pytest
import pyvista as pv
from PySide6.QtWidgets import QApplication, QWidget

from widgets.latent_map import LatentMap
from widgets.mode_panel import ModePanel
from widgets.timeline import Timeline
from widgets.trajectory_canvas import TrajectoryCanvas
from widgets.viewport import SkeletonViewport


def _filled(kind: type[QWidget]) -> QWidget:
    widget = kind()
    if isinstance(widget, LatentMap):
        widget.set_points(np.zeros((3, 2)), np.ones((3, 3)), np.arange(3), None)
    elif isinstance(widget, ModePanel):
        widget.set_action_modes("walk", [2, 3], [0.5, 0.6], 2, [5, 5], [1.0, 1.0])
    elif isinstance(widget, SkeletonViewport):
        widget.set_skeletons([-1, 0, 1], 2)
    elif isinstance(widget, Timeline):
        widget.set_length(10, 30.0)
        widget.play()
    return widget


@pytest.mark.parametrize("kind", [LatentMap, ModePanel, SkeletonViewport, Timeline, TrajectoryCanvas])
def test_widget_closes_without_leaks(qtbot, kind: type[QWidget]) -> None:
    plotters_before = len(pv.plotting.plotter._ALL_PLOTTERS)
    widget = _filled(kind)
    widget.show()
    qtbot.waitExposed(widget)
    assert widget.close()
    widget.deleteLater()
    qtbot.wait(10)
    QApplication.sendPostedEvents(None, 0)
    gc.collect()
    assert len(pv.plotting.plotter._ALL_PLOTTERS) == plotters_before
    assert not [w for w in QApplication.topLevelWidgets() if w.isVisible()]
