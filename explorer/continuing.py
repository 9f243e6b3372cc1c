"""Futures and continuations of the motion shown, for kinds that complete a prefix or extend a motion.

"Complete from here" (Motion menu, timeline button) asks the model for ``FUTURES`` continuations of the
first motion shown, from its first frame up to the timeline's frame, and plays them side by side (or as
the layout says): each future is the whole motion, prefix then new frames. "Continue" extends every
motion shown and plays on from the current frame; "Keep going" does so whenever playback nears the end.
Files can be played as recorded (File ▸ Play motion file…, or dropped on the map of a kind that neither
encodes nor inverts), so that a clip from disk can be completed too.

The model runs in tasks; a result is dropped when a newer request was made, another model was opened or
other motions were shown meanwhile. Each tool is enabled only where the loaded kind declares its
capability ("complete", "extend").
"""

from __future__ import annotations

import re
from pathlib import Path
from typing import TYPE_CHECKING

from PySide6.QtWidgets import QFileDialog

from explorer.decoding import condition
from explorer.encoding import MOTION_FILTER, file_error
from explorer.requests import label_index
from explorer.state import Decoded
from explorer.workers import Cancel, Progress

if TYPE_CHECKING:
    from engine.generators.base import Generator
    from engine.motion.motion import Motion
    from explorer.controller import Controller

#: futures a "Complete from here" asks for
FUTURES = 3
#: model windows of new frames a future, or one "Continue", adds
WINDOWS_AHEAD = 2
#: "Keep going" stops extending past this many frames
KEEP_GOING_MAX_FRAMES = 20_000
_FUTURE_PREFIX = re.compile(r"^future \d+/\d+ · from frame \d+ of ")
_CONTINUED = " · continued to "


def frames_ahead(generator: Generator) -> int:
    """Frames a future or a continuation adds: ``WINDOWS_AHEAD`` model windows."""
    return WINDOWS_AHEAD * int(generator.window)


def root_label(label: str) -> str:
    """``label`` without what completing and continuing added to it."""
    return _FUTURE_PREFIX.sub("", label).split(_CONTINUED)[0]


class Continuation:
    """The completing and continuing tools of controller ``c``."""

    def __init__(self, c: Controller) -> None:
        self.c = c
        self.asked = 0  # id of the newest completion or continuation asked for
        self.pending = False  # a continuation is running (Keep going asks for no second one)
        w = c.window
        w.complete_action.triggered.connect(lambda: self.complete_here())
        w.continue_action.triggered.connect(lambda: self.continue_shown())
        w.keep_going_action.toggled.connect(self._keep_going_toggled)
        w.play_file_action.triggered.connect(self.ask_files)
        c.state.events.frame.connect(self._frame_changed)
        c.modelLoaded.connect(self._model_changed)

    def _model_changed(self, generator: Generator) -> None:
        self.asked += 1
        self.pending = False
        if "extend" not in generator.capabilities:
            self.c.window.keep_going_action.setChecked(False)

    # -- complete ------------------------------------------------------------------------------------

    def complete_here(self, n: int = FUTURES, frames: int | None = None) -> None:
        """Ask for ``n`` futures of the first motion shown from its first frame up to the timeline's, each
        ``frames`` new frames long (default ``frames_ahead``), and play them."""
        if self.c.state.model is None or self.c.refuse("complete"):
            return
        shown, played = self.c.state.shown, self.c.playback.played
        if not shown or not played:
            self.c.window.show_status("Completing needs a motion: click a point or play a motion file.")
            return
        generator, item = self.c.generator, shown[0]
        source = played[0]  # what plays (a chained sequence is one motion)
        k = min(int(self.c.state.frame), source.n_frames - 1)
        if k < 1:
            self.c.window.show_status("Move the timeline past the first frame: the futures start after it.")
            return
        frames = frames_ahead(generator) if frames is None else int(frames)
        prefix = source.with_joints(source.joints[: k + 1].copy())
        action, seed = condition(generator, item.action), self.c.new_seed()
        self.asked += 1
        asked = self.asked

        def job(progress: Progress, _c: Cancel) -> list[Motion]:
            progress(f"Completing {k + 1} frames with {n} futures of {frames} frames", 0.0)
            return generator.complete(prefix, frames, n, seed, action)

        def done(futures: list[Motion]) -> None:
            if self._current(asked, generator, shown):
                self.show_futures(futures, item, k, seed)

        self.c.run_task(f"Completing {item.label} from frame {k + 1}", job, done)

    def show_futures(self, futures: list[Motion], item: Decoded, k: int, seed: int) -> None:
        """Play ``futures`` of ``item`` completed after its frame ``k`` (0-based), labelled and numbered."""
        base = root_label(item.label)
        head = int(futures[0].meta.get("prefix_frames", k + 1))
        note = f"frames 1–{head} are {base}'s, the rest the model's ({len(futures)} futures)"
        self.c.state.shown = tuple(
            Decoded(
                m,
                f"future {j + 1}/{len(futures)} · from frame {k + 1} of {base}",
                None,
                item.action,
                seed=seed,
                note=note,
            )
            for j, m in enumerate(futures)
        )

    # -- continue ------------------------------------------------------------------------------------

    def continue_shown(self, frames: int | None = None) -> None:
        """Extend every motion shown by ``frames`` frames (default ``frames_ahead``) and play on from the
        current frame."""
        if self.c.state.model is None or self.c.refuse("extend"):
            return
        shown = self.c.state.shown
        if not shown:
            self.c.window.show_status("Continuing needs a motion: click a point or play a motion file.")
            return
        generator = self.c.generator
        frames = frames_ahead(generator) if frames is None else int(frames)
        seeds = [self.c.new_seed() for _ in shown]
        actions = [condition(generator, d.action) for d in shown]
        motions = [d.motion for d in shown]
        self.asked += 1
        asked = self.asked
        self.pending = True

        def job(progress: Progress, cancel: Cancel) -> list[Motion]:
            out = []
            for j, (motion, seed, action) in enumerate(zip(motions, seeds, actions, strict=True)):
                if cancel():
                    break
                progress(f"Continuing {len(motions)} motion(s) by {frames} frames", j / len(motions))
                out.append(generator.extend(motion, frames, seed, action))
            return out

        def done(longer: list[Motion]) -> None:
            if asked == self.asked:
                self.pending = False
            if self._current(asked, generator, shown) and len(longer) == len(shown):
                self.show_continued(shown, longer, seeds)

        def stopped() -> None:
            if asked == self.asked:
                self.pending = False
            self.c.window.keep_going_action.setChecked(False)

        def failed(exc: BaseException) -> None:
            stopped()
            self.c.report_error("Cannot continue the motion", exc)

        task = self.c.tasks.run(f"Continuing by {frames} frames", job, done, failed)
        task.cancelled.connect(stopped)

    def show_continued(self, shown: tuple[Decoded, ...], longer: list[Motion], seeds: list[int]) -> None:
        """Replace ``shown`` by its ``longer`` motions, playing on from the current frame."""
        items = tuple(
            Decoded(
                m,
                f"{d.label.split(_CONTINUED)[0]}{_CONTINUED}{m.n_frames} frames",
                d.code,
                d.action,
                d.end,
                d.mode,
                seed,
                d.bank_index,
                d.note,
            )
            for d, m, seed in zip(shown, longer, seeds, strict=True)
        )
        self.c.playback.keep_frame = True
        self.c.state.shown = items

    def _keep_going_toggled(self, on: bool) -> None:
        if on:
            self._frame_changed(self.c.state.frame)

    def _frame_changed(self, frame: int) -> None:
        """With Keep going on: extend what plays once playback is within a window of its end."""
        w = self.c.window
        if not w.keep_going_action.isChecked() or self.pending or not self.c.can("extend"):
            return
        played = self.c.playback.played
        if not played or self.c.state.layout == "sequence":
            return
        length = max(m.n_frames for m in played)
        if length >= KEEP_GOING_MAX_FRAMES:
            w.keep_going_action.setChecked(False)
            w.show_status(f"Kept going up to {length} frames; stopped there.")
            return
        if frame >= length - int(self.c.generator.window):
            self.continue_shown()

    def _current(self, asked: int, generator: Generator, shown: tuple[Decoded, ...]) -> bool:
        """True when a result asked for as ``asked`` on ``shown`` may still be shown."""
        return asked == self.asked and self.c.state.model is generator and self.c.state.shown is shown

    # -- motion files --------------------------------------------------------------------------------

    def ask_files(self) -> None:
        """Ask for motion files and play them as recorded."""
        paths, _ = QFileDialog.getOpenFileNames(self.c.window, "Play motion files", "", MOTION_FILTER)
        if paths:
            self.play_files(paths)

    def play_files(self, paths: list[str]) -> None:
        """Read ``paths`` in the background and play them as recorded, side by side, on the model's joints
        (a file with joints beyond them, such as Bandai's ``joint_Root``, plays without those); the files
        that cannot be read or are of another rig are named in one message."""
        if self.c.state.model is None:
            self.c.report_error("Cannot play the files", "no model is loaded (File ▸ Open model folder…)")
            return
        generator = self.c.generator

        def job(progress: Progress, _c: Cancel) -> tuple[list[tuple[Path, Motion]], list[str]]:
            from engine.errors import OdmoError
            from engine.motion.datasets import conform_to
            from engine.motion.formats import read_motion

            read, failed = [], []
            for j, name in enumerate(paths):
                progress(f"Reading {Path(name).name}", j / len(paths))
                try:
                    read.append((Path(name), conform_to(generator.skeleton, read_motion(name))))
                except (OdmoError, OSError, ValueError) as exc:
                    failed.append(file_error(name, exc))
            return read, failed

        def done(result: tuple[list[tuple[Path, Motion]], list[str]]) -> None:
            read, failed = result
            if failed:
                self.c.report_error("Some files could not be played", "\n".join(failed))
            if not read or self.c.state.model is not generator:
                return
            self.c.state.shown = tuple(
                Decoded(m, f"{p.name} (file)", None, label_index(generator, m)) for p, m in read
            )
            named = (("complete", "Complete from here"), ("extend", "Continue"))
            tools = [name for cap, name in named if self.c.can(cap)]
            hint = f" · {' and '.join(tools)} in the Motion menu" if tools else ""
            self.c.window.show_status(self.c.window.status_label.text() + hint)

        self.c.run_task(f"Reading {len(paths)} motion file(s)", job, done)
