"""Differentiable (torch) kinematics on a fixed skeleton: bone-length projection and forward kinematics.

``BoneProjection`` maps any joint positions to the nearest-in-direction pose with the skeleton's bone
lengths that a BVH can hold exactly: every bone keeps its length, a joint with one child points it
along the input's direction, and a joint with several children (hips, chest) places them rigidly, as
its rest offsets turned by one rotation (the frame of two of its child bones). ``forward_kinematics``
is the same tree walked from local rotation matrices, for rotation-based generators.
"""

from __future__ import annotations

import functools
import itertools
from typing import NamedTuple

import numpy as np
import torch
from torch import Tensor, nn

from engine.motion.skeleton import Skeleton

_EPS = 1e-8


def _frame(a: Tensor, b: Tensor, eps: float = _EPS) -> Tensor:
    """(..., 3, 3) orthonormal frame (columns) of vectors ``a`` and ``b`` (..., 3) by Gram–Schmidt
    (TorchScript-compatible)."""
    e1 = a / torch.linalg.vector_norm(a, dim=-1, keepdim=True).clamp_min(eps)
    b = b - (b * e1).sum(-1, keepdim=True) * e1
    e2 = b / torch.linalg.vector_norm(b, dim=-1, keepdim=True).clamp_min(eps)
    return torch.stack([e1, e2, torch.linalg.cross(e1, e2)], dim=-1)


def _frame_pair(offsets: np.ndarray, kids: list[int]) -> tuple[int, int]:
    """The two children of a joint whose rest offsets are furthest from parallel."""
    unit = offsets[kids] / np.maximum(np.linalg.norm(offsets[kids], axis=1, keepdims=True), _EPS)
    best, pair = -1.0, (kids[0], kids[1])
    for i in range(len(kids)):
        for k in range(i + 1, len(kids)):
            s = float(np.linalg.norm(np.cross(unit[i], unit[k])))
            if s > best:
                best, pair = s, (kids[i], kids[k])
    return pair


class BoneProjection(nn.Module):
    """Joint positions (..., J, 3) onto ``skeleton``'s bone lengths (the root stays where it is).

    Bones whose rest offset is zero keep a zero length; a joint whose children are all parallel in the
    rest pose is treated as having one child (its longest).
    """

    def __init__(self, skeleton: Skeleton):
        super().__init__()
        parents = np.array(skeleton.parents)
        offsets = np.array(skeleton.offsets, dtype=np.float64)
        n = len(parents)
        self.root = skeleton.root
        lengths = np.linalg.norm(offsets, axis=1)
        lengths[self.root] = 0.0
        ancestors = np.zeros((n, n), dtype=np.float32)  # ancestors[j, k] = 1: bone k lies on root → j
        for j in range(n):
            k = j
            while parents[k] >= 0:
                ancestors[j, k] = 1.0
                k = parents[k]
        rigid, single = [], []
        for p in range(n):
            kids = [c for c in skeleton.children(p) if lengths[c] > _EPS]
            if len(kids) >= 2:
                a, b = _frame_pair(offsets, kids)
                if np.linalg.norm(np.cross(offsets[a], offsets[b])) > 1e-6 * lengths[a] * lengths[b]:
                    rigid.append((p, kids, a, b))
                    continue
            single.extend(kids)
        self.rigid = rigid
        self.n_joints = n
        # bones (flattened J·3) = joints · to_bones; positions − root = bones · to_joints (one GEMM each)
        parent_of = np.zeros((n, n))
        parent_of[np.flatnonzero(parents >= 0), parents[parents >= 0]] = 1.0
        eye3 = np.eye(3)
        to_bones = np.kron(np.eye(n) - parent_of, eye3).T
        to_joints = np.kron(ancestors, eye3).T
        lengths_single = np.where(np.isin(np.arange(n), single), lengths, 0.0)
        self.register_buffer("to_bones", torch.as_tensor(to_bones, dtype=torch.float32), persistent=False)
        self.register_buffer("to_joints", torch.as_tensor(to_joints, dtype=torch.float32), persistent=False)
        self.register_buffer(
            "lengths", torch.as_tensor(lengths_single, dtype=torch.float32), persistent=False
        )
        self.register_buffer("offsets", torch.as_tensor(offsets, dtype=torch.float32), persistent=False)
        rests = [_frame(self.offsets[a], self.offsets[b]) for _, _, a, b in rigid]
        self._rest_frames = [r.transpose(-1, -2) for r in rests]

    def forward(self, joints: Tensor) -> Tensor:
        """Projected positions, same shape as ``joints``, in float32 (also under autocast: bone lengths in
        bfloat16 would be off by about 0.4 %)."""
        with torch.autocast(joints.device.type, enabled=False):
            return self._project(joints.float())

    def _project(self, joints: Tensor) -> Tensor:
        shape = joints.shape
        flat = joints.reshape(-1, self.n_joints * 3)
        bones = (flat @ self.to_bones.to(joints)).view(-1, self.n_joints, 3)
        scale = self.lengths.to(joints)[:, None] / bones.norm(dim=-1, keepdim=True).clamp_min(_EPS)
        out = bones * scale  # single-child bones: the input direction at the rest length; the rest 0
        if self.rigid:
            offsets = self.offsets.to(joints)
            for (_, kids, a, b), rest in zip(self.rigid, self._rest_frames, strict=True):
                turn = _frame(bones[:, a], bones[:, b]) @ rest.to(joints)
                out[:, kids] = torch.einsum("nij,kj->nki", turn, offsets[kids])
        placed = out.reshape(-1, self.n_joints * 3) @ self.to_joints.to(joints)
        return (
            placed.view(-1, self.n_joints, 3) + flat.view(-1, self.n_joints, 3)[:, self.root : self.root + 1]
        ).view(shape)


def rotation_6d_to_matrix(d6: Tensor) -> Tensor:
    """(..., 3, 3) rotation matrices (columns from Gram–Schmidt) of 6D rotations (..., 6)."""
    return _frame(d6[..., :3], d6[..., 3:])


class FkLevels(NamedTuple):
    """A tree's joints a depth at a time, for ``walk_tree``: ``joints[d]`` the joints of depth d,
    ``slots[d - 1]`` the index of each one's parent among ``joints[d - 1]``, ``back`` the index that puts
    the depth-ordered joints back in joint order."""

    joints: list[Tensor]
    slots: list[Tensor]
    back: Tensor

    def to(self, device: torch.device) -> FkLevels:
        """The same levels on ``device``."""
        return FkLevels(
            [j.to(device) for j in self.joints], [s.to(device) for s in self.slots], self.back.to(device)
        )


@functools.cache
def fk_levels(parents: tuple[int, ...]) -> FkLevels:
    """The depth levels of the tree ``parents`` (parents precede children, the root's is -1)."""
    depth: list[int] = []
    for j, p in enumerate(parents):
        if p >= j:
            raise ValueError(f"parents must precede their children; joint {j} has parent {p}")
        depth.append(0 if p < 0 else depth[p] + 1)
    levels = [[j for j in range(len(parents)) if depth[j] == d] for d in range(max(depth, default=-1) + 1)]
    slots = [[above.index(parents[j]) for j in joints] for above, joints in itertools.pairwise(levels)]
    order = [j for level in levels for j in level]
    with torch.inference_mode(False):  # cached: ordinary tensors, which autograd may save, wherever built
        return FkLevels(
            [torch.tensor(level) for level in levels],
            [torch.tensor(slot) for slot in slots],
            torch.tensor([order.index(j) for j in range(len(parents))]),
        )


def walk_tree(
    local: Tensor, offsets: Tensor, root: Tensor, joints: list[Tensor], slots: list[Tensor], back: Tensor
) -> Tensor:
    """(..., J, 3) positions from local rotation matrices (..., J, 3, 3), rest ``offsets`` (J, 3) and root
    positions (..., 3), a depth level (``fk_levels``) at a time: every joint of one depth in one batched
    product, so the number of tensor operations grows with the tree's depth, not its joint count.
    TorchScript-compatible (the free-running rotation decoder runs it every frame)."""
    axis = local.dim() - 3
    world = local.index_select(axis, joints[0])
    pos = root.unsqueeze(-2).expand_as(world.select(-1, 0))
    places = [pos]
    for k in range(1, len(joints)):
        above = world.index_select(axis, slots[k - 1])
        step = (above @ offsets.index_select(0, joints[k]).unsqueeze(-1)).squeeze(-1)
        pos = pos.index_select(axis, slots[k - 1]) + step
        world = above @ local.index_select(axis, joints[k])
        places.append(pos)
    return torch.cat(places, dim=axis).index_select(axis, back)


def forward_kinematics(local: Tensor, offsets: Tensor, parents: np.ndarray, root: Tensor) -> Tensor:
    """(..., J, 3) positions from local rotation matrices (..., J, 3, 3), rest ``offsets`` (J, 3) and root
    positions (..., 3); ``parents`` precede children, the root's is -1 (``walk_tree``)."""
    levels = fk_levels(tuple(int(p) for p in np.asarray(parents))).to(local.device)
    return walk_tree(local, offsets.to(local), root, levels.joints, levels.slots, levels.back)
