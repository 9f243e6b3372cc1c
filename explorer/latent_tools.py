"""A style-based generator's latent operations in the app: truncation ψ for sampling, style mixing of the
last two picked codes, a crowd around the shown code, and inversion of motion files (File ▸ Invert clip…,
the panel's button, or files dropped on the map of a kind that inverts).

Each tool is enabled only where the loaded kind declares its capability (see ``capabilities``). Mixing
is a frozen request for the decode worker (a newer split makes an older one stale); crowds and
inversions are tasks with progress and cancel whose results are dropped once a newer one was asked for
or another model was opened.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np
from PySide6.QtWidgets import QFileDialog

from explorer.decoding import map_codes
from explorer.encoding import MOTION_FILTER
from explorer.requests import MixDecode, frozen_array, label_index
from explorer.state import Decoded, ExtraPoints, Pick
from explorer.workers import Cancel, Progress

if TYPE_CHECKING:
    from engine.generate import Sample
    from engine.generators.base import Generator
    from engine.motion.motion import Motion
    from explorer.controller import Controller


@dataclass(frozen=True, eq=False)
class InvertedClip:
    """A motion file inverted: its path, the code space and code, the mean joint error (m) the inversion
    reached, the code's motion and the window of the file it fits (placed as decoded motions are)."""

    path: Path
    space: str
    code: np.ndarray
    error_m: float
    decoded: Motion
    real: Motion


class LatentTools:
    """The latent-operation tools of controller ``c`` and its window's latent-tools panel."""

    def __init__(self, c: Controller) -> None:
        self.c = c
        self.crowds = 0  # id of the newest crowd asked for
        self.inversions = 0  # id of the newest inversion asked for
        panel = c.window.latent_panel
        panel.truncationChanged.connect(lambda psi: setattr(c.state, "truncation", float(psi)))
        panel.mixRequested.connect(self.mix)
        panel.crowdRequested.connect(self.crowd)
        panel.invertRequested.connect(self.ask_invert)
        c.window.invert_action.triggered.connect(
            lambda: self.ask_invert(panel.space_combo.currentText(), panel.steps_spin.value())
        )
        c.state.events.picked.connect(self._picked_changed)
        c.modelLoaded.connect(self._model_changed)  # before --select's click, which picks a code

    def _model_changed(self, generator: Generator) -> None:
        self.crowds += 1
        self.inversions += 1
        self.c.state.picked = ()
        self.c.window.latent_panel.set_levels(getattr(generator, "n_levels", 0))

    def _picked_changed(self, picked: tuple[Pick, ...]) -> None:
        labels = [p.label for p in picked]
        self.c.window.latent_panel.set_mix_codes(*([None] * (2 - len(labels)) + labels))

    def mix(self, split: int) -> None:
        """Decode the style mix of the last two picked codes at level ``split`` in the decode worker."""
        if self.c.refuse("mix"):
            return
        picked = self.c.state.picked
        if len(picked) < 2:
            self.c.window.show_status("Style mixing takes two codes: click two points on the map first.")
            return
        a, b = picked
        request = MixDecode(self.c.generator, a.code, b.code, int(split), f"A {a.label}", f"B {b.label}")
        self.c.decoder.submit(request.run)

    def crowd(self, n: int, sigma: float) -> None:
        """Sample ``n`` motions of codes drawn from N(shown code, σ²), put them on the map and play them."""
        if self.c.refuse("crowd"):
            return
        shown = next((d for d in self.c.state.shown if d.code is not None), None)
        if shown is None:
            self.c.window.show_status("A crowd is drawn around the shown code: click a point first.")
            return
        generator, code, seed = self.c.generator, frozen_array(shown.code), self.c.new_seed()
        self.crowds += 1
        crowd = self.crowds

        def job(_p: Progress, _c: Cancel) -> list[Sample]:
            return generator.crowd(code.copy(), int(n), float(sigma), seed)

        def done(samples: list[Sample]) -> None:
            if crowd == self.crowds and self.c.state.model is generator:
                self.c.generation.show_samples(samples, seed, f"crowd σ {sigma:g}")

        self.c.run_task(f"Sampling a crowd of {n} (σ {sigma:g})", job, done)

    def ask_invert(self, space: str, steps: int) -> None:
        """Ask for motion files and invert them into ``space`` codes."""
        if self.c.state.model is None or self.c.refuse("invert"):
            return
        paths, _ = QFileDialog.getOpenFileNames(self.c.window, "Invert clips", "", MOTION_FILTER)
        if paths:
            self.invert_files(paths, space, steps)

    def invert_files(self, paths: list[str], space: str = "W+", steps: int = 0) -> None:
        """Invert each file's centre window into a ``space`` code by optimisation (``steps`` of it; 0: the
        model's default) in a task with progress and cancel; show the codes on the map and play the first
        file's motion beside its real window."""
        if self.c.state.model is None or self.c.refuse("invert"):
            return
        from engine.motion.formats import read_motion

        generator = self.c.generator
        options = {"steps": int(steps)} if steps > 0 else {}
        self.inversions += 1
        inversion = self.inversions

        def job(progress: Progress, cancel: Cancel) -> list[InvertedClip]:
            found = []
            for k, name in enumerate(paths):
                path, motion = Path(name), read_motion(name)

                def report(step: int, total: int, error_m: float, path: Path = path, k: int = k) -> None:
                    text = (
                        f"Inverting {path.name} in {space}: step {step}/{total}, error {100 * error_m:.1f} cm"
                    )
                    progress(text, (k + step / total) / len(paths))

                code, error = generator.invert(motion, space, progress=report, cancel=cancel, **options)
                [decoded] = generator.decode(code[None], None)
                found.append(InvertedClip(path, space, code, error, decoded, generator.real_window(motion)))
            return found

        def done(found: list[InvertedClip]) -> None:
            if inversion == self.inversions and self.c.state.model is generator:
                self.show_inverted(found)

        self.c.run_task(f"Inverting {len(paths)} clip(s) in {space}", job, done)

    def show_inverted(self, found: list[InvertedClip]) -> None:
        """Mark the inverted codes on the map (at their W points) and play the first beside its clip."""
        generator, projection = self.c.generator, self.c.projection
        codes = np.stack([f.code for f in found]).astype(np.float32)
        actions = np.array([label_index(generator, f.decoded) for f in found], dtype=np.int64)
        points = map_codes(generator, codes)
        xy = projection.transform(points) if projection is not None else np.zeros((len(codes), 2))
        self.c.state.extra = ExtraPoints(codes, actions, xy)
        first = found[0]
        cm = 100 * first.error_m
        label = f"{first.path.name} inverted ({first.space}, error {cm:.1f} cm)"
        self.c.state.shown = (
            Decoded(first.decoded, label, first.code, int(actions[0])),
            Decoded(first.real, f"{first.path.name} (real clip)", None, int(actions[0])),
        )
        self.c.state.pick(first.code, f"{first.path.name} ({first.space})", int(actions[0]))
        others = f"; {len(found) - 1} more marked ◆ on the map" if len(found) > 1 else ""
        self.c.window.show_status(
            f"Inverted {first.path.name} into a {first.space} code: mean joint error {cm:.1f} cm; "
            f"marked ◆ on the map{others}. Playing it beside the clip's window."
        )
