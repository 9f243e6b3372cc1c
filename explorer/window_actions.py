"""The main window's toolbar and menus: the controls and actions the controller connects."""

from __future__ import annotations

from typing import TYPE_CHECKING

from PySide6.QtCore import Qt
from PySide6.QtGui import QKeySequence
from PySide6.QtWidgets import QComboBox, QLabel, QSpinBox, QToolBar

from explorer.state import COLOR_BY, PROJECTIONS

if TYPE_CHECKING:
    from explorer.main_window import MainWindow

PROJECTION_LABELS = {"pca": "PCA", "tsne": "t-SNE", "umap": "UMAP"}


def build_toolbar(window: MainWindow) -> None:
    """The toolbar: projection, colouring, action, strip steps, layout, ghosts, encode stride."""
    bar = QToolBar("Map", window)
    bar.setObjectName("toolbar_map")
    window.addToolBar(Qt.TopToolBarArea, bar)

    bar.addWidget(QLabel(" Projection "))
    window.projection_combo = QComboBox()
    for name in PROJECTIONS:
        window.projection_combo.addItem(PROJECTION_LABELS[name], name)
    window.projection_combo.setToolTip("Map projection: precomputed ones switch instantly")
    bar.addWidget(window.projection_combo)

    bar.addWidget(QLabel("  Colour by "))
    window.color_combo = QComboBox()
    for name in COLOR_BY:
        window.color_combo.addItem(name, name)
    bar.addWidget(window.color_combo)

    bar.addSeparator()
    bar.addWidget(QLabel(" Action "))
    window.action_combo = QComboBox()
    window.action_combo.setToolTip("Action for the mode panel, sampling and empty-space decoding")
    bar.addWidget(window.action_combo)

    bar.addSeparator()
    window.steps_spin = _spin_box(
        bar,
        "Strip steps",
        (2, 16),
        5,
        "Number of motions in the interpolation strip a drag leaves behind",
    )
    window.layout_combo = QComboBox()
    window.layout_combo.addItem("side by side", "side_by_side")
    window.layout_combo.addItem("overlaid", "overlay")
    window.layout_combo.addItem("in sequence", "sequence")
    window.layout_combo.setToolTip("How several motions are shown")
    bar.addWidget(window.layout_combo)
    window.ghosts_spin = _spin_box(
        bar, "Ghosts", (0, 16), 4, "Faint poses drawn along a single motion (0: none)"
    )
    window.stride_spin = _spin_box(
        bar,
        "Encode stride",
        (1, 600),
        30,
        "Frames between the windows a long clip is encoded as (one code each)",
        suffix=" frames",
    )


def build_menus(window: MainWindow) -> None:
    """The File, Selection, Motion and View menus."""
    file_menu = window.menuBar().addMenu("&File")
    file_menu.setToolTipsVisible(True)
    window.open_model_action = file_menu.addAction("Open &model folder…")
    window.open_model_action.setShortcut(QKeySequence.Open)
    window.recent_menu = file_menu.addMenu("Open &recent model")
    window.bundled_menu = file_menu.addMenu("&Bundled models")
    window.open_data_action = file_menu.addAction("Open &dataset folder…")
    window.encode_action = file_menu.addAction("E&ncode clips… (or drop files on the map)")
    window.invert_action = file_menu.addAction("&Invert clips… (by optimisation)")
    window.play_file_action = file_menu.addAction("&Play motion file as recorded…")
    file_menu.addSeparator()
    window.export_motion_action = file_menu.addAction("&Export shown motion(s) (BVH / NPZ)…")
    window.export_motion_action.setShortcut(QKeySequence("Ctrl+E"))
    window.export_timelapse_action = file_menu.addAction("Export &time-lapse strip (PNG)…")
    window.export_map_action = file_menu.addAction("Export &map (PNG)…")
    window.export_video_action = file_menu.addAction("Export 3-D &video (MP4 / GIF)…")
    window.export_timelapse_video_action = file_menu.addAction("Export time-lapse v&ideo (MP4 / GIF)…")
    file_menu.addSeparator()
    window.quit_action = file_menu.addAction("&Quit")
    window.quit_action.setShortcut(QKeySequence.Quit)
    window.quit_action.triggered.connect(window.close)

    sel = window.menuBar().addMenu("&Selection")
    sel.setToolTipsVisible(True)
    window.select_clip_action = sel.addAction("Select the &clip's windows")
    window.select_clip_action.setToolTip("Select every code of the playing code's clip, in time order")
    window.play_selection_action = sel.addAction("&Play selection together")
    window.variations_action = sel.addAction("Sample &variations around selection")
    window.fit_mode_action = sel.addAction("&Fit a local mode to selection")
    window.export_selection_action = sel.addAction("E&xport selection (BVH / NPZ)…")
    sel.addSeparator()
    window.clear_selection_action = sel.addAction("&Clear selection and samples")
    window.clear_selection_action.setShortcut(QKeySequence(Qt.Key_Escape))

    motion = window.menuBar().addMenu("&Motion")
    motion.setToolTipsVisible(True)
    window.complete_action = motion.addAction("Complete from &here")
    window.complete_action.setShortcut(QKeySequence("Ctrl+K"))
    window.continue_action = motion.addAction("C&ontinue")
    window.continue_action.setShortcut(QKeySequence("Ctrl+Right"))
    window.keep_going_action = motion.addAction("&Keep going while it plays")
    window.keep_going_action.setCheckable(True)

    view = window.menuBar().addMenu("&View")
    for dock in window.docks():
        view.addAction(dock.toggleViewAction())
    view.addSeparator()
    window.reset_camera_action = view.addAction("Reset &camera")
    window.follow_camera_action = view.addAction("&Follow the skeleton")
    window.follow_camera_action.setCheckable(True)
    window.labels_action = view.addAction("&Labels over skeletons")
    window.labels_action.setCheckable(True)
    window.labels_action.setChecked(True)
    window.reset_layout_action = view.addAction("&Reset panel layout")
    window.reset_layout_action.triggered.connect(window.reset_layout)


def _spin_box(
    bar: QToolBar, label: str, bounds: tuple[int, int], value: int, tip: str, suffix: str = ""
) -> QSpinBox:
    """A labelled integer spin box added to the toolbar ``bar``."""
    bar.addWidget(QLabel(f" {label} "))
    spin = QSpinBox()
    spin.setRange(*bounds)
    spin.setValue(value)
    spin.setSuffix(suffix)
    spin.setToolTip(tip)
    bar.addWidget(spin)
    return spin
