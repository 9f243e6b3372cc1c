"""Start-up order: the map is painted from the bank (numpy only) before torch, scikit-learn or VTK load."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import numpy as np

from engine.latent.bank import LatentBank
from explorer.preview import read_preview
from tests.explorer.conftest import Opened


def test_preview_reads_the_banks_map(tiny_model_dir: Path) -> None:
    preview = read_preview(tiny_model_dir)
    bank = LatentBank.load(tiny_model_dir / "latent_bank.npz")
    assert preview is not None
    np.testing.assert_array_equal(preview.actions, bank.actions)
    assert preview.action_names == bank.action_names
    np.testing.assert_array_equal(preview.embeddings["pca"], bank.projections["pca"].embedding_)
    # the tiny model's bank is written in the current format (sources and meta as columns)
    assert int(np.load(tiny_model_dir / "latent_bank.npz")["version"]) == 3
    assert list(preview.sources) == list(bank.sources)
    assert [dict(m) for m in preview.meta] == [dict(m) for m in bank.meta]
    assert len(preview.meta) == len(bank.codes) and all("style" in m for m in preview.meta)


def test_preview_of_a_folder_without_bank_is_none(tmp_path: Path) -> None:
    assert read_preview(tmp_path) is None
    (tmp_path / "latent_bank.npz").write_bytes(b"not a zip")
    assert read_preview(tmp_path) is None


def test_window_and_map_need_no_torch_sklearn_or_vtk(tiny_model_dir: Path) -> None:
    script = (
        "import sys\n"
        "from explorer import app, controller, main_window, map_layers, preview\n"
        f"p = preview.read_preview({str(tiny_model_dir)!r})\n"
        "map_layers.category_colors(len(p.action_names))[p.actions]\n"
        "map_layers.tooltip_texts(p.sources, p.actions, p.action_names, p.meta)\n"
        "heavy = ('torch', 'sklearn', 'umap', 'pyvista', 'vtkmodules', 'engine.generate')\n"
        "print(' '.join(m for m in heavy if m in sys.modules))\n"
    )
    done = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True, timeout=120)
    assert done.returncode == 0, done.stderr
    assert done.stdout.strip() == "", f"imported before the first paint: {done.stdout}"


def test_map_is_painted_before_the_model_loads(qtbot, open_explorer, tiny_model_dir: Path) -> None:
    seen: list[tuple[bool, int]] = []
    opened: Opened = open_explorer(tiny_model_dir, wait=False)
    window, c = opened.window, opened.controller
    if not opened.explorer.waiting:  # painted while the window was being exposed
        assert len(window.latent_map.visible_rows()) == len(read_preview(tiny_model_dir).actions)
    else:
        window.mapPainted.connect(
            lambda: seen.append((c.state.model is None, len(window.latent_map.visible_rows())))
        )
        qtbot.waitUntil(lambda: bool(seen), timeout=10_000)
        assert seen[0] == (True, len(read_preview(tiny_model_dir).actions))
    qtbot.waitUntil(lambda: c.state.model is not None, timeout=60_000)
    qtbot.waitUntil(window.has_viewport, timeout=10_000)
    assert len(window.latent_map.visible_rows()) == len(c.bank.codes)
    with qtbot.waitSignal(c.shownChanged, timeout=20_000):
        c.gestures.click_point(0)


def test_opening_the_3d_view_does_not_recreate_the_shown_window(qtbot, open_explorer, tiny_model_dir) -> None:
    native_ids: list[int] = []
    hidden: list[bool] = []

    def watch(window) -> None:
        window.winId()  # the native window the user sees, created now so its id is known before show
        native_ids.append(int(window.winId()))
        window.windowHandle().visibleChanged.connect(lambda visible: visible or hidden.append(True))

    opened: Opened = open_explorer(tiny_model_dir, wait=False, before_show=watch)
    window = opened.window
    qtbot.waitUntil(window.has_viewport, timeout=20_000)
    qtbot.wait(300)
    assert (int(window.winId()), hidden) == (native_ids[0], []), "the window blinked out"


def test_vtk_is_imported_off_the_gui_thread_after_the_model(tiny_model_dir: Path, tmp_path: Path) -> None:
    script = (
        "import json, sys, threading\n"
        "first = {}\n"
        "def hook(event, args):\n"
        "    if event == 'import' and args[0] in ('pyvista', 'torch') and args[0] not in first:\n"
        "        first[args[0]] = threading.current_thread() is threading.main_thread()\n"
        "sys.addaudithook(hook)\n"
        "from PySide6.QtCore import QSettings, QTimer\n"
        "from PySide6.QtWidgets import QApplication\n"
        "from explorer.app import create_explorer\n"
        "app = QApplication([])\n"
        f"ex = create_explorer({str(tiny_model_dir)!r}, None, QSettings({str(tmp_path / 's.ini')!r}, "
        "QSettings.Format.IniFormat))\n"
        "order = []\n"
        "ex.controller.modelLoaded.connect(lambda m: order.append('model'))\n"
        "def created():\n"
        "    order.append('viewport')\n"
        "    points = ex.window.viewport.skeleton_points()\n"
        "    joints = len(ex.controller.state.model.skeleton.parents)\n"
        "    rig = list(points.shape[:2])\n"
        "    print(json.dumps({'order': order, 'on_main': first, 'rig': rig, 'joints': joints}))\n"
        "    app.quit()\n"
        "ex.window.viewportCreated.connect(lambda: QTimer.singleShot(0, created))\n"
        "ex.window.show()\n"
        "QTimer.singleShot(60_000, app.quit)\n"
        "app.exec()\n"
        "ex.close()\n"
    )
    done = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True, timeout=120)
    assert done.returncode == 0, done.stderr
    seen = json.loads(done.stdout.strip().splitlines()[-1])
    assert seen["order"] == ["model", "viewport"]
    assert seen["on_main"] == {"torch": False, "pyvista": False}, "imported on the GUI thread"
    assert seen["rig"] == [1, seen["joints"]], "the new 3-D view does not show the model's skeleton"
