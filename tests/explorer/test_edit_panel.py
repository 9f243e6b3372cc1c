"""The edit panel on a real window: one slider per edit direction of the loaded model, applied to the
clicked bank code and checked against the engine's own edit; off, saying why, where a model cannot edit."""

from __future__ import annotations

import threading

import numpy as np
import pytest

from engine.generators import open_generator, refusal
from engine.generators.base import FolderGenerator
from explorer.capabilities import gate_tools
from explorer.scene import short_label
from tests.explorer.conftest import Opened
from tests.explorer.gestures import click_map, isolated_points

pytestmark = pytest.mark.usefixtures("torch_single_thread")


def opened_with_directions(qtbot, open_explorer, folder) -> Opened:
    opened = open_explorer(folder)
    qtbot.waitUntil(lambda: bool(opened.window.latent_panel.edit_sliders), timeout=120_000)
    return opened


def decoded(generator, code: np.ndarray, action: str | None) -> np.ndarray:
    [motion] = generator.decode(np.asarray(code, np.float32)[None], action)
    return motion.joints


@pytest.mark.parametrize("fixture", ["tiny_model_dir", "tiny_modi_dir"])
def test_the_energy_slider_plays_the_engines_edit_of_the_clicked_code(
    qtbot, open_explorer, fixture: str, request
) -> None:
    opened = opened_with_directions(qtbot, open_explorer, request.getfixturevalue(fixture))
    window, c = opened.window, opened.controller
    panel, g = window.latent_panel, c.generator
    assert panel.edit_box.isEnabled() and panel.edit_box.toolTip() == ""
    directions = g.edit_directions  # found by the app's task: the cached directions
    assert list(panel.edit_sliders) == list(directions)
    labels = [w.text() for w in panel.findChildren(type(panel.edit_note)) if "R²" in w.text()]
    assert f"energy (R² {directions['energy'].score:.2f})" in labels

    index = isolated_points(c.state.embedding, 1, np.flatnonzero(c.bank.actions != 0))[0]  # not label 0
    with qtbot.waitSignal(c.shownChanged, timeout=30_000):
        click_map(qtbot, opened, c.state.embedding[index])
    code = c.bank.codes[index]
    action = None if g.action_names is None else g.action_names[int(c.bank.actions[index])]

    with qtbot.waitSignal(c.shownChanged, timeout=30_000):
        panel.edit_sliders["energy"].setValue(15)  # 1.5 spreads
    c.decoder.wait_idle()
    edited, original = c.state.shown
    expected = g.edit(code, action, "energy", 1.5).motion.joints
    np.testing.assert_allclose(edited.motion.joints, expected, atol=1e-5)
    np.testing.assert_allclose(original.motion.joints, decoded(g, code, action), atol=1e-5)
    assert not np.allclose(expected, original.motion.joints, atol=1e-3)  # the edit changes the motion
    assert c.state.edits == (("energy", 1.5),) and "energy +1.5" in edited.label
    assert short_label(edited, g.label_names).endswith(" edited")  # over its skeleton
    assert not short_label(original, g.label_names).endswith(" edited")

    # a second slider adds its own step: amount · spread · normal of each, summed
    style = next(name for name in directions if name.startswith("style="))
    with qtbot.waitSignal(c.shownChanged, timeout=30_000):
        panel.edit_sliders[style].setValue(-10)
    c.decoder.wait_idle()
    both = code + sum(
        a * directions[n].scale * directions[n].normal for n, a in ((style, -1.0), ("energy", 1.5))
    )
    np.testing.assert_allclose(c.state.shown[0].code, both, atol=1e-5)
    # codes summed in another order differ in their last float32 bits: the same motion within 0.1 mm
    np.testing.assert_allclose(c.state.shown[0].motion.joints, decoded(g, both, action), atol=1e-4)

    # a burst of slider moves: the last one plays
    for value in (5, 10, 20, 25, -30):
        panel.edit_sliders["energy"].setValue(value)
        qtbot.wait(5)
    qtbot.waitUntil(lambda: not c.decoding(), timeout=30_000)
    last = code + sum(
        a * directions[n].scale * directions[n].normal for n, a in ((style, -1.0), ("energy", -3.0))
    )
    np.testing.assert_allclose(c.state.shown[0].motion.joints, decoded(g, last, action), atol=1e-4)

    with qtbot.waitSignal(c.shownChanged, timeout=30_000):
        panel.edit_reset.click()
    assert c.state.edits == () and all(s.value() == 0 for s in panel.edit_sliders.values())
    [unedited] = c.state.shown
    np.testing.assert_allclose(unedited.motion.joints, decoded(g, code, action), atol=1e-5)

    # another clicked code starts from zero
    panel.edit_sliders["energy"].setValue(10)
    other = isolated_points(c.state.embedding, 2)[1]
    with qtbot.waitSignal(c.shownChanged, timeout=30_000):
        click_map(qtbot, opened, c.state.embedding[other])
    assert c.state.edits == () and panel.edit_sliders["energy"].value() == 0


def test_the_edit_panel_is_off_for_a_model_that_cannot_edit(qtbot, open_explorer, tiny_a2m_old_dir) -> None:
    opened = open_explorer(tiny_a2m_old_dir, wait=False)
    c, panel = opened.controller, opened.window.latent_panel
    qtbot.waitUntil(lambda: bool(c.loader.load_error), timeout=60_000)  # no bank: the app cannot show it
    assert "no latent bank" in c.loader.load_error
    assert not panel.edit_box.isEnabled() and not panel.edit_sliders
    generator = open_generator(tiny_a2m_old_dir)
    assert "edit" not in generator.capabilities
    off = gate_tools(opened.window, generator)  # as the loader gates a loaded model
    assert off["edit_box"] == str(refusal(generator, "edit")) == panel.edit_box.toolTip()
    assert not panel.edit_box.isEnabled() and "cannot edit" in panel.edit_box.toolTip()


def test_a_cancelled_search_for_directions_says_so(qtbot, open_explorer, tiny_modi_dir, monkeypatch) -> None:
    cancelled = threading.Event()

    def found_after_the_cancel(generator) -> dict:  # the search ends only once Cancel was clicked
        assert cancelled.wait(60)
        return {}

    monkeypatch.setattr(FolderGenerator, "edit_directions", property(found_after_the_cancel))
    opened = open_explorer(tiny_modi_dir, wait=False)
    c, panel = opened.controller, opened.window.latent_panel
    qtbot.waitUntil(
        lambda: any(t.title == "Finding edit directions" for t in c.tasks.active), timeout=120_000
    )
    assert "Finding the edit directions" in panel.edit_note.text()
    opened.window.cancel_button.click()
    cancelled.set()
    qtbot.waitUntil(lambda: not c.tasks.active, timeout=120_000)
    assert "cancelled" in panel.edit_note.text() and not panel.edit_sliders and not c.state.edit_directions
