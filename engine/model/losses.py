"""ODMO training losses; every frame-level term is masked so padded frames never count."""

from __future__ import annotations

import torch
from torch import Tensor

from engine.model.config import OdmoConfig

LOSS_TERMS = ("recon", "traj", "consistency", "contrastive", "prior")


def masked_mse(pred: Tensor, target: Tensor, mask: Tensor, axis_weights: Tensor | None = None) -> Tensor:
    """Mean squared error over real frames only.

    Parameters
    ----------
    pred, target : (B, T, ..., 3) tensors.
    mask : (B, T) bool or 0/1, True for real frames.
    axis_weights : optional (3,) weight of each of x, y, z.
    """
    err = (pred - target).square()
    if axis_weights is not None:
        err = err * axis_weights
    per_frame = err.flatten(2).mean(dim=2)
    m = mask.to(per_frame.dtype)
    return (per_frame * m).sum() / m.sum().clamp(min=1.0)


def contrastive_loss(
    mu_a: Tensor, mu_b: Tensor, same: Tensor, alpha: float, pull_weight: float = 1.0
) -> Tensor:
    """Pairwise loss on code means (B, D): same action pull_weight·0.5·relu(d² − 0.25), different
    0.5·relu(α − d)²."""
    d2 = (mu_a - mu_b).square().sum(dim=1)
    pull = pull_weight * 0.5 * torch.relu(d2 - 0.25)
    push = 0.5 * torch.relu(alpha - torch.sqrt(d2 + 1e-12)).square()
    return torch.where(same, pull, push).mean()


def prior_loss(logvar: Tensor, sigma2: float) -> Tensor:
    """Posterior prior −log det Σ + tr Σ / σ² (diagonal Σ), shifted to 0 at Σ = σ²I, per dimension."""
    ratio = logvar.exp() / sigma2
    return (ratio - logvar + torch.log(torch.as_tensor(sigma2)) - 1.0).mean()


def odmo_losses(
    config: OdmoConfig,
    *,
    joints: Tensor,
    trajectory: Tensor,
    mask: Tensor,
    pred_joints: Tensor,
    pred_trajectory: Tensor,
    mu: Tensor,
    logvar: Tensor,
    same: Tensor,
    root: int,
) -> dict[str, Tensor]:
    """Every loss term and the weighted ``total``.

    Parameters
    ----------
    joints, pred_joints : (2B, T, J, 3) real and generated joints of B anchors followed by their B partners.
    trajectory, pred_trajectory : (2B, T, 3) real and generated root paths.
    mask : (2B, T) real frames.
    mu, logvar : (2B, D) code posteriors.
    same : (B,) True where anchor i and partner i share an action.
    root : index of the root joint.
    """
    axis = torch.tensor([1.0, config.traj_y_weight, 1.0], device=joints.device)
    b = same.shape[0]
    terms = {
        "recon": masked_mse(pred_joints, joints, mask),
        "traj": masked_mse(pred_trajectory, trajectory, mask, axis),
        "consistency": masked_mse(pred_joints[:, :, root], pred_trajectory, mask),
        "contrastive": contrastive_loss(mu[:b], mu[b:], same, config.alpha, config.contrastive_pull),
        "prior": prior_loss(logvar, config.prior_sigma2),
    }
    weights = {
        "recon": config.w_recon,
        "traj": config.w_traj,
        "consistency": config.w_consistency,
        "contrastive": config.w_contrastive,
        "prior": config.w_prior,
    }
    terms["total"] = sum(weights[k] * terms[k] for k in LOSS_TERMS if weights[k] > 0)
    return terms
