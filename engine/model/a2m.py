"""Action2Motion (Guo et al. 2020): a conditional temporal VAE with a learned prior, on Lie-algebra poses.

Per frame t (c_t = t/T, a the action one-hot, p_t the flattened joint positions):
posterior q(z_t | p_{1:t}) = GRU_φ(E(p_t, a, c_t)),
learned prior p(z_t | p_{1:t-1}) = GRU_ψ(E(p_{t-1}, a, c_t)),
generator (w_t, J_0,t) = D(GRU_θ(E(p_{t-1}, a, c_t, z_t))), p̂_t = Γ(w_t, J_0,t); p_0 = 0.
``pose_rep = "lie"``: w_t are so(3) axis-angle vectors of every joint with children, Γ the forward
kinematics of the data's fixed skeleton (``offsets`` scaled by ``bone_scale`` at decode time: the paper's
body-shape control) and J_0,t the root translation. ``pose_rep = "joints"``: the paper's "w/o Lie"
ablation, D emits the joint positions directly. Encoders and decoders are single linear layers.

The code space (``code_dim`` > 0): principal components of the training clips' posterior-mean sequences
z_1..z_T, stored with the weights (``code_mean``, ``code_basis``); a code decodes by rolling the generator
out with z = code_mean + code · code_basis.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import ClassVar

import numpy as np
import torch
import torch.nn.functional as F  # noqa: N812
from torch import Tensor, nn

from engine.errors import ConfigError
from engine.model.config_base import ModelConfig
from engine.motion.kinematics import forward_kinematics
from engine.motion.skeleton import Skeleton

A2M_LOSS_TERMS = ("recon", "trajectory", "kl")
POSE_REPS = ("lie", "joints")
#: what the joint-position baseline's folders mean by the fields added after them
_BEFORE = {"pose_rep": "joints", "trajectory_weight": 0.0, "code_dim": 0}


@dataclass
class A2mConfig(ModelConfig):
    """Sizes, loss weights and training schedule of one Action2Motion model.

    Sizes follow the paper's HumanAct12 setup (GRU hidden 128, z 30 per frame, a 2-layer generator GRU,
    teacher forcing for a whole batch with probability 0.6, Adam 2e-4 with weight decay 1e-5, batch 128);
    the loss weights are those of the released HumanAct12 configuration (λ_KL = 0.001, λ_trajec = 0.8;
    the paper's text says λ = 0.01, see the README). Epochs are of ``epoch_size`` class-balanced windows,
    like ODMO's, so budgets compare. ``code_dim``: size of the code space (0: none, sampling only).
    ``lr_floor`` < 1 lowers the learning rate along a cosine to lr · lr_floor at the last epoch (1, the
    paper's: constant).
    """

    n_actions: int
    n_joints: int
    window: int = 60
    fps: float = 20.0
    hidden: int = 128
    latent_dim: int = 30
    gen_layers: int = 2
    pose_rep: str = "lie"
    kl_weight: float = 0.001
    trajectory_weight: float = 0.8
    tf_rate: float = 0.6
    lr: float = 2e-4
    lr_floor: float = 1.0
    weight_decay: float = 1e-5
    batch_size: int = 128
    epoch_size: int = 2048
    epochs: int = 300
    grad_clip: float = 1.0
    code_dim: int = 32
    arch: str = "a2m"

    POSITIVE = ("n_actions", "n_joints", "window", "fps", "hidden", "latent_dim", "gen_layers", "lr")
    POSITIVE += ("batch_size", "epoch_size", "grad_clip")
    NON_NEGATIVE = ("kl_weight", "trajectory_weight", "weight_decay", "epochs", "code_dim")
    RATES = ("tf_rate", "lr_floor")
    CHOICES: ClassVar[dict[str, tuple[str, ...]]] = {"pose_rep": POSE_REPS}
    ARCH = "a2m"
    BEFORE = _BEFORE

    def check(self) -> None:
        """A code space no larger than the z sequence."""
        if self.code_dim > self.window * self.latent_dim:
            raise ConfigError(f"code_dim {self.code_dim} exceeds window × latent_dim")


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
    """Linear encoder → multi-layer GRU → linear decoder to the pose parameters."""

    def __init__(self, n_in: int, hidden: int, layers: int, n_out: int):
        super().__init__()
        self.encoder = nn.Linear(n_in, hidden)
        self.gru = nn.GRU(hidden, hidden, layers, batch_first=True)
        self.decoder = nn.Linear(hidden, n_out)

    def forward(self, x: Tensor, h: Tensor | None = None) -> tuple[Tensor, Tensor]:
        """Pose parameters (B, S, out) and the GRU state of inputs (B, S, in)."""
        out, h = self.gru(self.encoder(x), h)
        return self.decoder(out), h


def so3_exp(w: Tensor) -> Tensor:
    """(..., 3, 3) rotation matrices exp(ŵ) of so(3) axis-angle vectors (..., 3), by Rodrigues' formula
    (sin θ / θ and (1 − cos θ) / θ² by their Taylor series near θ = 0)."""
    theta2 = (w * w).sum(-1, keepdim=True)
    small = theta2 < 1e-6
    theta = theta2.clamp_min(1e-12).sqrt()
    a = torch.where(small, 1.0 - theta2 / 6.0, torch.sin(theta) / theta)
    b = torch.where(small, 0.5 - theta2 / 24.0, (1.0 - torch.cos(theta)) / theta2.clamp_min(1e-12))
    zero = torch.zeros_like(w[..., 0])
    hat = torch.stack(
        [zero, -w[..., 2], w[..., 1], w[..., 2], zero, -w[..., 0], -w[..., 1], w[..., 0], zero], -1
    ).unflatten(-1, (3, 3))
    eye = torch.eye(3, dtype=w.dtype, device=w.device)
    return eye + a[..., None] * hat + b[..., None] * (hat @ hat)


@dataclass
class A2mOutput:
    """One pass over a batch: predicted joints (B, T, J, 3), posterior and prior Gaussians (B, T, Z)."""

    joints: Tensor
    mu_q: Tensor
    logvar_q: Tensor
    mu_p: Tensor
    logvar_p: Tensor


class A2mModel(nn.Module):
    """The Action2Motion conditional temporal VAE; parameters initialised from an explicit seed.

    A "lie" model holds its skeleton as buffers (``parents``, ``offsets`` with the root's zeroed: the root
    translation places it); :meth:`set_skeleton` fills them before training.
    """

    def __init__(self, config: A2mConfig, seed: int = 0):
        super().__init__()
        self.config = config
        pose = config.n_joints * 3
        cond = config.n_actions + 1
        n_out = pose + 3 if config.pose_rep == "lie" else pose  # lie: one rotation per joint + root
        with torch.device("meta"):  # construction never draws from torch's global RNG
            self.posterior = _GaussianGru(pose + cond, config.hidden, config.latent_dim)
            self.prior = _GaussianGru(pose + cond, config.hidden, config.latent_dim)
            self.generator = _PoseGru(
                pose + cond + config.latent_dim, config.hidden, config.gen_layers, n_out
            )
        self.to_empty(device="cpu")
        self.reset_parameters(torch.Generator().manual_seed(seed))
        if config.pose_rep == "lie":
            self.register_buffer("parents", torch.full((config.n_joints,), -1, dtype=torch.int64))
            self.register_buffer("offsets", torch.zeros(config.n_joints, 3))
        if config.code_dim:
            size = config.window * config.latent_dim
            self.register_buffer("code_mean", torch.zeros(size))
            self.register_buffer("code_basis", torch.zeros(config.code_dim, size))

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

    @torch.no_grad()
    def set_skeleton(self, skeleton: Skeleton) -> None:
        """Take the fixed skeleton forward kinematics runs on (a "lie" model)."""
        offsets = torch.tensor(np.asarray(skeleton.offsets), dtype=torch.float32)
        offsets[skeleton.root] = 0.0
        self.parents.copy_(torch.tensor(np.asarray(skeleton.parents), dtype=torch.int64))
        self.offsets.copy_(offsets)

    @torch.no_grad()
    def set_rest_bias(self, rotvecs: np.ndarray) -> None:
        """Start the generator's output at the pose of local rotations ``rotvecs`` (J, 3), root at 0."""
        bias = torch.zeros_like(self.generator.decoder.bias)
        bias[: self.config.n_joints * 3] = torch.as_tensor(np.asarray(rotvecs).reshape(-1), dtype=bias.dtype)
        self.generator.decoder.bias.copy_(bias)

    @torch.no_grad()
    def set_code_space(self, mean: np.ndarray, basis: np.ndarray) -> None:
        """Take the code space: mean (T·Z,) and orthonormal rows ``basis`` (code_dim, T·Z)."""
        self.code_mean.copy_(torch.as_tensor(mean, dtype=torch.float32))
        self.code_basis.copy_(torch.as_tensor(basis, dtype=torch.float32))

    def codes_to_z(self, codes: Tensor) -> Tensor:
        """z sequences (B, T, Z) of codes (B, code_dim)."""
        z = self.code_mean + codes @ self.code_basis
        return z.view(len(codes), self.config.window, self.config.latent_dim)

    def z_to_codes(self, z: Tensor) -> Tensor:
        """Codes (B, code_dim) of z sequences (B, T, Z): their projection onto the code space."""
        return (z.reshape(len(z), -1) - self.code_mean) @ self.code_basis.T

    def _condition(self, actions: Tensor) -> Tensor:
        """(B, T, C + 1): the action one-hot and the time counter c_t = t/T, t = 1..T."""
        t = self.config.window
        onehot = F.one_hot(actions.long(), self.config.n_actions).float()
        steps = torch.arange(1, t + 1, dtype=torch.float32, device=actions.device) / t
        return torch.cat(
            [onehot.unsqueeze(1).expand(-1, t, -1), steps.view(1, t, 1).expand(len(actions), -1, -1)], 2
        )

    def _pose(self, params: Tensor, bone_scale: Tensor | float = 1.0) -> Tensor:
        """Flattened joint positions (B, S, J·3) of generator outputs (B, S, out)."""
        if self.config.pose_rep == "joints":
            return params
        j = self.config.n_joints
        local = so3_exp(params[..., : j * 3].unflatten(-1, (j, 3)))
        offsets = self.offsets * (bone_scale if torch.is_tensor(bone_scale) else float(bone_scale))
        joints = forward_kinematics(local, offsets, self.parents.tolist(), params[..., j * 3 :])
        return joints.flatten(-2)

    def _rollout(
        self,
        cond: Tensor,
        z: Tensor | None,
        generator: torch.Generator | None,
        with_prior: bool = True,
        psi: float = 1.0,
    ) -> tuple[Tensor, Tensor, Tensor, Tensor, Tensor]:
        """Free-running poses (B, T, J·3), generator outputs (B, T, out), the z used (B, T, Z) and the prior
        mean / log-variance (B, T, Z).

        Each step feeds the previous generated pose; z_t is taken from ``z`` (B, T, Z) or drawn from the
        prior with ``generator``, its standard deviation scaled by ``psi``. Without ``with_prior`` (and with
        ``z`` given) the prior network is skipped and ``z`` stands in for its mean and log-variance.
        """
        b, t = cond.shape[:2]
        prev = cond.new_zeros(b, 1, self.config.n_joints * 3)
        h_prior = h_gen = None
        poses, outputs, zs, mus, logvars = [], [], [], [], []
        for i in range(t):
            c = cond[:, i : i + 1]
            if z is not None and not with_prior:
                mu_p = logvar_p = z[:, i : i + 1]
            else:
                mu_p, logvar_p, h_prior = self.prior(torch.cat([prev, c], 2), h_prior)
            if z is None:
                eps = torch.randn(mu_p.shape, generator=generator, device=mu_p.device)
                z_t = mu_p + psi * torch.exp(0.5 * logvar_p) * eps
            else:
                z_t = z[:, i : i + 1]
            params, h_gen = self.generator(torch.cat([prev, c, z_t], 2), h_gen)
            prev = self._pose(params)
            steps = (prev, params, z_t, mu_p, logvar_p)
            for seq, value in zip((poses, outputs, zs, mus, logvars), steps, strict=True):
                seq.append(value)
        out = [torch.cat(seq, 1) for seq in (poses, outputs, zs, mus, logvars)]
        return out[0], out[1], out[2], out[3], out[4]

    def _motions(self, poses: Tensor, params: Tensor, bone_scale: Tensor | float) -> Tensor:
        """(B, T, J, 3) motions of a rollout, the skeleton's bones scaled by ``bone_scale`` (a number or
        (J, 1) factors: each bone by its child joint's) after the rollout ran on the unscaled skeleton."""
        if not (torch.is_tensor(bone_scale) or bone_scale != 1.0):
            out = poses
        elif self.config.pose_rep != "lie":
            raise ConfigError("a joint-position (w/o Lie) model has no bones to scale")
        else:
            out = self._pose(params, bone_scale)
        return out.reshape(len(poses), self.config.window, self.config.n_joints, 3)

    def posterior_means(self, joints: Tensor, actions: Tensor) -> Tensor:
        """Posterior means z_1..z_T (B, T, Z) of real windows ``joints`` (B, T, J, 3) of ``actions``."""
        b, t, j, _ = joints.shape
        mu_q, _, _ = self.posterior(torch.cat([joints.reshape(b, t, j * 3), self._condition(actions)], 2))
        return mu_q

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
            params, _ = self.generator(torch.cat([prev, cond, z], 2))
            pred = self._pose(params)
        else:
            pred, _, _, mu_p, logvar_p = self._rollout(cond, z, None)
        return A2mOutput(pred.reshape(b, t, j, 3), mu_q, logvar_q, mu_p, logvar_p)

    def sample(
        self, actions: Tensor, generator: torch.Generator, bone_scale: Tensor | float = 1.0, psi: float = 1.0
    ) -> tuple[Tensor, Tensor]:
        """Motions (B, T, J, 3) of ``actions`` (B,) and their z (B, T, Z), each z_t from the learned prior
        with its standard deviation scaled by the truncation ``psi`` (1: the paper's, 0: its mean)."""
        poses, params, z, _, _ = self._rollout(self._condition(actions), None, generator, psi=psi)
        return self._motions(poses, params, bone_scale), z

    def decode(self, z: Tensor, actions: Tensor, bone_scale: Tensor | float = 1.0) -> Tensor:
        """Motions (B, T, J, 3) of z sequences (B, T, Z) and ``actions`` (B,), rolled out free-running."""
        poses, params, _, _, _ = self._rollout(self._condition(actions), z, None, with_prior=False)
        return self._motions(poses, params, bone_scale)


def a2m_losses(
    config: A2mConfig, joints: Tensor, mask: Tensor, out: A2mOutput, root: int
) -> dict[str, Tensor]:
    """``recon`` (mean squared joint error), ``trajectory`` (mean squared root error), ``kl`` (KL(q ‖ p)
    summed over z) and ``total``, over real frames.

    ``joints`` (B, T, J, 3) are the targets, ``mask`` (B, T) marks real (unpadded) frames and ``root``
    is the root joint's index.
    """
    weight = mask.to(joints.dtype)
    denom = weight.sum().clamp_min(1.0)
    err = (out.joints - joints) ** 2
    recon = (err.mean(dim=(2, 3)) * weight).sum() / denom
    trajectory = (err[:, :, root].mean(dim=2) * weight).sum() / denom
    var_q, var_p = out.logvar_q.exp(), out.logvar_p.exp()
    kl_t = 0.5 * (out.logvar_p - out.logvar_q + (var_q + (out.mu_q - out.mu_p) ** 2) / var_p - 1.0).sum(2)
    kl = (kl_t * weight).sum() / denom
    total = recon + config.trajectory_weight * trajectory + config.kl_weight * kl
    return {"recon": recon, "trajectory": trajectory, "kl": kl, "total": total}
