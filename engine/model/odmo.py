"""OdmoModel: LMP encoder + trajectory generator + motion generator, conditioned on action ⊗ code."""

from __future__ import annotations

import math
from typing import NamedTuple

import torch
import torch.nn.functional as F  # noqa: N812
from torch import Tensor, nn

from engine.model.config import OdmoConfig
from engine.model.encoder import LmpEncoder
from engine.model.generator import MotionGenerator
from engine.model.trajectory import TrajectoryGenerator
from engine.motion.kinematics import BoneProjection
from engine.motion.skeleton import Skeleton

#: Free-running decodes of more codes than this run in slices of it: each slice's LSTM states and gates
#: stay in the CPU cache, which is faster than one large batch.
DECODE_SLICE = 256


class Decoded(NamedTuple):
    """What a decode produces: ``joints`` (B, T, J, 3) (on the skeleton's bone lengths once one is
    attached and ``bone_projection`` is on), ``trajectory`` (B, T, 3), the decoder's ``raw`` joints
    (B, T, J, 3) and ``contact`` logits (B, T, F) of the config's foot joints (None without the head)."""

    joints: Tensor
    trajectory: Tensor
    raw: Tensor
    contact: Tensor | None


class OdmoModel(nn.Module):
    """The ODMO generator (paper sizes by default); parameters initialised from an explicit seed."""

    def __init__(self, config: OdmoConfig, seed: int = 0):
        super().__init__()
        self.config = config
        cond_dim = config.n_actions * config.latent_dim
        # torch's default initialisation below is overwritten by reset_parameters; forking the RNG keeps
        # it from moving torch's global RNG (a meta-device build would cost 1.4 s of imports at start-up).
        with torch.random.fork_rng(devices=[]):
            self.encoder = LmpEncoder(
                config.n_joints * 3,
                config.enc_hidden,
                config.enc_fc,
                config.latent_dim,
                config.encoder_reverse,
            )
            self.traj_gen = TrajectoryGenerator(
                cond_dim, config.traj_hidden, config.window, config.use_end_location, config.exact_end
            )
            self.motion_gen = MotionGenerator(
                config.n_joints,
                cond_dim,
                config.motion_hidden,
                config.window,
                config.root_relative_poses,
                config.scheduled_sampling == "free_run",
                config.root_velocity_input,
                config.fps,
                config.pose_output == "rotations",
                config.pose_update == "residual",
                config.clock_hz,
                config.step_input,
                config.code_rhythms,
            )
            n_feet = len(config.foot_joints) if config.foot_contact else 0
            self.contact = nn.Linear(config.motion_hidden, n_feet) if n_feet else None
        self.reset_parameters(torch.Generator().manual_seed(seed))
        self.projection: BoneProjection | None = None
        self.skeleton: Skeleton | None = None

    def attach_skeleton(self, skeleton: Skeleton) -> None:
        """Decode onto ``skeleton`` from now on: by forward kinematics (``pose_output`` "rotations") or
        projected onto its bone lengths (``bone_projection``)."""
        self.skeleton = skeleton
        if self.config.pose_output == "rotations":
            self.motion_gen.attach_skeleton(skeleton)
        elif self.config.bone_projection:
            device = next(self.parameters()).device
            self.projection = BoneProjection(skeleton).to(device)

    @torch.no_grad()
    def reset_parameters(self, generator: torch.Generator) -> None:
        """Re-initialise every weight like torch's defaults, drawing only from ``generator``."""
        for module in self.modules():
            if isinstance(module, nn.Linear):
                bound = 1.0 / math.sqrt(module.in_features)
                module.weight.uniform_(-bound, bound, generator=generator)
                module.bias.uniform_(-bound, bound, generator=generator)
            elif isinstance(module, nn.LSTM):
                bound = 1.0 / math.sqrt(module.hidden_size)
                for p in module.parameters():
                    p.uniform_(-bound, bound, generator=generator)
            elif isinstance(module, nn.BatchNorm1d):
                module.reset_running_stats()
                module.weight.fill_(1.0)
                module.bias.zero_()
            elif isinstance(module, nn.PReLU):
                module.weight.fill_(0.25)

    def condition(self, z: Tensor, action: Tensor) -> Tensor:
        """Outer product of the action one-hot and the code, flattened: (B, C·D)."""
        onehot = F.one_hot(action.long(), self.config.n_actions).to(z.dtype)
        return (onehot.unsqueeze(2) * z.unsqueeze(1)).flatten(1)

    def encode(self, lmp: Tensor, mask: Tensor | None = None) -> tuple[Tensor, Tensor]:
        """Code mean and log-variance (B, D) of local movement profiles ``lmp`` (B, T, J·3)."""
        return self.encoder(lmp, mask)

    def trajectory(self, z: Tensor, action: Tensor, end: Tensor | None = None) -> Tensor:
        """Root trajectory (B, T, 3) of codes ``z`` (B, D) for ``action`` (B,), ending near ``end`` (B, 3)."""
        return self.traj_gen(self.condition(z, action), end)

    def decode(
        self,
        z: Tensor,
        action: Tensor,
        end: Tensor | None = None,
        prev_truth: Tensor | None = None,
        tf_rate: float = 0.0,
        generator: torch.Generator | None = None,
    ) -> tuple[Tensor, Tensor]:
        """Joints (B, T, J, 3) and trajectory (B, T, 3) for codes ``z`` (B, D) and ``action`` (B,).

        ``prev_truth`` (B, T, J, 3) enables (scheduled) teacher forcing for training; without it the
        decoder runs free.
        """
        out = self.decode_full(z, action, end, prev_truth, tf_rate, generator)
        return out.joints, out.trajectory

    def decode_full(
        self,
        z: Tensor,
        action: Tensor,
        end: Tensor | None = None,
        prev_truth: Tensor | None = None,
        tf_rate: float = 0.0,
        generator: torch.Generator | None = None,
        tf_noise: Tensor | None = None,
    ) -> Decoded:
        """``decode`` with the raw joints and the foot-contact logits as well (``tf_noise``: the
        teacher-forcing draws, see ``MotionGenerator.forward``)."""
        if prev_truth is None and not torch.is_grad_enabled() and z.shape[0] > DECODE_SLICE:
            parts = [
                self.decode_full(z[i : i + DECODE_SLICE], action[i : i + DECODE_SLICE], end_slice)
                for i, end_slice in _slices(end, z.shape[0])
            ]
            return Decoded(*(None if p[0] is None else torch.cat(p) for p in zip(*parts, strict=True)))
        cond = self.condition(z, action)
        traj = self.traj_gen(cond, end)
        raw, hidden = self.motion_gen(traj, cond, prev_truth, tf_rate, generator, tf_noise)
        joints = raw if self.projection is None else self.projection(raw)
        contact = None if self.contact is None else self.contact(hidden).float()
        return Decoded(joints, traj, raw, contact)

    def rollout(
        self, z: Tensor, action: Tensor, end: Tensor | None, truth: Tensor, start: int, frames: int
    ) -> Tensor:
        """Joints (B, frames, J, 3) of frames ``start`` … ``start + frames − 1`` decoded free-running after
        teacher-forced ones (``MotionGenerator.rollout``), on the skeleton as ``decode_full`` places them."""
        cond = self.condition(z, action)
        traj = self.traj_gen(cond, end)
        raw = self.motion_gen.rollout(traj, cond, truth, start, frames).unflatten(-1, (-1, 3))
        if self.config.root_relative_poses:
            raw = raw - raw[..., :1, :] + traj[:, start : start + frames, None]
        return raw if self.projection is None else self.projection(raw)


def _slices(end: Tensor | None, n: int) -> list[tuple[int, Tensor | None]]:
    """Start of each DECODE_SLICE-sized slice of ``n`` rows, with its rows of ``end`` (or None)."""
    return [(i, None if end is None else end[i : i + DECODE_SLICE]) for i in range(0, n, DECODE_SLICE)]
