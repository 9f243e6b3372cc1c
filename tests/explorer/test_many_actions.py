"""A user's own model with more actions than the palette (17, one of them with no clip) in the window."""

from __future__ import annotations

import dataclasses
from pathlib import Path

import pytest
from PySide6.QtWidgets import QLabel

from engine.motion.motion import Motion
from engine.train.loop import train
from explorer.app import take_screenshot
from tests.explorer.conftest import Opened
from tests.fixtures.tiny_model import TINY_PROJECTIONS, single_thread, tiny_config

ACTIONS = [f"action-{k:02d}" for k in range(17)]
EMPTY = 16  # listed by the dataset, but no clip has it


@pytest.fixture(scope="module")
def many_actions_dir(tmp_path_factory, procedural_clips: list[Motion]) -> Path:
    """A tiny model of 17 actions: the procedural clips relabelled round-robin over the first 16."""
    clips = [dataclasses.replace(c, action=ACTIONS[k % EMPTY]) for k, c in enumerate(procedural_clips)]
    out = tmp_path_factory.mktemp("many_actions")
    with single_thread():
        train(
            clips,
            ACTIONS,
            out,
            tiny_config(n_actions=len(ACTIONS), epochs=2, tf_decay_epochs=2),
            seed=0,
            device="cpu",
            bank_projections=TINY_PROJECTIONS,
            bank_k_range=(2, 3),
        )
    return out


def test_every_action_has_its_own_colour_and_a_mode_note(qtbot, open_explorer, many_actions_dir) -> None:
    opened: Opened = open_explorer(many_actions_dir)
    window, c = opened.window, opened.controller
    qtbot.waitUntil(lambda: c.state.model is not None, timeout=60_000)
    legend = [window.latent_map.legend_checkbox(k) for k in range(len(ACTIONS))]
    assert [check.text() for check in legend] == ACTIONS
    swatches = {check.icon().pixmap(12, 12).toImage().pixelColor(6, 6).rgb() for check in legend}
    assert len(swatches) == len(ACTIONS), "two actions share a colour"
    drawn = window.latent_map.point_colors()
    per_action = [{tuple(rgba) for rgba in drawn[c.bank.actions == a]} for a in range(EMPTY)]
    assert all(len(colours) == 1 for colours in per_action)
    assert len(set.union(*per_action)) == EMPTY, "two actions' points share a colour"

    panel = window.mode_panel
    window.action_combo.setCurrentIndex(EMPTY)
    qtbot.waitUntil(lambda: ACTIONS[EMPTY] in panel.title.text())
    assert "0 modes" in panel.title.text()
    assert "no code of this action" in panel.note.text()
    x_range, _ = panel.plot.getPlotItem().viewRange()
    assert x_range[0] >= 0 and x_range[1] <= 13, "the loading-time axis is left on the mode plot"

    window.action_combo.setCurrentIndex(0)
    qtbot.waitUntil(lambda: ACTIONS[0] in panel.title.text())
    n_codes = len(c.bank.indices_of(0))
    assert panel.note.text(), "no word on why this action has the modes it shows"
    assert str(n_codes) in panel.note.text() or "K =" in panel.note.text()


def test_a_screenshot_right_after_a_change_shows_the_new_mode_rows(
    qtbot, open_explorer, many_actions_dir, tmp_path
) -> None:
    opened: Opened = open_explorer(many_actions_dir)
    window, c = opened.window, opened.controller
    qtbot.waitUntil(lambda: c.state.model is not None, timeout=60_000)

    def rows() -> list[str]:
        box = window.mode_panel._modes_box
        return [
            label.text()
            for label in box.findChildren(QLabel)
            if label.isVisible() and "clips" in label.text()
        ]

    window.action_combo.setCurrentIndex(0)
    qtbot.waitUntil(lambda: rows() == [f"{len(c.bank.indices_of(0))} clips"])
    later = EMPTY - 1
    assert len(c.bank.indices_of(later)) != len(c.bank.indices_of(0))
    window.action_combo.setCurrentIndex(later)  # no event processed before the grab
    take_screenshot(opened.explorer, tmp_path / "shot.png")
    assert rows() == [f"{len(c.bank.indices_of(later))} clips"]
