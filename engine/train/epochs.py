"""The epoch loop every generator kind trains with: steps, progress and cancel, validation, a CSV log of
every loss term, atomic checkpoints and exact resume; each kind supplies its step (``EpochSteps``)."""

from __future__ import annotations

import csv
import io
import logging
import math
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Protocol

import numpy as np
import torch

from engine.errors import CancelledError, ConfigError, ModelFormatError
from engine.fileio import atomic_write_text
from engine.latent.bank import LatentBank
from engine.model.config_base import ModelConfig
from engine.train.checkpoint import (
    BEST_FILE,
    checkpoint_path,
    load_checkpoint,
    load_weights,
    save_checkpoint,
    save_weights,
)
from engine.train.distributed import SINGLE, Ranks, same_on_every_rank
from engine.train.windows import PreparedClips

log = logging.getLogger(__name__)

LOG_FILE = "train_log.csv"


def cosine_lr(base: float, epoch: int, epochs: int, floor: float = 0.05) -> float:
    """Learning rate of ``epoch`` (0-based): cosine from ``base`` down to ``floor`` · base at the last."""
    if epochs <= 1:
        return base
    return base * (floor + (1.0 - floor) * 0.5 * (1.0 + math.cos(math.pi * epoch / (epochs - 1))))


class EpochSteps(Protocol):
    """One kind's training step: what ``run_epochs`` calls, checkpoints and logs."""

    terms: tuple[str, ...]  # the loss names each step reports, "total" last
    windows_per_step: int
    modules: torch.nn.Module  # everything a checkpoint keeps
    optimizers: Sequence[torch.optim.Optimizer]

    def step(self, epoch: int, rng: np.random.Generator, generator: torch.Generator) -> dict[str, float]:
        """One optimisation step (backward and optimiser steps included); its loss terms."""
        ...

    def validate(self) -> dict[str, float] | None:
        """The loss terms on the fixed validation set (None without one)."""
        ...

    def epoch_columns(self, epoch: int) -> dict[str, float]:
        """Columns of the CSV log for the epoch just run, written before the losses (e.g. ``tf_rate``)."""
        ...


@dataclass
class TrainProgress:
    """One progress report: after every step (stage "train") and during bank building (stage "bank").

    ``epoch``/``step`` are 1-based and count completed work; ``losses`` are the running means of the
    current epoch, one per loss term of the kind, and ``total``; ``val_losses`` those of the last finished
    epoch's validation (None before the first); ``fraction`` is 0..1 of the stage; ``message`` is the bank
    builder's text.
    """

    stage: str
    epoch: int
    epochs: int
    step: int
    steps: int
    losses: dict[str, float]
    val_losses: dict[str, float] | None
    windows_per_s: float
    steps_per_s: float
    eta_s: float
    fraction: float
    message: str = ""


@dataclass
class TrainResult:
    """What a kind's ``train`` produced."""

    model_dir: Path
    epochs: int
    train_losses: dict[str, float]
    val_losses: dict[str, float] | None
    windows_per_s: float
    train_seconds: float
    n_train: int
    n_val: int
    bank: LatentBank | None = field(default=None, repr=False)

    @classmethod
    def of(
        cls,
        out: Path,
        epochs: int,
        run: EpochsRun,
        split: tuple[np.ndarray, np.ndarray],
        bank: LatentBank | None,
    ) -> TrainResult:
        """The result of a run of ``epochs`` into ``out`` on the (train, validation) clips ``split``."""
        return cls(
            out, epochs, run.train_losses, run.val_losses, run.windows_per_s, run.train_seconds,
            len(split[0]), len(split[1]), bank,
        )  # fmt: skip


@dataclass
class EpochsRun:
    """What ``run_epochs`` leaves: the log rows (resumed ones included) and the last epoch's figures."""

    rows: list[dict[str, float]]
    train_seconds: float
    train_losses: dict[str, float]
    val_losses: dict[str, float] | None
    windows_per_s: float
    selected_epoch: int | None = None


def write_log(path: Path, rows: list[dict[str, float]]) -> None:
    """Write the per-epoch CSV log (one row per epoch; every column any row has, blank where a row resumed
    from an older checkpoint lacks it) atomically; no rows, no file."""
    if not rows:
        return
    buffer = io.StringIO()
    columns = list(dict.fromkeys(name for row in rows for name in row))
    writer = csv.DictWriter(buffer, fieldnames=columns, restval="", lineterminator="\n")
    writer.writeheader()
    writer.writerows(rows)
    atomic_write_text(path, buffer.getvalue())


def run_identity(config: ModelConfig, fingerprint: str, seed: int, val_fraction: float) -> dict[str, Any]:
    """What a checkpoint must match to be resumed: the config (every field but ``epochs``, so resuming may
    extend it), the data, the seed and the split."""
    return {"config": _fields(config), "fingerprint": fingerprint, "seed": seed, "val_fraction": val_fraction}


def _fields(config: ModelConfig) -> dict[str, Any]:
    return {k: v for k, v in config.to_dict().items() if k != "epochs"}


def _same_run(saved: Any, identity: dict[str, Any], config: ModelConfig) -> bool:
    """Whether a checkpoint's identity is ``identity``, its config read as ``config``'s class reads it (so
    a checkpoint from before a field existed still matches)."""
    if not isinstance(saved, dict) or not isinstance(saved.get("config"), dict):
        return False
    try:
        read = type(config).from_dict(saved["config"])
    except ModelFormatError:
        return False
    return (saved | {"config": _fields(read)}) == identity


def run_epochs(
    steps: EpochSteps,
    out_dir: Path,
    config: ModelConfig,
    identity: dict[str, Any],
    *,
    epochs: int,
    steps_per_epoch: int,
    rng: np.random.Generator,
    generator: torch.Generator,
    resume: bool = False,
    progress: Callable[[TrainProgress], None] | None = None,
    cancel: Callable[[], bool] | None = None,
    checkpoint_every: int = 10,
    ranks: Ranks = SINGLE,
    select: Callable[[], float] | None = None,
) -> EpochsRun:
    """Train ``epochs`` epochs of ``steps_per_epoch`` steps, logging to ``out_dir``/train_log.csv and
    checkpointing to checkpoints/last.pt every ``checkpoint_every`` epochs and at the end (rank 0 of
    ``ranks`` alone writes; every rank resumes from the same checkpoint).

    ``select`` (one process only) scores the model at each checkpoint (higher is better; the log's
    ``select_score``): the best-scoring weights are kept in checkpoints/best.pt and are the modules'
    at the end, their epoch ``selected_epoch``.

    ``resume`` continues exactly from that checkpoint (RNG states included); one made with another
    ``identity`` (see ``run_identity``) raises ModelFormatError. ``cancel`` is checked before every step;
    cancelling raises CancelledError and keeps the last checkpoint (across ranks it must fire on every
    rank: one rank that stops leaves the others waiting in the next all-reduce).
    """
    if select is not None and ranks.distributed:
        raise ConfigError("choosing the best epoch by a score trains in one process only")
    out = Path(out_dir)
    ckpt = checkpoint_path(out)
    best_path = ckpt.parent / BEST_FILE
    rows: list[dict[str, float]] = []
    start, train_seconds = 0, 0.0
    best: list[float] | None = None  # [epoch, score]
    if resume and ckpt.exists():
        start, extra = load_checkpoint(
            ckpt, model=steps.modules, optimizers=steps.optimizers, rng=rng, torch_rng=generator
        )
        if not _same_run(extra.get("identity"), identity, config):
            raise ModelFormatError(f"{ckpt}: checkpoint is from a different config, seed or data set")
        rows, train_seconds = list(extra["log"]), float(extra["train_seconds"])
        best = extra.get("best")
        log.info("resuming %s after epoch %d", out, start)
    elif resume:
        log.info("%s: no checkpoint, training from scratch", ckpt)
    same_on_every_rank(start, "the epoch to resume from", ranks)

    train_losses: dict[str, float] = {}
    val_losses: dict[str, float] | None = None
    rate = 0.0
    for epoch in range(start, epochs):
        steps.modules.train()
        sums = dict.fromkeys(steps.terms, 0.0)
        t0 = time.perf_counter()
        for step in range(steps_per_epoch):
            if cancel is not None and cancel():
                raise CancelledError(f"training cancelled in epoch {epoch + 1}; resume from {ckpt}")
            terms = steps.step(epoch, rng, generator)
            for k in steps.terms:
                sums[k] += terms[k]
            rate = (step + 1) / (time.perf_counter() - t0)
            if progress is not None:
                left = (steps_per_epoch - step - 1) + (epochs - epoch - 1) * steps_per_epoch
                progress(
                    TrainProgress(
                        stage="train",
                        epoch=epoch + 1,
                        epochs=epochs,
                        step=step + 1,
                        steps=steps_per_epoch,
                        losses={k: v / (step + 1) for k, v in sums.items()},
                        val_losses=val_losses,
                        windows_per_s=rate * steps.windows_per_step,
                        steps_per_s=rate,
                        eta_s=left / rate,
                        fraction=(epoch * steps_per_epoch + step + 1) / (epochs * steps_per_epoch),
                    )
                )
        seconds = time.perf_counter() - t0
        train_seconds += seconds
        train_losses = {k: v / steps_per_epoch for k, v in sums.items()}
        steps.modules.eval()
        val_losses = steps.validate()
        row: dict[str, float] = {"epoch": epoch + 1, **steps.epoch_columns(epoch)}
        row |= {f"train_{k}": v for k, v in train_losses.items()}
        row |= {f"val_{k}": (val_losses or {}).get(k, float("nan")) for k in steps.terms}
        row |= {"seconds": seconds, "windows_per_s": steps_per_epoch * steps.windows_per_step / seconds}
        rows.append(row)
        if ranks.is_main and ((epoch + 1) % checkpoint_every == 0 or epoch + 1 == epochs):
            if select is not None:
                row["select_score"] = score = float(select())
                if best is None or score > best[1]:
                    best = [epoch + 1, score]
                    save_weights(best_path, steps.modules)
            write_log(out / LOG_FILE, rows)
            save_checkpoint(
                ckpt,
                epoch=epoch + 1,
                model=steps.modules,
                optimizers=steps.optimizers,
                rng=rng,
                torch_rng=generator,
                extra={"identity": identity, "log": rows, "train_seconds": train_seconds, "best": best},
            )
    if ranks.is_main:
        write_log(out / LOG_FILE, rows)
    selected = None
    if select is not None and best is not None:
        selected = int(best[0])
        load_weights(best_path, steps.modules)
    steps.modules.eval()
    return EpochsRun(rows, train_seconds, train_losses, val_losses, rate * steps.windows_per_step, selected)


def clipped_step(
    optimizer: torch.optim.Optimizer, model: torch.nn.Module, loss: torch.Tensor, clip: float
) -> None:
    """One optimiser step on ``loss``, the gradient norm of ``model``'s parameters clipped to ``clip``."""
    optimizer.zero_grad(set_to_none=True)
    loss.backward()
    torch.nn.utils.clip_grad_norm_(model.parameters(), clip)
    optimizer.step()


def steps_per_epoch(config: ModelConfig) -> int:
    """Steps of one epoch: the config's ``epoch_size`` windows in batches of ``batch_size``."""
    return max(1, math.ceil(config.epoch_size / config.batch_size))  # type: ignore[attr-defined]


def root_height(prepared: PreparedClips) -> float:
    """Median root height over every frame of the clips: where a decoded motion's root is shown."""
    root = prepared.skeleton.root
    return float(np.median(np.concatenate([j[:, root, 1] for j in prepared.joints])))


def split_metas(prepared: PreparedClips, val_idx: np.ndarray) -> list[dict[str, Any]]:
    """Each clip's metadata with ``split`` ("train" or "val"), as the latent bank keeps it."""
    in_val = np.isin(np.arange(prepared.n_clips), val_idx)
    return [m | {"split": "val" if v else "train"} for m, v in zip(prepared.meta, in_val, strict=True)]
