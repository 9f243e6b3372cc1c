"""MoDi's losses (paper §3.4): non-saturating adversarial, R1 on real motions, and the foot-contact terms."""

from __future__ import annotations

from collections.abc import Callable

import torch
import torch.nn.functional as F  # noqa: N812
from torch import Tensor

from engine.model.modi_motion import MotionCoder

#: MoDi's contact activation s(c) = sigmoid(12 (c − ½)): a label value of 1 reads as contact.
CONTACT_SHARPNESS = 12.0


def d_adversarial(real_logits: Tensor, fake_logits: Tensor) -> Tensor:
    """−E log D(m) − E log(1 − D(G(z))) (eq. 3), D = sigmoid of the logits."""
    return F.softplus(-real_logits).mean() + F.softplus(fake_logits).mean()


def g_adversarial(fake_logits: Tensor) -> Tensor:
    """Non-saturating −E log D(G(z)) (eq. 2)."""
    return F.softplus(-fake_logits).mean()


def r1_penalty(critic: Callable[[Tensor], Tensor], real: Tensor) -> Tensor:
    """E ‖∇_m D(m)‖² over real motions ``real`` (eq. 7), differentiable for the critic's update."""
    real = real.detach().requires_grad_(True)
    (grad,) = torch.autograd.grad(critic(real).sum(), real, create_graph=True)
    return grad.square().flatten(1).sum(1).mean()


def contact_activation(contacts: Tensor) -> Tensor:
    """s(c) of contact values: near 1 where the motion says a foot is planted."""
    return torch.sigmoid(CONTACT_SHARPNESS * (contacts - 0.5))


def contact_losses(coder: MotionCoder, x: Tensor, fps: float) -> tuple[Tensor, Tensor]:
    """``touch`` = E[−log s(c)] (eq. 4) and ``fcon`` = E[‖foot velocity‖² · s(c)] (eq. 5, m²/s², the
    velocity of each foot joint by forward kinematics) of network features ``x`` (B, E, K, T)."""
    feet, contacts = coder.feet_and_contacts(x)
    touch = F.softplus(-CONTACT_SHARPNESS * (contacts - 0.5)).mean()
    velocity = feet.diff(dim=1) * fps
    fcon = (velocity.square().sum(-1) * contact_activation(contacts[:, 1:])).mean()
    return touch, fcon
