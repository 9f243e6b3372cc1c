"""Training loop of Action2Motion: ODMO's windows, split and budget; A2M's losses, code space and bank."""

from __future__ import annotations

import logging
import math
import platform
import time
from collections.abc import Callable, Sequence
from datetime import UTC, datetime
from pathlib import Path

import numpy as np
import torch
from scipy.spatial.transform import Rotation
from sklearn.decomposition import PCA

from engine import __version__
from engine.errors import CancelledError, ConfigError, ModelFormatError
from engine.latent.bank import LatentBank, build_bank
from engine.model.a2m import A2M_LOSS_TERMS, A2mConfig, A2mModel, a2m_losses
from engine.modelio import resolve_device, save_bank, write_model_folder
from engine.motion.ik import joints_to_rotations
from engine.motion.motion import Motion
from engine.train.checkpoint import checkpoint_path, load_checkpoint, save_checkpoint
from engine.train.loop import LOG_FILE, TrainProgress, TrainResult, write_log
from engine.train.pairs import PairSampler, split_clips
from engine.train.windows import PreparedClips, WindowBatch, crop_windows, prepare_clips

log = logging.getLogger(__name__)

_TERMS = (*A2M_LOSS_TERMS, "total")


def _losses(
    model: A2mModel,
    batch: WindowBatch,
    device: torch.device,
    *,
    teacher: bool,
    generator: torch.Generator | None,
) -> dict[str, torch.Tensor]:
    """Loss terms of one window batch (z sampled with ``generator``, posterior means without)."""
    joints = torch.from_numpy(np.ascontiguousarray(batch.joints, np.float32)).to(device)
    mask = torch.from_numpy(np.asarray(batch.mask, bool)).to(device)
    actions = torch.from_numpy(np.asarray(batch.actions, np.int64)).to(device)
    out = model(joints, actions, teacher=teacher, generator=generator)
    return a2m_losses(model.config, joints, mask, out, batch.root)


def rest_rotations(prepared: PreparedClips, indices: np.ndarray) -> np.ndarray:
    """(J, 3) axis-angle of each joint's mean local rotation over the canonical centre windows of clips
    ``indices`` (inverse kinematics, ``engine.motion.ik``): where a "lie" generator's output starts."""
    batch = crop_windows(prepared, indices, None)
    frames = batch.joints[batch.mask]
    _, local, _, _ = joints_to_rotations(Motion(frames, prepared.fps, prepared.skeleton))
    return np.stack(
        [Rotation.from_quat(local[:, j], scalar_first=True).mean().as_rotvec() for j in range(local.shape[1])]
    )


@torch.no_grad()
def posterior_means(
    model: A2mModel, prepared: PreparedClips, indices: np.ndarray, batch: int = 256
) -> tuple[np.ndarray, np.ndarray]:
    """Posterior-mean sequences (N, T·Z) of the canonical centre windows of clips ``indices`` and those
    windows' root positions at their last real frame (N, 3)."""
    device = next(model.parameters()).device
    means, ends = [], []
    for lo in range(0, len(indices), batch):
        windows = crop_windows(prepared, indices[lo : lo + batch], None)
        joints = torch.from_numpy(np.ascontiguousarray(windows.joints, np.float32)).to(device)
        actions = torch.from_numpy(np.asarray(windows.actions, np.int64)).to(device)
        means.append(model.posterior_means(joints, actions).flatten(1).cpu().numpy())
        ends.append(windows.ends)
    return np.concatenate(means), np.concatenate(ends)


def fit_code_space(model: A2mModel, prepared: PreparedClips, train_idx: np.ndarray) -> None:
    """Set the model's code space: the first ``code_dim`` principal components of the posterior-mean
    sequences of the training clips (scikit-learn's PCA; rows past the number of clips stay zero)."""
    means, _ = posterior_means(model, prepared, train_idx)
    dim = model.config.code_dim
    pca = PCA(n_components=min(dim, *means.shape), svd_solver="full").fit(means)
    basis = np.zeros((dim, means.shape[1]), dtype=np.float32)  # fewer clips than dims: unused dims are 0
    basis[: len(pca.components_)] = pca.components_
    model.set_code_space(pca.mean_, basis)


def a2m_bank(
    model: A2mModel,
    prepared: PreparedClips,
    val_idx: np.ndarray,
    *,
    projections: Sequence[str] = ("pca", "tsne", "umap"),
    k_range: tuple[int, int] = (3, 11),
    seed: int = 0,
) -> LatentBank:
    """The latent bank of every clip: the code of its posterior-mean sequence, modes and maps."""
    everything = np.arange(prepared.n_clips)
    means, ends = posterior_means(model, prepared, everything)
    with torch.no_grad():
        codes = model.z_to_codes(torch.from_numpy(means).to(model.code_mean)).cpu().numpy()
    in_val = np.isin(everything, val_idx)
    metas = [m | {"split": "val" if v else "train"} for m, v in zip(prepared.meta, in_val, strict=True)]
    return build_bank(
        codes,
        prepared.actions,
        ends,
        prepared.sources,
        metas,
        prepared.action_names,
        k_range=k_range,
        projections=tuple(projections),
        seed=seed,
    )


def train_a2m(
    clips: Sequence[Motion],
    action_names: list[str],
    out_dir: Path,
    config: A2mConfig,
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
    """Train an A2M baseline on ``clips`` and write its model folder ``out_dir``.

    Same windows, clip split (``val_fraction``, ``seed``) and budget (``epochs`` × ``epoch_size``
    class-balanced windows) as ``engine.train.loop.train``. Each batch is teacher-forced with probability
    ``config.tf_rate``, else the generator runs on its own outputs. A "lie" model runs on the data's
    skeleton and starts at its mean pose. The folder gets model.safetensors, model.json, train_log.csv,
    checkpoints/last.pt and, with a code space, latent_bank.npz (``bank_projections`` maps, modes over
    ``bank_k_range``); ``resume`` and ``cancel`` behave as in ``train``.
    """
    out = Path(out_dir)
    dev = resolve_device(device)
    prepared = prepare_clips(clips, action_names, config.fps, config.window)
    if config.n_actions != len(prepared.action_names) or config.n_joints != prepared.skeleton.n_joints:
        raise ConfigError(
            f"config has {config.n_actions} actions and {config.n_joints} joints, data has "
            f"{len(prepared.action_names)} and {prepared.skeleton.n_joints}"
        )
    fingerprint = prepared.fingerprint()
    train_idx, val_idx = split_clips(prepared.actions, val_fraction, seed)
    sampler = PairSampler(prepared.actions, train_idx)
    validation = crop_windows(prepared, val_idx, None) if len(val_idx) else None

    model = A2mModel(config, seed=seed)
    if config.pose_rep == "lie":
        model.set_skeleton(prepared.skeleton)
        model.set_rest_bias(rest_rotations(prepared, train_idx))
    model = model.to(dev)
    optimizer = torch.optim.Adam(model.parameters(), lr=config.lr, weight_decay=config.weight_decay)
    rng = np.random.default_rng(seed)
    tgen = torch.Generator(dev).manual_seed(seed)
    rows: list[dict[str, float]] = []
    start_epoch, train_seconds = 0, 0.0
    ckpt = checkpoint_path(out)
    identity = {
        "config": {k: v for k, v in config.to_dict().items() if k != "epochs"},
        "fingerprint": fingerprint,
        "seed": seed,
        "val_fraction": val_fraction,
    }
    if resume and ckpt.exists():
        start_epoch, extra = load_checkpoint(ckpt, model=model, optimizer=optimizer, rng=rng, torch_rng=tgen)
        if extra.get("identity") != identity:
            raise ModelFormatError(f"{ckpt}: checkpoint is from a different config, seed or data set")
        rows, train_seconds = list(extra["log"]), float(extra["train_seconds"])
        log.info("resuming %s after epoch %d", out, start_epoch)

    steps = max(1, math.ceil(config.epoch_size / config.batch_size))
    train_losses: dict[str, float] = {}
    val_losses: dict[str, float] | None = None
    rate = 0.0
    for epoch in range(start_epoch, config.epochs):
        model.train()
        sums = dict.fromkeys(_TERMS, 0.0)
        n_teacher = 0
        t0 = time.perf_counter()
        for step in range(steps):
            if cancel is not None and cancel():
                raise CancelledError(f"training cancelled in epoch {epoch + 1}; resume from {ckpt}")
            anchors, _ = sampler.anchors(config.batch_size, rng)
            batch = crop_windows(prepared, anchors, rng)
            teacher = bool(rng.random() < config.tf_rate)
            n_teacher += teacher
            terms = _losses(model, batch, dev, teacher=teacher, generator=tgen)
            optimizer.zero_grad(set_to_none=True)
            terms["total"].backward()
            torch.nn.utils.clip_grad_norm_(model.parameters(), config.grad_clip)
            optimizer.step()
            for k in _TERMS:
                sums[k] += float(terms[k].detach())
            rate = (step + 1) / (time.perf_counter() - t0)
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
                        windows_per_s=rate * config.batch_size,
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
                val_terms = _losses(model, validation, dev, teacher=False, generator=None)
            val_losses = {k: float(v) for k, v in val_terms.items()}
        row = {"epoch": epoch + 1, "teacher_batches": n_teacher / steps}
        row |= {f"train_{k}": v for k, v in train_losses.items()}
        row |= {f"val_{k}": (val_losses or {}).get(k, float("nan")) for k in _TERMS}
        row |= {"seconds": epoch_seconds, "windows_per_s": steps * config.batch_size / epoch_seconds}
        rows.append(row)
        if (epoch + 1) % checkpoint_every == 0 or epoch + 1 == config.epochs:
            write_log(out / LOG_FILE, rows)
            extra = {"identity": identity, "log": rows, "train_seconds": train_seconds}
            save_checkpoint(
                ckpt, epoch=epoch + 1, model=model, optimizer=optimizer, rng=rng, torch_rng=tgen, extra=extra
            )

    write_log(out / LOG_FILE, rows)
    model.eval()
    if config.code_dim:
        fit_code_space(model, prepared, train_idx)
    provenance = {
        "arch": "a2m",
        "data_fingerprint": fingerprint,
        "n_clips": prepared.n_clips,
        "n_train": len(train_idx),
        "n_val": len(val_idx),
        "seed": seed,
        "epochs": config.epochs,
        "windows_seen": config.epochs * steps * config.batch_size,
        "train_seconds": round(train_seconds, 3),
        "device": str(dev),
        "created": datetime.now(UTC).isoformat(timespec="seconds"),
        "train_sources": [prepared.sources[i] for i in train_idx],
        "versions": {
            "odmo_explorer": __version__,
            "torch": torch.__version__,
            "numpy": np.__version__,
            "python": platform.python_version(),
        },
    }
    root = prepared.skeleton.root
    root_height = float(np.median(np.concatenate([j[:, root, 1] for j in prepared.joints])))
    write_model_folder(
        out, model, config.to_dict(), prepared.skeleton, prepared.action_names, provenance, root_height, "a2m"
    )
    if config.code_dim:
        bank = a2m_bank(
            model, prepared, val_idx, projections=bank_projections, k_range=bank_k_range, seed=seed
        )
        save_bank(out, bank)
    return TrainResult(
        model_dir=out,
        epochs=config.epochs,
        train_losses=train_losses,
        val_losses=val_losses,
        windows_per_s=rate * config.batch_size,
        train_seconds=train_seconds,
        n_train=len(train_idx),
        n_val=len(val_idx),
    )
