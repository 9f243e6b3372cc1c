"""ODMO behind the Generator interface: codes from discovered modes, end locations, encoding, paths."""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from engine import generate
from engine.errors import ConfigError
from engine.generate import PathResult, Sample, WindowCodes
from engine.generators.base import CodeSpace, FolderGenerator, Generator, SampleRequest, require
from engine.latent.bank import LatentBank
from engine.latent.modes import STRATEGIES
from engine.modelio import LoadedModel, load_model
from engine.motion.motion import Motion

_ALWAYS = frozenset({"decode", "interpolate", "interpolate_across", "encode", "follow_path", "bank"})
_WITH_BANK = frozenset({"sample", "modes", "edit"})


@dataclass(eq=False)
class OdmoGenerator(FolderGenerator):
    """A loaded ODMO model folder (``loaded``) seen through the Generator interface."""

    loaded: LoadedModel
    kind: str = "odmo"

    @property
    def code_space(self) -> CodeSpace:
        """ODMO's per-motion latent code z."""
        return CodeSpace("z", int(self.loaded.config.latent_dim))

    @property
    def bank(self) -> LatentBank | None:
        """The latent bank (training codes, modes, maps), if the folder has one."""
        return self.loaded.bank

    @property
    def capabilities(self) -> frozenset[str]:
        """Decode, interpolate, encode, follow paths and build a bank; sampling from modes and edits need the
        bank; end locations need the model to take them."""
        found = _ALWAYS | (_WITH_BANK if self.loaded.bank is not None else frozenset())
        return found | ({"end"} if self.loaded.config.use_end_location else frozenset())

    @property
    def strategies(self) -> tuple[str, ...]:
        """ODMO samples only from its bank's modes (``engine.latent.modes``), slider weights included."""
        return STRATEGIES

    def sample(self, request: SampleRequest) -> list[Sample]:
        """Motions drawn from the action's modes (mode-preserving unless the request says otherwise)."""
        action, mode, end = request.action, request.mode, request.end
        if action is None:
            raise ConfigError(
                f"{self.path}: an ODMO model needs an action; it knows {', '.join(self.action_names)}"
            )
        require(self, "sample", "sample without a latent bank (run `odmo bank`)")
        if end is not None:
            require(self, "end", "take an end location")
        chosen = "mode" if mode is not None else (request.strategy or "mode_preserving")
        weights = None if request.weights is None else np.asarray(request.weights, dtype=np.float64)
        return generate.sample(
            self.loaded, action, request.n, request.seed, chosen, mode=mode, weights=weights, end=end
        )

    def decode(
        self,
        codes: np.ndarray,
        actions: Sequence[str] | str | None,
        end: np.ndarray | None = None,
        seed: int | None = None,
    ) -> list[Motion]:
        """One motion per code of one action (the end location predicted from the bank when None)."""
        if actions is None or (not isinstance(actions, str) and len(set(actions)) != 1):
            raise ConfigError("ODMO decodes the codes of one action at a time; name it")
        action = actions if isinstance(actions, str) else next(iter(actions))
        return generate.decode_batch(self.loaded, codes, action, end, seed=seed)

    def encode(self, motion: Motion) -> tuple[np.ndarray, int | None]:
        """The posterior-mean code of ``motion`` and a guess of its action index."""
        return generate.encode(self.loaded, motion)

    def encode_bank(
        self,
        clips: Sequence[Motion],
        stride: int | None = None,
        progress: Callable[[int, int], None] | None = None,
        cancel: Callable[[], bool] | None = None,
    ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray | None]:
        """Codes, end locations, clip index and window start of ``clips`` for a latent bank, streamed in
        batches of windows; progress(windows done, windows in all)."""
        return generate.encode_bank_windows(self.loaded, clips, stride, progress=progress, cancel=cancel)

    def encode_windows(self, motion: Motion, stride: int) -> WindowCodes:
        """``motion``'s windows every ``stride`` frames, encoded in one batch, with their end locations."""
        return generate.encode_windows(self.loaded, motion, stride)

    def interpolate(
        self,
        code_a: np.ndarray,
        code_b: np.ndarray,
        action: str,
        steps: int,
        method: str = "linear",
        end_a: np.ndarray | None = None,
        end_b: np.ndarray | None = None,
    ) -> list[Sample]:
        """``steps`` motions from ``code_a`` to ``code_b`` within ``action`` (ends blended linearly)."""
        return generate.interpolate(self.loaded, code_a, code_b, action, steps, method, end_a, end_b)

    def interpolate_across(
        self,
        code_a: np.ndarray,
        action_a: str,
        code_b: np.ndarray,
        action_b: str,
        steps: int,
        end_a: np.ndarray | None = None,
        end_b: np.ndarray | None = None,
    ) -> list[Sample]:
        """``steps`` motions from a code of one action to a code of another (see ``generate.ACROSS_RULE``)."""
        loaded = self.loaded
        return generate.interpolate_across(loaded, code_a, action_a, code_b, action_b, steps, end_a, end_b)

    def vary(self, code: np.ndarray, action: str, n: int, radius: float, seed: int) -> list[Sample]:
        """``n`` variations around ``code``, each with its own predicted end location and mode."""
        return generate.neighbours(self.loaded, code, action, n, radius, seed)

    def full_end(self, code: np.ndarray, action: str, end: np.ndarray | None) -> np.ndarray | None:
        """(3,) end location for ``code``: ``end`` when (3,), a floor point (x, z) at the bank's predicted
        height when (2,), the bank's prediction when None."""
        index = generate.action_index(self.loaded, action)
        rows = generate.resolve_ends(self.loaded, np.asarray(code, np.float32)[None], index, end)
        return None if rows is None else rows[0].astype(np.float32)

    def follow_path(self, path_xz: np.ndarray, action: str) -> PathResult:
        """The code of ``action`` whose root path follows ``path_xz`` (K, 2), and its motion."""
        return generate.follow_path(self.loaded, path_xz, action)


def open_odmo(path: Path, device: str, with_bank: bool = True) -> Generator:
    """Open an ODMO model folder."""
    return OdmoGenerator(load_model(path, device=device, with_bank=with_bank))
