"""MoDi (Raab et al. 2023): an unconditional skeleton-aware StyleGAN2 generator of motion, and its critic.

A motion is a tensor of entities × features × frames (``engine.model.modi_motion``): per joint a 6D
rotation, the root displacement and the foot contacts. The generator maps z → w (an MLP), starts from a
learned constant on the coarsest pooled skeleton (``engine.model.skeleton_conv``) and, level by level,
doubles the frames and refines the skeleton with modulated skeletal convolutions (one w per layer: W+),
adding per-level noise and summing per-level motion outputs (StyleGAN2's skip generator). The
discriminator mirrors it with residual blocks that pool the skeleton and halve the frames.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any, ClassVar

import torch
import torch.nn.functional as F  # noqa: N812
from torch import Tensor, nn

from engine.errors import ConfigError
from engine.model.config_base import ModelConfig
from engine.model.modi_motion import FEATURES, MotionCoder
from engine.model.skeleton_conv import (
    SkeletalConv,
    SkeletonLevel,
    lrelu,
    neighbourhood,
    pooling_mask,
    skeleton_hierarchy,
)
from engine.motion.contact import foot_joints
from engine.motion.skeleton import Skeleton

NOISE_MODES = ("const", "random", "none")


@dataclass
class ModiConfig(ModelConfig):
    """Sizes, losses and schedule of one MoDi model.

    ``levels`` hierarchy levels (the window must divide by 2^(levels−1)); the coarsest has ``channels``
    channels, each finer level half as many, never under ``min_channels``. ``distance``: how far (in
    edges) an in-place skeletal kernel sees. Losses (paper §3.4): non-saturating adversarial, R1 with
    weight ``r1_gamma`` every ``r1_every`` steps (lazy), foot contact ``touch_weight`` and consistency
    ``fcon_weight``; ``mixing`` is the share of style-mixed training samples; ``w_avg_beta`` the EMA rate
    of the mean w (truncation); ``ema_windows`` the half-life (windows) of the generator EMA that is
    shipped. ``n_actions``: actions of the training data (unused by the model, kept for labelling).
    ``foot_heights``: resting height (m) of each foot joint (``foot_joints`` order) in the training data,
    set when the model is saved; the decode-time foot clean-up needs them (empty: no clean-up).
    ``root_velocity``: the root as horizontal velocity and height (MoDi's), else as positions
    (``engine.model.modi_motion``).
    """

    n_joints: int
    n_actions: int = 0
    window: int = 64
    fps: float = 20.0
    levels: int = 5
    channels: int = 128
    min_channels: int = 16
    w_dim: int = 256
    mapping_layers: int = 4
    mapping_lr_mul: float = 0.01
    kernel: int = 3
    distance: int = 1
    lr: float = 0.002
    batch_size: int = 16
    r1_gamma: float = 10.0
    r1_every: int = 16
    touch_weight: float = 0.01
    fcon_weight: float = 1.0
    mixing: float = 0.9
    w_avg_beta: float = 0.995
    ema_windows: int = 10_000
    epoch_size: int = 2048
    epochs: int = 160
    foot_heights: tuple[float, ...] = ()
    root_velocity: bool = True
    arch: str = "modi"

    POSITIVE = ("n_joints", "window", "fps", "levels", "channels", "min_channels", "w_dim", "kernel", "lr")
    POSITIVE += ("mapping_layers", "mapping_lr_mul", "batch_size", "r1_every", "epoch_size")
    NON_NEGATIVE = ("n_actions", "distance", "r1_gamma", "touch_weight", "fcon_weight", "ema_windows")
    NON_NEGATIVE += ("epochs",)
    RATES = ("mixing", "w_avg_beta")
    ARCH = "modi"
    BEFORE: ClassVar[dict[str, Any]] = {"root_velocity": False}  # the first models stored root positions

    def check(self) -> None:
        """A window that halves ``levels − 1`` times; an odd kernel."""
        if self.window % 2 ** (self.levels - 1):
            raise ConfigError(f"window {self.window} does not halve {self.levels - 1} times")
        if self.kernel % 2 == 0:
            raise ConfigError(f"kernel must be odd, got {self.kernel}")
        try:
            self.foot_heights = tuple(float(h) for h in self.foot_heights)
        except (TypeError, ValueError) as exc:
            raise ConfigError(f"foot_heights must be a list of numbers ({exc})") from None

    def level_channels(self) -> list[int]:
        """Channels of each level, coarsest first."""
        return [max(self.min_channels, self.channels >> level) for level in range(self.levels)]

    def level_frames(self) -> list[int]:
        """Frames of each level, coarsest first."""
        return [self.window >> (self.levels - 1 - level) for level in range(self.levels)]


class EqualLinear(nn.Module):
    """Linear layer with equalised learning rate (weights N(0, 1/lr_mul²), scaled by lr_mul/√in)."""

    def __init__(self, n_in: int, n_out: int, bias_init: float = 0.0, lr_mul: float = 1.0):
        super().__init__()
        self.weight = nn.Parameter(torch.empty(n_out, n_in))
        self.bias = nn.Parameter(torch.empty(n_out))
        self.bias_init, self.lr_mul, self.scale = bias_init, lr_mul, lr_mul / math.sqrt(n_in)

    def forward(self, x: Tensor) -> Tensor:
        """``x`` (..., in) → (..., out)."""
        return F.linear(x, self.weight * self.scale, self.bias * self.lr_mul)

    @torch.no_grad()
    def reset_parameters(self, generator: torch.Generator) -> None:
        """Weights from ``generator``, biases at their initial value."""
        self.weight.normal_(generator=generator).div_(self.lr_mul)
        self.bias.fill_(self.bias_init / self.lr_mul)


class _StyledConv(nn.Module):
    """A skeletal convolution modulated by w through a learned affine map, with noise, bias, activation."""

    def __init__(self, conv: SkeletalConv, w_dim: int, frames: int, *, noise: bool, activate: bool):
        super().__init__()
        self.conv = conv
        self.affine = EqualLinear(w_dim, conv.c_in, bias_init=1.0)
        self.bias = nn.Parameter(torch.zeros(conv.e_out * conv.c_out))
        self.activate = activate
        self.noise_strength = nn.Parameter(torch.zeros(())) if noise else None
        if noise:
            self.register_buffer("noise_const", torch.zeros(1, conv.e_out, 1, frames))

    def forward(self, x: Tensor, w: Tensor, noise: str, generator: torch.Generator | None) -> Tensor:
        """Features of ``x`` under style vector ``w`` (B, w_dim)."""
        out = self.conv(x, self.affine(w))
        if self.noise_strength is not None and noise != "none":
            b, _, t = out.shape
            shape = (b, self.conv.e_out, 1, t)
            n = (
                self.noise_const
                if noise == "const"
                else torch.randn(shape, generator=generator, device=out.device, dtype=out.dtype)
            )
            out = (out.reshape(b, self.conv.e_out, -1, t) + self.noise_strength * n).view(b, -1, t)
        out = out + self.bias[:, None]
        return lrelu(out) if self.activate else out


def _hierarchy(config: ModiConfig, skeleton: Skeleton) -> list[SkeletonLevel]:
    """The pooled skeletons of ``skeleton``, coarsest first."""
    if skeleton.n_joints != config.n_joints:
        raise ConfigError(f"config has {config.n_joints} joints, the skeleton {skeleton.n_joints}")
    return skeleton_hierarchy(skeleton.parents, foot_joints(skeleton), config.levels)[::-1]


def _reset(module: nn.Module, generator: torch.Generator) -> None:
    """Re-draw every weight of ``module``'s layers from ``generator``."""
    for layer in module.modules():
        if isinstance(layer, SkeletalConv | EqualLinear):
            layer.reset_parameters(generator)


class ModiNetwork(nn.Module):
    """Mapping network and motion synthesis network on ``skeleton``; parameters from ``seed``.

    Style layers (``n_styles``): the coarsest level's convolution and motion output, then per finer
    level its up-scaling convolution, in-place convolution and motion output. ``style_levels[i]`` is the
    level of style layer i. ``w_avg`` (the running mean of mapped w) centres truncation.
    """

    def __init__(self, config: ModiConfig, skeleton: Skeleton, seed: int = 0):
        super().__init__()
        self.config = config
        self.coder = MotionCoder(skeleton, config.root_velocity)
        levels = _hierarchy(config, skeleton)
        channels, frames = config.level_channels(), config.level_frames()
        self.mapping = nn.ModuleList(
            EqualLinear(config.w_dim, config.w_dim, lr_mul=config.mapping_lr_mul)
            for _ in range(config.mapping_layers)
        )
        self.const = nn.Parameter(torch.empty(1, levels[0].n_entities * channels[0], frames[0]))
        w, k, d = config.w_dim, config.kernel, config.distance
        self.convs = nn.ModuleList()
        self.outputs = nn.ModuleList()
        self.style_levels: list[int] = []
        for level, skel in enumerate(levels):
            same = SkeletalConv(neighbourhood(skel, d), channels[level], channels[level], k, demodulate=True)
            if level:
                up = SkeletalConv(
                    pooling_mask(skel, levels[level - 1]).T,
                    channels[level - 1],
                    channels[level],
                    k,
                    demodulate=True,
                    resample="up",
                )
                self.convs.append(_StyledConv(up, w, frames[level], noise=True, activate=True))
                self.register_buffer(
                    f"unpool{level}",
                    torch.as_tensor(pooling_mask(skel, levels[level - 1]).T, dtype=torch.float32),
                    persistent=False,
                )
                self.style_levels.append(level)
            self.convs.append(_StyledConv(same, w, frames[level], noise=True, activate=True))
            out = SkeletalConv(neighbourhood(skel, 0), channels[level], FEATURES, 1, bias=False)
            self.outputs.append(_StyledConv(out, w, frames[level], noise=False, activate=False))
            self.style_levels += [level, level]
        self.n_levels = len(levels)
        self.register_buffer("w_avg", torch.zeros(config.w_dim))
        self.reset_parameters(torch.Generator().manual_seed(seed))

    @property
    def n_styles(self) -> int:
        """Style layers: the length of a W+ code."""
        return len(self.style_levels)

    @torch.no_grad()
    def reset_parameters(self, generator: torch.Generator) -> None:
        """Draw every weight, the constant input and the fixed noise from ``generator``."""
        _reset(self, generator)
        self.const.normal_(generator=generator)
        for conv in self.convs:
            conv.noise_const.normal_(generator=generator)

    def map(self, z: Tensor) -> Tensor:
        """w (B, w_dim) of z (B, w_dim): pixel norm, then the MLP."""
        x = z * torch.rsqrt(z.square().mean(1, keepdim=True) + 1e-8)
        for layer in self.mapping:
            x = lrelu(layer(x))
        return x

    def truncate(self, w: Tensor, psi: float) -> Tensor:
        """w pulled towards ``w_avg``: w_avg + ψ (w − w_avg); works on W (B, D) and W+ (B, S, D)."""
        return self.w_avg + psi * (w - self.w_avg)

    def broadcast(self, w: Tensor) -> Tensor:
        """W+ (B, n_styles, D) of w (B, D): the same w for every layer."""
        return w[:, None].expand(-1, self.n_styles, -1)

    def mix(self, w1: Tensor, w2: Tensor, split: int | Tensor) -> Tensor:
        """W+ codes whose layers of levels below ``split`` (a level, or one per code (B,)) take ``w1`` and
        the others ``w2`` (each (B, D)): split 0 is ``w2`` throughout, split ``n_levels`` is ``w1``."""
        split = torch.as_tensor(split, device=w1.device)
        if split.lt(0).any() or split.gt(self.n_levels).any():
            raise ConfigError(f"style mixing split must lie in 0..{self.n_levels}, got {split.tolist()}")
        levels = torch.tensor(self.style_levels, device=w1.device)
        first = levels[None, :] < split.reshape(-1, 1)
        return torch.where(first[:, :, None], self.broadcast(w1), self.broadcast(w2))

    def synthesize(
        self, ws: Tensor, noise: str = "const", generator: torch.Generator | None = None
    ) -> Tensor:
        """Normalised motion features (B, E, K, T) of W+ codes ``ws`` (B, n_styles, D) or w (B, D).

        ``noise``: "const" (the fixed noise drawn at initialisation, for repeatable decoding), "random"
        (from ``generator``) or "none".
        """
        if noise not in NOISE_MODES:
            raise ConfigError(f"unknown noise mode {noise!r}; choose one of {', '.join(NOISE_MODES)}")
        if ws.ndim == 2:
            ws = self.broadcast(ws)
        if ws.shape[1:] != (self.n_styles, self.config.w_dim):
            raise ConfigError(f"W+ codes must be (N, {self.n_styles}, {self.config.w_dim}), got {ws.shape}")
        x = self.const.expand(len(ws), -1, -1)
        conv, skip = iter(self.convs), None
        i = 0
        for level, output in enumerate(self.outputs):
            if level:
                x = next(conv)(x, ws[:, i], noise, generator)
                i += 1
            x = next(conv)(x, ws[:, i], noise, generator)
            y = output(x, ws[:, i + 1], noise, generator)
            i += 2
            if skip is not None:
                b, _, t = skip.shape
                skip = skip.reshape(b, -1, FEATURES, t)
                skip = torch.einsum("fc,bckt->bfkt", getattr(self, f"unpool{level}"), skip).flatten(1, 2)
                y = y + F.interpolate(skip, scale_factor=2.0, mode="linear", align_corners=False)
            skip = y
        b, _, t = skip.shape
        return skip.reshape(b, -1, FEATURES, t) * self.coder.feature_mask[:, :, None]

    def forward(
        self, z: Tensor, psi: float = 1.0, noise: str = "const", generator: torch.Generator | None = None
    ) -> Tensor:
        """Normalised motion features (B, E, K, T) of z (B, w_dim) with truncation ``psi``."""
        return self.synthesize(self.truncate(self.map(z), psi), noise, generator)


class ModiDiscriminator(nn.Module):
    """The critic: skeletal residual blocks from the finest level down to the coarsest, minibatch
    standard deviation, a convolution and two linear layers to one logit per motion."""

    def __init__(self, config: ModiConfig, skeleton: Skeleton, seed: int = 0):
        super().__init__()
        levels = _hierarchy(config, skeleton)
        channels, frames = config.level_channels(), config.level_frames()
        k, d = config.kernel, config.distance
        fine = levels[-1]
        self.from_motion = SkeletalConv(neighbourhood(fine, 0), FEATURES, channels[-1], 1)
        self.blocks = nn.ModuleList()
        for level in range(len(levels) - 1, 0, -1):
            skel, coarse = levels[level], levels[level - 1]
            pool = pooling_mask(skel, coarse)
            c, c_out = channels[level], channels[level - 1]
            self.blocks.append(
                nn.ModuleList([
                    SkeletalConv(neighbourhood(skel, d), c, c, k),
                    SkeletalConv(pool, c, c_out, k, resample="down"),
                    SkeletalConv(pool, c, c_out, 1, resample="down", bias=False),
                ])
            )  # fmt: skip
        top, c0 = levels[0], channels[0]
        self.n_top = top.n_entities
        self.final_conv = SkeletalConv(neighbourhood(top, d), c0 + 1, c0, k)
        self.final_fc = EqualLinear(top.n_entities * c0 * frames[0], c0)
        self.logit = EqualLinear(c0, 1)
        _reset(self, torch.Generator().manual_seed(seed))

    def forward(self, x: Tensor) -> Tensor:
        """Logits (B,) of normalised motion features (B, E, K, T)."""
        h = lrelu(self.from_motion(x.flatten(1, 2)))
        for conv, down, skip in self.blocks:
            h = (lrelu(down(lrelu(conv(h)))) + skip(h)) / math.sqrt(2.0)
        b, _, t = h.shape
        group = next(g for g in (4, 3, 2, 1) if b % g == 0)
        spread = h.reshape(group, -1, *h.shape[1:]).std(0, unbiased=False).mean((1, 2))
        spread = spread.repeat(group)[:, None, None, None].expand(-1, self.n_top, 1, t)
        h = torch.cat([h.reshape(b, self.n_top, -1, t), spread], 2).flatten(1, 2)
        h = lrelu(self.final_conv(h))
        return self.logit(lrelu(self.final_fc(h.reshape(b, -1))))[:, 0]
