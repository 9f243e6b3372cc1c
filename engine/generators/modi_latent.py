"""MoDi's latent operations on its network: sampling W with truncation, decoding W and W+ codes, style
mixing, crowds and inversion of a motion by optimisation (MoDi paper §4, re-implemented).

Codes travel as float32 arrays: a W code is (D,), a W+ code (S·D,) (its S style layers flattened, so
that every code of a bank has one row). Decoded joints are canonical: frame-0 root above the origin,
facing +z, root height relative to frame 0 (the caller lifts them to display height).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
import torch

from engine.errors import CancelledError, ConfigError
from engine.generators.base import check_psi
from engine.model.modi import ModiNetwork

SPACES = ("W", "W+")
#: Codes decoded per forward pass.
DECODE_BATCH = 256
#: Adam steps and learning rate of an inversion (W+ converges in about 200 on the bundled model).
INVERT_STEPS = 300
INVERT_LR = 0.03


def _device(net: ModiNetwork) -> torch.device:
    return net.w_avg.device


def sample_w(net: ModiNetwork, n: int, seed: int, psi: float = 1.0) -> np.ndarray:
    """(n, D) W codes of n z drawn from N(0, I) with ``seed`` (on the CPU, so any device gives the same
    codes), truncated towards the mean w by ``psi`` (1: none, 0: the mean)."""
    if n < 1:
        raise ConfigError(f"n must be at least 1, got {n}")
    check_psi(psi)
    z = torch.randn(n, net.config.w_dim, generator=torch.Generator().manual_seed(int(seed)))
    with torch.inference_mode():
        w = net.truncate(net.map(z.to(_device(net))), psi)
    return w.cpu().numpy().astype(np.float32)


def as_wplus(net: ModiNetwork, codes: np.ndarray) -> torch.Tensor:
    """W+ tensor (N, S, D) of W codes (N, D) or flattened W+ codes (N, S·D); ConfigError otherwise."""
    x = np.asarray(codes, dtype=np.float32)
    if x.ndim == 1:
        x = x[None]
    s, d = net.n_styles, net.config.w_dim
    if x.ndim != 2 or x.shape[1] not in (d, s * d) or not np.all(np.isfinite(x)):
        raise ConfigError(f"codes must be finite W (N, {d}) or W+ (N, {s * d}) rows, got {np.shape(codes)}")
    t = torch.from_numpy(np.ascontiguousarray(x)).to(_device(net))
    return net.broadcast(t) if x.shape[1] == d else t.reshape(len(x), s, d)


def decode_codes(net: ModiNetwork, codes: np.ndarray, psi: float = 1.0) -> tuple[np.ndarray, np.ndarray]:
    """Canonical joints (N, T, J, 3) and foot-contact values (N, T, F; > 0.5 planted) of W or W+ codes,
    truncated by ``psi``, with the network's fixed noise (the same code, the same motion)."""
    check_psi(psi)
    ws = as_wplus(net, codes)
    joints, contacts = [], []
    with torch.inference_mode():
        for lo in range(0, len(ws), DECODE_BATCH):
            x = net.synthesize(net.truncate(ws[lo : lo + DECODE_BATCH], psi))
            joints.append(net.coder.joints(x).cpu().numpy())
            contacts.append(net.coder.split(x)[2].cpu().numpy())
    return np.concatenate(joints).astype(np.float32), np.concatenate(contacts).astype(np.float32)


def mix_codes(net: ModiNetwork, code_a: np.ndarray, code_b: np.ndarray, split: int) -> np.ndarray:
    """The flattened W+ code (S·D,) whose style layers of levels coarser than ``split`` come from
    ``code_a`` and the others from ``code_b`` (0: all ``code_b``; the number of levels: all ``code_a``).

    The coarse levels carry the body's overall movement, the fine ones its details (paper §4.2)."""
    if not 0 <= int(split) <= net.n_levels:
        raise ConfigError(f"style mixing split must lie in 0..{net.n_levels}, got {split}")
    a, b = as_wplus(net, code_a), as_wplus(net, code_b)
    if len(a) != 1 or len(b) != 1:
        raise ConfigError("style mixing takes one code on each side")
    levels = torch.tensor(net.style_levels, device=a.device)
    mixed = torch.where((levels < int(split))[None, :, None], a, b)
    return mixed.reshape(-1).cpu().numpy().astype(np.float32)


def crowd_codes(code: np.ndarray, n: int, sigma: float, seed: int) -> np.ndarray:
    """(n, len(code)) codes drawn from N(code, σ² I): a crowd of variations of one motion (paper §4.4)."""
    if n < 1 or not np.isfinite(sigma) or sigma < 0:
        raise ConfigError(f"a crowd needs n >= 1 and a finite sigma >= 0, got n={n}, sigma={sigma}")
    centre = np.asarray(code, dtype=np.float32).reshape(-1)
    if not np.all(np.isfinite(centre)):
        raise ConfigError("the crowd's code must be finite")
    noise = np.random.default_rng(seed).standard_normal((n, len(centre)))
    return (centre + np.float32(sigma) * noise).astype(np.float32)


@dataclass(frozen=True)
class Inversion:
    """Codes found for target motions (N, D) in W or (N, S·D) in W+, and each target's mean joint error
    (m) over its real frames after the last step."""

    codes: np.ndarray
    errors: np.ndarray
    space: str
    steps: int


def invert(
    net: ModiNetwork,
    targets: np.ndarray,
    mask: np.ndarray | None = None,
    space: str = "W+",
    steps: int = INVERT_STEPS,
    lr: float = INVERT_LR,
    progress: Callable[[int, int, float], None] | None = None,
    cancel: Callable[[], bool] | None = None,
) -> Inversion:
    """Codes whose motions match canonical target joints (N, T, J, 3) on the frames ``mask`` (N, T) holds.

    Adam from the mean w minimises the mean squared joint distance (forward kinematics of the decoded
    rotations and root), in W (one w for every layer) or W+ (one per layer). ``progress(step, steps,
    mean error in m)`` is called every step; ``cancel()`` returning True raises CancelledError.
    """
    if space not in SPACES:
        raise ConfigError(f"unknown inversion space {space!r}; choose one of {', '.join(SPACES)}")
    if steps < 1 or not lr > 0:
        raise ConfigError(f"inversion needs steps >= 1 and lr > 0, got {steps}, {lr}")
    target = np.asarray(targets, dtype=np.float32)
    t, j = net.config.window, net.config.n_joints
    if target.ndim != 4 or target.shape[1:] != (t, j, 3) or not np.all(np.isfinite(target)):
        raise ConfigError(f"targets must be finite (N, {t}, {j}, 3) joints, got {np.shape(targets)}")
    keep = np.ones(target.shape[:2], bool) if mask is None else np.asarray(mask, bool)
    if keep.shape != target.shape[:2] or not keep.any(axis=1).all():
        raise ConfigError("the inversion mask must be (N, T) with a real frame in every row")
    device = _device(net)
    goal = torch.from_numpy(target).to(device)
    weight = torch.from_numpy(keep.astype(np.float32)).to(device)[:, :, None]
    start = net.w_avg.detach().expand(len(target), *([net.n_styles] if space == "W+" else []), -1)
    code = start.clone().requires_grad_(True)
    optimiser = torch.optim.Adam([code], lr=lr)
    frozen = [p.requires_grad for p in net.parameters()]
    for p in net.parameters():
        p.requires_grad_(False)
    try:
        for step in range(1, steps + 1):
            if cancel is not None and cancel():
                raise CancelledError("inversion cancelled")
            distance = (net.coder.joints(net.synthesize(code)) - goal).norm(dim=-1)
            loss = (distance.square() * weight).sum() / (weight.sum() * j)
            optimiser.zero_grad(set_to_none=True)
            loss.backward()
            optimiser.step()
            if progress is not None:
                progress(step, steps, float((distance.detach() * weight).sum() / (weight.sum() * j)))
    finally:
        for p, flag in zip(net.parameters(), frozen, strict=True):
            p.requires_grad_(flag)
    with torch.no_grad():
        distance = (net.coder.joints(net.synthesize(code)) - goal).norm(dim=-1)
        errors = ((distance * weight).sum((1, 2)) / (weight.sum((1, 2)) * j)).cpu().numpy()
    found = code.detach().reshape(len(target), -1).cpu().numpy().astype(np.float32)
    return Inversion(found, errors.astype(np.float32), space, steps)
