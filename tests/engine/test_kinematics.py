"""Bone-length projection and torch forward kinematics against scipy-based FK and the BVH IK."""

from __future__ import annotations

import numpy as np
import pytest
import torch
from scipy.spatial.transform import Rotation

from engine.motion.ik import joints_to_rotations
from engine.motion.kinematics import BoneProjection, forward_kinematics, rotation_6d_to_matrix
from engine.motion.motion import Motion
from engine.motion.rotations import forward_kinematics as fk_numpy
from tests.fixtures.procedural import procedural_skeleton


def _random_pose(skeleton, t: int, seed: int) -> np.ndarray:
    """(T, J, 3) FK of random local rotations: a pose the skeleton can hold, bones at rest length."""
    rng = np.random.default_rng(seed)
    quats = Rotation.random(t * skeleton.n_joints, random_state=rng).as_quat(scalar_first=True)
    return fk_numpy(skeleton, quats.reshape(t, -1, 4), rng.normal(size=(t, 3)))


def _lengths(joints: np.ndarray, parents: np.ndarray) -> np.ndarray:
    kids = np.flatnonzero(parents >= 0)
    return np.linalg.norm(joints[..., kids, :] - joints[..., parents[kids], :], axis=-1)


def test_projection_puts_any_pose_on_the_skeleton_bone_lengths() -> None:
    skeleton = procedural_skeleton()
    clean = _random_pose(skeleton, 20, 0)
    noisy = clean + np.random.default_rng(1).normal(scale=0.02, size=(20, 11, 3))
    projected = BoneProjection(skeleton)(torch.tensor(noisy, dtype=torch.float32)).numpy()
    expected = np.linalg.norm(skeleton.offsets, axis=1)[skeleton.parents >= 0]
    np.testing.assert_allclose(
        _lengths(projected, skeleton.parents), np.broadcast_to(expected, (20, 10)), atol=1e-5
    )
    np.testing.assert_allclose(projected[:, 0], noisy[:, 0], atol=1e-6)  # the root stays
    # near the pose the noise was added to (noise of 3.5 cm per joint), not some other pose
    assert np.linalg.norm(projected - clean, axis=-1).mean() < 0.06


def test_projection_leaves_a_pose_on_the_skeleton_unchanged() -> None:
    skeleton = procedural_skeleton()
    pose = _random_pose(skeleton, 10, 2)
    projected = BoneProjection(skeleton)(torch.tensor(pose, dtype=torch.float32)).numpy()
    np.testing.assert_allclose(projected, pose, atol=2e-5)


def test_a_projected_pose_survives_ik_and_fk_exactly() -> None:
    """What the BVH export does (IK to rotations, FK back) reproduces a projected pose."""
    skeleton = procedural_skeleton()
    noisy = _random_pose(skeleton, 15, 3) + np.random.default_rng(4).normal(scale=0.08, size=(15, 11, 3))
    projected = BoneProjection(skeleton)(torch.tensor(noisy)).numpy()
    rest, local, root, error = joints_to_rotations(Motion(projected.astype(np.float32), 20.0, skeleton))
    np.testing.assert_allclose(fk_numpy(rest, local, root), projected, atol=1e-4)
    assert error < 1e-4
    # the raw (unprojected) pose is not held: IK moves it by centimetres
    _, _, _, raw_error = joints_to_rotations(Motion(noisy.astype(np.float32), 20.0, skeleton))
    assert raw_error > 0.01


def test_projection_is_differentiable() -> None:
    skeleton = procedural_skeleton()
    x = torch.tensor(_random_pose(skeleton, 4, 5), dtype=torch.float32, requires_grad=True)
    BoneProjection(skeleton)(x * 1.1).square().sum().backward()
    assert x.grad is not None and torch.isfinite(x.grad).all() and x.grad.abs().sum() > 0


def test_torch_forward_kinematics_matches_the_scipy_one() -> None:
    skeleton = procedural_skeleton()
    rng = np.random.default_rng(6)
    rotations = Rotation.random(5 * 11, random_state=rng)
    root = rng.normal(size=(5, 3))
    expected = fk_numpy(skeleton, rotations.as_quat(scalar_first=True).reshape(5, 11, 4), root)
    local = torch.tensor(rotations.as_matrix().reshape(5, 11, 3, 3))
    got = forward_kinematics(local, torch.tensor(skeleton.offsets), skeleton.parents, torch.tensor(root))
    np.testing.assert_allclose(got.numpy(), expected, atol=1e-10)


@pytest.mark.parametrize("seed", [0, 1])
def test_6d_rotations_are_the_first_two_matrix_columns(seed: int) -> None:
    matrices = Rotation.random(8, random_state=seed).as_matrix()
    d6 = torch.tensor(np.concatenate([matrices[..., 0], matrices[..., 1]], axis=-1) * 3.0)
    np.testing.assert_allclose(rotation_6d_to_matrix(d6).numpy(), matrices, atol=1e-10)


def _fk_one_joint_at_a_time(local: torch.Tensor, offsets: torch.Tensor, parents, root: torch.Tensor):
    """The textbook walk, joint by joint, as an independent reference."""
    world, pos = [], []
    for j, p in enumerate(parents):
        if p < 0:
            world.append(local[..., j, :, :])
            pos.append(root)
        else:
            world.append(world[p] @ local[..., j, :, :])
            pos.append(pos[p] + world[p] @ offsets[j])
    return torch.stack(pos, dim=-2)


def test_forward_kinematics_by_depth_has_the_joint_by_joint_values_and_gradients() -> None:
    skeleton = procedural_skeleton()
    rng = np.random.default_rng(8)
    matrices = Rotation.random(3 * 7 * 11, random_state=rng).as_matrix().reshape(3, 7, 11, 3, 3)
    root_path = rng.normal(size=(3, 7, 3))
    offsets = torch.tensor(skeleton.offsets)
    grads = []
    for fk in (forward_kinematics, _fk_one_joint_at_a_time):
        local = torch.tensor(matrices, requires_grad=True)
        root = torch.tensor(root_path, requires_grad=True)
        out = fk(local, offsets, skeleton.parents, root)
        (out * torch.linspace(-1, 1, out.numel()).reshape(out.shape)).sum().backward()
        grads.append((out.detach(), local.grad, root.grad))
    for got, want in zip(grads[0], grads[1], strict=True):
        np.testing.assert_allclose(got.numpy(), want.numpy(), atol=1e-12)


def test_forward_kinematics_places_every_root_at_the_root_position() -> None:
    parents = np.array([-1, 0, -1, 2])  # two chains
    offsets = torch.tensor([[0.0, 0, 0], [1, 0, 0], [0, 0, 0], [0, 2, 0]])
    local = torch.eye(3).expand(4, 3, 3)
    got = forward_kinematics(local, offsets, parents, torch.tensor([5.0, 0, 0]))
    np.testing.assert_allclose(got.numpy(), [[5, 0, 0], [6, 0, 0], [5, 0, 0], [5, 2, 0]])


def test_fk_levels_built_under_inference_mode_still_train() -> None:
    """The depth levels are cached: first built under inference_mode, they must still serve autograd."""
    parents = (-1, 0, 1, 1, 0)  # a tree no other test builds, so this call fills the cache
    offsets = torch.tensor([[0.0, 0, 0], [0, 1, 0], [0, 1, 0], [1, 0, 0], [0, -1, 0]])
    with torch.inference_mode():
        forward_kinematics(torch.eye(3).repeat(5, 1, 1), offsets, np.array(parents), torch.zeros(3))
    local = torch.eye(3).repeat(5, 1, 1).requires_grad_()
    forward_kinematics(local, offsets, np.array(parents), torch.zeros(3)).sum().backward()
    assert local.grad is not None
