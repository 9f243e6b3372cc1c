"""What every kind's ``train`` does around its own steps: the clips as windows checked against the
config, the split of the clips, the epoch loop, and the provenance and result of the run."""

from __future__ import annotations

import hashlib
import platform
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass
from datetime import UTC, datetime
from pathlib import Path
from typing import Any

import numpy as np
import torch

from engine import __version__
from engine.errors import ConfigError
from engine.latent.bank import LatentBank
from engine.model.config_base import ModelConfig
from engine.modelio import resolve_device
from engine.motion.motion import Motion
from engine.train.distributed import SINGLE, Ranks, rank_device
from engine.train.epochs import (
    EpochsRun,
    EpochSteps,
    TrainProgress,
    TrainResult,
    run_epochs,
    run_identity,
    steps_per_epoch,
)
from engine.train.pairs import split_clips
from engine.train.windows import PreparedClips, prepare_clips


@dataclass(frozen=True)
class RunOptions:
    """How one training run goes, whatever the kind (the keywords every ``train`` function takes)."""

    seed: int = 0
    device: str = "auto"
    resume: bool = False
    val_fraction: float = 0.1
    progress: Callable[[TrainProgress], None] | None = None
    cancel: Callable[[], bool] | None = None
    checkpoint_every: int = 10
    ranks: Ranks = SINGLE


@dataclass(frozen=True)
class WarmStart:
    """Weights a run starts from instead of its initialisation: a saved model's ``state`` (every tensor
    the model holds) and ``source``, what the provenance records of where they came from."""

    state: Mapping[str, torch.Tensor]
    source: dict[str, Any]

    @classmethod
    def from_folder(
        cls,
        folder: Path,
        load: Callable[..., Any],
        check: Callable[[dict[str, Any]], None] | None = None,
    ) -> WarmStart:
        """The weights of model folder ``folder``, read with its kind's ``load`` (which refuses another
        kind's folder) after ``check`` of its provenance; the source names the folder, its budget, seed
        and date, and the weights' sha256."""
        loaded = load(folder, with_bank=False)
        made = loaded.provenance
        if check is not None:
            check(made)
        source = {k: made[k] for k in ("epochs", "windows_seen", "seed", "created") if k in made}
        weights = hashlib.sha256((Path(folder) / "model.safetensors").read_bytes()).hexdigest()
        return cls(
            loaded.model.state_dict(), {"model": Path(folder).name, **source, "weights_sha256": weights}
        )

    def load_into(self, model: torch.nn.Module) -> None:
        """Copy the state into ``model``; ConfigError when its tensors are not the model's."""
        try:
            model.load_state_dict(self.state)
        except RuntimeError as error:
            first = str(error).strip().splitlines()[-1].strip()
            name = self.source.get("model", "those weights")
            raise ConfigError(f"cannot start from {name}: {first}") from None


@dataclass
class KindRun:
    """One training run: the clips as windows at the config's rate and length, their (train, validation)
    split, the device, and the options; ``train`` runs a kind's steps on it."""

    prepared: PreparedClips
    train_idx: np.ndarray
    val_idx: np.ndarray
    device: torch.device
    options: RunOptions

    @classmethod
    def prepare(
        cls, clips: Sequence[Motion], action_names: list[str], config: ModelConfig, options: RunOptions
    ) -> KindRun:
        """Windows of ``clips`` for ``config`` (ConfigError unless its action and joint counts are the
        data's), split by ``options.val_fraction`` and ``options.seed``, on this rank's device."""
        device = rank_device(resolve_device(options.device), options.ranks)
        prepared = prepare_clips(clips, action_names, config.fps, config.window)  # type: ignore[attr-defined]
        n_actions, n_joints = config.n_actions, config.n_joints  # type: ignore[attr-defined]
        if n_actions != len(prepared.action_names) or n_joints != prepared.skeleton.n_joints:
            raise ConfigError(
                f"config has {n_actions} actions and {n_joints} joints, data has "
                f"{len(prepared.action_names)} and {prepared.skeleton.n_joints}"
            )
        train_idx, val_idx = split_clips(prepared.actions, options.val_fraction, options.seed)
        return cls(prepared, train_idx, val_idx, device, options)

    @property
    def split(self) -> tuple[np.ndarray, np.ndarray]:
        """The (train, validation) clip indices."""
        return self.train_idx, self.val_idx

    def train(
        self, steps: EpochSteps, out: Path, config: ModelConfig, select: Callable[[], float] | None = None
    ) -> EpochsRun:
        """``run_epochs`` of ``steps``: ``config.epochs`` epochs of ``steps_per_epoch``, the run's identity
        from its config, data, seed and split, the RNGs from the seed; ``select`` as there."""
        o = self.options
        return run_epochs(
            steps,
            out,
            config,
            run_identity(config, self.prepared.fingerprint(), o.seed, o.val_fraction),
            epochs=config.epochs,  # type: ignore[attr-defined]
            steps_per_epoch=steps_per_epoch(config),
            rng=np.random.default_rng(o.seed),
            generator=torch.Generator(self.device).manual_seed(o.seed),
            resume=o.resume,
            progress=o.progress,
            cancel=o.cancel,
            checkpoint_every=o.checkpoint_every,
            ranks=o.ranks,
            select=select,
        )

    def provenance(
        self, run: EpochsRun, config: ModelConfig, warm_start: WarmStart | None = None, **extra: Any
    ) -> dict[str, Any]:
        """The model folder's provenance: kind, data, split, seed, budget, device, time and versions
        (+ the ``warm_start``'s source and ``extra``)."""
        if warm_start is not None:
            extra["warm_start"] = warm_start.source
        epochs = config.epochs  # type: ignore[attr-defined]
        return {
            "arch": config.ARCH,
            "data_fingerprint": self.prepared.fingerprint(),
            "n_clips": self.prepared.n_clips,
            "n_train": len(self.train_idx),
            "n_val": len(self.val_idx),
            "seed": self.options.seed,
            "epochs": epochs,
            "windows_seen": epochs * steps_per_epoch(config) * config.batch_size,  # type: ignore[attr-defined]
            "train_seconds": round(run.train_seconds, 3),
            "device": str(self.device),
            "created": datetime.now(UTC).isoformat(timespec="seconds"),
            **extra,
            "train_sources": [self.prepared.sources[i] for i in self.train_idx],
            "versions": {
                "odmo_explorer": __version__,
                "torch": torch.__version__,
                "numpy": np.__version__,
                "python": platform.python_version(),
            },
        }

    def result(self, out: Path, config: ModelConfig, run: EpochsRun, bank: LatentBank | None) -> TrainResult:
        """What the kind's ``train`` returns."""
        return TrainResult.of(out, config.epochs, run, self.split, bank)  # type: ignore[attr-defined]
