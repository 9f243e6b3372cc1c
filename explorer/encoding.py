"""Encode motion files in the app (File ▸ Encode clips…, or files dropped on the map).

Each file is read and encoded window by window in a worker (a long clip becomes a path of codes,
one every ``stride`` frames); the codes appear on the map as marked points joined in time order, and
the windows play in the viewport. Unreadable files are named in one message; the rest still show.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np
from PySide6.QtCore import QObject
from PySide6.QtWidgets import QFileDialog

from engine.errors import OdmoError
from explorer.decoding import map_codes
from explorer.state import Decoded, ExtraPoints

if TYPE_CHECKING:
    from engine.generate import WindowCodes
    from engine.generators.base import Generator
    from explorer.controller import Controller

MOTION_FILTER = "Motion files (*.bvh *.npz *.npy);;All files (*)"
MAX_PLAYED_WINDOWS = 12


@dataclass(frozen=True, eq=False)
class EncodedClip:
    """One encoded file: its path, its windows' codes and the decoded windows, by ``generator``."""

    path: Path
    windows: WindowCodes
    decoded: list[Decoded]
    generator: Generator


class ClipEncoder(QObject):
    """Encodes files for the controller and shows them on the map and in the viewport."""

    def __init__(self, controller: Controller) -> None:
        super().__init__(controller)
        self.c = controller
        self.clips: list[EncodedClip] = []
        controller.window.encode_action.triggered.connect(self.ask)
        controller.window.latent_map.filesDropped.connect(self.dropped)

    def ask(self) -> None:
        """Ask for motion files and encode them."""
        paths, _ = QFileDialog.getOpenFileNames(self.c.window, "Encode clips", "", MOTION_FILTER)
        if paths:
            self.encode_files(paths)

    def dropped(self, paths: list[str]) -> None:
        """Files dropped on the map: inverted where the loaded kind inverts by optimisation, else encoded;
        played as recorded by a kind that does neither but completes or extends motions."""
        if self.c.can("invert"):
            panel = self.c.window.latent_panel
            self.c.latent.invert_files(paths, panel.space_combo.currentText(), panel.steps_spin.value())
        elif not self.c.can("encode") and (self.c.can("complete") or self.c.can("extend")):
            self.c.continuation.play_files(paths)
        else:
            self.encode_files(paths)

    def encode_files(self, paths: list[str]) -> None:
        """Encode ``paths`` in the background; show what could be read, report what could not."""
        if self.c.state.model is None:
            self.c.report_error("Cannot encode", "no model is loaded (File ▸ Open model folder…)")
            return
        if self.c.refuse("encode"):
            return
        loaded, stride = self.c.generator, self.c.window.stride_spin.value()

        def job(progress, cancel) -> tuple[list[EncodedClip], list[str]]:
            from engine.motion.formats import read_motion

            done, failed = [], []
            for k, name in enumerate(paths):
                if cancel():
                    break
                progress(f"Encoding {Path(name).name}", k / len(paths))
                try:
                    motion = read_motion(name)
                    windows = loaded.encode_windows(motion, stride)
                    decoded = _decode_windows(loaded, Path(name), windows)
                except (OdmoError, OSError, ValueError) as exc:
                    failed.append(file_error(name, exc))
                    continue
                done.append(EncodedClip(Path(name), windows, decoded, loaded))
            return done, failed

        self.c.run_task(f"Encoding {len(paths)} file(s)", job, self._encoded)

    def _encoded(self, result: tuple[list[EncodedClip], list[str]]) -> None:
        done, failed = result
        if failed:
            self.c.report_error("Some files could not be encoded", "\n".join(failed))
        done = [clip for clip in done if clip.generator is self.c.state.model]  # not another model's codes
        if not done:
            return
        self.clips = done
        self.show()
        first = done[0]
        shown = first.decoded[:MAX_PLAYED_WINDOWS]
        self.c.state.shown = tuple(shown)
        windows = sum(len(clip.windows.starts) for clip in done)
        names = self.c.generator.label_names
        guesses = np.concatenate([clip.windows.actions for clip in done])
        tally = np.bincount(guesses[guesses >= 0], minlength=len(names))
        counts = ", ".join(f"{names[a]} ×{n}" for a, n in enumerate(tally) if n)
        seconds = first.windows.stride / self.c.generator.fps
        self.c.window.show_status(
            f"Encoded {len(done)} file(s) into {windows} windows (one every {first.windows.stride} frames = "
            f"{seconds:.2f} s): guessed {counts}. Marked ◆ on the map, joined in time order; "
            f"playing {len(shown)} window(s) of {first.path.name}."
        )

    def show(self) -> None:
        """Put the encoded codes on the map (diamonds in the guessed action's colour) and their paths; the
        codes of a model no longer loaded are forgotten."""
        self.clips = [clip for clip in self.clips if clip.generator is self.c.state.model]
        projection = self.c.projection
        if projection is None or not self.clips:
            self.c.window.latent_map.set_paths([])
            return
        codes = np.concatenate([clip.windows.codes for clip in self.clips]).astype(np.float32)
        actions = np.concatenate([np.maximum(clip.windows.actions, 0) for clip in self.clips])
        xy = projection.transform(map_codes(self.c.generator, codes))
        self.c.state.extra = ExtraPoints(codes, actions, xy)
        paths, start = [], 0
        for clip in self.clips:
            n = len(clip.windows.starts)
            if n > 1:
                paths.append(xy[start : start + n])
            start += n
        self.c.window.latent_map.set_paths(paths)


def file_error(name: str, exc: BaseException) -> str:
    """The message of ``exc`` raised reading or using file ``name``, naming the file once."""
    text, base = str(exc), Path(name).name
    return text if base in text else f"{base}: {text}"


def _decode_windows(loaded, path: Path, windows: WindowCodes) -> list[Decoded]:
    """Decode each window's code as its guessed action, labelled with the file and the window."""
    from explorer.decoding import decode_one

    items = []
    count = len(windows.starts)
    for k, (code, end, start, action) in enumerate(
        zip(windows.codes, windows.ends, windows.starts, windows.actions, strict=True)
    ):
        action = int(max(action, 0))
        motion = decode_one(loaded, code, action, end, None)
        label = f"{path.name} window {k + 1}/{count} @ frame {int(start)}"
        items.append(Decoded(motion, label, code.copy(), action, end.copy(), None))
    return items
