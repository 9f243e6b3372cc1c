"""The ODMO training loop: class-balanced contrastive batches, scheduled teacher forcing, checkpoints,
a per-epoch CSV log, and the final model folder with its latent bank."""

from __future__ import annotations

import csv
import dataclasses
import io
import logging
import math
import platform
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from datetime import UTC, datetime
from pathlib import Path
from typing import Any

import numpy as np
import torch

from engine import __version__
from engine.errors import CancelledError, ConfigError, ModelFormatError
from engine.fileio import atomic_write_text
from engine.latent.bank import LatentBank, build_bank
from engine.model.config import OdmoConfig
from engine.model.losses import LOSS_TERMS, odmo_losses
from engine.model.odmo import OdmoModel
from engine.model.precision import bfloat16_autocast, native_bfloat16
from engine.modelio import resolve_device, save_bank, save_model
from engine.motion.contact import contact_labels, foot_joints, resting_heights
from engine.motion.motion import Motion
from engine.train.checkpoint import checkpoint_path, load_checkpoint, save_checkpoint
from engine.train.pairs import PairSampler, split_clips
from engine.train.windows import PreparedClips, WindowBatch, crop_windows, prepare_clips

log = logging.getLogger(__name__)

LOG_FILE = "train_log.csv"
_TERMS = (*LOSS_TERMS, "total")


@dataclass
class TrainProgress:
    """One progress report: after every step (stage "train") and during bank building (stage "bank").

    ``epoch``/``step`` are 1-based and count completed work; ``losses`` are the running means of the
    current epoch (keys: recon, traj, consistency, contrastive, prior, total); ``val_losses`` those of the
    last finished epoch's validation (None before the first); ``fraction`` is 0..1 of the stage;
    ``message`` is the bank builder's text.
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
    """What ``train`` produced."""

    model_dir: Path
    epochs: int
    train_losses: dict[str, float]
    val_losses: dict[str, float] | None
    windows_per_s: float
    train_seconds: float
    n_train: int
    n_val: int
    bank: LatentBank | None = field(default=None, repr=False)


@dataclass
class _Tensors:
    """A window batch on the device."""

    joints: torch.Tensor
    lmp: torch.Tensor
    trajectory: torch.Tensor
    mask: torch.Tensor
    actions: torch.Tensor
    ends: torch.Tensor
    contacts: torch.Tensor | None = None

    @classmethod
    def of(cls, batch: WindowBatch, device: torch.device, config: OdmoConfig | None = None) -> _Tensors:
        """The batch on ``device``, with the foot-contact labels when ``config`` has a contact head."""

        def t(a: np.ndarray) -> torch.Tensor:
            return torch.from_numpy(np.ascontiguousarray(a)).to(device)

        contacts = None
        if config is not None and config.foot_contact and config.foot_joints:
            lifted = batch.joints.copy()
            lifted[..., 1] += batch.origin[:, None, None, 1]  # canonical windows, floor back at y = 0
            feet, heights = list(config.foot_joints), np.array(config.foot_heights)
            labels = contact_labels(lifted, config.fps, feet, heights)
            contacts = t(labels.astype(np.float32))
        return cls(
            t(batch.joints),
            t(batch.lmp),
            t(batch.trajectory),
            t(batch.mask),
            t(batch.actions),
            t(batch.ends),
            contacts,
        )


def _forward(
    model: OdmoModel,
    config: OdmoConfig,
    data: _Tensors,
    same: torch.Tensor,
    root: int,
    *,
    tf_rate: float,
    generator: torch.Generator | None,
) -> dict[str, torch.Tensor]:
    """Loss terms of one batch (anchors then partners); training samples z, evaluation uses the mean."""
    mu, logvar = model.encode(data.lmp, data.mask)
    if model.training:
        eps = torch.randn(mu.shape, generator=generator, device=mu.device)
        z = mu + torch.exp(0.5 * logvar) * eps
        truth = data.joints
    else:
        z, truth = mu, None
    end = data.ends if config.use_end_location else None
    out = model.decode_full(z, data.actions, end, prev_truth=truth, tf_rate=tf_rate, generator=generator)
    free = None
    if config.w_free > 0 or config.w_speed > 0:
        free = out.joints if truth is None else model.decode_full(z, data.actions, end).joints
    return odmo_losses(
        config,
        joints=data.joints,
        trajectory=data.trajectory,
        mask=data.mask,
        pred_joints=out.joints,
        pred_trajectory=out.trajectory,
        mu=mu,
        logvar=logvar,
        same=same,
        root=root,
        raw_joints=out.raw if model.projection is not None else None,
        contact_logits=out.contact,
        contacts=data.contacts,
        free_joints=free,
    )


def _identity_config(config: dict[str, Any]) -> dict[str, Any]:
    """A checkpoint's config with every field filled in as ``OdmoConfig.from_dict`` reads it (so a
    checkpoint from before a field existed still matches), ``epochs`` left out (resuming may extend it)."""
    return {k: v for k, v in OdmoConfig.from_dict(config).to_dict().items() if k != "epochs"}


def _validation_set(
    prepared: PreparedClips, val_idx: np.ndarray, seed: int, device: torch.device, config: OdmoConfig
) -> tuple[_Tensors, torch.Tensor] | None:
    """Fixed validation batch: centre crops of every validation clip and partners among them."""
    if len(val_idx) == 0:
        return None
    rng = np.random.default_rng([seed, 0x7A1])
    sampler = PairSampler(prepared.actions, val_idx)
    slot = np.searchsorted(sampler.actions, prepared.actions[val_idx])
    partners, same = sampler.partners(slot, rng)
    batch = crop_windows(prepared, np.concatenate([val_idx, partners]), None)
    return _Tensors.of(batch, device, config), torch.from_numpy(same).to(device)


def write_log(path: Path, rows: list[dict[str, float]]) -> None:
    """Write the per-epoch CSV log (one row per epoch, header from the first) atomically; no rows, no file."""
    if not rows:
        return
    buffer = io.StringIO()
    writer = csv.DictWriter(buffer, fieldnames=list(rows[0]), lineterminator="\n")
    writer.writeheader()
    writer.writerows(rows)
    atomic_write_text(path, buffer.getvalue())


def _encode_all(model: OdmoModel, prepared: PreparedClips, device: torch.device) -> tuple[np.ndarray, ...]:
    """Code means (N, D) and end locations (N, 3) of every clip's centre window."""
    batch = crop_windows(prepared, np.arange(prepared.n_clips), None)
    model.eval()
    with torch.inference_mode():
        mu, _ = model.encode(torch.from_numpy(batch.lmp).to(device), torch.from_numpy(batch.mask).to(device))
    return mu.cpu().numpy().astype(np.float32), batch.ends.astype(np.float32)


def _check_sizes(config: OdmoConfig, prepared: PreparedClips) -> None:
    if config.n_actions != len(prepared.action_names):
        raise ConfigError(f"config has {config.n_actions} actions, data has {len(prepared.action_names)}")
    if config.n_joints != prepared.skeleton.n_joints:
        raise ConfigError(f"config has {config.n_joints} joints, data has {prepared.skeleton.n_joints}")


def with_feet(config: OdmoConfig, prepared: PreparedClips, train_idx: np.ndarray) -> OdmoConfig:
    """``config`` with its foot joints (by name) and their resting heights over the training clips filled
    in when it has a contact head and none given; the head is switched off for a skeleton without feet."""
    if not config.foot_contact or config.foot_joints:
        return config
    feet = foot_joints(prepared.skeleton)
    if not feet:
        log.warning("no foot joints (foot, toe, ankle) in the skeleton: training without foot contact")
        return dataclasses.replace(config, foot_contact=False)
    heights = resting_heights([prepared.joints[i] for i in train_idx], feet)
    return dataclasses.replace(config, foot_joints=tuple(feet), foot_heights=tuple(float(h) for h in heights))


def train(
    clips: Sequence[Motion],
    action_names: list[str],
    out_dir: Path,
    config: OdmoConfig,
    *,
    seed: int = 0,
    device: str = "auto",
    resume: bool = False,
    val_fraction: float = 0.1,
    progress: Callable[[TrainProgress], None] | None = None,
    cancel: Callable[[], bool] | None = None,
    checkpoint_every: int = 10,
    bank_projections: Sequence[str] = ("pca", "tsne", "umap"),
    bank_k_range: tuple[int, int] = (3, 11),
) -> TrainResult:
    """Train an ODMO model on ``clips`` and write the model folder ``out_dir``.

    The folder gets model.safetensors, model.json, latent_bank.npz, train_log.csv and
    checkpoints/last.pt (written every ``checkpoint_every`` epochs and at the end). The bank holds the
    code means of every clip's centre window (validation clips too, ``meta["split"]`` says which),
    with ``bank_projections`` maps and modes searched over ``bank_k_range``. ``resume``
    continues exactly from that checkpoint (the config may only differ in ``epochs``). ``cancel`` is
    checked before every step; cancelling raises CancelledError and keeps the last checkpoint.
    """
    out = Path(out_dir)
    dev = resolve_device(device)
    if config.train_precision == "bfloat16" and not native_bfloat16(dev.type):
        log.warning(
            "this %s has no bfloat16 instructions: bfloat16 training runs, but slower than float32", dev
        )
    prepared = prepare_clips(clips, action_names, config.fps, config.window)
    _check_sizes(config, prepared)
    fingerprint = prepared.fingerprint()
    train_idx, val_idx = split_clips(prepared.actions, val_fraction, seed)
    config = with_feet(config, prepared, train_idx)
    sampler = PairSampler(prepared.actions, train_idx)
    validation = _validation_set(prepared, val_idx, seed, dev, config)
    root = prepared.skeleton.root

    model = OdmoModel(config, seed=seed).to(dev)
    model.attach_skeleton(prepared.skeleton)
    optimizer = torch.optim.Adam(model.parameters(), lr=config.lr)
    rng = np.random.default_rng(seed)
    tgen = torch.Generator(dev).manual_seed(seed)
    rows: list[dict[str, float]] = []
    start_epoch, train_seconds = 0, 0.0
    ckpt = checkpoint_path(out)
    identity = {
        "config": _identity_config(config.to_dict()),
        "fingerprint": fingerprint,
        "seed": seed,
        "val_fraction": val_fraction,
    }
    if resume and ckpt.exists():
        start_epoch, extra = load_checkpoint(ckpt, model=model, optimizer=optimizer, rng=rng, torch_rng=tgen)
        saved = extra.get("identity")
        if isinstance(saved, dict) and isinstance(saved.get("config"), dict):
            saved = saved | {"config": _identity_config(saved["config"])}
        if saved != identity:
            raise ModelFormatError(f"{ckpt}: checkpoint is from a different config, seed or data set")
        rows, train_seconds = list(extra["log"]), float(extra["train_seconds"])
        log.info("resuming %s after epoch %d", out, start_epoch)
    elif resume:
        log.info("%s: no checkpoint, training from scratch", ckpt)

    steps = max(1, math.ceil(config.epoch_size / config.batch_size))
    n_pairs = config.batch_size // 2
    train_losses: dict[str, float] = {}
    val_losses: dict[str, float] | None = None
    rate = 0.0
    for epoch in range(start_epoch, config.epochs):
        model.train()
        tf_rate = config.teacher_forcing(epoch)
        sums = dict.fromkeys(_TERMS, 0.0)
        t0 = time.perf_counter()
        for step in range(steps):
            if cancel is not None and cancel():
                raise CancelledError(f"training cancelled in epoch {epoch + 1}; resume from {ckpt}")
            anchors, slot = sampler.anchors(n_pairs, rng)
            partners, same = sampler.partners(slot, rng)
            batch = crop_windows(prepared, np.concatenate([anchors, partners]), rng)
            with bfloat16_autocast(dev.type, enabled=config.train_precision == "bfloat16"):
                terms = _forward(
                    model,
                    config,
                    _Tensors.of(batch, dev, config),
                    torch.from_numpy(same).to(dev),
                    root,
                    tf_rate=tf_rate,
                    generator=tgen,
                )
            optimizer.zero_grad(set_to_none=True)
            terms["total"].backward()
            torch.nn.utils.clip_grad_norm_(model.parameters(), config.grad_clip)
            optimizer.step()
            for k in _TERMS:
                sums[k] += float(terms[k].detach())
            elapsed = time.perf_counter() - t0
            rate = (step + 1) / elapsed
            if progress is not None:
                left = (steps - step - 1) + (config.epochs - epoch - 1) * steps
                progress(
                    TrainProgress(
                        stage="train",
                        epoch=epoch + 1,
                        epochs=config.epochs,
                        step=step + 1,
                        steps=steps,
                        losses={k: v / (step + 1) for k, v in sums.items()},
                        val_losses=val_losses,
                        windows_per_s=rate * 2 * n_pairs,
                        steps_per_s=rate,
                        eta_s=left / rate,
                        fraction=(epoch * steps + step + 1) / (config.epochs * steps),
                    )
                )
        epoch_seconds = time.perf_counter() - t0
        train_seconds += epoch_seconds
        train_losses = {k: v / steps for k, v in sums.items()}
        if validation is not None:
            model.eval()
            with torch.no_grad():
                val_terms = _forward(
                    model, config, validation[0], validation[1], root, tf_rate=0.0, generator=None
                )
            val_losses = {k: float(v) for k, v in val_terms.items()}
        row = {"epoch": epoch + 1, "tf_rate": tf_rate}
        row |= {f"train_{k}": v for k, v in train_losses.items()}
        row |= {f"val_{k}": (val_losses or {}).get(k, float("nan")) for k in _TERMS}
        row |= {"seconds": epoch_seconds, "windows_per_s": steps * 2 * n_pairs / epoch_seconds}
        rows.append(row)
        if (epoch + 1) % checkpoint_every == 0 or epoch + 1 == config.epochs:
            write_log(out / LOG_FILE, rows)
            extra = {"identity": identity, "log": rows, "train_seconds": train_seconds}
            save_checkpoint(
                ckpt, epoch=epoch + 1, model=model, optimizer=optimizer, rng=rng, torch_rng=tgen, extra=extra
            )

    write_log(out / LOG_FILE, rows)
    model.eval()
    provenance = {
        "data_fingerprint": fingerprint,
        "n_clips": prepared.n_clips,
        "n_train": len(train_idx),
        "n_val": len(val_idx),
        "seed": seed,
        "epochs": config.epochs,
        "train_seconds": round(train_seconds, 3),
        "device": str(dev),
        "created": datetime.now(UTC).isoformat(timespec="seconds"),
        "versions": {
            "odmo_explorer": __version__,
            "torch": torch.__version__,
            "numpy": np.__version__,
            "python": platform.python_version(),
        },
    }
    root_height = float(np.median(np.concatenate([j[:, root, 1] for j in prepared.joints])))
    save_model(out, model, config, prepared.skeleton, prepared.action_names, provenance, root_height)

    codes, ends = _encode_all(model, prepared, dev)
    in_val = np.zeros(prepared.n_clips, dtype=bool)
    in_val[val_idx] = True
    metas = [m | {"split": "val" if v else "train"} for m, v in zip(prepared.meta, in_val, strict=True)]

    def bank_progress(message: str, fraction: float) -> None:
        if progress is not None:
            report = TrainProgress(
                stage="bank",
                epoch=config.epochs,
                epochs=config.epochs,
                step=0,
                steps=0,
                losses=train_losses,
                val_losses=val_losses,
                windows_per_s=0.0,
                steps_per_s=0.0,
                eta_s=0.0,
                fraction=fraction,
                message=message,
            )
            progress(report)

    bank = build_bank(
        codes,
        prepared.actions,
        ends,
        prepared.sources,
        metas,
        prepared.action_names,
        k_range=bank_k_range,
        projections=tuple(bank_projections),
        seed=seed,
        progress=bank_progress,
        cancel=cancel,
    )
    save_bank(out, bank)
    return TrainResult(
        model_dir=out,
        epochs=config.epochs,
        train_losses=train_losses,
        val_losses=val_losses,
        windows_per_s=rate * 2 * n_pairs,
        train_seconds=train_seconds,
        n_train=len(train_idx),
        n_val=len(val_idx),
        bank=bank,
    )
