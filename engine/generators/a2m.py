"""Action2Motion behind the Generator interface: its model folder, sampling from its learned prior, and
its code space (the posterior-mean z sequences of the training clips, reduced by PCA; see
``engine.model.a2m``): decoding, encoding, interpolation, the latent bank and its modes.

Prior samples keep the z they were drawn with: their code is its projection onto the code space, so they
land on the map next to the training clips they resemble.
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
    check_psi,
    check_strategy,
    refusal,
    require,
)
from engine.latent.bank import LatentBank
from engine.model.a2m import A2mConfig, A2mModel
from engine.modelio import LoadedFolder, read_kind_folder
from engine.motion.datasets import conform_to
from engine.motion.motion import Motion
from engine.train.windows import prepare_clips, windows_at

ARCH = "a2m"


@dataclass
class LoadedA2m(LoadedFolder):
    """An A2M model folder in memory: the network (eval mode), its latent bank and what using it needs."""

    model: A2mModel
    config: A2mConfig


def load_a2m(model_dir: str | Path, device: str = "cpu", with_bank: bool = True) -> LoadedA2m:
    """Read an A2M folder strictly: bad, newer or non-A2M files raise ModelFormatError."""
    fields = read_kind_folder(
        model_dir, ARCH, A2mConfig, lambda config, _: A2mModel(config), device, with_bank
    )
    return LoadedA2m(**fields)


def action_index(loaded: LoadedA2m, action: int | str) -> int:
    """The index of ``action`` (a name or an index), or ConfigError naming the known actions."""
    if isinstance(action, str):
        if action not in loaded.action_names:
            known = ", ".join(loaded.action_names)
            raise ConfigError(f"unknown action {action!r}; the model knows: {known}")
        return loaded.action_names.index(action)
    if not 0 <= int(action) < loaded.config.n_actions:
        raise ConfigError(f"action index {action} out of range 0..{loaded.config.n_actions - 1}")
    return int(action)


def _device(loaded: LoadedA2m) -> torch.device:
    return next(loaded.model.parameters()).device


def _bone_scale(loaded: LoadedA2m, bone_scale: float | np.ndarray) -> torch.Tensor | float:
    """``bone_scale`` checked: a positive number, or (J,) positive factors (one per bone, by child joint)."""
    scale = np.asarray(bone_scale, dtype=np.float32)
    if scale.shape not in ((), (loaded.config.n_joints,)) or not np.all(np.isfinite(scale) & (scale > 0)):
        raise ConfigError(f"bone_scale must be a positive number or {loaded.config.n_joints} of them")
    if loaded.config.pose_rep != "lie" and not np.all(scale == 1):
        raise ConfigError(f"{loaded.path}: a joint-position (w/o Lie) model has no bones to scale")
    if np.all(scale == 1):
        return 1.0
    return float(scale) if scale.ndim == 0 else torch.from_numpy(scale[:, None]).to(_device(loaded))


def generate_a2m(
    loaded: LoadedA2m,
    action: int | str,
    n: int,
    generator: torch.Generator | int,
    bone_scale: float | np.ndarray = 1.0,
    psi: float = 1.0,
) -> tuple[np.ndarray, np.ndarray]:
    """(n, T, J, 3) float32 motions of ``action`` sampled from the learned prior and their z (n, T, Z).

    ``generator`` is a torch.Generator on the model's device or a seed; the same seed gives the same
    motions. ``bone_scale`` scales the skeleton's bones (the paper's body-shape control; "lie" models);
    the truncation ``psi`` scales the prior's standard deviation (1: the paper's sampling).
    """
    if n < 1:
        raise ConfigError(f"n must be at least 1, got {n}")
    check_psi(psi)
    index = action_index(loaded, action)
    device = _device(loaded)
    scale = _bone_scale(loaded, bone_scale)
    if isinstance(generator, int):
        generator = torch.Generator(device).manual_seed(generator)
    with torch.inference_mode():
        joints, z = loaded.model.sample(
            torch.full((n,), index, dtype=torch.long, device=device), generator, scale, psi
        )
    return joints.cpu().numpy().astype(np.float32), z.cpu().numpy().astype(np.float32)


def _has_code_space(loaded: LoadedA2m) -> bool:
    return loaded.config.code_dim > 0


def decode_a2m(
    loaded: LoadedA2m, codes: np.ndarray, action: int | str, bone_scale: float | np.ndarray = 1.0
) -> np.ndarray:
    """(N, T, J, 3) float32 motions of codes (N, code_dim) of one action, rolled out free-running."""
    x = np.asarray(codes, dtype=np.float32)
    if x.ndim == 1:
        x = x[None]
    if x.ndim != 2 or x.shape[1] != loaded.config.code_dim or not np.all(np.isfinite(x)):
        raise ConfigError(
            f"codes must be finite, of shape (N, {loaded.config.code_dim}), got {np.shape(codes)}"
        )
    index = action_index(loaded, action)
    device = _device(loaded)
    scale = _bone_scale(loaded, bone_scale)
    with torch.inference_mode():
        z = loaded.model.codes_to_z(torch.from_numpy(x).to(device))
        actions = torch.full((len(x),), index, dtype=torch.long, device=device)
        return loaded.model.decode(z, actions, scale).cpu().numpy().astype(np.float32)


def encode_a2m(loaded: LoadedA2m, motion: Motion, action: int | str) -> np.ndarray:
    """The code (code_dim,) of ``motion``'s posterior-mean z sequence under ``action`` (its centre window
    at the model's frame rate, canonical like the training windows)."""
    motion = conform_to(loaded.skeleton, motion)
    index = action_index(loaded, action)
    clip = Motion(motion.joints, motion.fps, loaded.skeleton, action=loaded.action_names[index])
    prepared = prepare_clips([clip], loaded.action_names, loaded.fps, loaded.window)
    start = max(int(prepared.lengths[0]) - loaded.window, 0) // 2
    window = windows_at(prepared, [0], [start])
    device = _device(loaded)
    with torch.inference_mode():
        joints = torch.from_numpy(np.ascontiguousarray(window.joints, np.float32)).to(device)
        mu = loaded.model.posterior_means(joints, torch.tensor([index], device=device))
        return loaded.model.z_to_codes(mu.flatten(1))[0].cpu().numpy().astype(np.float32)


@dataclass(eq=False)
class A2mGenerator(FolderGenerator):
    """A loaded Action2Motion folder (``loaded``) seen through the Generator interface.

    A folder with a code space decodes, encodes and interpolates codes; with its latent bank it also
    maps its codes and samples from their modes. Older (joint-position baseline) folders only sample.
    """

    loaded: LoadedA2m
    kind: str = "a2m"

    @property
    def bank(self) -> LatentBank | None:
        """The latent bank (training codes, modes, maps), if the folder has one."""
        return self.loaded.bank

    @property
    def code_space(self) -> CodeSpace:
        """PCA coordinates of posterior-mean z sequences (or, without a code space, the z_t sequence)."""
        if _has_code_space(self.loaded):
            return CodeSpace("PCA of z_1..z_T", int(self.loaded.config.code_dim))
        return CodeSpace("z_t per frame", int(self.loaded.config.latent_dim) * self.window)

    @property
    def capabilities(self) -> frozenset[str]:
        """Sample (with truncation); with a code space decode, encode, interpolate; with a bank also the
        map, modes, edits."""
        found = {"sample", "truncate"}
        if _has_code_space(self.loaded):
            found |= {"decode", "encode", "interpolate"}
            if self.loaded.bank is not None:
                found |= {"bank", "modes", "edit"}
        return frozenset(found)

    def _samples(
        self, joints: np.ndarray, codes: np.ndarray, index: int, modes: np.ndarray, meta: dict
    ) -> list[Sample]:
        """Samples of motions (N, T, J, 3) at display height."""
        joints = joints.copy()
        joints[..., 1] += np.float32(self.loaded.root_height)  # its origin is frame 0's root on the floor
        action = self.loaded.action_names[index]
        meta = meta | {"action": action, "model": str(self.path), "kind": self.kind}
        return [
            Sample(
                np.asarray(codes[i], np.float32),
                index,
                int(modes[i]),
                None,
                Motion(j, self.fps, self.skeleton, action=action, meta=meta | {"index": i}),
            )
            for i, j in enumerate(joints)
        ]

    def _modes_of(self, codes: np.ndarray, index: int) -> np.ndarray:
        bank = self.loaded.bank
        model = None if bank is None or not len(codes) else bank.modes.get(index)
        return np.full(len(codes), -1) if model is None else np.asarray(model.predict(codes), dtype=np.int64)

    def sample(self, request: SampleRequest, bone_scale: float | np.ndarray = 1.0) -> list[Sample]:
        """Motions of the action: from the learned prior (default), or decoded from codes drawn from the
        bank's modes (``mode_preserving``, ``conventional`` or one ``mode``). The truncation ψ pulls
        each draw towards the mean of the Gaussian it came from: z_t towards the prior's mean, a code
        towards its mode's (or, conventional, the action's)."""
        if request.end is not None:
            require(self, "end", "take an end location")
        if request.action is None:
            raise ConfigError(f"{self.path}: an Action2Motion model needs an action")
        index = action_index(self.loaded, request.action)
        strategy = "mode" if request.mode is not None else (request.strategy or "prior")
        psi = float(request.truncation)
        check_psi(psi)
        meta = {"seed": request.seed, "strategy": strategy, "truncation": psi}
        if strategy == "prior":
            joints, z = generate_a2m(self.loaded, index, request.n, request.seed, bone_scale, psi)
            codes = np.zeros((request.n, 0), np.float32)
            if _has_code_space(self.loaded):
                with torch.inference_mode():
                    z_t = torch.from_numpy(z).to(_device(self.loaded))
                    codes = self.loaded.model.z_to_codes(z_t).cpu().numpy().astype(np.float32)
            return self._samples(joints, codes, index, self._modes_of(codes, index), meta)
        check_strategy(strategy)
        require(self, "modes", f"sample {strategy.replace('_', '-')} codes from modes")
        modes = self.loaded.bank.modes.get(index)
        if modes is None:
            raise ConfigError(f"{self.path}: no modes for action {request.action!r}")
        rng = np.random.default_rng(request.seed)
        codes, labels = modes.sample(request.n, rng, strategy=strategy, mode=request.mode)
        centres = np.where(labels[:, None] < 0, modes.conventional_mean_, modes.means_[np.maximum(labels, 0)])
        codes = (centres + psi * (codes - centres)).astype(np.float32)
        joints = decode_a2m(self.loaded, codes, index, bone_scale)
        return self._samples(joints, codes, index, np.asarray(labels), meta | {"mode": request.mode})

    def decode(
        self,
        codes: np.ndarray,
        actions: Sequence[str] | str | None,
        end: np.ndarray | None = None,
        seed: int | None = None,
        bone_scale: float | np.ndarray = 1.0,
    ) -> list[Motion]:
        """One motion per code of one action, at display height (``bone_scale``: see ``generate_a2m``)."""
        if not _has_code_space(self.loaded):
            raise refusal(self, "decode")
        if end is not None:
            require(self, "end", "take an end location")
        if actions is None or (not isinstance(actions, str) and len(set(actions)) != 1):
            raise ConfigError("Action2Motion decodes the codes of one action at a time; name it")
        action = actions if isinstance(actions, str) else next(iter(actions))
        index = action_index(self.loaded, action)
        x = np.asarray(codes, np.float32).reshape(-1, self.loaded.config.code_dim)
        joints = decode_a2m(self.loaded, x, index, bone_scale)
        return [s.motion for s in self._samples(joints, x, index, self._modes_of(x, index), {"seed": seed})]

    def encode(self, motion: Motion) -> tuple[np.ndarray, int | None]:
        """The code of ``motion`` under its own action (its label), or, unlabelled, under the action whose
        bank codes lie nearest; and that action's index (None without a label or a bank)."""
        require(self, "encode")
        if motion.action in self.loaded.action_names:
            index = self.loaded.action_names.index(motion.action)
            return encode_a2m(self.loaded, motion, index), index
        bank = self.loaded.bank
        if bank is None:
            return encode_a2m(self.loaded, motion, 0), None
        best: tuple[float, int, np.ndarray] | None = None
        for index in np.unique(bank.actions):
            code = encode_a2m(self.loaded, motion, int(index))
            distance = float(np.min(np.linalg.norm(bank.codes[bank.indices_of(int(index))] - code, axis=1)))
            if best is None or distance < best[0]:
                best = (distance, int(index), code)
        return best[2], best[1]

    def interpolate(
        self, code_a: np.ndarray, code_b: np.ndarray, action: str, steps: int, method: str = "linear"
    ) -> list[Sample]:
        """``steps`` motions decoded from codes from ``code_a`` to ``code_b`` within ``action``."""
        require(self, "interpolate")
        if steps < 2:
            raise ConfigError(f"steps must be at least 2, got {steps}")
        index = action_index(self.loaded, action)
        a, b = (np.asarray(c, np.float32).reshape(-1) for c in (code_a, code_b))
        bank = self.loaded.bank
        modes = None if bank is None else bank.modes.get(index)
        centre = np.zeros_like(a) if modes is None else np.asarray(modes.conventional_mean_, np.float32)
        codes = interpolation_codes(a, b, steps, method, centre)
        joints = decode_a2m(self.loaded, codes, index)
        return self._samples(joints, codes, index, self._modes_of(codes, index), {"interpolation": method})


def open_a2m(path: Path, device: str, with_bank: bool = True) -> Generator:
    """Open an Action2Motion folder."""
    return A2mGenerator(load_a2m(path, device=device, with_bank=with_bank))
