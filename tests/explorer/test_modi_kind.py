"""The explorer on an unconditional MoDi model: its labelled map, click and drag decoding, prior sampling
with truncation, style mixing, crowds and clip inversion, each checked against the engine's own call."""

from __future__ import annotations

import numpy as np
import pytest

from engine.generators import SampleRequest, open_generator
from engine.generators.modi import ModiGenerator
from engine.motion.formats import write_motion
from tests.explorer.conftest import Opened
from tests.explorer.gestures import click_map, drag_map, isolated_points

pytestmark = pytest.mark.usefixtures("torch_single_thread")

#: A code decoded in a batch and the same code decoded alone differ by float32 rounding (1.04e-5 m seen
#: in a CI run): those comparisons hold to 0.1 mm, decodes of the same batch shape to 1e-5 m.
BATCH_ATOL = 1e-4


@pytest.fixture(scope="module")
def modi(tiny_modi_dir) -> ModiGenerator:
    generator = open_generator(tiny_modi_dir)
    assert isinstance(generator, ModiGenerator)
    return generator


@pytest.fixture
def opened(qtbot, open_explorer, tiny_modi_dir) -> Opened:
    opened = open_explorer(tiny_modi_dir)
    qtbot.waitUntil(lambda: opened.controller.state.model is not None, timeout=60_000)
    return opened


def joints_of(generator: ModiGenerator, code: np.ndarray) -> np.ndarray:
    [motion] = generator.decode(np.asarray(code, np.float32)[None])
    return motion.joints


def click(qtbot, opened: Opened, index: int) -> None:
    with qtbot.waitSignal(opened.controller.shownChanged, timeout=30_000):
        click_map(qtbot, opened, opened.controller.state.embedding[index])


def test_the_map_shows_labelled_codes_that_click_and_drag_decode(qtbot, opened: Opened, modi) -> None:
    window, c = opened.window, opened.controller
    assert c.generator.kind == "modi" and "modi codes W of size 32" in window.status_label.text()
    assert "unconditional" in window.status_label.text()
    legend = [check.text() for check in window.latent_map._legend_checks]
    assert legend == modi.label_names
    labels = c.bank.actions
    assert len(np.unique(labels)) > 1  # the bank's codes carry several labels, coloured apart
    colors = c.map.drawn[1]
    a, b = (int(np.flatnonzero(labels == k)[0]) for k in np.unique(labels)[:2])
    assert not np.allclose(colors[a], colors[b])

    index = isolated_points(c.state.embedding, 1)[0]
    click(qtbot, opened, index)
    np.testing.assert_allclose(
        c.state.shown[0].motion.joints, joints_of(modi, c.bank.codes[index]), atol=1e-5
    )
    assert c.state.shown[0].motion.action == modi.label_names[labels[index]]

    # a drag to a code of another label interpolates in W (the labels are no condition)
    other = np.flatnonzero(labels != labels[index])
    far = int(other[np.argmax(np.linalg.norm(c.state.embedding[other] - c.state.embedding[index], axis=1))])
    with qtbot.waitSignal(c.shownChanged, timeout=60_000):
        drag_map(qtbot, opened, list(np.linspace(c.state.embedding[index], c.state.embedding[far], 6)))
    qtbot.waitUntil(lambda: len(c.state.shown) == window.steps_spin.value(), timeout=60_000)
    strip = c.state.shown
    np.testing.assert_allclose(strip[0].motion.joints, joints_of(modi, c.bank.codes[index]), atol=BATCH_ATOL)
    np.testing.assert_allclose(strip[-1].motion.joints, joints_of(modi, c.bank.codes[far]), atol=BATCH_ATOL)
    middle = 0.5 * (c.bank.codes[index] + c.bank.codes[far])
    np.testing.assert_allclose(strip[2].motion.joints, joints_of(modi, middle), atol=BATCH_ATOL)

    # what MoDi lacks is off, saying why
    assert not window.trajectory.isEnabled()
    assert "cannot set where the motion ends" in window.trajectory.toolTip()
    for box in ("truncate_box", "mix_box", "crowd_box", "invert_box"):
        assert getattr(window.latent_panel, box).isEnabled(), box


def test_sampling_draws_from_the_prior_and_truncation_zero_gives_the_mean_motion(
    qtbot, opened: Opened, modi
) -> None:
    window, c = opened.window, opened.controller
    panel = window.mode_panel
    assert panel.strategy_box.currentData() == "prior"
    assert "weights" not in [panel.strategy_box.itemData(k) for k in range(panel.strategy_box.count())]
    panel.n_box.setValue(3)
    with qtbot.waitSignal(c.shownChanged, timeout=60_000):
        panel.sample_button.click()
    shown = c.state.shown
    expected = modi.sample(SampleRequest(None, 3, shown[0].seed))
    for d, s in zip(shown, expected, strict=True):
        np.testing.assert_allclose(d.motion.joints, s.motion.joints, atol=1e-5)
    assert c.state.extra is not None and len(c.state.extra.xy) == 3
    assert not np.allclose(shown[0].motion.joints, shown[1].motion.joints)

    window.latent_panel.psi_slider.setValue(0)
    assert c.state.truncation == 0.0 and window.latent_panel.psi_label.text() == "ψ 0.00"
    with qtbot.waitSignal(c.shownChanged, timeout=60_000):
        panel.sample_button.click()
    mean = joints_of(modi, modi.loaded.model.w_avg.numpy())
    for d in c.state.shown:
        np.testing.assert_allclose(d.motion.joints, mean, atol=BATCH_ATOL)

    # a label's modes sample codes of that label
    panel.strategy_box.setCurrentIndex(panel.strategy_box.findData("mode_preserving"))
    with qtbot.waitSignal(c.shownChanged, timeout=60_000):
        panel.sample_button.click()
    assert {d.motion.action for d in c.state.shown} <= set(modi.label_names)


def test_style_mixing_of_the_last_two_clicked_codes_follows_the_split(qtbot, opened: Opened, modi) -> None:
    window, c = opened.window, opened.controller
    panel = window.latent_panel
    first, a, b = isolated_points(c.state.embedding, 3)
    for index in (first, a, b):  # the last two clicked are mixed
        click(qtbot, opened, index)
    assert panel.split_spin.maximum() == modi.n_levels
    assert f"A (coarse): #{a} " in panel.mix_codes.text() and f"B (fine): #{b} " in panel.mix_codes.text()
    with qtbot.waitSignal(c.shownChanged, timeout=30_000):
        panel.mix_button.click()
    split = panel.split_spin.value()
    mixed = modi.mix(c.bank.codes[a], c.bank.codes[b], split)
    np.testing.assert_allclose(c.state.shown[0].motion.joints, mixed.motion.joints, atol=1e-5)
    np.testing.assert_allclose(c.state.shown[1].motion.joints, joints_of(modi, c.bank.codes[a]), atol=1e-5)
    np.testing.assert_allclose(c.state.shown[2].motion.joints, joints_of(modi, c.bank.codes[b]), atol=1e-5)

    with qtbot.waitSignal(c.shownChanged, timeout=30_000):  # a new split re-mixes at once
        panel.split_spin.setValue(split + 1 if split < modi.n_levels else split - 1)
    other = modi.mix(c.bank.codes[a], c.bank.codes[b], panel.split_spin.value())
    np.testing.assert_allclose(c.state.shown[0].motion.joints, other.motion.joints, atol=1e-5)
    assert not np.allclose(other.motion.joints, mixed.motion.joints)
    # every level from A is A's motion, none is B's
    for split, side in ((modi.n_levels, a), (0, b)):
        with qtbot.waitSignal(c.shownChanged, timeout=30_000):
            panel.split_spin.setValue(split)
        np.testing.assert_allclose(
            c.state.shown[0].motion.joints, joints_of(modi, c.bank.codes[side]), atol=1e-4
        )


def test_a_crowd_around_the_shown_code(qtbot, opened: Opened, modi) -> None:
    window, c = opened.window, opened.controller
    panel = window.latent_panel
    index = isolated_points(c.state.embedding, 1)[0]
    click(qtbot, opened, index)
    panel.crowd_n.setValue(4)
    panel.crowd_sigma.setValue(0.3)
    with qtbot.waitSignal(c.shownChanged, timeout=60_000):
        panel.crowd_button.click()
    shown = c.state.shown
    assert len(shown) == 4 and len(c.state.extra.codes) == 4
    expected = modi.crowd(c.bank.codes[index], 4, 0.3, shown[0].seed)
    for d, s in zip(shown, expected, strict=True):
        np.testing.assert_allclose(d.motion.joints, s.motion.joints, atol=1e-5)
    spread = np.linalg.norm(c.state.extra.codes - c.bank.codes[index], axis=1) / np.sqrt(modi.code_space.size)
    assert 0.15 < spread.mean() < 0.45  # σ 0.3 per coordinate


def test_a_dropped_clip_is_inverted_with_progress_and_shown_beside_it(
    qtbot, opened: Opened, modi, procedural_clips, tmp_path
) -> None:
    window, c = opened.window, opened.controller
    clip = procedural_clips[0]
    path = tmp_path / "clip.npz"
    write_motion(clip, path)
    seen: list[str] = []
    c.tasks.started.connect(lambda task: task.progress.connect(lambda text, _f: seen.append(text)))
    with qtbot.waitSignal(c.shownChanged, timeout=120_000):
        window.latent_map.filesDropped.emit([str(path)])
    inverted, real = c.state.shown
    assert real.code is None and "(real clip)" in real.label and "inverted (W+" in inverted.label
    assert any(text.startswith("Inverting clip.npz in W+: step ") for text in seen)
    target = modi.real_window(clip).joints
    error = float(np.linalg.norm(inverted.motion.joints - target, axis=-1).mean())
    mean_error = float(
        np.linalg.norm(joints_of(modi, modi.loaded.model.w_avg.numpy()) - target, axis=-1).mean()
    )
    assert error < 0.5 * mean_error, (error, mean_error)  # the inversion fits the clip, not the average
    np.testing.assert_allclose(real.motion.joints, target, atol=1e-6)
    code = c.state.extra.codes[0]
    assert code.shape == (modi.n_styles * modi.code_space.size,)
    np.testing.assert_allclose(inverted.motion.joints, joints_of(modi, code), atol=1e-5)
    np.testing.assert_allclose(c.state.extra.xy[0], c.projection.transform(modi.as_w(code))[0], atol=1e-6)
    assert c.state.picked[-1].code is not None and "clip.npz (W+)" in window.latent_panel.mix_codes.text()

    # an inversion asked for before a newer one is dropped even when it ends last
    older, newer = tmp_path / "older.npz", tmp_path / "newer.npz"
    write_motion(procedural_clips[1], older)
    write_motion(procedural_clips[2], newer)
    c.latent.invert_files([str(older)], "W", 150)
    with qtbot.waitSignal(c.shownChanged, timeout=120_000):
        c.latent.invert_files([str(newer)], "W", 5)
    qtbot.waitUntil(lambda: not c.tasks.active, timeout=120_000)
    assert c.state.shown[0].label.startswith("newer.npz inverted (W,")
    inverted = c.state.shown[0]

    # a cancelled inversion shows nothing and leaves what plays
    window.latent_panel.steps_spin.setValue(20_000)
    start = len(seen)
    c.latent.invert_files([str(path)], "W", 20_000)
    qtbot.waitUntil(lambda: any("step 2/20000" in t for t in seen[start:]), timeout=60_000)
    window.cancel_button.click()
    qtbot.waitUntil(lambda: not c.tasks.active, timeout=60_000)
    assert c.state.shown[0] is inverted


def test_an_odmo_model_has_the_latent_tools_off_with_the_reason(qtbot, open_explorer, tiny_model_dir) -> None:
    opened = open_explorer(tiny_model_dir)
    window, c = opened.window, opened.controller
    qtbot.waitUntil(lambda: c.state.model is not None, timeout=60_000)
    panel = window.latent_panel
    for box, why in (("truncate_box", "sample with truncation"), ("mix_box", "mix styles")):
        assert not getattr(panel, box).isEnabled() and why in getattr(panel, box).toolTip()
    assert "sample a crowd around a code" in panel.crowd_box.toolTip()
    assert not window.invert_action.isEnabled()
    assert window.mode_panel.strategy_box.currentData() == "mode_preserving"


def test_the_selection_tools_and_energy_colouring_work_on_a_modi_model(qtbot, opened: Opened, modi) -> None:
    window, c = opened.window, opened.controller
    chosen = [int(i) for i in np.flatnonzero(c.bank.actions == 0)[:6]]
    c.state.selection = tuple(chosen)
    for action in (window.variations_action, window.fit_mode_action, window.play_selection_action):
        assert action.isEnabled(), action.text()
        with qtbot.waitSignal(c.shownChanged, timeout=60_000):
            action.trigger()
        assert c.state.shown and all(np.isfinite(d.motion.joints).all() for d in c.state.shown)
    played = [d for d in c.state.shown if d.bank_index is not None]
    for d in played:
        np.testing.assert_allclose(
            d.motion.joints, joints_of(modi, c.bank.codes[d.bank_index]), atol=BATCH_ATOL
        )

    c.state.color_by = "motion energy"
    qtbot.waitUntil(lambda: c.map.energy is not None, timeout=60_000)
    joints = np.stack([joints_of(modi, c.bank.codes[i]) for i in chosen])
    speed = np.linalg.norm(np.diff(joints, axis=1), axis=-1).mean(axis=(1, 2)) * modi.fps
    np.testing.assert_allclose(c.map.energy[chosen], speed, rtol=1e-4)
