"""Inverse kinematics: joints -> rotations -> joints, checked with an independent forward kinematics."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from engine.errors import ConfigError
from engine.motion import Motion, Skeleton
from engine.motion.bvh import read_bvh
from engine.motion.humanact12 import smpl24_skeleton
from engine.motion.ik import joints_to_rotations


def chain_positions(skeleton: Skeleton, quats_wxyz: np.ndarray, root: np.ndarray) -> np.ndarray:
    """(T, J, 3) positions by composing parent rotations joint by joint (written here, not imported)."""
    T, J = quats_wxyz.shape[:2]
    world = [None] * J
    pos = np.zeros((T, J, 3))
    for j in range(J):
        local = Rotation.from_quat(quats_wxyz[:, j], scalar_first=True)
        p = skeleton.parents[j]
        if p < 0:
            world[j], pos[:, j] = local, root
        else:
            world[j] = world[p] * local
            pos[:, j] = pos[:, p] + world[p].apply(np.array(skeleton.offsets[j]))
    return pos


def random_tree(rng: np.random.Generator, n: int) -> Skeleton:
    """A random skeleton of ``n`` joints with bones 5-40 cm long."""
    parents = [-1] + [int(rng.integers(0, j)) for j in range(1, n)]
    offsets = rng.normal(size=(n, 3))
    offsets *= rng.uniform(0.05, 0.4, size=(n, 1)) / np.linalg.norm(offsets, axis=1, keepdims=True)
    offsets[0] = 0.0
    return Skeleton(tuple(f"j{j}" for j in range(n)), np.array(parents), offsets)


def smooth_rotations(rng: np.random.Generator, T: int, J: int) -> np.ndarray:
    """(T, J, 4) wxyz quaternions of a random walk in rotation-vector space."""
    rotvec = rng.normal(scale=0.5, size=(1, J, 3)) + np.cumsum(rng.normal(scale=0.05, size=(T, J, 3)), axis=0)
    return Rotation.from_rotvec(rotvec.reshape(-1, 3)).as_quat(scalar_first=True).reshape(T, J, 4)


@pytest.mark.parametrize(("skeleton_seed", "kind"), [(0, "smpl24"), (1, "random"), (2, "random")])
def test_ik_reproduces_bone_length_consistent_joints(skeleton_seed: int, kind: str) -> None:
    rng = np.random.default_rng(skeleton_seed)
    skel = smpl24_skeleton() if kind == "smpl24" else random_tree(rng, 18)
    T = 60
    root = np.cumsum(rng.normal(scale=0.02, size=(T, 3)), axis=0)
    joints = chain_positions(skel, smooth_rotations(rng, T, skel.n_joints), root)
    rest, local, root_t, err = joints_to_rotations(Motion(joints, 30.0, skel))

    again = chain_positions(rest, local, root_t)
    independent = np.mean(np.linalg.norm(again - joints, axis=-1))
    assert err < 0.01 and independent < 0.01
    assert err == pytest.approx(independent, abs=1e-5)
    assert np.allclose(rest.bone_lengths(), skel.bone_lengths(), atol=1e-5)
    assert np.allclose(np.linalg.norm(local, axis=-1), 1.0)
    assert np.all(np.sum(local[1:] * local[:-1], axis=-1) >= 0), "quaternion signs must be continuous"
    leaves = [j for j in range(skel.n_joints) if not skel.children(j)]
    assert np.allclose(local[:, leaves], [1.0, 0.0, 0.0, 0.0])


def test_rest_pose_keeps_input_directions_scaled_to_median_lengths() -> None:
    skel = smpl24_skeleton()
    rng = np.random.default_rng(3)
    joints = chain_positions(skel.scaled(1.2), smooth_rotations(rng, 20, 24), np.zeros((20, 3)))
    rest = joints_to_rotations(Motion(joints, 20.0, skel))[0]
    bones = np.arange(1, 24)
    unit = skel.offsets[bones] / np.linalg.norm(skel.offsets[bones], axis=1, keepdims=True)
    assert np.allclose(rest.offsets[bones], unit * 1.2 * skel.bone_lengths()[bones, None], atol=1e-6)
    assert np.allclose(rest.offsets[0], 0.0)


def test_noisy_joints_report_the_true_mean_error() -> None:
    rng = np.random.default_rng(4)
    skel = smpl24_skeleton()
    joints = chain_positions(skel, smooth_rotations(rng, 40, 24), np.zeros((40, 3)))
    noisy = joints + rng.normal(scale=0.005, size=joints.shape)
    rest, local, root_t, err = joints_to_rotations(Motion(noisy, 20.0, skel))
    measured = np.mean(
        np.linalg.norm(chain_positions(rest, local, root_t) - noisy.astype(np.float32), axis=-1)
    )
    assert err == pytest.approx(measured, rel=1e-4)
    assert 0.001 < err < 0.02, "bone-length-inconsistent input cannot be matched exactly, but stays close"


def test_ik_on_a_real_bandai_clip(bandai_dir) -> None:
    clip = read_bvh(bandai_dir / "data" / "dataset-2_walk_normal_001.bvh")
    body = clip.without_joints(["joint_Root"])
    rest, local, root_t, err = joints_to_rotations(body)
    assert body.skeleton.names[rest.root] == "Hips" and body.n_joints == 21
    assert err < 0.01
    assert np.mean(np.linalg.norm(chain_positions(rest, local, root_t) - body.joints, axis=-1)) < 0.01


def test_unknown_twist_policy_is_refused() -> None:
    skel = smpl24_skeleton()
    with pytest.raises(ConfigError, match="twist"):
        joints_to_rotations(Motion(np.zeros((2, 24, 3)), 20.0, skel), twist="free")
