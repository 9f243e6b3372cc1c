"""The explorer opens any generator kind: an Action2Motion model on the real window, gated tools, menus."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from engine.generators import SampleRequest, open_generator
from engine.motion.formats import read_motion, write_motion
from explorer.model_menu import bundled_models
from tests.explorer.conftest import Opened
from tests.explorer.gestures import click_map, drag_map, isolated_points, outside_view, played_points


def test_an_a2m_model_decodes_interpolates_and_samples_in_the_window(
    qtbot, open_explorer, tiny_a2m_dir
) -> None:
    opened: Opened = open_explorer(tiny_a2m_dir)
    window, c = opened.window, opened.controller
    qtbot.waitUntil(lambda: c.state.model is not None, timeout=60_000)
    generator = open_generator(tiny_a2m_dir)
    assert c.generator.kind == "a2m" and "a2m codes" in window.status_label.text()

    index = isolated_points(c.state.embedding, 1)[0]
    with qtbot.waitSignal(c.shownChanged, timeout=30_000):
        click_map(qtbot, opened, c.state.embedding[index])
    shown = c.state.shown[0]
    action = c.bank.action_names[int(c.bank.actions[index])]
    [expected] = generator.decode(c.bank.codes[index][None], action)
    np.testing.assert_allclose(shown.motion.joints, expected.joints, atol=1e-5)
    assert outside_view(window.viewport, played_points(opened)) == 0
    assert shown.end is None and " end (" not in window.status_label.text()  # the kind takes no end
    assert not window.viewport._end_actor.GetVisibility()

    same = np.flatnonzero(c.bank.actions == c.bank.actions[index])
    far = int(same[np.argmax(np.linalg.norm(c.state.embedding[same] - c.state.embedding[index], axis=1))])
    with qtbot.waitSignal(c.shownChanged, timeout=60_000):
        drag_map(qtbot, opened, list(np.linspace(c.state.embedding[index], c.state.embedding[far], 6)))
    qtbot.waitUntil(lambda: len(c.state.shown) == window.steps_spin.value(), timeout=60_000)
    strip = c.state.shown
    np.testing.assert_allclose(strip[0].motion.joints, expected.joints, atol=1e-5)
    [last] = generator.decode(c.bank.codes[far][None], action)
    np.testing.assert_allclose(strip[-1].motion.joints, last.joints, atol=1e-5)

    assert window.mode_panel.sample_button.isEnabled()
    with qtbot.waitSignal(c.shownChanged, timeout=60_000):
        window.mode_panel.sample_button.click()
    assert len(c.state.shown) == window.mode_panel.n_box.value()
    assert c.state.extra is not None and len(c.state.extra.xy) == len(c.state.shown)

    # ψ 0 on the truncation slider: every z_t at its prior's mean, so every sample is the same motion
    assert window.latent_panel.truncate_box.isEnabled()
    window.mode_panel.strategy_box.setCurrentIndex(window.mode_panel.strategy_box.findData("prior"))
    window.latent_panel.psi_slider.setValue(0)
    with qtbot.waitSignal(c.shownChanged, timeout=60_000):
        window.mode_panel.sample_button.click()
    [mean] = generator.sample(SampleRequest(c.state.shown[0].motion.action, 1, 0, truncation=0.0))
    for d in c.state.shown:
        np.testing.assert_allclose(d.motion.joints, mean.motion.joints, atol=1e-5)


def test_tools_the_kind_lacks_are_off_with_the_reason(
    qtbot, open_explorer, tiny_a2m_dir, tiny_model_dir
) -> None:
    opened: Opened = open_explorer(tiny_a2m_dir)
    window, c = opened.window, opened.controller
    qtbot.waitUntil(lambda: c.state.model is not None, timeout=60_000)
    assert not window.trajectory.isEnabled()
    assert "cannot set where the motion ends" in window.trajectory.toolTip()
    assert window.encode_action.isEnabled() == ("encode" in c.generator.capabilities)
    c.generation.set_end(1.0, 2.0)  # a gesture that reaches the controller anyway is refused, not run
    assert "cannot set where the motion ends" in window.status_label.text()

    with qtbot.waitSignal(c.modelLoaded, timeout=60_000):
        c.loader.open_model(tiny_model_dir)
    assert window.trajectory.isEnabled() and window.trajectory.toolTip() == ""


def test_file_menu_lists_bundled_and_recent_models(qtbot, open_explorer, tiny_model_dir) -> None:
    opened: Opened = open_explorer(tiny_model_dir)
    window, c = opened.window, opened.controller
    qtbot.waitUntil(lambda: c.state.model is not None, timeout=60_000)
    assert [a.text() for a in window.bundled_menu.actions()] == [p.name for p in bundled_models()]
    assert "bandai2-odmo" in [a.text() for a in window.bundled_menu.actions()]
    recent = [Path(a.text()) for a in window.recent_menu.actions()]
    assert recent[0] == Path(tiny_model_dir).resolve()


def test_every_enabled_selection_tool_works_on_an_a2m_model(
    qtbot, open_explorer, tiny_a2m_dir, procedural_clips, tmp_path
) -> None:
    opened: Opened = open_explorer(tiny_a2m_dir)
    window, c = opened.window, opened.controller
    qtbot.waitUntil(lambda: c.state.model is not None, timeout=60_000)
    walks = [int(i) for i in np.flatnonzero(c.bank.actions == 0)[:6]]
    c.state.selection = tuple(walks)
    for action in (window.variations_action, window.fit_mode_action, window.play_selection_action):
        assert action.isEnabled(), action.text()
        with qtbot.waitSignal(c.shownChanged, timeout=60_000):
            action.trigger()
        assert c.state.shown and all(np.isfinite(d.motion.joints).all() for d in c.state.shown)
    assert c.map.local_mode is not None  # outlined on the map

    written = c.exporter.export_selection(tmp_path / "walks.bvh")
    assert [read_motion(p).n_frames for p in written] == [c.generator.window] * len(walks)

    clip = tmp_path / "clip.npz"
    write_motion(procedural_clips[0], clip)
    with qtbot.waitSignal(c.shownChanged, timeout=60_000):
        c.encoder.encode_files([str(clip)])
    assert c.state.extra is not None and len(c.state.extra.codes) >= 1
    code, _ = open_generator(tiny_a2m_dir).encode(
        procedural_clips[0].with_joints(procedural_clips[0].joints[:60])
    )
    np.testing.assert_allclose(c.state.extra.codes[0], code, atol=1e-4)


def test_opening_another_model_forgets_the_codes_encoded_by_the_last(
    qtbot, open_explorer, tiny_model_dir, tiny_a2m_dir, procedural_clips, tmp_path
) -> None:
    opened: Opened = open_explorer(tiny_model_dir)
    window, c = opened.window, opened.controller
    qtbot.waitUntil(lambda: c.state.model is not None, timeout=60_000)
    clip = procedural_clips[0]
    long = clip.with_joints(np.concatenate([clip.joints, clip.joints[::-1]]))  # two windows: a path
    path = tmp_path / "long.npz"
    write_motion(long, path)
    with qtbot.waitSignal(c.shownChanged, timeout=60_000):
        c.encoder.encode_files([str(path)])
    assert c.state.extra is not None and len(c.state.extra.codes) >= 2 and window.latent_map._paths
    errors: list[str] = []
    c.errorOccurred.connect(errors.append)
    with qtbot.waitSignal(c.modelLoaded, timeout=60_000):
        c.loader.open_model(tiny_a2m_dir)  # its codes are 6-d, the ODMO model's 20-d
    assert errors == [] and c.generator.kind == "a2m"
    assert c.state.extra is None and not window.latent_map._paths and c.state.shown == ()
    viewport = window.viewport  # nothing of the old motions is drawn: no root path, ghosts, end or label
    assert viewport._trajectory_actor is None and viewport._ghost_actor is None
    assert not viewport._end_actor.GetVisibility() and viewport.labels() == []
    with qtbot.waitSignal(c.shownChanged, timeout=30_000):
        click_map(qtbot, opened, c.state.embedding[isolated_points(c.state.embedding, 1)[0]])
    assert c.state.shown[0].motion.n_joints == c.generator.skeleton.n_joints
    qtbot.wait(300)  # a few playback ticks
    assert errors == [] and window.timeline.is_playing() and window.timeline.frame() > 0
