"""Atomic training checkpoints: modules, optimisers, RNG states, epoch and the log so far."""

from __future__ import annotations

import io
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np
import torch

from engine.errors import ModelFormatError
from engine.fileio import atomic_write_bytes

CHECKPOINT_DIR = "checkpoints"
CHECKPOINT_FILE = "last.pt"
BEST_FILE = "best.pt"


def checkpoint_path(out_dir: str | Path) -> Path:
    """Where ``train`` keeps the latest checkpoint of ``out_dir``."""
    return Path(out_dir) / CHECKPOINT_DIR / CHECKPOINT_FILE


def save_weights(path: str | Path, model: torch.nn.Module) -> None:
    """Write ``model``'s state alone (atomically): the weights a run chose to keep."""
    buffer = io.BytesIO()
    torch.save(model.state_dict(), buffer)
    atomic_write_bytes(path, buffer.getvalue())


def load_weights(path: str | Path, model: torch.nn.Module) -> None:
    """Load a state written by ``save_weights`` into ``model``; ModelFormatError if it does not fit."""
    try:
        model.load_state_dict(torch.load(path, map_location="cpu", weights_only=True))
    except (OSError, RuntimeError, KeyError, TypeError, ValueError) as exc:
        raise ModelFormatError(f"{path}: unusable weights: {exc}") from exc


def save_checkpoint(
    path: str | Path,
    *,
    epoch: int,
    model: torch.nn.Module,
    optimizers: Sequence[torch.optim.Optimizer],
    rng: np.random.Generator,
    torch_rng: torch.Generator,
    extra: dict[str, Any],
) -> None:
    """Write everything needed to continue training exactly after ``epoch`` epochs (atomically)."""
    state = rng.bit_generator.state
    payload = {
        "epoch": int(epoch),
        "model": model.state_dict(),
        "optimizers": [o.state_dict() for o in optimizers],
        # PCG64 state words exceed 64 bits; strings keep them exact under weights_only loading.
        "numpy_rng": {k: v for k, v in state.items() if k != "state"},
        "numpy_rng_words": {k: str(v) for k, v in state["state"].items()},
        "torch_rng": torch_rng.get_state(),
        "extra": extra,
    }
    buffer = io.BytesIO()
    torch.save(payload, buffer)
    atomic_write_bytes(path, buffer.getvalue())


def load_checkpoint(
    path: str | Path,
    *,
    model: torch.nn.Module,
    optimizers: Sequence[torch.optim.Optimizer],
    rng: np.random.Generator,
    torch_rng: torch.Generator,
) -> tuple[int, dict[str, Any]]:
    """Restore the states saved by ``save_checkpoint`` (or by its one-optimiser version before); returns
    the epoch count and the extra dictionary."""
    path = Path(path)
    try:
        payload = torch.load(path, map_location="cpu", weights_only=True)
        model.load_state_dict(payload["model"])
        saved = payload["optimizers"] if "optimizers" in payload else [payload["optimizer"]]
        if len(saved) != len(optimizers):
            raise ValueError(f"{len(saved)} optimiser states for {len(optimizers)} optimisers")
        for optimizer, state_dict in zip(optimizers, saved, strict=True):
            optimizer.load_state_dict(state_dict)
        state = dict(payload["numpy_rng"])
        state["state"] = {k: int(v) for k, v in payload["numpy_rng_words"].items()}
        rng.bit_generator.state = state
        torch_rng.set_state(payload["torch_rng"])
        return int(payload["epoch"]), dict(payload["extra"])
    except (OSError, RuntimeError, KeyError, TypeError, ValueError) as exc:
        raise ModelFormatError(f"{path}: unusable checkpoint: {exc}") from exc
