"""MoDi's training step for the shared epoch loop (``engine.train.epochs.EpochSteps``).

Real windows are the project's canonical windows (``engine.train.windows``) of uniformly drawn training
clips, as MoDi features: local rotations solved once per clip by ``engine.motion.ik``, the root turned
and shifted as the window's joints are, and the foot-contact labels of ``engine.motion.contact`` (computed
on the clip, floor at y = 0). Each step updates the critic (and every ``r1_every`` steps its lazy R1),
then the generator, then the generator's EMA copy, which is the model to ship.
"""

from __future__ import annotations

import copy
from dataclasses import dataclass

import numpy as np
import torch
from scipy.spatial.transform import Rotation
from torch import Tensor, nn

from engine.model.modi import ModiConfig, ModiDiscriminator, ModiNetwork
from engine.model.modi_losses import contact_losses, d_adversarial, g_adversarial, r1_penalty
from engine.motion.contact import contact_labels, foot_joints, resting_heights
from engine.motion.ik import joints_to_rotations
from engine.motion.motion import Motion
from engine.train.windows import PreparedClips, WindowBatch, crop_windows

TERMS = ("d_adv", "r1", "g_adv", "touch", "fcon", "total")
#: Most validation windows scored after each epoch.
MAX_VALIDATION = 256


@dataclass
class ClipFeatures:
    """Per clip at the prepared rate: local rotation matrices (T, J, 3, 3), root positions (T, 3) and
    foot-contact labels (T, F), all float32."""

    rotations: list[np.ndarray]
    root: list[np.ndarray]
    contacts: list[np.ndarray]


def clip_features(prepared: PreparedClips) -> ClipFeatures:
    """Rotations (inverse kinematics), root path and contact labels of every prepared clip."""
    skeleton = prepared.skeleton
    feet = foot_joints(skeleton)
    rest = resting_heights(prepared.joints, feet)
    rotations, roots, contacts = [], [], []
    for joints in prepared.joints:
        _, local, root, _ = joints_to_rotations(Motion(joints, prepared.fps, skeleton))
        matrices = Rotation.from_quat(local.reshape(-1, 4), scalar_first=True).as_matrix()
        rotations.append(matrices.reshape(*local.shape[:2], 3, 3).astype(np.float32))
        roots.append(root.astype(np.float32))
        contacts.append(contact_labels(joints, prepared.fps, feet, rest).astype(np.float32))
    return ClipFeatures(rotations, roots, contacts)


def window_features(
    generator: ModiNetwork, clips: ClipFeatures, batch: WindowBatch
) -> tuple[Tensor, Tensor, Tensor]:
    """Rotations (B, T, J, 3, 3), root positions (B, T, 3) and contacts (B, T, F) of ``batch``'s windows,
    in its canonical frame (padded like its joints, with the last frame)."""
    t = batch.joints.shape[1]

    def crop(arrays: list[np.ndarray]) -> np.ndarray:
        out = []
        for i, s in zip(batch.indices, batch.starts, strict=True):
            piece = arrays[i][s : s + t]
            out.append(np.concatenate([piece, np.repeat(piece[-1:], t - len(piece), axis=0)]))
        return np.stack(out)

    rotations, root, contacts = crop(clips.rotations), crop(clips.root), crop(clips.contacts)
    turn = Rotation.from_euler("y", -np.asarray(batch.yaw, dtype=np.float64)[:, None]).as_matrix()
    r = batch.root
    rotations[:, :, r] = np.einsum("bij,btjk->btik", turn, rotations[:, :, r])
    root = np.einsum("bij,btj->bti", turn, root - batch.origin[:, None, :])
    device = generator.w_avg.device
    rotations, root, contacts = (
        torch.as_tensor(np.ascontiguousarray(a, np.float32), device=device)
        for a in (rotations, root, contacts)
    )
    return rotations, root, contacts


class _Counter(nn.Module):
    """The steps taken and the last R1 penalty, as buffers so that checkpoints keep them."""

    def __init__(self) -> None:
        super().__init__()
        self.register_buffer("steps", torch.zeros((), dtype=torch.int64))
        self.register_buffer("last_r1", torch.zeros(()))


def _trainable(module: nn.Module, flag: bool) -> None:
    for p in module.parameters():
        p.requires_grad_(flag)


class ModiSteps:
    """The MoDi GAN step on ``prepared``'s clips ``train_idx`` (validation on ``val_idx``), models from
    ``seed``; ``clips`` are their ``clip_features`` when already computed.

    ``modules`` holds the generator ``g``, its EMA ``g_ema``, the critic ``d`` and the step count;
    ``optimizers`` are the generator's and the critic's Adam (β₁ = 0, β₂ = 0.99, the critic's adjusted
    for lazy R1 as in StyleGAN2). ``total`` is the generator's objective; ``r1`` the last penalty taken.
    """

    terms = TERMS

    def __init__(
        self,
        config: ModiConfig,
        prepared: PreparedClips,
        train_idx: np.ndarray,
        val_idx: np.ndarray,
        *,
        seed: int = 0,
        device: torch.device | str = "cpu",
        clips: ClipFeatures | None = None,
    ):
        self.config, self.prepared = config, prepared
        self.train_idx = np.asarray(train_idx, dtype=np.int64)
        self.windows_per_step = config.batch_size
        self.clips = clip_features(prepared) if clips is None else clips
        g = ModiNetwork(config, prepared.skeleton, seed).to(device)
        g.coder.set_statistics(self._raw(g, crop_windows(prepared, self.train_idx, None)))
        d = ModiDiscriminator(config, prepared.skeleton, seed + 1).to(device)
        g_ema = copy.deepcopy(g).eval()
        _trainable(g_ema, False)
        self.g, self.d, self.g_ema, self.counter = g, d, g_ema, _Counter().to(device)
        self.modules = nn.ModuleDict({"g": g, "g_ema": g_ema, "d": d, "counter": self.counter})
        lazy = config.r1_every / (config.r1_every + 1)
        self.optimizers = (
            torch.optim.Adam(g.parameters(), lr=config.lr, betas=(0.0, 0.99)),
            torch.optim.Adam(d.parameters(), lr=config.lr * lazy, betas=(0.0, 0.99**lazy)),
        )
        val_idx = np.asarray(val_idx, dtype=np.int64)[:MAX_VALIDATION]
        self.val_real = (
            g.coder.normalise(self._raw(g, crop_windows(prepared, val_idx, None))) if len(val_idx) else None
        )
        val_gen = torch.Generator(g.w_avg.device).manual_seed(seed + 2)
        self.val_z = torch.randn(max(len(val_idx), 1), config.w_dim, generator=val_gen, device=g.w_avg.device)

    def _raw(self, g: ModiNetwork, batch: WindowBatch) -> Tensor:
        return g.coder.raw_features(*window_features(g, self.clips, batch))

    def real(self, rng: np.random.Generator) -> Tensor:
        """Normalised features (B, E, K, T) of random windows of uniformly drawn training clips."""
        clips = rng.choice(self.train_idx, self.config.batch_size)
        return self.g.coder.normalise(self._raw(self.g, crop_windows(self.prepared, clips, rng)))

    def fake(self, generator: torch.Generator) -> Tensor:
        """A batch of generated features; ``mixing`` of them style-mixed at a random level; mapped w
        update the generator's ``w_avg``."""
        g, n, dim = self.g, self.config.batch_size, self.config.w_dim
        device = g.w_avg.device
        w = g.map(torch.randn(n, dim, generator=generator, device=device))
        w2 = g.map(torch.randn(n, dim, generator=generator, device=device))
        with torch.no_grad():
            g.w_avg.lerp_(w.detach().mean(0), 1.0 - self.config.w_avg_beta)
        mixed = torch.rand(n, generator=generator, device=device) < self.config.mixing
        split = torch.randint(1, g.n_levels, (n,), generator=generator, device=device)
        ws = g.mix(w, w2, torch.where(mixed, split, g.n_levels))
        return g.synthesize(ws, "random", generator)

    def step(self, epoch: int, rng: np.random.Generator, generator: torch.Generator) -> dict[str, float]:
        """One critic update (with R1 every ``r1_every`` steps), one generator update, the EMA."""
        config, g, d = self.config, self.g, self.d
        opt_g, opt_d = self.optimizers
        real = self.real(rng)
        _trainable(d, True)
        _trainable(g, False)
        with torch.no_grad():
            fake = self.fake(generator)
        d_loss = d_adversarial(d(real), d(fake))
        opt_d.zero_grad(set_to_none=True)
        d_loss.backward()
        opt_d.step()
        if int(self.counter.steps) % config.r1_every == 0 and config.r1_gamma > 0:
            r1 = r1_penalty(d, real)
            opt_d.zero_grad(set_to_none=True)
            (0.5 * config.r1_gamma * config.r1_every * r1).backward()
            opt_d.step()
            self.counter.last_r1.copy_(r1.detach())
        _trainable(d, False)
        _trainable(g, True)
        fake = self.fake(generator)
        g_adv = g_adversarial(d(fake))
        touch, fcon = contact_losses(g.coder, fake, config.fps)
        total = g_adv + config.touch_weight * touch + config.fcon_weight * fcon
        opt_g.zero_grad(set_to_none=True)
        total.backward()
        opt_g.step()
        self._update_ema()
        self.counter.steps += 1
        values = (d_loss, self.counter.last_r1, g_adv, touch, fcon, total)
        return _floats(values)

    @torch.no_grad()
    def _update_ema(self) -> None:
        windows = self.config.ema_windows
        beta = 0.5 ** (self.config.batch_size / windows) if windows else 0.0
        for p_ema, p in zip(self.g_ema.parameters(), self.g.parameters(), strict=True):
            p_ema.lerp_(p, 1.0 - beta)
        for b_ema, b in zip(self.g_ema.buffers(), self.g.buffers(), strict=True):
            b_ema.copy_(b)

    def validate(self) -> dict[str, float] | None:
        """The terms on the validation windows against as many EMA samples of fixed z (constant noise)."""
        if self.val_real is None:
            return None
        config, d = self.config, self.d
        with torch.no_grad():
            fake = self.g_ema(self.val_z)
            real_logits, fake_logits = d(self.val_real), d(fake)
            touch, fcon = contact_losses(self.g_ema.coder, fake, config.fps)
        with torch.enable_grad():
            r1 = r1_penalty(d, self.val_real)
        g_adv = g_adversarial(fake_logits)
        total = g_adv + config.touch_weight * touch + config.fcon_weight * fcon
        values = (d_adversarial(real_logits, fake_logits), r1, g_adv, touch, fcon, total)
        return _floats(values)

    def epoch_columns(self, epoch: int) -> dict[str, float]:
        """The steps taken so far and the size of the mean w."""
        return {"steps": float(self.counter.steps), "w_avg_norm": float(self.g.w_avg.norm())}


def _floats(values: tuple[Tensor | float, ...]) -> dict[str, float]:
    """The terms as plain numbers."""
    return {k: float(v.detach() if isinstance(v, Tensor) else v) for k, v in zip(TERMS, values, strict=True)}
