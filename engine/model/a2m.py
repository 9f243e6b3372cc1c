"""Action2Motion-style baseline: a conditional temporal VAE on joint positions (Guo et al. 2020, w/o Lie).

Per frame t (c_t = t/T, a the action one-hot, p_t the flattened pose):
posterior q(z_t | p_{1:t}) = GRU_φ(E(p_t, a, c_t)),
learned prior p(z_t | p_{1:t-1}) = GRU_ψ(E(p_{t-1}, a, c_t)),
generator p̂_t = D(GRU_θ(E(p_{t-1}, a, c_t, z_t))); p_0 = 0. Encoders and decoder are single linear layers.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import torch
import torch.nn.functional as F  # noqa: N812
from torch import Tensor, nn

from engine.model.config_base import ModelConfig

A2M_LOSS_TERMS = ("recon", "kl")


@dataclass
class A2mConfig(ModelConfig):
    """Sizes, loss weight and training schedule of one Action2Motion baseline.

    Defaults follow the paper's HumanAct12 setup (GRU hidden 128, z 30 per frame, a 2-layer generator GRU,
    λ_KL = 0.01, teacher forcing for a whole batch with probability 0.6, Adam 2e-4 with weight decay 1e-5,
    batch 128); epochs are of ``epoch_size`` class-balanced windows, like ODMO's, so budgets compare.
    """

    n_actions: int
    n_joints: int
    window: int = 60
    fps: float = 20.0
    hidden: int = 128
    latent_dim: int = 30
    gen_layers: int = 2
    kl_weight: float = 0.01
    tf_rate: float = 0.6
    lr: float = 2e-4
    weight_decay: float = 1e-5
    batch_size: int = 128
    epoch_size: int = 2048
    epochs: int = 300
    grad_clip: float = 1.0
    arch: str = "a2m"

    POSITIVE = ("n_actions", "n_joints", "window", "fps", "hidden", "latent_dim", "gen_layers", "lr")
    POSITIVE += ("batch_size", "epoch_size", "grad_clip")
    NON_NEGATIVE = ("kl_weight", "weight_decay", "epochs")
    RATES = ("tf_rate",)
    ARCH = "a2m"


class _GaussianGru(nn.Module):
    """Linear encoder → 1-layer GRU → mean and log-variance of a diagonal Gaussian."""

    def __init__(self, n_in: int, hidden: int, latent: int):
        super().__init__()
        self.encoder = nn.Linear(n_in, hidden)
        self.gru = nn.GRU(hidden, hidden, 1, batch_first=True)
        self.mu = nn.Linear(hidden, latent)
        self.logvar = nn.Linear(hidden, latent)

    def forward(self, x: Tensor, h: Tensor | None = None) -> tuple[Tensor, Tensor, Tensor]:
        """Mean, log-variance (B, S, Z) and the GRU state of inputs (B, S, in)."""
        out, h = self.gru(self.encoder(x), h)
        return self.mu(out), self.logvar(out), h


class _PoseGru(nn.Module):
    """Linear encoder → multi-layer GRU → linear decoder to a pose."""

    def __init__(self, n_in: int, hidden: int, layers: int, n_out: int):
        super().__init__()
        self.encoder = nn.Linear(n_in, hidden)
        self.gru = nn.GRU(hidden, hidden, layers, batch_first=True)
        self.decoder = nn.Linear(hidden, n_out)

    def forward(self, x: Tensor, h: Tensor | None = None) -> tuple[Tensor, Tensor]:
        """Poses (B, S, out) and the GRU state of inputs (B, S, in)."""
        out, h = self.gru(self.encoder(x), h)
        return self.decoder(out), h


@dataclass
class A2mOutput:
    """One pass over a batch: predicted joints (B, T, J, 3), posterior and prior Gaussians (B, T, Z)."""

    joints: Tensor
    mu_q: Tensor
    logvar_q: Tensor
    mu_p: Tensor
    logvar_p: Tensor


class A2mModel(nn.Module):
    """The Action2Motion conditional temporal VAE; parameters initialised from an explicit seed."""

    def __init__(self, config: A2mConfig, seed: int = 0):
        super().__init__()
        self.config = config
        pose = config.n_joints * 3
        cond = config.n_actions + 1
        with torch.device("meta"):  # construction never draws from torch's global RNG
            self.posterior = _GaussianGru(pose + cond, config.hidden, config.latent_dim)
            self.prior = _GaussianGru(pose + cond, config.hidden, config.latent_dim)
            self.generator = _PoseGru(pose + cond + config.latent_dim, config.hidden, config.gen_layers, pose)
        self.to_empty(device="cpu")
        self.reset_parameters(torch.Generator().manual_seed(seed))

    @torch.no_grad()
    def reset_parameters(self, generator: torch.Generator) -> None:
        """Re-initialise every weight like torch's defaults, drawing only from ``generator``."""
        for module in self.modules():
            if isinstance(module, nn.Linear):
                bound = 1.0 / math.sqrt(module.in_features)
            elif isinstance(module, nn.GRU):
                bound = 1.0 / math.sqrt(module.hidden_size)
            else:
                continue
            for p in module.parameters(recurse=False):
                p.uniform_(-bound, bound, generator=generator)

    def _condition(self, actions: Tensor) -> Tensor:
        """(B, T, C + 1): the action one-hot and the time counter c_t = t/T, t = 1..T."""
        t = self.config.window
        onehot = F.one_hot(actions.long(), self.config.n_actions).float()
        steps = torch.arange(1, t + 1, dtype=torch.float32, device=actions.device) / t
        return torch.cat(
            [onehot.unsqueeze(1).expand(-1, t, -1), steps.view(1, t, 1).expand(len(actions), -1, -1)], 2
        )

    def _rollout(
        self, cond: Tensor, z: Tensor | None, generator: torch.Generator | None
    ) -> tuple[Tensor, Tensor, Tensor]:
        """Free-running poses (B, T, P) and prior mean / log-variance (B, T, Z).

        Each step feeds the previous generated pose; z_t is taken from ``z`` (B, T, Z) or drawn from the
        prior with ``generator``.
        """
        b, t = cond.shape[:2]
        prev = cond.new_zeros(b, 1, self.config.n_joints * 3)
        h_prior = h_gen = None
        poses, mus, logvars = [], [], []
        for i in range(t):
            c = cond[:, i : i + 1]
            mu_p, logvar_p, h_prior = self.prior(torch.cat([prev, c], 2), h_prior)
            if z is None:
                eps = torch.randn(mu_p.shape, generator=generator, device=mu_p.device)
                z_t = mu_p + torch.exp(0.5 * logvar_p) * eps
            else:
                z_t = z[:, i : i + 1]
            prev, h_gen = self.generator(torch.cat([prev, c, z_t], 2), h_gen)
            poses.append(prev)
            mus.append(mu_p)
            logvars.append(logvar_p)
        return torch.cat(poses, 1), torch.cat(mus, 1), torch.cat(logvars, 1)

    def forward(
        self, joints: Tensor, actions: Tensor, *, teacher: bool, generator: torch.Generator | None
    ) -> A2mOutput:
        """Reconstruct real windows ``joints`` (B, T, J, 3) of ``actions`` (B,).

        ``teacher``: previous poses are the real ones (one vectorised pass) instead of the generated ones.
        With a ``generator`` z_t is sampled from the posterior (training); without, its mean is used.
        """
        b, t, j, _ = joints.shape
        x = joints.reshape(b, t, j * 3)
        cond = self._condition(actions)
        mu_q, logvar_q, _ = self.posterior(torch.cat([x, cond], 2))
        z = mu_q
        if generator is not None:
            z = mu_q + torch.exp(0.5 * logvar_q) * torch.randn(
                mu_q.shape, generator=generator, device=x.device
            )
        if teacher:
            prev = torch.cat([x.new_zeros(b, 1, j * 3), x[:, :-1]], 1)
            mu_p, logvar_p, _ = self.prior(torch.cat([prev, cond], 2))
            pred, _ = self.generator(torch.cat([prev, cond, z], 2))
        else:
            pred, mu_p, logvar_p = self._rollout(cond, z, None)
        return A2mOutput(pred.reshape(b, t, j, 3), mu_q, logvar_q, mu_p, logvar_p)

    def sample(self, actions: Tensor, generator: torch.Generator) -> Tensor:
        """Motions (B, T, J, 3) of ``actions`` (B,); every z_t is drawn from the learned prior."""
        b = len(actions)
        poses, _, _ = self._rollout(self._condition(actions), None, generator)
        return poses.reshape(b, self.config.window, self.config.n_joints, 3)


def a2m_losses(config: A2mConfig, joints: Tensor, mask: Tensor, out: A2mOutput) -> dict[str, Tensor]:
    """``recon`` (mean squared joint error), ``kl`` (KL(q ‖ p) summed over z) and ``total``, over real frames.

    ``joints`` (B, T, J, 3) are the targets and ``mask`` (B, T) marks real (unpadded) frames.
    """
    weight = mask.to(joints.dtype)
    denom = weight.sum().clamp_min(1.0)
    recon = (((out.joints - joints) ** 2).mean(dim=(2, 3)) * weight).sum() / denom
    var_q, var_p = out.logvar_q.exp(), out.logvar_p.exp()
    kl_t = 0.5 * (out.logvar_p - out.logvar_q + (var_q + (out.mu_q - out.mu_p) ** 2) / var_p - 1.0).sum(2)
    kl = (kl_t * weight).sum() / denom
    return {"recon": recon, "kl": kl, "total": recon + config.kl_weight * kl}
