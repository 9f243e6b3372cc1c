"""The Action2Motion baseline behind the Generator interface: it samples from its learned prior only."""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from engine.a2m_io import LoadedA2m, generate_a2m, load_a2m
from engine.errors import ConfigError
from engine.generate import Sample
from engine.generators.base import CodeSpace, FolderGenerator, Generator, SampleRequest, refusal, require
from engine.latent.bank import LatentBank
from engine.motion.motion import Motion


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
