"""Training loop of Action2Motion: ODMO's windows, split and budget; A2M's losses, code space and bank."""

from __future__ import annotations

import logging
from collections.abc import Callable, Sequence
from pathlib import Path

import numpy as np
import torch
from sklearn.decomposition import PCA

from engine.latent.bank import LatentBank, build_bank
from engine.model.a2m import A2M_LOSS_TERMS, A2mConfig, A2mModel, a2m_losses
from engine.modelio import save_bank, write_model_folder
from engine.motion.motion import Motion
from engine.train.epochs import (
    TrainProgress,
    TrainResult,
    clipped_step,
    cosine_lr,
    root_height,
    split_metas,
)
from engine.train.kind_run import KindRun, RunOptions, WarmStart
from engine.train.pairs import PairSampler
from engine.train.rest_pose import mean_local_rotations
from engine.train.windows import PreparedClips, WindowBatch, crop_windows

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


class A2mSteps:
    """Action2Motion's training step: class-balanced windows, the whole batch teacher-forced with
    probability ``tf_rate``, Adam with weight decay and gradient clipping; validation free-running."""

    terms = _TERMS

    def __init__(
        self, model: A2mModel, prepared: PreparedClips, train_idx: np.ndarray, validation: WindowBatch | None
    ) -> None:
        self.model = self.modules = model
        self.config = model.config
        self.prepared = prepared
        self.sampler = PairSampler(prepared.actions, train_idx)
        self.validation = validation
        self.device = next(model.parameters()).device
        lr, decay = self.config.lr, self.config.weight_decay
        self.optimizer = torch.optim.Adam(model.parameters(), lr=lr, weight_decay=decay)
        self.optimizers = (self.optimizer,)
        self.windows_per_step = self.config.batch_size
        self.batches = self.teacher_batches = 0

    def step(self, epoch: int, rng: np.random.Generator, generator: torch.Generator) -> dict[str, float]:
        """One Adam step on a fresh batch, teacher-forced or free-running by a coin flip, at the epoch's
        learning rate."""
        for group in self.optimizer.param_groups:
            group["lr"] = cosine_lr(self.config.lr, epoch, self.config.epochs, self.config.lr_floor)
        anchors, _ = self.sampler.anchors(self.config.batch_size, rng)
        batch = crop_windows(self.prepared, anchors, rng)
        teacher = bool(rng.random() < self.config.tf_rate)
        self.batches += 1
        self.teacher_batches += teacher
        terms = _losses(self.model, batch, self.device, teacher=teacher, generator=generator)
        clipped_step(self.optimizer, self.model, terms["total"], self.config.grad_clip)
        return {k: float(v.detach()) for k, v in terms.items()}

    def validate(self) -> dict[str, float] | None:
        """Loss terms of the validation windows, free-running from the posterior means."""
        if self.validation is None:
            return None
        with torch.no_grad():
            terms = _losses(self.model, self.validation, self.device, teacher=False, generator=None)
        return {k: float(v) for k, v in terms.items()}

    def epoch_columns(self, epoch: int) -> dict[str, float]:
        """The share of the epoch's batches that were teacher-forced."""
        share = self.teacher_batches / max(1, self.batches)
        self.batches = self.teacher_batches = 0
        return {"teacher_batches": share}


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
    return build_bank(
        codes,
        prepared.actions,
        ends,
        prepared.sources,
        split_metas(prepared, val_idx),
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
    warm_start: WarmStart | None = None,
    select: Callable[[A2mModel], float] | None = None,
) -> TrainResult:
    """Train an A2M baseline on ``clips`` and write its model folder ``out_dir``.

    Same windows, clip split (``val_fraction``, ``seed``) and budget (``epochs`` × ``epoch_size``
    class-balanced windows) as ``engine.train.loop.train``. Each batch is teacher-forced with probability
    ``config.tf_rate``, else the generator runs on its own outputs. A "lie" model runs on the data's
    skeleton and starts at its mean pose. The folder gets model.safetensors, model.json, train_log.csv,
    checkpoints/last.pt and, with a code space, latent_bank.npz (``bank_projections`` maps, modes over
    ``bank_k_range``); ``resume`` and ``cancel`` behave as in ``train``. With ``warm_start`` the model
    starts from those weights (a checkpoint to resume from still wins) and the provenance names them.
    With ``select`` (a score of the model, higher is better; e.g. ``prior_accuracy``) the folder gets the
    weights of the checkpoint epoch that scored best, and the provenance names that epoch.
    """
    out = Path(out_dir)
    options = RunOptions(seed, device, resume, val_fraction, progress, cancel, checkpoint_every)
    data = KindRun.prepare(clips, action_names, config, options)
    prepared, train_idx = data.prepared, data.train_idx
    model = A2mModel(config, seed=seed)
    if config.pose_rep == "lie":
        model.set_skeleton(prepared.skeleton)
        model.set_rest_bias(mean_local_rotations(prepared, train_idx).as_rotvec())
    if warm_start is not None:
        warm_start.load_into(model)
    model = model.to(data.device)
    validation = crop_windows(prepared, data.val_idx, None) if len(data.val_idx) else None
    score = None if select is None else (lambda: select(model))
    run = data.train(A2mSteps(model, prepared, train_idx, validation), out, config, score)
    if config.code_dim:
        fit_code_space(model, prepared, train_idx)
    chosen = {} if run.selected_epoch is None else {"selected_epoch": run.selected_epoch}
    made = data.provenance(run, config, warm_start, **chosen)
    height = root_height(prepared)
    write_model_folder(
        out, model, config.to_dict(), prepared.skeleton, prepared.action_names, made, height, "a2m"
    )
    bank = None
    if config.code_dim:
        bank = a2m_bank(
            model, prepared, data.val_idx, projections=bank_projections, k_range=bank_k_range, seed=seed
        )
        save_bank(out, bank)
    return data.result(out, config, run, bank)
