"""Issue 12 'Confusing': what the window tells the user matches what it does."""

from __future__ import annotations

import numpy as np
from PySide6.QtCore import QPoint, Qt

from explorer.map_layers import category_colors
from tests.explorer.conftest import Opened
from tests.explorer.gestures import click_map, drag_map, isolated_points


def test_action_box_and_mode_panel_follow_the_clicked_code(qtbot, explorer: Opened) -> None:
    c, w = explorer.controller, explorer.window
    bank = c.bank
    for action in (2, 1):
        index = isolated_points(c.state.embedding, 1, among=bank.indices_of(action))[0]
        with qtbot.waitSignal(c.shownChanged, timeout=20_000):
            click_map(qtbot, explorer, c.state.embedding[index])
        assert w.action_combo.currentText() == bank.action_names[action]
        assert bank.action_names[action] in w.mode_panel.title.text()
    emb = c.state.embedding
    with qtbot.waitSignal(c.shownChanged, timeout=20_000):
        click_map(qtbot, explorer, emb.min(axis=0) - 0.02 * np.ptp(emb, axis=0))
    assert w.action_combo.currentText() == bank.action_names[c.state.shown[0].action]


def test_mode_panel_explains_the_chosen_k(explorer: Opened) -> None:
    c, w = explorer.controller, explorer.window
    for action in range(len(c.bank.action_names)):
        w.action_combo.setCurrentIndex(action)
        modes = c.bank.modes[action]
        note = w.mode_panel.note.text()
        assert f"K = {modes.k_chosen_} chosen" in note or "could be scored" in note
        assert f"{modes.n_modes_} mode" in w.mode_panel.title.text()
        starred = w.mode_panel._chosen.data["x"].tolist()
        assert starred in ([modes.k_chosen_], [])
        if modes.n_modes_ < modes.k_chosen_:
            assert "dropped" in note
        assert not w.mode_panel.slider(0).isEnabled()  # the default strategy does not use the sliders


def test_colour_by_mode_and_style_show_their_key(qtbot, explorer: Opened) -> None:
    c, w = explorer.controller, explorer.window
    assert w.latent_map.key_text() == ""
    w.color_combo.setCurrentIndex(w.color_combo.findData("mode"))
    assert c.state.color_by == "mode"
    assert "Mode" in w.latent_map.key_text() and "mode 0" in w.latent_map.key_text()
    style = w.color_combo.findData("meta:style")
    assert style >= 0, "the bank's style metadata is offered as a colouring"
    w.color_combo.setCurrentIndex(style)
    styles = sorted({m["style"] for m in c.bank.meta})
    key = w.latent_map.key_text()
    assert all(s in key for s in styles)
    first = [m["style"] for m in c.bank.meta].index(styles[0])
    assert first in w.latent_map.visible_rows()
    expected = category_colors(len(styles))[0]
    got = w.latent_map.point_colors()[first, :3] / 255
    np.testing.assert_allclose(got, expected[:3], atol=1 / 255)


def test_strip_skeletons_wear_their_actions_colour(qtbot, explorer: Opened) -> None:
    c, w = explorer.controller, explorer.window
    a, b = isolated_points(c.state.embedding, 2, among=c.bank.indices_of(0))
    emb = c.state.embedding
    drag_map(qtbot, explorer, [emb[a] + t * (emb[b] - emb[a]) for t in np.linspace(0, 1, 4)])
    steps = w.steps_spin.value()
    qtbot.waitUntil(lambda: len(c.state.shown) == steps and c.gestures.drag_from is None, timeout=20_000)
    qtbot.wait(50)
    colors = w.viewport.colors().astype(int)
    action_rgb = (category_colors(len(c.bank.action_names))[0, :3] * 255).round()
    other = (category_colors(len(c.bank.action_names))[1:, :3] * 255).round()
    for rgb in colors:
        # a shade of the walk colour: closer to it (after scaling) than to any other action's colour
        direction = rgb / max(np.linalg.norm(rgb), 1)
        cos_self = direction @ (action_rgb / np.linalg.norm(action_rgb))
        cos_other = (other / np.linalg.norm(other, axis=1, keepdims=True)) @ direction
        assert cos_self > cos_other.max() - 0.02, (rgb, action_rgb)
    assert len({tuple(c) for c in colors.tolist()}) == len(colors)


def test_map_keeps_one_unit_square_and_frames_a_new_projection(qtbot, explorer: Opened) -> None:
    c, w = explorer.controller, explorer.window
    sx, sy = w.latent_map.view_box.viewPixelSize()
    assert abs(sx - sy) / max(sx, sy) < 0.01
    w.projection_combo.setCurrentIndex(w.projection_combo.findData("tsne"))
    qtbot.waitUntil(
        lambda: c.projection is not None and c.state.embedding is c.projection.embedding_, timeout=60_000
    )
    qtbot.wait(50)
    (x0, x1), (y0, y1) = w.latent_map.view_box.viewRange()
    emb = c.state.embedding
    assert x0 <= emb[:, 0].min() and emb[:, 0].max() <= x1
    assert y0 <= emb[:, 1].min() and emb[:, 1].max() <= y1
    width = max(x1 - x0, y1 - y0)
    assert max(np.ptp(emb[:, 0]), np.ptp(emb[:, 1])) > 0.5 * width, "the points fill the view"
    # mode outlines under t-SNE are smooth ellipses, not spiky hulls
    curves = [item.getData() for item in w.latent_map._overlays]
    assert curves and all(len(x) == 65 for x, _ in curves)


def test_lasso_message_survives_hover_and_play_selection_covers_it(qtbot, explorer: Opened) -> None:
    c, w = explorer.controller, explorer.window
    emb = c.state.embedding
    c.gestures.lasso(np.array([[-1e9, -1e9], [1e9, -1e9], [1e9, 1e9], [-1e9, 1e9]]))
    assert "Lasso selected" in w.status_label.text()
    index = isolated_points(emb, 1)[0]
    pixel = w.latent_map.data_to_widget(emb[index]).toPoint()
    qtbot.mouseMove(w.latent_map.plot.viewport(), pixel)
    qtbot.mouseMove(w.latent_map.plot.viewport(), pixel + QPoint(1, 0))
    qtbot.waitUntil(lambda: f"#{index}" in w.hover_label.text(), timeout=3_000)
    assert "Lasso selected" in w.status_label.text()
    with qtbot.waitSignal(c.shownChanged, timeout=30_000):
        w.play_selection_action.trigger()
    played = [d.bank_index for d in c.state.shown]
    assert len(played) == 12
    actions = np.bincount(c.bank.actions[played], minlength=len(c.bank.action_names))
    assert np.all(actions >= 1), "every action of the selection is played"
    assert played != list(range(12))
    assert "of" in w.status_label.text() and "spread over the selection" in w.status_label.text()


def test_vtk_keys_do_nothing_in_the_3d_view(qtbot, explorer: Opened) -> None:
    c, w = explorer.controller, explorer.window
    with qtbot.waitSignal(c.shownChanged, timeout=20_000):
        c.gestures.click_point(0)
    interactor = w.viewport.plotter.interactor
    for key in (Qt.Key.Key_3, Qt.Key.Key_W, Qt.Key.Key_S, Qt.Key.Key_E):
        qtbot.keyClick(interactor, key)
    assert not w.viewport.plotter.ren_win.GetStereoRender()
    actors = w.viewport.plotter.renderer.GetActors()
    actors.InitTraversal()
    for _ in range(actors.GetNumberOfItems()):
        assert actors.GetNextActor().GetProperty().GetRepresentation() != 1  # 1: wireframe
    assert w.isVisible()


def test_polish_pause_icon_progress_and_empty_view(qtbot, explorer: Opened) -> None:
    c, w = explorer.controller, explorer.window
    assert w.viewport.skeleton_points().shape[0] == 1
    for actor in w.viewport._actors:  # nothing is drawn before the first decode (no dot at the origin)
        assert not actor.GetVisibility()
    with qtbot.waitSignal(c.shownChanged, timeout=20_000):
        c.gestures.click_point(1)
    assert w.timeline.is_playing() and not w.timeline.play_button.icon().isNull()
    assert w.timeline.play_button.text() == ""
    w.show_progress("Decoding bank codes for motion energy of every code in the bank", 0.5)
    assert w.progress_bar.width() >= 320
    w.hide_progress()
    w.resize(320, 240)
    qtbot.wait(50)
    w.resize(1500, 900)
    qtbot.wait(50)
    assert w.viewport.width() >= 240 and w.viewport.height() >= 200


def test_no_stale_star_or_diamonds_after_new_gestures(qtbot, explorer: Opened) -> None:
    c, w = explorer.controller, explorer.window
    emb = c.state.embedding
    corner = emb.min(axis=0) - 0.02 * np.ptp(emb, axis=0)
    with qtbot.waitSignal(c.shownChanged, timeout=20_000):
        click_map(qtbot, explorer, corner)  # empty space: decoded and starred
    assert len(w.latent_map._marker.data) == 1
    w.mode_panel.n_box.setValue(3)
    with qtbot.waitSignal(c.shownChanged, timeout=30_000):
        qtbot.mouseClick(w.mode_panel.sample_button, Qt.MouseButton.LeftButton)
    assert len(w.latent_map.extra_points()) == 3
    a, b = isolated_points(emb, 2)
    drag_map(qtbot, explorer, [emb[a] + t * (emb[b] - emb[a]) for t in np.linspace(0, 1, 4)])
    qtbot.waitUntil(
        lambda: c.gestures.drag_from is None and len(c.state.shown) == w.steps_spin.value(), timeout=20_000
    )
    assert len(w.latent_map._marker.data) == 0, "released on a code: the rings mark the ends, no star"
    with qtbot.waitSignal(c.shownChanged, timeout=20_000):
        click_map(qtbot, explorer, emb[a])
    assert len(w.latent_map.extra_points()) == 0 and len(w.latent_map._marker.data) == 0
