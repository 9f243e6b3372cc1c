"""DVGAN's training step for the shared epoch loop (``engine.train.epochs.EpochSteps``): WGAN-GP with
``critic_steps`` critic updates per generator update.

Real windows are N-frame pieces of training clips at least N frames long, the action drawn uniformly
and then a clip of it, as DVGAN features (``engine.model.dvgan_features``) on the data's typical skeleton.
Generated windows are final cuts of generated tapes; with probability ``prefix_rate`` a batch instead
starts from the first 1..``max_prefix`` frames of real windows of its actions and the RNN completes
them (the completion the paper trains a conditional GAN for). Both pass through the shift augmentation
before the critic sees them.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import torch
from torch import Tensor, nn

from engine.errors import DataError
from engine.model.dvgan import (
    DVGAN_TERMS,
    DenseCritic,
    DvganConfig,
    DvganNetwork,
    final_cut,
    gradient_penalty,
    shifted,
)
from engine.model.dvgan_features import motion_features, typical_skeleton
from engine.motion.contact import foot_joints, resting_heights
from engine.motion.skeleton import Skeleton
from engine.train.kind_run import WarmStart
from engine.train.windows import PreparedClips

#: Frames of each clip used to find the typical skeleton (every this many clips).
TYPICAL_EVERY = 10
#: Most validation windows scored after each epoch.
MAX_VALIDATION = 256


@dataclass
class ClipFeatures:
    """Per clip, DVGAN features (T_i, F) float32 on ``skeleton`` (the data's typical one), and the
    resting foot heights (F_feet,) their contact labels used."""

    features: list[np.ndarray]
    skeleton: Skeleton
    foot_heights: np.ndarray


def clip_features(prepared: PreparedClips) -> ClipFeatures:
    """Features of every prepared clip (inverse kinematics on the data's typical skeleton)."""
    frames = np.concatenate(prepared.joints[::TYPICAL_EVERY])
    skeleton = typical_skeleton(prepared.skeleton, frames, prepared.fps)
    rest = resting_heights(prepared.joints, foot_joints(skeleton))
    features = [motion_features(j, prepared.fps, skeleton, rest)[0] for j in prepared.joints]
    return ClipFeatures(features, skeleton, rest)


class _Counter(nn.Module):
    """The generator updates taken, as a buffer so that checkpoints keep it."""

    def __init__(self) -> None:
        super().__init__()
        self.register_buffer("steps", torch.zeros((), dtype=torch.int64))


class DvganSteps:
    """The DVGAN step on ``prepared``'s clips ``train_idx`` (validation on ``val_idx``), from ``seed``.

    ``modules`` holds the generator ``g``, the critic ``d`` and the step count; ``optimizers`` are their
    Adam (β = 0.5, 0.9, as WGAN-GP). ``total`` is the generator's objective. With ``warm_start`` the
    generator starts from those weights (a model folder holds no critic: it starts afresh).
    """

    terms = DVGAN_TERMS

    def __init__(
        self,
        config: DvganConfig,
        prepared: PreparedClips,
        train_idx: np.ndarray,
        val_idx: np.ndarray,
        features: ClipFeatures,
        *,
        seed: int = 0,
        device: torch.device | str = "cpu",
        warm_start: WarmStart | None = None,
    ):
        self.config, self.prepared = config, prepared
        self.phrases = list(prepared.action_names)
        self.windows_per_step = config.batch_size
        lengths = np.array([len(f) for f in features.features])
        self.train_idx = np.asarray(train_idx, np.int64)[lengths[train_idx] >= config.window]
        by_action = [self.train_idx[prepared.actions[self.train_idx] == a] for a in range(len(self.phrases))]
        self.by_action = [rows for rows in by_action if len(rows)]
        self.actions = np.array([a for a, rows in enumerate(by_action) if len(rows)])
        if not len(self.actions):
            raise DataError(f"no training clip has the {config.window} frames of a window")
        self.g = DvganNetwork(config, seed).to(device)
        self.g.set_statistics(
            torch.from_numpy(np.concatenate([features.features[i] for i in self.train_idx]))
        )
        if warm_start is not None:  # its weights, with the feature statistics they were trained on
            warm_start.load_into(self.g)
        with torch.no_grad():
            self.clips = [self.g.normalise(torch.from_numpy(f).to(device)) for f in features.features]
        self.d = DenseCritic(config, seed + 1).to(device)
        self.counter = _Counter().to(device)
        self.modules = nn.ModuleDict({"g": self.g, "d": self.d, "counter": self.counter})
        self.optimizers = (
            torch.optim.Adam(self.g.parameters(), lr=config.lr, betas=(0.5, 0.9)),
            torch.optim.Adam(self.d.parameters(), lr=config.lr, betas=(0.5, 0.9)),
        )
        val_rng = np.random.default_rng(seed + 2)
        val_idx = np.asarray(val_idx, np.int64)
        val_idx = val_idx[lengths[val_idx] >= config.window][:MAX_VALIDATION]
        self.val = None
        if len(val_idx):
            starts = [int(val_rng.integers(0, lengths[i] - config.window + 1)) for i in val_idx]
            self.val = (
                self._windows(val_idx, starts),
                torch.as_tensor(prepared.actions[val_idx], device=device),
            )
            self.val_gen = seed + 3

    def _windows(self, clips: np.ndarray, starts: list[int]) -> Tensor:
        n = self.config.window
        return torch.stack([self.clips[i][s : s + n] for i, s in zip(clips, starts, strict=True)])

    def real(self, rng: np.random.Generator, n: int) -> tuple[Tensor, Tensor]:
        """``n`` real windows (n, N, F) and their actions (n,): action uniform, then one of its clips."""
        pick = rng.integers(0, len(self.actions), n)
        clips = np.array([rng.choice(self.by_action[p]) for p in pick])
        starts = [int(rng.integers(0, len(self.clips[i]) - self.config.window + 1)) for i in clips]
        actions = torch.as_tensor(self.actions[pick], device=self.g.mean.device)
        return self._windows(clips, starts), actions

    def fake(self, actions: Tensor, generator: torch.Generator, prefix: Tensor | None = None) -> Tensor:
        """Generated windows (B, N, F) of ``actions``: final cuts of tapes, or completions of ``prefix``."""
        config, g = self.config, self.g
        text = g.language(self.phrases)[actions]
        n = len(actions)
        z0 = torch.randn(n, config.noise_dim, generator=generator, device=text.device)
        if prefix is not None:
            z = g.noise(n, config.window - prefix.shape[1], generator)[0]
            frames, _ = g.rnn(text, z0, z, prefix=prefix)
            return frames
        tape = g.tape(text, z0, g.noise(n, config.tape - 1, generator))
        return final_cut(tape, config.window, generator) if config.final_cut else tape[:, : config.window]

    def _prefix(self, rng: np.random.Generator, actions: Tensor) -> Tensor | None:
        """Real prefixes for a batch of ``actions`` (with probability ``prefix_rate``, RNN only)."""
        config = self.config
        if config.generator != "rnn" or rng.random() >= config.prefix_rate:
            return None
        length = int(rng.integers(1, config.max_prefix + 1))
        clips = np.array(
            [rng.choice(self.by_action[int(np.flatnonzero(self.actions == a)[0])]) for a in actions.tolist()]
        )
        starts = [int(rng.integers(0, len(self.clips[i]) - config.window + 1)) for i in clips]
        return self._windows(clips, starts)[:, :length]

    def _critic_loss(
        self, real: Tensor, fake: Tensor, actions: Tensor, generator: torch.Generator
    ) -> tuple[Tensor, Tensor, Tensor]:
        d, config = self.d, self.config
        text = d.language(self.phrases)[actions]
        if config.shift:
            real, fake = shifted(real, generator), shifted(fake, generator)
        wasserstein = d(real, text).mean() - d(fake, text).mean()
        gp = gradient_penalty(d, real, fake, text, generator)
        return -wasserstein + config.gp_weight * gp, wasserstein, gp

    def step(self, epoch: int, rng: np.random.Generator, generator: torch.Generator) -> dict[str, float]:
        """``critic_steps`` critic updates, then one generator update."""
        config, d = self.config, self.d
        opt_g, opt_d = self.optimizers
        b, k = config.batch_size, config.critic_steps
        real, actions = self.real(rng, b * k)
        with torch.no_grad():
            fakes = self.fake(actions, generator, self._prefix(rng, actions))
        for i in range(k):
            part = slice(i * b, (i + 1) * b)
            critic, wasserstein, gp = self._critic_loss(real[part], fakes[part], actions[part], generator)
            opt_d.zero_grad(set_to_none=True)
            critic.backward()
            opt_d.step()
        for p in d.parameters():
            p.requires_grad_(False)
        _, actions = self.real(rng, b)
        fake = self.fake(actions, generator, self._prefix(rng, actions))
        if config.shift:
            fake = shifted(fake, generator)
        g_loss = -d(fake, d.language(self.phrases)[actions]).mean()
        opt_g.zero_grad(set_to_none=True)
        g_loss.backward()
        opt_g.step()
        for p in d.parameters():
            p.requires_grad_(True)
        self.counter.steps += 1
        return _floats((critic, wasserstein, gp, g_loss, g_loss))

    def validate(self) -> dict[str, float] | None:
        """The terms on the validation windows against as many generated windows of fixed noise."""
        if self.val is None:
            return None
        real, actions = self.val
        generator = torch.Generator(real.device).manual_seed(self.val_gen)
        with torch.no_grad():
            fake = self.fake(actions, generator)
        with torch.enable_grad():
            critic, wasserstein, gp = self._critic_loss(real, fake, actions, generator)
        with torch.no_grad():
            g_loss = -self.d(fake, self.d.language(self.phrases)[actions]).mean()
        return _floats((critic, wasserstein, gp, g_loss, g_loss))

    def epoch_columns(self, epoch: int) -> dict[str, float]:
        """The generator updates taken so far."""
        return {"steps": float(self.counter.steps)}


def _floats(values: tuple[Tensor, ...]) -> dict[str, float]:
    return {k: float(v.detach()) for k, v in zip(DVGAN_TERMS, values, strict=True)}
