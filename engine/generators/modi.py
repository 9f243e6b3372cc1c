"""MoDi behind the Generator interface: its model folder, W and W+ codes, truncation, style mixing, crowds,
inversion of real clips and the latent bank of sampled and inverted codes (see ``modi_latent``).

MoDi is unconditional: ``action_names`` is None and sampling needs no action. Its bank labels each code
with an action of the training data (inverted clips by their own label, sampled codes by the evaluation
classifier or by their nearest inverted clips), so the map can be coloured and, given an action, codes
can be drawn from that label's modes.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from engine.errors import ConfigError
from engine.generate import Sample, interpolation_codes
from engine.generators.base import (
    CodeSpace,
    FolderGenerator,
    Generator,
    SampleRequest,
    check_strategy,
    require,
)
from engine.generators.modi_latent import (
    INVERT_STEPS,
    Inversion,
    crowd_codes,
    decode_codes,
    invert,
    mix_codes,
    sample_w,
)
from engine.latent.bank import LatentBank
from engine.model.modi import ModiConfig, ModiNetwork
from engine.modelio import (
    LoadedFolder,
    read_kind_folder,
    write_model_folder,
)
from engine.motion.contact import foot_joints
from engine.motion.ik import plant_feet
from engine.motion.motion import Motion
from engine.motion.skeleton import Skeleton

ARCH = "modi"


@dataclass
class LoadedModi(LoadedFolder):
    """A MoDi model folder in memory: the shipped (EMA) network in eval mode, its bank and what using it
    needs; ``action_names`` are the labels of the training data (the bank's), not a condition."""

    model: ModiNetwork
    config: ModiConfig


def load_modi(model_dir: str | Path, device: str = "cpu", with_bank: bool = True) -> LoadedModi:
    """Read a MoDi folder strictly: bad, newer or non-MoDi files raise ModelFormatError."""
    return LoadedModi(**read_kind_folder(model_dir, ARCH, ModiConfig, ModiNetwork, device, with_bank))


def save_modi(
    out_dir: str | Path,
    network: ModiNetwork,
    skeleton: Skeleton,
    label_names: list[str],
    provenance: dict[str, Any],
    root_height: float,
) -> None:
    """Write a MoDi model folder (weights and model.json; see ``modelio.write_model_folder``)."""
    config = network.config.to_dict()
    write_model_folder(out_dir, network, config, skeleton, label_names, provenance, root_height, ARCH)


def display_joints(loaded: LoadedModi, joints: np.ndarray, contacts: np.ndarray) -> np.ndarray:
    """Canonical joints (N, T, J, 3) at display height, feet pinned where the model predicts contact and
    lifted out of the floor (``plant_feet``; unchanged without the config's foot heights)."""
    lifted = joints + np.array([0.0, loaded.root_height, 0.0], dtype=np.float32)
    heights = loaded.config.foot_heights
    if not heights:
        return lifted
    feet = foot_joints(loaded.skeleton)
    return plant_feet(lifted, contacts > 0.5, loaded.skeleton, feet, heights, fps=loaded.fps)


def decode_display(loaded: LoadedModi, codes: np.ndarray, psi: float = 1.0) -> np.ndarray:
    """(N, T, J, 3) joints at display height of W or W+ codes: what the app shows and exports write."""
    return display_joints(loaded, *decode_codes(loaded.model, codes, psi))


def invert_motions(
    loaded: LoadedModi,
    motions: Sequence[Motion],
    space: str = "W+",
    steps: int = INVERT_STEPS,
    progress: Callable[[int, int, float], None] | None = None,
    cancel: Callable[[], bool] | None = None,
) -> Inversion:
    """The codes of ``motions``' centre windows (canonical, as the model's output), found together."""
    from engine.generate import bank_window

    t = loaded.window
    targets = np.zeros((len(motions), t, loaded.skeleton.n_joints, 3), dtype=np.float32)
    mask = np.zeros((len(motions), t), dtype=bool)
    for i, motion in enumerate(motions):
        joints = bank_window(loaded, motion).joints
        joints = joints - np.array([0.0, loaded.root_height, 0.0], dtype=np.float32)
        targets[i, : len(joints)], targets[i, len(joints) :] = joints, joints[-1]
        mask[i, : len(joints)] = True
    return invert(loaded.model, targets, mask, space, steps, progress=progress, cancel=cancel)


@dataclass(eq=False)
class ModiGenerator(FolderGenerator):
    """A loaded MoDi folder (``loaded``) seen through the Generator interface; its code space is W."""

    loaded: LoadedModi
    kind: str = "modi"

    @property
    def action_names(self) -> list[str] | None:
        """None: MoDi is unconditional (its bank's labels are ``label_names``)."""
        return None

    @property
    def bank(self) -> LatentBank | None:
        """Sampled and inverted W codes with their labels, modes and maps, if the folder has them."""
        return self.loaded.bank

    @property
    def code_space(self) -> CodeSpace:
        """W, the mapping network's output (a W+ code is ``n_styles`` of them, flattened)."""
        return CodeSpace("W", int(self.loaded.config.w_dim))

    @property
    def n_styles(self) -> int:
        """Style layers of a W+ code."""
        return self.loaded.model.n_styles

    @property
    def n_levels(self) -> int:
        """Skeleton levels, coarsest first: the style-mixing splits are 0..n_levels."""
        return self.loaded.model.n_levels

    @property
    def capabilities(self) -> frozenset[str]:
        """Sample (with truncation), decode, interpolate, mix, crowds, invert and encode (by inversion);
        with the bank its map, the modes of its labels and edit directions."""
        found = {"sample", "decode", "interpolate", "truncate", "mix", "crowd", "invert", "encode"}
        if self.loaded.bank is not None:
            found |= {"bank", "modes", "edit"}
        return frozenset(found)

    def _samples(
        self, codes: np.ndarray, psi: float, meta: dict[str, Any], labels: np.ndarray | None = None
    ) -> list[Sample]:
        """Samples of W / W+ codes (N, ·): decoded, at display height, labelled from the bank."""
        joints = decode_display(self.loaded, codes, psi)
        labels = self.labels_of(codes) if labels is None else labels
        modes = self._modes_of(codes, labels)
        meta = {"model": str(self.path), "kind": self.kind, "truncation": psi} | meta
        out = []
        for i, j in enumerate(joints):
            name = None if labels[i] < 0 else self.loaded.action_names[labels[i]]
            motion = Motion(j, self.fps, self.skeleton, action=name, meta=meta | {"index": i})
            out.append(Sample(np.asarray(codes[i], np.float32), int(labels[i]), int(modes[i]), None, motion))
        return out

    def labels_of(self, codes: np.ndarray) -> np.ndarray:
        """(N,) label of each code: the majority label of its 5 nearest bank codes in W (−1 without a
        bank); W+ codes are placed at the mean of their layers."""
        bank = self.loaded.bank
        x = self.as_w(codes)
        if bank is None or not len(bank.codes):
            return np.full(len(x), -1, dtype=np.int64)
        from sklearn.neighbors import KNeighborsClassifier

        k = min(5, len(bank.codes))
        knn = KNeighborsClassifier(n_neighbors=k).fit(bank.codes, bank.actions)
        return knn.predict(x).astype(np.int64)

    def as_w(self, codes: np.ndarray) -> np.ndarray:
        """(N, D) W codes of W or flattened W+ codes (W+ layers averaged: its point on the map)."""
        x = np.asarray(codes, dtype=np.float32)
        x = x[None] if x.ndim == 1 else x
        d = self.code_space.size
        if x.ndim == 2 and x.shape[1] == d * self.n_styles and self.n_styles > 1:
            return x.reshape(len(x), self.n_styles, d).mean(axis=1)
        return x

    def _modes_of(self, codes: np.ndarray, labels: np.ndarray) -> np.ndarray:
        bank, x = self.loaded.bank, self.as_w(codes)
        out = np.full(len(x), -1, dtype=np.int64)
        for label in np.unique(labels):
            model = None if bank is None or label < 0 else bank.modes.get(int(label))
            if model is not None:
                rows = labels == label
                out[rows] = model.predict(x[rows])
        return out

    def sample(self, request: SampleRequest) -> list[Sample]:
        """Motions from the prior (z ~ N(0, I) → w, truncated by ``request.truncation``), or, given an
        action, codes drawn from the modes of the bank codes labelled with it."""
        if request.end is not None:
            require(self, "end", "take an end location")
        psi = float(request.truncation)
        strategy = request.strategy or ("prior" if request.action is None and request.mode is None else None)
        meta: dict[str, Any] = {"seed": request.seed}
        if strategy == "prior":
            if request.action is not None:
                raise ConfigError(f"{self.path}: MoDi's prior is unconditional; drop the action")
            codes = sample_w(self.loaded.model, request.n, request.seed, psi)
            return self._samples(codes, 1.0, meta | {"strategy": "prior", "truncation": psi})
        chosen = "mode" if request.mode is not None else (strategy or "mode_preserving")
        check_strategy(chosen)
        require(self, "modes", f"sample {chosen.replace('_', '-')} codes of a labelled action")
        if request.action not in self.label_names:
            raise ConfigError(
                f"{self.path}: sampling from modes needs an action label: {', '.join(self.label_names)}"
            )
        index = self.label_names.index(request.action)
        modes = self.loaded.bank.modes.get(index)
        if modes is None:
            raise ConfigError(f"{self.path}: no bank codes are labelled {request.action!r}")
        codes, _ = modes.sample(
            request.n, np.random.default_rng(request.seed), strategy=chosen, mode=request.mode
        )
        codes = np.asarray(codes, np.float32)
        return self._samples(codes, psi, meta | {"strategy": chosen}, np.full(len(codes), index))

    def decode(
        self,
        codes: np.ndarray,
        actions: Sequence[str] | str | None = None,
        end: np.ndarray | None = None,
        seed: int | None = None,
        psi: float = 1.0,
    ) -> list[Motion]:
        """One motion per W (N, D) or W+ (N, S·D) code, truncated by ``psi``; ``actions`` are not used
        (MoDi is unconditional), ``seed`` neither (decoding uses the network's fixed noise)."""
        if end is not None:
            require(self, "end", "take an end location")
        return [s.motion for s in self._samples(np.asarray(codes, np.float32), psi, {"seed": seed})]

    def encode(self, motion: Motion) -> tuple[np.ndarray, int | None]:
        """The W code of ``motion``'s centre window, found by inversion, and its label (None: no bank)."""
        code = invert_motions(self.loaded, [motion], "W").codes[0]
        label = int(self.labels_of(code[None])[0])
        return code, None if label < 0 else label

    def invert(
        self,
        motion: Motion,
        space: str = "W+",
        steps: int = INVERT_STEPS,
        progress: Callable[[int, int, float], None] | None = None,
        cancel: Callable[[], bool] | None = None,
    ) -> tuple[np.ndarray, float]:
        """The W or W+ code whose motion matches ``motion``'s centre window, and its mean joint error (m)."""
        found = invert_motions(self.loaded, [motion], space, steps, progress, cancel)
        return found.codes[0], float(found.errors[0])

    def interpolate(
        self,
        code_a: np.ndarray,
        code_b: np.ndarray,
        action: str | None,
        steps: int,
        method: str = "linear",
    ) -> list[Sample]:
        """``steps`` motions decoded from codes between two W or two W+ codes (``action`` not used)."""
        if steps < 2:
            raise ConfigError(f"steps must be at least 2, got {steps}")
        a, b = (np.asarray(c, np.float32).reshape(-1) for c in (code_a, code_b))
        if a.shape != b.shape:
            raise ConfigError("interpolation needs two codes of one space (both W or both W+)")
        centre = np.asarray(self.loaded.model.w_avg.cpu().numpy(), np.float32)
        centre = np.tile(centre, len(a) // len(centre))
        codes = interpolation_codes(a, b, steps, method, centre)
        return self._samples(codes, 1.0, {"interpolation": method})

    def mix(self, code_a: np.ndarray, code_b: np.ndarray, split: int) -> Sample:
        """The motion of the W+ code taking ``code_a``'s coarse levels (below ``split``) and ``code_b``'s
        fine ones: ``code_a``'s overall movement with ``code_b``'s details."""
        mixed = mix_codes(self.loaded.model, code_a, code_b, split)
        return self._samples(mixed[None], 1.0, {"mix_split": int(split)})[0]

    def crowd(self, code: np.ndarray, n: int, sigma: float, seed: int) -> list[Sample]:
        """``n`` motions of codes drawn from N(code, σ²): a crowd doing variations of one motion."""
        return self._samples(crowd_codes(code, n, sigma, seed), 1.0, {"crowd_sigma": sigma, "seed": seed})

    def vary(self, code: np.ndarray, action: str | None, n: int, radius: float, seed: int) -> list[Sample]:
        """``n`` motions of codes drawn uniformly from the ball of ``radius`` around ``code``."""
        from engine.generate import ball_codes

        return self._samples(ball_codes(np.asarray(code, np.float32), n, radius, seed), 1.0, {"seed": seed})

    def real_window(self, clip: Motion, start: int | None = None) -> Motion:
        """The window of a real ``clip`` an inverted bank code stands for, placed as decoded motions are."""
        from engine.generate import bank_window

        return bank_window(self.loaded, clip, start)

    def encode_bank(
        self,
        clips: Sequence[Motion],
        stride: int | None = None,
        progress: Callable[[int, int], None] | None = None,
        cancel: Callable[[], bool] | None = None,
    ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray | None]:
        """W codes of ``clips``' centre windows, inverted together (a stride is refused: one per clip);
        progress(optimisation steps done, steps in all)."""
        if stride is not None:
            raise ConfigError("a MoDi bank inverts one centre window per clip; drop --stride")
        steps = None if progress is None else lambda done, total, _loss: progress(done, total)
        codes = invert_motions(self.loaded, clips, "W", progress=steps, cancel=cancel).codes
        n = len(clips)
        return codes, np.zeros((n, 3), np.float32), np.arange(n, dtype=np.int64), None


def open_modi(path: Path, device: str, with_bank: bool = True) -> Generator:
    """Open a MoDi model folder."""
    return ModiGenerator(load_modi(path, device=device, with_bank=with_bank))
