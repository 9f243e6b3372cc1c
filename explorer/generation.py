"""Tools that make new codes: samples from the modes, variations, a local mode, an end location, a path
to follow."""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

from engine.motion.ops import root_floor_path
from explorer.decoding import condition, map_codes
from explorer.state import Decoded, ExtraPoints
from explorer.workers import Cancel, Progress

if TYPE_CHECKING:
    from engine import generate
    from engine.generators.base import Generator
    from explorer.controller import Controller


VARIATIONS = 8
LOCAL_MODE_SAMPLES = 6
PANEL_STRATEGIES = {"one_mode": "mode"}  # mode panel key -> engine strategy


def panel_strategies(generator: Generator) -> list[str]:
    """The mode panel's keys of the strategies ``generator`` samples with, its default first."""
    engine_to_panel = {v: k for k, v in PANEL_STRATEGIES.items()}
    return [engine_to_panel.get(s, s) for s in generator.strategies]


class Generation:
    """The generating tools of controller ``c``."""

    def __init__(self, c: Controller) -> None:
        self.c = c

    def sample_variations(self) -> None:
        """Decode variations around the selection (the engine's ``neighbours``) and put them on the map."""
        from engine.latent.neighbours import selection_summary

        summary = self.c.guard(
            "Cannot sample variations", lambda: selection_summary(self.c.bank, self.c.state.selection)
        )
        if summary is None:
            return
        centre, action, radius = summary
        loaded, seed = self.c.generator, self.c.new_seed()
        name = condition(loaded, action)
        self.c.run_task(
            "Sampling variations",
            lambda _p, _c: loaded.vary(centre, name, VARIATIONS, radius, seed),
            lambda samples: self.show_samples(samples, seed, "variation"),
        )

    def fit_local_mode(self) -> None:
        """Fit one Gaussian to the selected codes, outline it on the map and sample from it."""
        sel = np.asarray(self.c.state.selection, dtype=np.int64)
        if len(sel) < 3:
            self.c.report_error("Cannot fit a local mode", "select at least 3 codes with the lasso")
            return
        from engine import generate
        from engine.latent.modes import ModeModel

        loaded, bank, with_end = self.c.generator, self.c.bank, self.c.can("end")
        action = int(np.bincount(bank.actions[sel]).argmax())
        local = ModeModel(k_range=(1, 1)).fit(bank.codes[sel])
        self.c.map.local_mode = (local, sel)
        self.c.map.draw_overlays()
        seed = self.c.new_seed()

        def job(_p: Progress, _c: Cancel) -> list[generate.Sample]:
            codes, _ = local.sample(LOCAL_MODE_SAMPLES, np.random.default_rng(seed), strategy="mode", mode=0)
            motions = loaded.decode(codes, condition(loaded, action))
            ends = bank.end_location(codes, action) if with_end else [None] * len(codes)
            return [
                generate.Sample(c.astype(np.float32), action, -1, e, m)
                for c, e, m in zip(codes, ends, motions, strict=True)
            ]

        self.c.run_task("Sampling the local mode", job, lambda s: self.show_samples(s, seed, "local mode"))

    def sample(self, strategy: str, n: int, mode: int) -> None:
        """Draw ``n`` samples of the focused action (mode panel's Sample buttons; an unconditional kind's
        "prior" strategy takes none) at the truncation ψ of the state, and show them."""
        if self.c.state.model is None or self.c.refuse("sample"):
            return
        loaded, action, seed = self.c.generator, self.c.state.focus_action, self.c.new_seed()
        strategy = PANEL_STRATEGIES.get(strategy, strategy)
        weights = self.c.map.weights.get(action) if strategy == "weights" else None
        from engine.generators.base import SampleRequest

        request = SampleRequest(
            None if loaded.action_names is None and strategy == "prior" else loaded.label_names[action],
            int(n),
            seed,
            strategy,
            None if mode < 0 else int(mode),
            weights=None if weights is None else tuple(float(w) for w in weights),
            truncation=self.c.state.truncation if self.c.can("truncate") else 1.0,
        )

        def job(_p: Progress, _c: Cancel) -> list[generate.Sample]:
            return loaded.sample(request)

        psi = f" at ψ {request.truncation:g}" if request.truncation != 1.0 else ""
        self.c.run_task(
            f"Sampling {n} × {request.action or 'any action'}{psi}",
            job,
            lambda s: self.show_samples(s, seed, strategy.replace("_", "-")),
        )

    def show_samples(self, samples: list[generate.Sample], seed: int, what: str) -> None:
        """Put ``samples`` on the map as marked points and play them, labelled ``what`` and numbered."""
        if not samples:
            return
        codes = np.stack([s.code for s in samples]).astype(np.float32)
        actions = np.array([max(s.action, 0) for s in samples], dtype=np.int64)
        projection = self.c.projection
        points = map_codes(self.c.generator, codes)
        xy = projection.transform(points) if projection is not None else np.zeros((len(codes), 2))
        self.c.state.extra = ExtraPoints(codes, actions, xy)
        names = self.c.generator.label_names
        self.c.state.shown = tuple(
            Decoded(
                s.motion,
                f"{what} {k + 1}/{len(samples)} {names[s.action] if s.action >= 0 else ''}".rstrip()
                + (f" mode {s.mode}" if s.mode >= 0 else ""),
                s.code,
                max(s.action, 0),
                s.end,
                s.mode if s.mode >= 0 else None,
                seed,
            )
            for k, s in enumerate(samples)
        )

    def set_end(self, x: float, z: float) -> None:
        """Re-decode the current code with its end location moved to floor point (x, z)."""
        current = next((d for d in self.c.state.shown if d.code is not None), None)
        if self.c.refuse("end") or current is None:
            return
        label = current.label.split(" · end (")[0]
        self.c.gestures.decode_code(
            current.code, current.action, f"{label} · end ({x:.2f}, {z:.2f})", np.array([x, z])
        )

    def follow_path(self, path: object) -> None:
        """Ask the engine for the code of the focused action whose root path follows ``path`` (K, 2)."""
        if self.c.state.model is None or self.c.refuse("follow_path"):
            return
        shown = next((d for d in self.c.state.shown if d.code is not None), None)
        loaded = self.c.generator
        action = shown.action if shown is not None else self.c.state.focus_action  # the motion playing
        path_xz = np.asarray(path, dtype=np.float64)
        length = float(np.linalg.norm(np.diff(path_xz, axis=0), axis=1).sum())

        def job(progress: Progress, _c: Cancel) -> generate.PathResult:
            progress("Optimising a code to follow the path", 0.0)
            return loaded.follow_path(path_xz, loaded.action_names[action])

        def done(result: generate.PathResult) -> None:
            share = result.path_error_m / max(length, 1e-9)
            label = (
                f"follow path · {loaded.action_names[action]} · error {result.path_error_m:.3f} m "
                f"({share:.0%} of {length:.1f} m)"
            )
            item = Decoded(result.motion, label, result.code, action, result.end)
            self.c.state.shown = (item,)
            self.c.window.trajectory.set_generated(root_floor_path(result.motion), result.path_error_m)

        self.c.run_task("Following the path", job, done)
