"""MoDi's motion representation (paper §3.1) on a fixed skeleton, and its decoding to joint positions.

Entities × features × frames, K = 6 features per entity: each joint's local rotation as 6D (the first two
columns of its matrix), then the root displacement and one contact label (0 or 1) per foot joint,
zero-padded to K. The root displacement is, as in MoDi, the root's horizontal velocity (x, z per frame)
and its height (y, relative to frame 0) with ``root_velocity``; or, in models trained before it, the
root position in the window's canonical frame (a GAN of those never learnt to walk: positions grow
over the window and their statistics mix every frame's). The network sees the features
normalised per entity and feature by the training windows' mean and standard deviation; features that
are padding or constant in the data are held at zero. Joints come from forward kinematics of the data's
skeleton (root offset zeroed: the displacement places the root).
"""

from __future__ import annotations

import numpy as np
import torch
from torch import Tensor, nn

from engine.motion.contact import foot_joints
from engine.motion.kinematics import forward_kinematics, rotation_6d_to_matrix
from engine.motion.skeleton import Skeleton

FEATURES = 6
#: Standard deviation under which a feature counts as constant in the data.
CONSTANT_STD = 1e-4


class MotionCoder(nn.Module):
    """Features of motions on ``skeleton`` and back: normalisation statistics and forward kinematics."""

    def __init__(self, skeleton: Skeleton, root_velocity: bool = True):
        super().__init__()
        self.root_velocity = root_velocity
        self.parents = np.asarray(skeleton.parents)
        self.feet = foot_joints(skeleton)
        chain = sorted({a for f in self.feet for a in _ancestors(skeleton.parents, f)})
        self.foot_chain = chain  # the joints forward kinematics needs to place the feet
        self.foot_chain_parents = np.array(
            [chain.index(p) if p >= 0 else -1 for p in skeleton.parents[chain]]
        )
        self.n_joints = skeleton.n_joints
        offsets = torch.tensor(np.array(skeleton.offsets), dtype=torch.float32)
        offsets[skeleton.root] = 0.0
        self.register_buffer("offsets", offsets)
        n = self.n_entities
        used = torch.zeros(n, FEATURES)
        used[: self.n_joints] = 1.0
        used[self.n_joints, :3] = 1.0
        used[self.n_joints + 1 :, 0] = 1.0
        self.register_buffer("padding_mask", used, persistent=False)
        self.register_buffer("mean", torch.zeros(n, FEATURES))
        self.register_buffer("std", torch.ones(n, FEATURES))
        self.register_buffer("feature_mask", used.clone())

    @property
    def n_entities(self) -> int:
        """Joints, the root displacement and the foot contacts."""
        return self.n_joints + 1 + len(self.feet)

    def raw_features(self, rotations: Tensor, root: Tensor, contacts: Tensor) -> Tensor:
        """(B, E, K, T) unnormalised features of local rotation matrices (B, T, J, 3, 3), root positions
        (B, T, 3) and contact labels (B, T, F)."""
        b, t = root.shape[:2]
        six = torch.cat([rotations[..., :, 0], rotations[..., :, 1]], -1)
        extra = root.new_zeros(b, t, 1 + len(self.feet), FEATURES)
        extra[:, :, 0, :3] = self._displacement(root) if self.root_velocity else root
        extra[:, :, 1:, 0] = contacts
        return torch.cat([six, extra], 2).permute(0, 2, 3, 1)

    @staticmethod
    def _displacement(root: Tensor) -> Tensor:
        """(B, T, 3) per-frame horizontal steps (frame 0: its own x, z) and the height of root positions."""
        step = torch.diff(root, dim=1, prepend=torch.zeros_like(root[:, :1]))
        return torch.stack([step[..., 0], root[..., 1], step[..., 2]], dim=-1)

    @staticmethod
    def _positions(displacement: Tensor) -> Tensor:
        """Root positions (B, T, 3) of ``_displacement`` output: the horizontal steps summed up."""
        summed = torch.cumsum(displacement, dim=1)
        return torch.stack([summed[..., 0], displacement[..., 1], summed[..., 2]], dim=-1)

    @torch.no_grad()
    def set_statistics(self, raw: Tensor) -> None:
        """Take the normalisation of unnormalised features (N, E, K, T) of training windows."""
        mean = raw.mean((0, 3)) * self.padding_mask
        std = raw.std((0, 3))
        varies = (std > CONSTANT_STD).float() * self.padding_mask
        self.mean.copy_(mean)
        self.std.copy_(torch.where(varies > 0, std, torch.ones_like(std)))
        self.feature_mask.copy_(varies)

    def normalise(self, raw: Tensor) -> Tensor:
        """Network features of unnormalised ones (B, E, K, T)."""
        return (raw - self.mean[:, :, None]) / self.std[:, :, None] * self.feature_mask[:, :, None]

    def denormalise(self, x: Tensor) -> Tensor:
        """Unnormalised features of network ones (B, E, K, T)."""
        return x * self.feature_mask[:, :, None] * self.std[:, :, None] + self.mean[:, :, None]

    def split(self, x: Tensor) -> tuple[Tensor, Tensor, Tensor]:
        """Local rotation matrices (B, T, J, 3, 3), root positions (B, T, 3) and contact values (B, T, F)
        of network features (B, E, K, T)."""
        raw = self.denormalise(x).permute(0, 3, 1, 2)
        j = self.n_joints
        root = self._positions(raw[:, :, j, :3]) if self.root_velocity else raw[:, :, j, :3]
        return rotation_6d_to_matrix(raw[:, :, :j]), root, raw[:, :, j + 1 :, 0]

    def joints(self, x: Tensor) -> Tensor:
        """(B, T, J, 3) joint positions of network features (B, E, K, T)."""
        rotations, root, _ = self.split(x)
        return forward_kinematics(rotations, self.offsets, self.parents, root)

    def feet_and_contacts(self, x: Tensor) -> tuple[Tensor, Tensor]:
        """Foot joint positions (B, T, F, 3) and contact values (B, T, F) of network features (B, E, K, T)
        (forward kinematics of the feet's chains only)."""
        rotations, root, contacts = self.split(x)
        chain = self.foot_chain
        placed = forward_kinematics(
            rotations[:, :, chain], self.offsets[chain], self.foot_chain_parents, root
        )
        return placed[:, :, [chain.index(f) for f in self.feet]], contacts


def _ancestors(parents: np.ndarray, joint: int) -> list[int]:
    """``joint`` and every joint above it."""
    found = [joint]
    while parents[found[-1]] >= 0:
        found.append(int(parents[found[-1]]))
    return found
