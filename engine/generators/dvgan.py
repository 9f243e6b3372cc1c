"""DVGAN behind the Generator interface: its model folder, sampling, completion and continuation.

A code is the top-level noise z_0 (the initial plot of the RNN, the one-frame plot of the CNN); the
finer noise (per frame or per level) and the place of the final cut follow from the seed, so that with
one seed a code is one motion, and a strip of codes between two of them is a smooth interpolation. The
RNN completes a prefix and continues a motion for any number of frames: its LSTM runs on in chunks of
``CHUNK`` frames, the state carried across, so a long sequence has no seams. The action may be any
phrase made of the words of the training phrases.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import torch

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
from engine.latent.bank import LatentBank
from engine.model.dvgan import DvganConfig, DvganNetwork
from engine.model.dvgan_features import feature_joints, motion_features
from engine.modelio import LoadedFolder, read_kind_folder
from engine.motion.contact import foot_joints
from engine.motion.datasets import conform_to
from engine.motion.ik import plant_feet
from engine.motion.motion import Motion
from engine.motion.resample import resample_motion

ARCH = "dvgan"
#: Frames the RNN generates per call when streaming a long sequence.
CHUNK = 256
#: Most frames of a prefix the RNN reads before continuing it (its last ones).
MAX_CONTEXT = 256
#: Most frames one request may generate.
MAX_FRAMES = 100_000


@dataclass
class LoadedDvgan(LoadedFolder):
    """A DVGAN model folder in memory."""

    model: DvganNetwork
    config: DvganConfig


def load_dvgan(model_dir: str | Path, device: str = "cpu", with_bank: bool = True) -> LoadedDvgan:
    """Read a DVGAN folder strictly: bad, newer or non-DVGAN files raise ModelFormatError."""
    fields = read_kind_folder(
        model_dir, ARCH, DvganConfig, lambda config, _: DvganNetwork(config), device, with_bank
    )
    return LoadedDvgan(**fields)


def _torch_seed(seed: int, index: int) -> torch.Generator:
    """The generator of sample ``index`` of ``seed``."""
    value = int(np.random.SeedSequence([seed, index]).generate_state(1)[0])
    return torch.Generator().manual_seed(value)


@dataclass(eq=False)
class DvganGenerator(FolderGenerator):
    """A loaded DVGAN folder (``loaded``) seen through the Generator interface."""

    loaded: LoadedDvgan
    kind: str = "dvgan"

    @property
    def bank(self) -> LatentBank | None:
        """The latent bank of top-level codes, if the folder has one."""
        return self.loaded.bank

    @property
    def code_space(self) -> CodeSpace:
        """The top-level noise z_0."""
        return CodeSpace(
            "z_0 (top-level noise; finer noise from the seed)", int(self.loaded.config.noise_dim)
        )

    @property
    def capabilities(self) -> frozenset[str]:
        """Sample, decode, interpolate; the RNN also completes and extends; with a bank, map and modes."""
        found = {"sample", "decode", "interpolate"}
        if self.loaded.config.generator == "rnn":
            found |= {"complete", "extend"}
        if self.loaded.bank is not None:
            found |= {"bank", "modes"}
        return frozenset(found)

    @property
    def network(self) -> DvganNetwork:
        """The generator network (eval mode)."""
        return self.loaded.model

    def phrase(self, action: str | None) -> str:
        """``action`` checked: a trained action or a phrase of known words (ConfigError otherwise)."""
        if action is None:
            raise ConfigError(f"{self.path}: a DVGAN model needs an action phrase")
        self.network.language.tokens([action])  # raises for unknown words
        return action

    def _index(self, action: str) -> int:
        """The action's index, -1 for a phrase it was never trained on."""
        names = self.loaded.action_names
        return names.index(action) if action in names else -1

    def _text(self, action: str, n: int) -> torch.Tensor:
        with torch.inference_mode():
            return self.network.language([action]).expand(n, -1)

    def _features(
        self,
        action: str,
        codes: np.ndarray,
        frames: int,
        seeds: Sequence[torch.Generator],
        prefix: torch.Tensor | None = None,
    ) -> np.ndarray:
        """Unnormalised features (N, P + frames, F): the ``prefix`` (P, F network frames; or the initial
        frame of each code) and ``frames`` more, each motion's noise and cut from its own generator."""
        config, net = self.loaded.config, self.network
        text = self._text(action, len(codes))
        z0 = torch.from_numpy(np.asarray(codes, np.float32))
        with torch.inference_mode():
            if config.generator == "cnn":
                if frames != config.window or prefix is not None:
                    raise ConfigError(
                        f"{self.path}: the CNN generator makes {config.window}-frame motions only"
                    )
                noise = [net.noise(1, 0, g) for g in seeds]
                levels = [torch.cat([n[i] for n in noise]) for i in range(len(noise[0]))]
                tape = net.tape(text, z0, levels)
                starts = [
                    int(torch.randint(0, config.tape - config.window + 1, (1,), generator=g)) for g in seeds
                ]
                out = torch.stack([tape[i, s : s + config.window] for i, s in enumerate(starts)])
            else:
                out = self._rollout(text, z0, frames, seeds, prefix)
            return net.denormalise(out).numpy()

    def _rollout(
        self,
        text: torch.Tensor,
        z0: torch.Tensor,
        frames: int,
        seeds: Sequence[torch.Generator],
        prefix: torch.Tensor | None,
    ) -> torch.Tensor:
        """RNN frames in chunks of ``CHUNK``, the LSTM state carried across. Without a prefix the tape is
        cut (final cut) when ``frames`` is the window, as in training."""
        config, net = self.loaded.config, self.network
        n = len(z0)
        cut = prefix is None and config.final_cut and frames == config.window
        total = config.tape if cut else frames
        seed_frames = None if prefix is None else prefix[None].expand(n, -1, -1)
        noise = torch.stack([torch.randn(total, config.noise_dim, generator=g) for g in seeds])
        first = 0 if prefix is not None else 1  # without a prefix the initial frame is one of the frames
        pieces, state, last = [], None, seed_frames
        done = 0
        while done < total - first or not pieces:
            step = min(CHUNK, total - first - done)
            z = noise[:, first + done : first + done + step]
            out, state = net.rnn(text, z0, z, prefix=last, state=state)
            pieces.append(out if not pieces else out[:, 1:])
            last = out[:, -1:]
            done += step
        tape = torch.cat(pieces, 1)
        if prefix is not None:
            return tape
        if cut:
            starts = [int(torch.randint(0, total - config.window + 1, (1,), generator=g)) for g in seeds]
            return torch.stack([tape[i, s : s + config.window] for i, s in enumerate(starts)])
        return tape[:, :frames]

    def _motions(
        self,
        features: np.ndarray,
        action: str,
        meta: dict,
        heading: float = 0.0,
        start: np.ndarray | None = None,
        given: int = 0,
    ) -> list[Motion]:
        """Motions of features (N, T, F), feet pinned where the model predicts contact; the first
        ``given`` frames (a prefix) are kept as they are, and the frames after them stand on its floor."""
        skeleton = self.skeleton
        placed = [feature_joints(f, skeleton, heading, start) for f in features]
        joints = np.stack([p[0] for p in placed])
        contacts = np.stack([p[1] for p in placed])
        heights = self.loaded.config.foot_heights
        if heights:
            feet = foot_joints(skeleton)
            joints = plant_feet(joints, contacts > 0.5, skeleton, feet, heights, fps=self.fps, given=given)
        meta = meta | {"action": action, "model": str(self.path), "kind": self.kind}
        return [
            Motion(j, self.fps, skeleton, action=action, meta=meta | {"index": i})
            for i, j in enumerate(joints)
        ]

    def _frames(self, frames: int | None) -> int:
        if frames is None:
            return self.window
        if not 2 <= frames <= MAX_FRAMES:
            raise ConfigError(f"frames must lie in 2..{MAX_FRAMES}, got {frames}")
        if frames != self.window:
            require(self, "extend", f"make {frames}-frame motions")
        return int(frames)

    def _modes_of(self, codes: np.ndarray, index: int) -> np.ndarray:
        bank = self.loaded.bank
        model = None if bank is None or index < 0 else bank.modes.get(index)
        return np.full(len(codes), -1) if model is None else np.asarray(model.predict(codes), dtype=np.int64)

    def _samples(self, codes: np.ndarray, action: str, seed: int, frames: int, meta: dict) -> list[Sample]:
        seeds = [_torch_seed(seed, i) for i in range(len(codes))]
        motions = self._motions(self._features(action, codes, frames, seeds), action, meta | {"seed": seed})
        index = self._index(action)
        modes = self._modes_of(codes, index)
        return [Sample(c, index, int(m), None, mo) for c, m, mo in zip(codes, modes, motions, strict=True)]

    def sample(self, request: SampleRequest, frames: int | None = None) -> list[Sample]:
        """Motions of the action phrase: codes from N(0, I) (default) or from the bank's modes; ``frames``
        long (default the window; longer needs the RNN)."""
        if request.end is not None:
            require(self, "end", "take an end location")
        if request.n < 1:
            raise ConfigError(f"n must be at least 1, got {request.n}")
        action = self.phrase(request.action)
        length = self._frames(frames)
        strategy = "mode" if request.mode is not None else (request.strategy or "prior")
        check_strategy(strategy)
        rng = np.random.default_rng(request.seed)
        if strategy == "prior":
            codes = rng.standard_normal((request.n, self.code_space.size)).astype(np.float32)
        else:
            require(self, "modes", f"sample {strategy.replace('_', '-')} codes from modes")
            modes = self.loaded.bank.modes.get(self._index(action))
            if modes is None:
                raise ConfigError(f"{self.path}: no modes for action {action!r}")
            codes, _ = modes.sample(request.n, rng, strategy=strategy, mode=request.mode)
            codes = np.asarray(codes, np.float32)
        return self._samples(codes, action, request.seed, length, {"strategy": strategy})

    def decode(
        self,
        codes: np.ndarray,
        actions: Sequence[str] | str | None,
        end: np.ndarray | None = None,
        seed: int | None = None,
    ) -> list[Motion]:
        """One motion per code of one action phrase; every code with the finer noise of ``seed``."""
        if end is not None:
            require(self, "end", "take an end location")
        if actions is None or (not isinstance(actions, str) and len(set(actions)) != 1):
            raise ConfigError("DVGAN decodes the codes of one action at a time; name it")
        action = self.phrase(actions if isinstance(actions, str) else next(iter(actions)))
        x = np.asarray(codes, np.float32).reshape(-1, self.code_space.size)
        if not np.all(np.isfinite(x)):
            raise ConfigError("codes must be finite")
        seeds = [_torch_seed(seed or 0, 0) for _ in x]
        return self._motions(self._features(action, x, self.window, seeds), action, {"seed": seed})

    def interpolate(
        self, code_a: np.ndarray, code_b: np.ndarray, action: str, steps: int, method: str = "linear"
    ) -> list[Sample]:
        """``steps`` motions of codes from ``code_a`` to ``code_b``, all with the same finer noise."""
        if steps < 2:
            raise ConfigError(f"steps must be at least 2, got {steps}")
        action = self.phrase(action)
        a, b = (np.asarray(c, np.float32).reshape(-1) for c in (code_a, code_b))
        codes = interpolation_codes(a, b, steps, method, np.zeros_like(a))
        motions = self.decode(codes, action, seed=0)
        index = self._index(action)
        modes = self._modes_of(codes, index)
        return [Sample(c, index, int(m), None, mo) for c, m, mo in zip(codes, modes, motions, strict=True)]

    def complete(
        self, prefix: Motion, frames: int, n: int = 1, seed: int = 0, action: str | None = None
    ) -> list[Motion]:
        """``n`` continuations of ``prefix`` by ``frames`` frames, each the whole motion (the prefix at the
        model's rate, re-posed on its skeleton, then the new frames), where the prefix stands; the action
        phrase is ``action`` or the prefix's own label ("complete")."""
        require(self, "complete")
        if n < 1:
            raise ConfigError(f"n must be at least 1, got {n}")
        if not 1 <= frames <= MAX_FRAMES:
            raise ConfigError(f"frames must lie in 1..{MAX_FRAMES}, got {frames}")
        prefix = conform_to(self.skeleton, prefix)
        phrase = self.phrase(action or prefix.action)
        clip = prefix if abs(prefix.fps - self.fps) < 1e-6 else resample_motion(prefix, self.fps)
        if len(clip.joints) < 2:
            raise ConfigError("the prefix needs at least 2 frames at the model's rate")
        heights = self.loaded.config.foot_heights or (0.0,) * len(foot_joints(self.skeleton))
        raw, heading, start = motion_features(clip.joints, self.fps, self.skeleton, np.asarray(heights))
        context = raw[-MAX_CONTEXT:]
        with torch.inference_mode():
            seed_frames = self.network.normalise(torch.from_numpy(context))
        seeds = [_torch_seed(seed, i) for i in range(n)]
        codes = np.zeros((n, self.code_space.size), np.float32)  # unused: the prefix stands for z_0
        made = self._features(phrase, codes, frames, seeds, prefix=seed_frames)[:, len(context) :]
        whole = np.concatenate([np.broadcast_to(raw, (n, *raw.shape)), made], axis=1)
        meta = {"seed": seed, "prefix_frames": len(raw), "completed_frames": frames}
        return self._motions(whole, phrase, meta, heading, start, given=len(raw))

    def extend(self, motion: Motion, frames: int, seed: int = 0, action: str | None = None) -> Motion:
        """``motion`` followed by ``frames`` more frames ("extend")."""
        require(self, "extend")
        return self.complete(motion, frames, 1, seed, action)[0]


def open_dvgan(path: Path, device: str, with_bank: bool = True) -> Generator:
    """Open a DVGAN folder."""
    return DvganGenerator(load_dvgan(path, device=device, with_bank=with_bank))
