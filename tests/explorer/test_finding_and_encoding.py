"""Issue 12 'Missing': search, nearest neighbours, bookmarks, encoding clips by menu or drop."""

from __future__ import annotations

import shutil
from pathlib import Path

import numpy as np
import pytest
from PySide6.QtCore import QMimeData, QPointF, Qt, QUrl
from PySide6.QtGui import QDragEnterEvent, QDropEvent
from PySide6.QtWidgets import QApplication

from engine.generate import window_starts
from engine.motion.formats import write_motion
from engine.motion.resample import resample_motion
from explorer.bookmarks import bookmarks_path, load_bookmarks
from tests.explorer.conftest import Opened, close_message_boxes
from tests.explorer.gestures import click_map, isolated_points


@pytest.fixture
def own_model(tiny_model_dir: Path, tmp_path: Path) -> Path:
    """A copy of the tiny model that a test may write bookmarks into."""
    return Path(shutil.copytree(tiny_model_dir, tmp_path / "model"))


def _click_row(qtbot, widget, row: int) -> None:
    rect = widget.visualItemRect(widget.item(row))
    qtbot.mouseClick(widget.viewport(), Qt.MouseButton.LeftButton, pos=rect.center())


def test_search_lists_matching_clips_and_a_click_plays_one(qtbot, explorer: Opened) -> None:
    c, w = explorer.controller, explorer.window
    panel = w.find_panel
    w.find_dock.show()
    w.find_dock.raise_()
    qtbot.keyClicks(panel.search_box, "style:march")
    expected = [i for i, m in enumerate(c.bank.meta) if "march" in m.get("style", "")]
    assert expected and panel.result_ids() == expected[:200]
    assert f"{len(expected)} codes match" in panel.results_label.text()
    panel.search_box.clear()
    qtbot.keyClicks(panel.search_box, f"{c.bank.action_names[2]} #{int(c.bank.indices_of(2)[0])}")
    assert panel.result_ids() == [int(c.bank.indices_of(2)[0])]
    with qtbot.waitSignal(c.shownChanged, timeout=20_000):
        _click_row(qtbot, panel.results, 0)
    assert c.state.selection == (int(c.bank.indices_of(2)[0]),)


def test_neighbours_are_nearest_in_the_full_latent_space(qtbot, explorer: Opened) -> None:
    c, w = explorer.controller, explorer.window
    w.find_dock.show()
    w.find_dock.raise_()
    index = isolated_points(c.state.embedding, 1)[0]
    with qtbot.waitSignal(c.shownChanged, timeout=20_000):
        click_map(qtbot, explorer, c.state.embedding[index])
    d = np.linalg.norm(c.bank.codes - c.bank.codes[index], axis=1)
    d[index] = np.inf
    expected = np.argsort(d)[:10].tolist()
    assert w.find_panel.neighbour_ids() == expected
    assert f"{c.bank.codes.shape[1]}-D" in w.find_panel.neighbours_label.text()
    with qtbot.waitSignal(c.shownChanged, timeout=20_000):
        _click_row(qtbot, w.find_panel.neighbours, 0)
    assert c.state.selection == (expected[0],)


def test_bookmarks_are_saved_next_to_the_model_and_come_back(qtbot, open_explorer, own_model: Path) -> None:
    first = open_explorer(own_model)
    c, panel = first.controller, first.window.find_panel
    c.state.selection = (1, 4, 9)
    qtbot.keyClicks(panel.bookmark_name, "three picks")
    qtbot.mouseClick(panel.bookmark_button, Qt.MouseButton.LeftButton)
    [mark] = load_bookmarks(own_model, len(c.bank.codes))
    assert mark.name == "three picks" and mark.indices == (1, 4, 9)
    assert mark.sources == tuple(str(c.bank.sources[i]) for i in (1, 4, 9))
    second = open_explorer(own_model)
    qtbot.waitUntil(lambda: second.window.find_panel.bookmark_ids() == [0], timeout=10_000)
    with qtbot.waitSignal(second.controller.shownChanged, timeout=20_000):
        _click_row(qtbot, second.window.find_panel.bookmarks, 0)
    assert second.controller.state.selection == (1, 4, 9)
    assert sorted(d.bank_index for d in second.controller.state.shown) == [1, 4, 9]


def test_a_bookmark_that_cannot_be_written_gives_a_message(qtbot, open_explorer, own_model: Path) -> None:
    bookmarks_path(own_model).mkdir()  # a folder where the file should go: the write fails
    opened = open_explorer(own_model)
    c = opened.controller
    close_message_boxes()  # the unreadable "file" was reported on opening
    c.state.selection = (2,)
    with qtbot.waitSignal(c.errorOccurred, timeout=5_000):
        qtbot.mouseClick(opened.window.find_panel.bookmark_button, Qt.MouseButton.LeftButton)
    assert close_message_boxes()
    assert opened.window.find_panel.bookmark_ids() == [] and opened.window.isVisible()
    assert [p.name for p in own_model.iterdir() if "tmp" in p.name] == []


def _drop(window, paths: list[Path]) -> None:
    mime = QMimeData()
    mime.setUrls([QUrl.fromLocalFile(str(p)) for p in paths])
    target = window.latent_map.plot.viewport()
    pos = QPointF(target.width() / 2, target.height() / 2)
    for kind in (QDropEvent.Type.DragEnter, QDropEvent.Type.Drop):
        cls = QDragEnterEvent if kind == QDropEvent.Type.DragEnter else QDropEvent
        args = (pos.toPoint(),) if cls is QDragEnterEvent else (pos,)
        event = cls(
            *args, Qt.DropAction.CopyAction, mime, Qt.MouseButton.NoButton, Qt.KeyboardModifier.NoModifier
        )
        QApplication.sendEvent(target, event)
        assert event.isAccepted()


def test_dropped_clips_are_encoded_as_windows_and_bad_files_are_named(
    qtbot, explorer: Opened, procedural_clips, tmp_path: Path
) -> None:
    c, w = explorer.controller, explorer.window
    clip = procedural_clips[0]
    long = clip.with_joints(np.concatenate([clip.joints] * 3))
    good = tmp_path / "long_walk.npz"
    write_motion(long, good)
    bad = tmp_path / "broken.bvh"
    bad.write_text("HIERARCHY\nROOT hips\n{\n")
    w.stride_spin.setValue(20)
    with qtbot.waitSignal(c.shownChanged, timeout=60_000):
        _drop(w, [good, bad])
    texts = close_message_boxes()
    assert texts and "broken.bvh" in texts[0] and "long_walk" not in texts[0]
    moved = resample_motion(long, c.generator.fps) if abs(long.fps - c.generator.fps) > 1e-6 else long
    starts = window_starts(moved.n_frames, c.generator.window, 20)
    assert len(c.state.extra.codes) == len(starts)
    np.testing.assert_allclose(
        w.latent_map.extra_points(), c.projection.transform(c.state.extra.codes), atol=1e-6
    )
    [path] = w.latent_map.paths()
    assert len(path) == len(starts)
    assert "20 frames" in w.status_label.text() and "long_walk.npz" in w.status_label.text()
    assert len(c.state.shown) == min(len(starts), 12)
    assert all("long_walk.npz window" in d.label for d in c.state.shown)
    assert w.isVisible()


def test_a_marked_sample_on_the_map_can_be_clicked_and_plays(qtbot, explorer: Opened) -> None:
    c, w = explorer.controller, explorer.window
    w.mode_panel.n_box.setValue(3)
    with qtbot.waitSignal(c.shownChanged, timeout=30_000):
        qtbot.mouseClick(w.mode_panel.sample_button, Qt.MouseButton.LeftButton)
    extra = c.state.extra
    k = 1
    with qtbot.waitSignal(c.shownChanged, timeout=20_000):
        click_map(qtbot, explorer, extra.xy[k])
    [item] = c.state.shown
    np.testing.assert_allclose(item.code, extra.codes[k], atol=1e-6)
    assert item.action == int(extra.actions[k]) and "marked point 2/3" in item.label
    assert c.state.extra is extra, "the marked points stay while one of them plays"
