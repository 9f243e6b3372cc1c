"""The Action2Motion baseline: its model folder, sampling from its learned prior, and the Generator
interface over them (it samples; it has no code to decode, encode or interpolate)."""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import torch

from engine.errors import ConfigError
from engine.generate import Sample
from engine.generators.base import CodeSpace, FolderGenerator, Generator, SampleRequest, refusal, require
from engine.latent.bank import LatentBank
from engine.model.a2m import A2mConfig, A2mModel
from engine.modelio import read_model_folder
from engine.motion.motion import Motion
from engine.motion.skeleton import Skeleton

ARCH = "a2m"


@dataclass
class LoadedA2m:
    """An A2M model folder in memory: the network (eval mode) and what is needed to use it."""

    model: A2mModel
    config: A2mConfig
    skeleton: Skeleton
    action_names: list[str]
    fps: float
    window: int
    root_height: float
    provenance: dict
    path: Path


def load_a2m(model_dir: str | Path, device: str = "cpu") -> LoadedA2m:
    """Read an A2M folder strictly: bad, newer or non-A2M files raise ModelFormatError."""
    return LoadedA2m(**read_model_folder(model_dir, ARCH, A2mConfig, A2mModel, device).loaded_fields())


def generate_a2m(
    loaded: LoadedA2m, action: int | str, n: int, generator: torch.Generator | int
) -> np.ndarray:
    """(n, T, J, 3) float32 motions of ``action`` (index or name) sampled from the learned prior.

    ``generator`` is a torch.Generator on the model's device or a seed; the same seed gives the same motions.
    """
    if n < 1:
        raise ConfigError(f"n must be at least 1, got {n}")
    if isinstance(action, str):
        if action not in loaded.action_names:
            raise ConfigError(f"unknown action {action!r}; the model knows {', '.join(loaded.action_names)}")
        action = loaded.action_names.index(action)
    if not 0 <= int(action) < loaded.config.n_actions:
        raise ConfigError(f"action index {action} out of range 0..{loaded.config.n_actions - 1}")
    device = next(loaded.model.parameters()).device
    if isinstance(generator, int):
        generator = torch.Generator(device).manual_seed(generator)
    with torch.inference_mode():
        joints = loaded.model.sample(
            torch.full((n,), int(action), dtype=torch.long, device=device), generator
        )
    return joints.cpu().numpy().astype(np.float32)


@dataclass(eq=False)
class A2mGenerator(FolderGenerator):
    """A loaded Action2Motion folder (``loaded``) seen through the Generator interface."""

    loaded: LoadedA2m
    kind: str = "a2m"
    capabilities: frozenset[str] = frozenset({"sample"})
    bank: LatentBank | None = None

    @property
    def code_space(self) -> CodeSpace:
        """The per-frame latent z_t of its temporal VAE, window frames of it per motion."""
        return CodeSpace("z_t per frame", int(self.loaded.config.latent_dim) * self.window)

    def sample(self, request: SampleRequest) -> list[Sample]:
        """Motions of the action from the learned prior, at display height."""
        action, seed = request.action, request.seed
        if request.mode is not None or request.strategy not in (None, "prior"):
            require(self, "modes", "sample from modes (it samples from its learned prior)")
        if request.end is not None:
            require(self, "end", "take an end location")
        if action is None or action not in self.loaded.action_names:
            known = ", ".join(self.loaded.action_names)
            raise ConfigError(f"unknown action {action!r}; the model knows: {known}")
        index = self.loaded.action_names.index(action)
        joints = generate_a2m(self.loaded, index, request.n, seed)
        joints[..., 1] += np.float32(self.loaded.root_height)  # its origin is frame 0's root on the floor
        meta = {"action": action, "seed": seed, "model": str(self.path), "kind": self.kind}
        return [
            Sample(
                np.zeros(0, dtype=np.float32),
                index,
                -1,
                None,
                Motion(j, self.fps, self.skeleton, action=action, meta=meta | {"index": i}),
            )
            for i, j in enumerate(joints)
        ]

    def decode(
        self,
        codes: np.ndarray,
        actions: Sequence[str] | str | None,
        end: np.ndarray | None = None,
        seed: int | None = None,
    ) -> list[Motion]:
        """Refused: this baseline draws its per-frame codes from the prior while it generates."""
        raise refusal(self, "decode")


def open_a2m(path: Path, device: str) -> Generator:
    """Open an Action2Motion folder."""
    return A2mGenerator(load_a2m(path, device=device))
