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


REACH_SLACK = 1.5  # a path up to this many times the action's longest bank travel is still attempted
HEADING_ARC = 0.15  # the path's initial heading is measured over this fraction of its length


def path_heading(path_xz: np.ndarray) -> float:
    """Yaw (radians about +y, 0 = +z) of the path's initial direction, over its first ``HEADING_ARC``."""
    points = resample_path(path_xz, 41)
    ahead = points[max(1, round(HEADING_ARC * 40))] - points[0]
    return float(np.arctan2(ahead[0], ahead[1]))


def turn_floor(xz: np.ndarray, yaw: float) -> np.ndarray:
    """Floor points or vectors (..., 2) as x/z turned by ``yaw`` about +y (the facing convention)."""
    c, s = np.cos(yaw), np.sin(yaw)
    x, z = xz[..., 0], xz[..., 1]
    return np.stack([x * c + z * s, -x * s + z * c], axis=-1)


def check_reachable(loaded: LoadedModel, index: int, path_xz: np.ndarray) -> None:
    """ConfigError when ``path_xz`` is far longer than any of the action's bank codes travels in the
    model's window (an 8 m path in 3 s is no walk)."""
    bank = loaded.bank
    travel = np.linalg.norm(bank.ends[bank.indices_of(index)][:, [0, 2]], axis=1)
    length = float(np.linalg.norm(np.diff(np.asarray(path_xz, np.float64), axis=0), axis=1).sum())
    longest = float(travel.max()) if len(travel) else 0.0
    if length > REACH_SLACK * longest + 0.2:
        seconds = (loaded.window - 1) / loaded.fps
        name = loaded.action_names[index]
        raise ConfigError(
            f"unreachable for {name}: the path is {length:.1f} m long, but {name} codes in the bank "
            f"travel at most {longest:.1f} m in the model's {seconds:.1f} s; draw a shorter path or "
            "pick another action"
        )


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
    the path's last point. Generated motions start facing +z: the path is also tried turned so that it
    sets off along +z (and the result turned back), so a walker follows a path drawn in any direction
    facing where it goes; the frame whose starting codes fit better is optimised. A path much longer
    than the action ever travels in the model's window raises ConfigError (see ``check_reachable``).
    Adam runs on ``restarts`` codes at once, the best of the mode means,
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
    k = len(modes.weights_)
    if mode is not None and not 0 <= mode < k:
        raise ConfigError(f"action {loaded.action_names[index]!r} has modes 0..{k - 1}, got {mode}")
    path = np.asarray(path_xz, dtype=np.float64)
    check_reachable(loaded, index, resample_path(path, 64))
    requested = resample_path(path, loaded.window) - path[:1]
    heading = path_heading(path)
    mean, cov = (
        (modes.conventional_mean_, modes.conventional_cov_)
        if mode is None
        else (modes.means_[mode], modes.covariances_[mode])
    )
    dim = len(mean)

    members = bank.indices_of(index)
    if mode is not None:
        members = members[np.asarray(modes.labels_) == mode]
    rng = np.random.default_rng(seed)
    drawn, _ = modes.sample(restarts, rng, strategy="conventional" if mode is None else "mode", mode=mode)
    means = modes.means_ if mode is None else modes.means_[mode : mode + 1]
    candidates = np.concatenate([means, bank.codes[members], drawn]).astype(np.float32)

    model = loaded.model
    device = next(model.parameters()).device
    end = None
    if loaded.config.use_end_location:
        height = float(np.median(bank.ends[bank.indices_of(index), 1]))
        end = np.array([requested[-1, 0], height, requested[-1, 1]], dtype=np.float32)
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

    best_frame = None
    for yaw in (0.0, heading) if abs(heading) > 1e-3 else (0.0,):
        target_np = turn_floor(requested, -yaw)
        if end is not None:
            end = np.array([target_np[-1, 0], end[1], target_np[-1, 1]], dtype=np.float32)
        target = torch.as_tensor(target_np, dtype=torch.float32, device=device)
        with torch.inference_mode():
            loss0, error0 = objective(torch.as_tensor(candidates, device=device))
        if best_frame is None or float(loss0.min()) < best_frame[0]:
            best_frame = (float(loss0.min()), yaw, target_np, target, end, loss0, error0)
    _, yaw, target_np, target, end, loss0, error0 = best_frame
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
    turned = joints[0].copy()
    turned[..., [0, 2]] = turn_floor(joints[0][..., [0, 2]].astype(np.float64), yaw)
    world_end = None
    if end is not None:
        world_end = end.copy()
        world_end[[0, 2]] = turn_floor(end[[0, 2]].astype(np.float64), yaw)
    motion = generated_motion(
        loaded, turned + offset, code, index, world_end, mode, seed, origin=offset.tolist(),
        path_error_m=error, heading=yaw,
    )  # fmt: skip
    log.info("follow_path: error %.3f m -> %.3f m (turned %.0f°)", initial_error, error, np.degrees(yaw))
    return PathResult(code, motion, error, world_end, initial_error)
