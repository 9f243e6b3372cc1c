"""The explorer's files, errors, layout memory and entry point on the tiny model."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from PySide6.QtGui import QImage

from engine.motion.formats import read_motion
from explorer import app
from tests.explorer.conftest import Opened, close_message_boxes


def _show_bank_code(qtbot, opened: Opened, index: int) -> None:
    with qtbot.waitSignal(opened.controller.shownChanged, timeout=20_000):
        opened.controller.gestures.click_point(index)


def test_export_npz_and_bvh_read_back_with_provenance(qtbot, explorer: Opened, tmp_path: Path) -> None:
    c = explorer.controller
    _show_bank_code(qtbot, explorer, 3)
    shown = c.state.shown[0]
    [npz] = c.exporter.export_shown(tmp_path / "clip.npz")
    back = read_motion(npz)
    np.testing.assert_allclose(back.joints, shown.motion.joints, atol=1e-6)
    assert back.meta["code"] == pytest.approx([float(v) for v in c.bank.codes[3]])
    assert back.meta["action"] == c.bank.action_names[int(c.bank.actions[3])]
    assert back.meta["model"] == str(c.generator.path)
    assert back.meta["end"] == pytest.approx([float(v) for v in c.bank.ends[3]])
    assert back.meta["bank_index"] == 3
    [bvh] = c.exporter.export_shown(tmp_path / "clip.bvh")
    read = read_motion(bvh)
    assert read.n_frames == shown.motion.n_frames
    assert read.skeleton.same_topology(shown.motion.skeleton)
    root = read.skeleton.root  # BVH stores the root's translation exactly; the limbs go through IK
    np.testing.assert_allclose(read.joints[:, root], shown.motion.joints[:, root], atol=1e-4)


def test_export_selection_writes_one_file_per_code(qtbot, explorer: Opened, tmp_path: Path) -> None:
    c = explorer.controller
    c.state.selection = (0, 5, 7)
    written = c.exporter.export_selection(tmp_path / "sel.npz")
    assert [p.name for p in written] == ["sel_000.npz", "sel_001.npz", "sel_002.npz"]
    assert [read_motion(p).meta["bank_index"] for p in written] == [0, 5, 7]


def test_failed_export_shows_error_and_leaves_nothing(qtbot, explorer: Opened, tmp_path: Path) -> None:
    c = explorer.controller
    _show_bank_code(qtbot, explorer, 0)
    blocked = tmp_path / "file"
    blocked.write_text("not a folder")
    before = sorted(tmp_path.iterdir())
    with qtbot.waitSignal(c.errorOccurred, timeout=5_000) as blocker:
        assert c.exporter.export_shown(blocked / "clip.bvh") is None
    assert "clip.bvh" in blocker.args[0] or "file" in blocker.args[0]
    with qtbot.waitSignal(c.errorOccurred, timeout=5_000):
        c.exporter.export_shown(tmp_path / "clip.txt")
    assert sorted(tmp_path.iterdir()) == before
    assert close_message_boxes()


def test_map_and_timelapse_pngs_carry_metadata(qtbot, explorer: Opened, tmp_path: Path) -> None:
    c = explorer.controller
    _show_bank_code(qtbot, explorer, 2)
    map_png = c.exporter.export_map(tmp_path / "map.png")
    strip_png = c.exporter.export_timelapse(tmp_path / "strip.png")
    image = QImage(str(map_png))
    assert image.width() > 100 and image.text("projection") == "pca"
    strip = QImage(str(strip_png))
    assert strip.width() > strip.height()
    assert json.loads(strip.text("code")) == pytest.approx([float(v) for v in c.bank.codes[2]])
    assert strip.text("model") == str(c.generator.path)


def test_broken_model_folder_shows_error_and_keeps_running(qtbot, explorer: Opened, tmp_path: Path) -> None:
    c = explorer.controller
    broken = tmp_path / "broken"
    broken.mkdir()
    (broken / "model.json").write_text("{ not json")
    before = c.state.model
    with qtbot.waitSignal(c.errorOccurred, timeout=20_000) as blocker:
        c.loader.open_model(broken)
    assert "broken" in blocker.args[0]
    texts = close_message_boxes()
    assert texts and "broken" in texts[0]
    assert c.state.model is before and explorer.window.isVisible()
    _show_bank_code(qtbot, explorer, 1)


def test_window_without_model_says_how_to_open_one(open_explorer, monkeypatch, tmp_path: Path) -> None:
    monkeypatch.setattr(app, "DEFAULT_MODEL", tmp_path / "not-installed")
    opened = open_explorer(None)
    assert "not installed" in opened.window.status_label.text()
    assert opened.controller.state.model is None


def test_dock_layout_is_remembered(qtbot, open_explorer, tiny_model_dir: Path, tmp_path: Path) -> None:
    settings = tmp_path / "layout.ini"
    first = open_explorer(tiny_model_dir, settings, wait=False)
    first.window.mode_dock.setFloating(True)
    first.window.trajectory_dock.hide()
    first.window.save_layout()
    second = open_explorer(tiny_model_dir, settings, wait=False)
    assert second.window.mode_dock.isFloating()
    assert not second.window.trajectory_dock.isVisible()
    assert second.window.viewport_dock.isVisible()


def _run_app(*args: str) -> subprocess.CompletedProcess:
    command = [sys.executable, "-m", "explorer.app", *args]
    return subprocess.run(command, capture_output=True, text=True, timeout=300, check=False)


def test_screenshot_entry_point_selects_and_colours_for_scripted_figures(
    tiny_model_dir: Path, tmp_path: Path
) -> None:
    shot = tmp_path / "figure.png"
    settings = tmp_path / "s.ini"
    done = _run_app(
        "--model", str(tiny_model_dir), "--screenshot", str(shot), "--after", "0.5",
        "--settings", str(settings), "--select", "3", "--color-by", "meta:style",
    )  # fmt: skip
    assert done.returncode == 0, done.stderr
    image = QImage(str(shot))
    assert image.width() >= 800 and image.height() >= 500
    assert image.text("model") == str(tiny_model_dir)
    assert json.loads(image.text("selection")) == [3]
    assert image.text("color_by") == "meta:style" and image.text("projection") == "pca"
    assert settings.is_file()


def test_screenshot_of_a_broken_model_exits_non_zero_and_writes_nothing(tmp_path: Path) -> None:
    broken = tmp_path / "broken"
    broken.mkdir()
    (broken / "model.json").write_text("{ not json")
    shot = tmp_path / "shot.png"
    done = _run_app("--model", str(broken), "--screenshot", str(shot), "--after", "0.2", "--settings",
                    str(tmp_path / "s.ini"))  # fmt: skip
    assert done.returncode != 0
    assert "broken" in done.stderr and "no screenshot" in done.stderr
    assert "Traceback" not in done.stderr
    assert not shot.exists() and not list(tmp_path.glob("*.tmp*"))


def test_a_damaged_latent_bank_gives_a_message_and_the_app_keeps_running(
    qtbot, explorer: Opened, tiny_model_dir: Path, tmp_path: Path
) -> None:
    import shutil

    c = explorer.controller
    damaged = tmp_path / "damaged"
    shutil.copytree(tiny_model_dir, damaged)
    bank = np.load(damaged / "latent_bank.npz")
    arrays = {k: bank[k] for k in bank.files}
    arrays["codes"] = arrays["codes"][:5]  # fewer codes than actions, sources, ends
    with open(damaged / "latent_bank.npz", "wb") as handle:
        np.savez(handle, **arrays)
    before = c.state.model
    with qtbot.waitSignal(c.errorOccurred, timeout=30_000) as blocker:
        c.loader.open_model(damaged)
    assert "damaged" in blocker.args[0] or "bank" in blocker.args[0]
    assert close_message_boxes()
    qtbot.wait(100)
    assert c.state.model is before and explorer.window.isVisible()
    assert len(explorer.window.latent_map.visible_rows()) == len(c.bank.codes)
    _show_bank_code(qtbot, explorer, 1)
