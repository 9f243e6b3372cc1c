"""The ODMO training loop: class-balanced contrastive batches, scheduled teacher forcing, checkpoints,
a per-epoch CSV log, and the final model folder with its latent bank."""

from __future__ import annotations

import dataclasses
import logging
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import torch

from engine.errors import ConfigError
from engine.latent.bank import build_bank
from engine.model.config import OdmoConfig
from engine.model.losses import LOSS_TERMS, LossJoints, odmo_losses
from engine.model.odmo import OdmoModel
from engine.model.precision import bfloat16_autocast, native_bfloat16
from engine.modelio import save_bank, save_model
from engine.motion.contact import contact_labels, foot_joints, resting_heights
from engine.motion.motion import Motion
from engine.train.distributed import SINGLE, Ranks, mean_over_ranks, parallel
from engine.train.epochs import (
    TrainProgress,
    TrainResult,
    clipped_step,
    root_height,
    split_metas,
)
from engine.train.kind_run import KindRun, RunOptions, WarmStart
from engine.train.pairs import PairSampler
from engine.train.rest_pose import centre_frames, mean_local_rotations
from engine.train.windows import (
    PreparedClips,
    WindowBatch,
    crop_starts,
    crop_windows,
    windows_at,
)

log = logging.getLogger(__name__)

_TERMS = (*LOSS_TERMS, "total")
MEAN_POSE_WEIGHT_SCALE = 0.1


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
    roles: LossJoints,
    *,
    tf_rate: float,
    noise: _Noise | None,
) -> dict[str, torch.Tensor]:
    """Loss terms of one batch (anchors then partners); training (``noise`` given) samples z and teacher
    forces, evaluation (None) decodes the code means free-running; ``roles``: the joints the terms read."""
    mu, logvar = model.encode(data.lmp, data.mask)
    if noise is not None:
        z = mu + torch.exp(0.5 * logvar) * noise.eps
        truth = data.joints
    else:
        z, truth = mu, None
    end = data.ends if config.use_end_location else None
    tf_noise = None if noise is None else noise.tf
    out = model.decode_full(z, data.actions, end, prev_truth=truth, tf_rate=tf_rate, tf_noise=tf_noise)
    free = None
    free_terms = (
        "w_free",
        "w_speed",
        "w_spectrum",
        "w_free_skate",
        "w_foot_height",
        "w_heading",
        "w_twist",
        "w_coordination",
        "w_start",
        "w_stance",
        "w_upper_speed",
        "w_skim",
        "w_stand",
        "w_floor",
    )
    if any(getattr(config, name) > 0 for name in free_terms):
        free = out.joints if truth is None else model.decode_full(z, data.actions, end).joints
    rollout = None
    if config.w_rollout > 0:
        start = (config.window - config.rollout_frames) // 2 if noise is None else noise.rollout_start
        rolled = model.rollout(z, data.actions, end, data.joints, start, config.rollout_frames)
        rollout = (start, rolled)
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
        root=roles.root,
        raw_joints=out.raw if model.projection is not None else None,
        contact_logits=out.contact,
        contacts=data.contacts,
        free_joints=free,
        spectrum_on=roles.spectrum_on,
        hips=roles.hips,
        shoulders=roles.shoulders,
        coordination_on=roles.coordination_on,
        rollout=rollout,
        upper_on=roles.upper_on,
        feet=roles.feet,
    )


@dataclass
class _Noise:
    """A training batch's random draws: the codes' reparameterisation noise, the teacher-forcing draws
    (None when every frame is teacher-forced) and the rollout's first frame (0 without ``w_rollout``)."""

    eps: torch.Tensor
    tf: torch.Tensor | None
    rollout_start: int = 0

    @classmethod
    def draw(
        cls, n: int, config: OdmoConfig, tf_rate: float, generator: torch.Generator, device: torch.device
    ) -> _Noise:
        """The draws of a global batch of ``n`` windows, in the order the decoder once drew them."""
        eps = torch.randn((n, config.latent_dim), generator=generator, device=device)
        tf = None
        if tf_rate < 1.0:
            tf = torch.rand((n, config.window - 1, 1), generator=generator, device=device)
        start = 0
        if config.w_rollout > 0:
            last = config.window - config.rollout_frames
            start = int(torch.randint(1, last + 1, (1,), generator=generator, device=device))
        return cls(eps, tf, start)

    def take(self, rows: torch.Tensor) -> _Noise:
        """The draws of ``rows`` of the batch."""
        return _Noise(self.eps[rows], None if self.tf is None else self.tf[rows], self.rollout_start)


class _StepLoss(torch.nn.Module):
    """The model and its training loss as one module, so DistributedDataParallel sees one forward."""

    def __init__(self, model: OdmoModel, roles: LossJoints) -> None:
        super().__init__()
        self.model, self.roles = model, roles

    def forward(
        self, data: _Tensors, same: torch.Tensor, tf_rate: float, noise: _Noise
    ) -> dict[str, torch.Tensor]:
        """The loss terms of a training batch."""
        return _forward(self.model, self.model.config, data, same, self.roles, tf_rate=tf_rate, noise=noise)


class OdmoSteps:
    """ODMO's training step: class-balanced contrastive pairs, scheduled teacher forcing, gradient clipping,
    optional bfloat16 autocast; validation on a fixed batch with the code means.

    Across ``ranks`` every process draws the same global batch (pairs, crops and noise) and trains on its
    share of the pairs; DistributedDataParallel averages the gradients, so the step is the global batch's.
    """

    terms = _TERMS

    def __init__(
        self,
        model: OdmoModel,
        prepared: PreparedClips,
        train_idx: np.ndarray,
        validation: tuple[_Tensors, torch.Tensor] | None,
        ranks: Ranks = SINGLE,
    ) -> None:
        self.model = self.modules = model
        self.ranks = ranks
        self.config = model.config
        self.prepared = prepared
        self.sampler = PairSampler(prepared.actions, train_idx)
        self.validation = validation
        self.device = next(model.parameters()).device
        self.optimizer = torch.optim.Adam(model.parameters(), lr=self.config.lr)
        self.optimizers = (self.optimizer,)
        self.n_pairs = self.config.batch_size // 2
        self.windows_per_step = 2 * self.n_pairs
        if self.n_pairs % ranks.world:
            raise ConfigError(
                f"batch_size {self.config.batch_size} does not split into equal shares of pairs over "
                f"{ranks.world} processes; use a multiple of {2 * ranks.world}"
            )
        self.roles = LossJoints.of(self.config, prepared.skeleton)
        self.loss = parallel(_StepLoss(model, self.roles), ranks)

    def step(self, epoch: int, rng: np.random.Generator, generator: torch.Generator) -> dict[str, float]:
        """One Adam step on a fresh batch of anchors and their partners."""
        config, dev = self.config, self.device
        anchors, slot = self.sampler.anchors(self.n_pairs, rng)
        partners, same = self.sampler.partners(slot, rng)
        clips = np.concatenate([anchors, partners])
        starts = crop_starts(self.prepared, clips, rng)
        tf_rate = config.teacher_forcing(epoch)
        noise = _Noise.draw(len(clips), config, tf_rate, generator, dev)
        pairs = self.ranks.share(self.n_pairs)
        rows = np.concatenate([pairs, self.n_pairs + pairs])
        batch = windows_at(self.prepared, clips[rows], starts[rows])
        with bfloat16_autocast(dev.type, enabled=config.train_precision == "bfloat16"):
            terms = self.loss(
                _Tensors.of(batch, dev, config),
                torch.from_numpy(same[pairs]).to(dev),
                tf_rate,
                noise.take(torch.from_numpy(rows).to(dev)),
            )
        clipped_step(self.optimizer, self.model, terms["total"], config.grad_clip)
        return mean_over_ranks({k: float(v.detach()) for k, v in terms.items()}, self.ranks)

    def validate(self) -> dict[str, float] | None:
        """Loss terms of the validation batch, decoded free-running from the code means."""
        if self.validation is None:
            return None
        with torch.no_grad():
            terms = _forward(
                self.model,
                self.config,
                *self.validation,
                self.roles,
                tf_rate=0.0,
                noise=None,
            )
        return {k: float(v) for k, v in terms.items()}

    def epoch_columns(self, epoch: int) -> dict[str, float]:
        """The epoch's teacher-forcing rate."""
        return {"tf_rate": self.config.teacher_forcing(epoch)}


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


def _encode_all(model: OdmoModel, prepared: PreparedClips, device: torch.device) -> tuple[np.ndarray, ...]:
    """Code means (N, D) and end locations (N, 3) of every clip's centre window."""
    batch = crop_windows(prepared, np.arange(prepared.n_clips), None)
    model.eval()
    with torch.inference_mode():
        mu, _ = model.encode(torch.from_numpy(batch.lmp).to(device), torch.from_numpy(batch.mask).to(device))
    return mu.cpu().numpy().astype(np.float32), batch.ends.astype(np.float32)


@torch.no_grad()
def start_at_mean_pose(model: OdmoModel, prepared: PreparedClips, train_idx: np.ndarray) -> None:
    """Set the pose decoder's output bias to the mean of what it emits over the real frames of the
    training clips' canonical centre windows (the pose, root-centred with ``root_relative_poses``; with
    ``pose_output`` "rotations" each joint's mean local rotation, in 6D), and scale its output weights by
    ``MEAN_POSE_WEIGHT_SCALE`` (``OdmoConfig.mean_pose_init``): from torch's default initialisation they
    move each joint by about 0.2 m, more than the hips lie apart. A residual decoder (``pose_update``) gets
    the mean pose as its start pose instead, its output (a step) unbiased."""
    if model.config.pose_output == "rotations":
        matrices = mean_local_rotations(prepared, train_idx).as_matrix()
        mean = np.concatenate([matrices[:, :, 0], matrices[:, :, 1]], axis=1)  # (J, 6): two columns
    else:
        frames = centre_frames(prepared, train_idx)
        mean = (frames - frames[:, :1] if model.config.root_relative_poses else frames).mean(axis=0)
    out, start = model.motion_gen.out, model.motion_gen.start
    out.weight.mul_(MEAN_POSE_WEIGHT_SCALE)
    mean = torch.as_tensor(mean.reshape(-1), dtype=out.bias.dtype, device=out.bias.device)
    if start is None:
        out.bias.copy_(mean)
    else:  # a residual decoder's output is a step: it starts still, at the mean pose
        out.bias.zero_()
        start.copy_(mean)


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
    ranks: Ranks = SINGLE,
    warm_start: WarmStart | None = None,
) -> TrainResult:
    """Train an ODMO model on ``clips`` and write the model folder ``out_dir``.

    The folder gets model.safetensors, model.json, latent_bank.npz, train_log.csv and
    checkpoints/last.pt (written every ``checkpoint_every`` epochs and at the end). The bank holds the
    code means of every clip's centre window (validation clips too, ``meta["split"]`` says which),
    with ``bank_projections`` maps and modes searched over ``bank_k_range``. ``resume``
    continues exactly from that checkpoint (the config may only differ in ``epochs``). ``cancel`` is
    checked before every step; cancelling raises CancelledError and keeps the last checkpoint. Across
    ``ranks`` (see ``engine.train.distributed``) each process trains on its share of every global batch
    and rank 0 alone writes the folder; the other ranks' result has no bank. With ``warm_start`` the model
    starts from those weights (a fine-tune: the config may change its loss weights and schedule; a
    checkpoint to resume from still wins) and the provenance names them.
    """
    out = Path(out_dir)
    options = RunOptions(seed, device, resume, val_fraction, progress, cancel, checkpoint_every, ranks)
    data = KindRun.prepare(clips, action_names, config, options)
    prepared, dev = data.prepared, data.device
    if config.train_precision == "bfloat16" and not native_bfloat16(dev.type):
        log.warning(
            "this %s has no bfloat16 instructions: bfloat16 training runs, but slower than float32", dev
        )
    config = with_feet(config, prepared, data.train_idx)
    model = OdmoModel(config, seed=seed).to(dev)
    if warm_start is not None:
        warm_start.load_into(model)
    elif config.mean_pose_init:
        start_at_mean_pose(model, prepared, data.train_idx)
    model.attach_skeleton(prepared.skeleton)
    validation = _validation_set(prepared, data.val_idx, seed, dev, config)
    run = data.train(OdmoSteps(model, prepared, data.train_idx, validation, ranks), out, config)
    if not ranks.is_main:
        return data.result(out, config, run, None)
    made = data.provenance(run, config, warm_start, processes=ranks.world)
    save_model(out, model, config, prepared.skeleton, prepared.action_names, made, root_height(prepared))

    codes, ends = _encode_all(model, prepared, dev)

    def bank_progress(message: str, fraction: float) -> None:
        if progress is not None:
            report = TrainProgress(
                stage="bank",
                epoch=config.epochs,
                epochs=config.epochs,
                step=0,
                steps=0,
                losses=run.train_losses,
                val_losses=run.val_losses,
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
        split_metas(prepared, data.val_idx),
        prepared.action_names,
        k_range=bank_k_range,
        projections=tuple(bank_projections),
        seed=seed,
        progress=bank_progress,
        cancel=cancel,
    )
    save_bank(out, bank)
    return data.result(out, config, run, bank)
