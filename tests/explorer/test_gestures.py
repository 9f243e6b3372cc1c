"""The explorer under real mouse events on the tiny model: click, drag, lasso, projection switch, modes."""

from __future__ import annotations

import numpy as np
from PySide6.QtCore import Qt

from engine import generate
from engine.latent.modes import ModeModel
from tests.explorer.conftest import Opened
from tests.explorer.gestures import click_map as _click
from tests.explorer.gestures import drag_map as _drag
from tests.explorer.gestures import isolated_points as _isolated_points


def _inside(point: np.ndarray, polygon: np.ndarray) -> bool:
    """Even-odd ray casting (an independent reference for the engine's hit test)."""
    x, y = point
    hit = False
    for (x1, y1), (x2, y2) in zip(polygon, np.roll(polygon, -1, axis=0), strict=True):
        if (y1 > y) != (y2 > y) and x < x1 + (y - y1) * (x2 - x1) / (y2 - y1):
            hit = not hit
    return hit


def test_window_opens_on_the_tiny_model(explorer: Opened) -> None:
    bank = explorer.controller.bank
    window = explorer.window
    assert len(window.latent_map.visible_rows()) == len(bank.codes)
    np.testing.assert_array_equal(explorer.controller.state.embedding, bank.projections["pca"].embedding_)
    assert [window.action_combo.itemText(i) for i in range(window.action_combo.count())] == bank.action_names
    assert "bank codes" in window.status_label.text()


def test_click_point_selects_decodes_and_plays(qtbot, explorer: Opened) -> None:
    c = explorer.controller
    bank, loaded = c.bank, c.generator.loaded
    index = _isolated_points(c.state.embedding, 1)[0]
    with qtbot.waitSignal(c.shownChanged, timeout=20_000):
        _click(qtbot, explorer, c.state.embedding[index])
    assert c.state.selection == (index,)
    shown = c.state.shown[0]
    expected = generate.decode(
        loaded, bank.codes[index], int(bank.actions[index]), bank.ends[index : index + 1]
    )
    np.testing.assert_allclose(shown.motion.joints[0], expected.joints[0], atol=1e-5)
    assert shown.bank_index == index
    assert explorer.window.timeline.is_playing()
    assert 0 <= c.state.frame < shown.motion.n_frames
    drawn = explorer.window.viewport.skeleton_points()[0]
    frame = c.state.frame
    np.testing.assert_allclose(
        drawn - drawn[0], expected.joints[frame] - expected.joints[frame][0], atol=1e-4
    )
    assert bank.action_names[int(bank.actions[index])] in explorer.window.status_label.text()


def test_drag_between_points_updates_viewport_and_leaves_strip(qtbot, explorer: Opened) -> None:
    c, window = explorer.controller, explorer.window
    a, b = _isolated_points(c.state.embedding, 2)
    xa, xb = c.state.embedding[a], c.state.embedding[b]
    poses: list[np.ndarray] = []

    def settle() -> None:
        c.decoder.wait_idle()
        qtbot.wait(20)
        if c.state.shown:
            poses.append(window.viewport.skeleton_points().copy())

    path = [xa + t * (xb - xa) for t in np.linspace(0.0, 1.0, 6)]
    _drag(qtbot, explorer, path, between=settle)
    qtbot.waitUntil(lambda: len(c.state.shown) == window.steps_spin.value(), timeout=20_000)
    assert len(poses) >= 3
    assert any(not np.allclose(poses[0], p) for p in poses[1:]), "the viewport did not change during the drag"
    codes = np.stack([d.code for d in c.state.shown])
    code_a, code_b = c.bank.codes[a], c.bank.codes[b]
    t = (codes - code_a) @ (code_b - code_a) / np.dot(code_b - code_a, code_b - code_a)
    np.testing.assert_allclose(codes, code_a + t[:, None] * (code_b - code_a), atol=1e-5)
    np.testing.assert_allclose(t, np.linspace(0.0, 1.0, len(codes)), atol=1e-5)
    assert c.state.selection == (a, b)
    # Side by side, the end marker sits at the first skeleton's end, shifted with that skeleton.
    viewport = window.viewport
    lead = viewport.offsets[0]
    assert lead[0] < 0
    lift = np.array([0.0, c.generator.root_height, 0.0])  # the model's end is relative to the floor origin
    expected = np.asarray(c.state.shown[0].end) + lift + lead
    np.testing.assert_allclose(viewport.end_marker(), expected, atol=1e-5)


def test_lasso_selects_exactly_the_points_inside(qtbot, explorer: Opened) -> None:
    c, window = explorer.controller, explorer.window
    emb = c.state.embedding
    lo, hi = np.percentile(emb, 20, axis=0), np.percentile(emb, 70, axis=0)
    window.latent_map.set_tool("lasso")
    corners = [np.array(p) for p in ((lo[0], lo[1]), (hi[0], lo[1]), (hi[0], hi[1]), (lo[0], hi[1]))]
    polygon = []
    for k in range(4):  # walk the rectangle's edges so the lasso polygon is the rectangle
        polygon += [corners[k] + s * (corners[(k + 1) % 4] - corners[k]) for s in np.linspace(0, 1, 4)[:-1]]
    with qtbot.waitSignal(window.latent_map.lassoFinished, timeout=5_000) as blocker:
        _drag(qtbot, explorer, [*polygon, corners[0]])
    inside = np.array([_inside(p, np.asarray(blocker.args[0])) for p in emb])
    assert 0 < inside.sum() < len(emb)
    assert c.state.selection == tuple(np.flatnonzero(inside))


def test_projection_switch_keeps_the_selection(qtbot, explorer: Opened) -> None:
    c, window = explorer.controller, explorer.window
    c.gestures.lasso(np.array([[-1e9, -1e9], [0.0, -1e9], [0.0, 1e9], [-1e9, 1e9]]))
    selection = c.state.selection
    assert selection
    window.projection_combo.setCurrentIndex(window.projection_combo.findData("tsne"))
    qtbot.waitUntil(lambda: c.projection is not None and c.state.embedding is c.projection.embedding_)
    assert c.state.projection == "tsne"
    assert c.state.selection == selection
    assert len(window.latent_map.visible_rows()) == len(c.bank.codes)


def test_mode_panel_shows_the_banks_chosen_k(explorer: Opened) -> None:
    c, window = explorer.controller, explorer.window
    for action in range(len(c.bank.action_names)):
        window.action_combo.setCurrentIndex(action)
        modes: ModeModel = c.bank.modes[action]
        assert c.state.focus_action == action
        assert len(window.mode_panel.weights()) == modes.n_modes_
        k = modes.k_chosen_ if modes.n_modes_ == modes.k_chosen_ else modes.n_modes_
        assert f"{k} mode" in window.mode_panel.title.text()
        assert c.bank.action_names[action] in window.mode_panel.title.text()


def test_empty_click_decodes_the_inverse_projection_and_marks_it(qtbot, explorer: Opened) -> None:
    c = explorer.controller
    emb = c.state.embedding
    d = np.linalg.norm(emb[:, None] - emb[None], axis=-1)
    np.fill_diagonal(d, np.inf)
    i, j = np.unravel_index(np.argmax(np.where(np.isfinite(d), d, -1)), d.shape)
    xy = (emb[i] + emb[j]) / 2  # midway between the two points farthest apart
    with qtbot.waitSignal(c.shownChanged, timeout=20_000):
        _click(qtbot, explorer, xy)
    assert c.state.selection == ()
    np.testing.assert_allclose(c.state.marker, xy, atol=0.05 * np.ptp(emb))
    expected = c.projection.inverse_transform(c.state.marker[None])[0]
    np.testing.assert_allclose(c.state.shown[0].code, expected, atol=1e-5)


def test_sampling_puts_samples_on_the_map(qtbot, explorer: Opened) -> None:
    c, window = explorer.controller, explorer.window
    window.mode_panel.n_box.setValue(4)
    with qtbot.waitSignal(c.shownChanged, timeout=30_000):
        qtbot.mouseClick(window.mode_panel.sample_button, Qt.MouseButton.LeftButton)
    extra = c.state.extra
    assert extra is not None and len(extra.codes) == 4
    np.testing.assert_allclose(extra.xy, c.projection.transform(extra.codes))
    assert len(c.state.shown) == 4
    assert all(d.seed is not None and d.action == c.state.focus_action for d in c.state.shown)


def test_legend_hides_an_action(qtbot, explorer: Opened) -> None:
    c, window = explorer.controller, explorer.window
    qtbot.mouseClick(window.latent_map.legend_checkbox(0), Qt.MouseButton.LeftButton)
    assert c.state.hidden_actions == frozenset({0})
    visible = window.latent_map.visible_rows()
    np.testing.assert_array_equal(visible, np.flatnonzero(c.bank.actions != 0))
