"""Find the code whose generated root trajectory follows a path drawn on the floor."""

from __future__ import annotations

import logging
from dataclasses import dataclass

import numpy as np
import torch

from engine.errors import ConfigError
from engine.generate._decode import action_index, decode_array, generated_motion
from engine.modelio import LoadedModel
from engine.motion.motion import Motion

log = logging.getLogger(__name__)


@dataclass(frozen=True, eq=False)
class PathResult:
    """The outcome of :func:`follow_path`.

    Parameters
    ----------
    code : (D,) float32 code found.
    motion : its decoded motion, moved so that it starts at the path's first point.
    path_error_m : mean distance (metres) between the generated root path and the path, on the floor.
    end : (3,) float32 end location used (relative to the start), or None for models without one.
    initial_error_m : the same error for the best starting code, before optimisation.
    """

    code: np.ndarray
    motion: Motion
    path_error_m: float
    end: np.ndarray | None
    initial_error_m: float


def resample_path(path_xz: np.ndarray, n: int) -> np.ndarray:
    """(n, 2) points evenly spaced by arc length along the polyline ``path_xz`` (K, 2)."""
    path = np.asarray(path_xz, dtype=np.float64)
    if path.ndim != 2 or path.shape[1] != 2 or len(path) < 2 or not np.all(np.isfinite(path)):
        raise ConfigError(f"a path must be (K >= 2, 2) finite x/z points, got shape {np.shape(path_xz)}")
    arc = np.concatenate([[0.0], np.cumsum(np.linalg.norm(np.diff(path, axis=0), axis=1))])
    if arc[-1] <= 0:
        raise ConfigError("a path must have a non-zero length")
    s = np.linspace(0.0, arc[-1], n)
    return np.stack([np.interp(s, arc, path[:, 0]), np.interp(s, arc, path[:, 1])], axis=1)


def _floor_error(trajectory: torch.Tensor, target: torch.Tensor) -> torch.Tensor:
    """(R,) mean floor distance between trajectories (R, T, 3) and the target (T, 2)."""
    return torch.linalg.vector_norm(trajectory[..., [0, 2]] - target, dim=-1).mean(dim=-1)


def follow_path(
    loaded: LoadedModel,
    path_xz: np.ndarray,
    action: int | str,
    mode: int | None = None,
    steps: int = 150,
    seed: int = 0,
    restarts: int = 4,
    lr: float = 0.05,
    prior_weight: float = 1.0,
) -> PathResult:
    """Optimise a code of ``action`` (optionally of one mode) so that its root path follows ``path_xz``.

    ``path_xz`` (K, 2) is in metres on the floor; it is resampled by arc length to the model's T
    frames and shifted to start at the origin, where generated motions start. The end location is
    the path's last point. Adam runs on ``restarts`` codes at once, the best of the mode means,
    bank codes and ``seed``-drawn samples of the chosen Gaussian (the mode's, or the action's single
    Gaussian). The objective is the mean squared floor distance plus ``prior_weight`` times the
    squared Mahalanobis distance in excess of D (its expectation), over D: free inside the
    distribution's typical set, pulled back outside it.
    """
    if steps < 0 or restarts < 1:
        raise ConfigError(f"need steps >= 0 and restarts >= 1, got {steps}, {restarts}")
    index = action_index(loaded, action)
    bank = loaded.bank
    modes = None if bank is None else bank.modes.get(index)
    if modes is None:
        raise ConfigError(f"{loaded.path}: following a path needs the action's modes in the latent bank")
    k = len(modes.weights)
    if mode is not None and not 0 <= mode < k:
        raise ConfigError(f"action {loaded.action_names[index]!r} has modes 0..{k - 1}, got {mode}")
    path = np.asarray(path_xz, dtype=np.float64)
    target_np = resample_path(path, loaded.window) - path[:1]
    mean, cov = (
        (modes.conventional_mean, modes.conventional_cov)
        if mode is None
        else (modes.means[mode], modes.covariances[mode])
    )
    dim = len(mean)

    members = bank.indices_of(index)
    if mode is not None:
        members = members[np.asarray(modes.labels) == mode]
    rng = np.random.default_rng(seed)
    drawn, _ = modes.sample(restarts, rng, strategy="conventional" if mode is None else "mode", mode=mode)
    means = modes.means if mode is None else modes.means[mode : mode + 1]
    candidates = np.concatenate([means, bank.codes[members], drawn]).astype(np.float32)

    model = loaded.model
    device = next(model.parameters()).device
    end = None
    if loaded.config.use_end_location:
        height = float(np.median(bank.ends[bank.indices_of(index), 1]))
        end = np.array([target_np[-1, 0], height, target_np[-1, 1]], dtype=np.float32)
    target = torch.as_tensor(target_np, dtype=torch.float32, device=device)
    mu = torch.as_tensor(mean, dtype=torch.float32, device=device)
    precision = torch.as_tensor(
        np.linalg.inv(np.asarray(cov, np.float64) + 1e-6 * np.eye(dim)), dtype=torch.float32, device=device
    )

    def objective(z: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
        actions = torch.full((len(z),), index, dtype=torch.long, device=device)
        ends = None if end is None else torch.as_tensor(end, device=device).expand(len(z), 3)
        trajectory = model.trajectory(z, actions, ends)
        sq = (trajectory[..., [0, 2]] - target).pow(2).sum(dim=-1).mean(dim=-1)
        d = z - mu
        excess = torch.relu(torch.einsum("bi,ij,bj->b", d, precision, d) - dim) / dim
        return sq + prior_weight * excess, _floor_error(trajectory, target)

    with torch.inference_mode():
        loss0, error0 = objective(torch.as_tensor(candidates, device=device))
    order = torch.argsort(loss0)[:restarts]
    initial_error = float(error0[order[0]])
    z = torch.as_tensor(candidates, device=device)[order].clone().requires_grad_(True)
    best_loss, best_z = loss0[order].clone(), z.detach().clone()
    optimiser = torch.optim.Adam([z], lr=lr)
    for _ in range(steps):
        loss, _ = objective(z)
        (grad,) = torch.autograd.grad(loss.sum(), z)
        with torch.no_grad():
            better = loss < best_loss
            best_loss = torch.where(better, loss, best_loss)
            best_z[better] = z[better]
        z.grad = grad
        optimiser.step()
    with torch.inference_mode():
        loss, _ = objective(z)
        better = loss < best_loss
        best_loss = torch.where(better, loss, best_loss)
        best_z[better] = z[better]
    code = best_z[torch.argmin(best_loss)].cpu().numpy().astype(np.float32)

    joints, trajectory = decode_array(
        loaded, code[None], np.array([index]), None if end is None else end[None]
    )
    error = float(np.linalg.norm(trajectory[0][:, [0, 2]] - target_np, axis=1).mean())
    offset = np.array([path[0, 0], 0.0, path[0, 1]], dtype=np.float32)
    motion = generated_motion(
        loaded, joints[0] + offset, code, index, end, mode, seed, origin=offset.tolist(), path_error_m=error
    )
    log.info("follow_path: error %.3f m -> %.3f m", initial_error, error)
    return PathResult(code, motion, error, end, initial_error)
