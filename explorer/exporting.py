"""The explorer's exports: motions, the selection, the map, the time-lapse strip and videos.

A companion of the controller that owns the File menu's export actions and their save dialogs (which
suggest a file name); every export reports failure in a message and leaves nothing half-written.
"""

from __future__ import annotations

import re
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np
from PySide6.QtCore import QObject
from PySide6.QtWidgets import QFileDialog, QInputDialog

from engine.errors import ConfigError
from explorer import export
from explorer.map_layers import mode_labels
from explorer.state import Decoded
from explorer.video import write_video

if TYPE_CHECKING:
    from explorer.controller import Controller

FILTERS = {
    "motion": "BVH (*.bvh);;NPZ (*.npz)",
    "selection": "BVH (*.bvh);;NPZ (*.npz)",
    "map": "PNG (*.png)",
    "timelapse": "PNG (*.png)",
    "video": "MP4 video (*.mp4);;GIF (*.gif)",
    "timelapse video": "MP4 video (*.mp4);;GIF (*.gif)",
}
MAP_WIDTH_PX = 2000


def suggested_name(label: str, suffix: str) -> str:
    """A file name from a label: '#12 data/walk_01.bvh (decoded)' -> 'walk_01_12_decoded.bvh'."""
    words = re.sub(r"\S*/", "", label)  # drop folders of clip paths
    words = re.sub(r"\.(bvh|npz|npy)\b", "", words)
    slug = re.sub(r"[^A-Za-z0-9]+", "_", words).strip("_").lower()
    return f"{slug[:60] or 'odmo'}{suffix}"


class Exporter(QObject):
    """Exports for the controller; each ``export_*`` returns what it wrote, or None after a message."""

    def __init__(self, controller: Controller) -> None:
        super().__init__(controller)
        self.c = controller
        w = controller.window
        w.export_motion_action.triggered.connect(lambda: self.ask("motion"))
        w.export_timelapse_action.triggered.connect(lambda: self.ask("timelapse"))
        w.export_map_action.triggered.connect(lambda: self.ask("map"))
        w.export_selection_action.triggered.connect(lambda: self.ask("selection"))
        w.export_video_action.triggered.connect(lambda: self.ask("video"))
        w.export_timelapse_video_action.triggered.connect(lambda: self.ask("timelapse video"))

    def _model_path(self) -> str:
        return str(self.c.generator.path)

    def export_shown(self, path: str | Path) -> list[Path] | None:
        """Write the motions shown in the viewport to ``path`` (BVH or NPZ; numbered when several)."""
        return self.c.guard(
            "Export failed", lambda: export.export_motions(self.c.state.shown, path, self._model_path())
        )

    def export_selection(self, path: str | Path) -> list[Path] | None:
        """Decode every selected bank code and write them to ``path`` (numbered files)."""
        from explorer.decoding import decode_one

        def run() -> list[Path]:
            c = self.c
            loaded, bank = c.generator, c.bank
            if not c.state.selection:
                raise ConfigError("nothing selected to export")
            labels = mode_labels(bank)
            items = []
            for i in c.state.selection:
                code, action, end = c.gestures.bank_item(i)
                mode = None if labels[i] < 0 else int(labels[i])
                motion = decode_one(loaded, code, action, end, mode)
                items.append(Decoded(motion, f"#{i} {bank.sources[i]}", code, action, end, mode, None, i))
            return export.export_motions(items, path, str(loaded.path))

        return self.c.guard("Export failed", run)

    def export_map(self, path: str | Path, width: int | None = None) -> Path | None:
        """Save the map plot alone (points, overlays, axis names; no tool buttons or legend boxes) as a
        PNG ``width`` pixels wide (default: as on screen), with projection, colouring and model as text."""
        state = self.c.state
        meta = {
            "model": str(state.model.path) if state.model else None,
            "projection": state.projection,
            "color_by": state.color_by,
            "selection": list(state.selection),
        }
        lmap = self.c.window.latent_map
        return self.c.guard("Export failed", lambda: export.save_png(lmap.render_plot(width), path, meta))

    def export_timelapse(self, path: str | Path) -> Path | None:
        """Save a time-lapse PNG of the first motion shown, seen from the side of its travel."""

        def run() -> Path:
            if not self.c.state.shown:
                raise ConfigError("no motion is shown")
            return export.save_timelapse(self.c.state.shown[0], path, self._model_path())

        return self.c.guard("Export failed", run)

    def video_frames(self) -> list[np.ndarray]:
        """Every frame of what plays, as the 3-D view renders it (the playback frame is restored)."""
        c, viewport = self.c, self.c.window.viewport
        played = c.playback.played
        if not played:
            raise ConfigError("no motion is shown")
        length = max(m.n_frames for m in played)
        current, frames = c.state.frame, []
        playing = c.window.timeline.is_playing()
        c.window.timeline.pause()
        try:
            for frame in range(length):
                c.playback.set_frame(frame)
                viewport.render_now()
                frames.append(np.asarray(viewport.plotter.screenshot(return_img=True), dtype=np.uint8))
        finally:
            c.playback.set_frame(current)
            if playing:
                c.window.timeline.play()
        return frames

    def export_video(self, path: str | Path) -> Path | None:
        """Write what plays in the 3-D view, every frame at the model's frame rate, as MP4 or GIF."""

        def run() -> Path:
            frames = self.video_frames()
            return write_video(frames, path, float(self.c.playback.played[0].fps))

        return self.c.guard("Export failed", run)

    def export_timelapse_video(self, path: str | Path) -> Path | None:
        """Write the time-lapse of the first motion shown, growing pose by pose, as MP4 or GIF."""

        def run() -> Path:
            if not self.c.state.shown:
                raise ConfigError("no motion is shown")
            item = self.c.state.shown[0]
            frames = export.timelapse_video_frames(item.motion, title=item.label)
            return write_video(frames, path, float(item.motion.fps))

        return self.c.guard("Export failed", run)

    def ask(self, what: str) -> None:
        """Ask where to export ``what`` (a file name is suggested), then export it."""
        shown = self.c.state.shown
        suffix = FILTERS[what].split("*")[1].split(")")[0]
        label = shown[0].label if shown and what != "map" else f"map_{self.c.state.projection}"
        path, chosen = QFileDialog.getSaveFileName(
            self.c.window, f"Export {what}", suggested_name(label, suffix), FILTERS[what]
        )
        if not path:
            return
        if not Path(path).suffix:
            path += "." + chosen.split("*.")[-1].rstrip(")")
        if what == "map":
            width, ok = QInputDialog.getInt(
                self.c.window, "Map width", "Width in pixels", MAP_WIDTH_PX, 200, 16000
            )
            if not ok:
                return
            done = self.export_map(path, width)
        else:
            run = {
                "motion": self.export_shown,
                "selection": self.export_selection,
                "timelapse": self.export_timelapse,
                "video": self.export_video,
                "timelapse video": self.export_timelapse_video,
            }[what]
            done = run(path)
        if done:
            self.c.window.show_status(f"Exported {what} to {path}")
