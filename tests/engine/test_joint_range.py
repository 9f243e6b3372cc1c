"""The share of joint rotations outside the real range: known answers on a bent chain, the real dataset,
and the decoder failure it exists for (a pelvis turned half round between the legs)."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from engine.errors import ConfigError
from engine.metrics.joint_range import RANGE_QUANTILE, JointRange
from engine.motion.contact import hip_pair
from engine.motion.formats import read_motion
from engine.motion.ik import joints_to_rotations
from engine.motion.motion import Motion
from engine.motion.rotations import forward_kinematics
from engine.motion.skeleton import Skeleton

CHAIN = Skeleton(("Root", "Upper", "Lower", "Tip"), np.array([-1, 0, 1, 2]), np.array(
    [[0, 0, 0], [0, 0.5, 0], [0, 0.4, 0], [0, 0.3, 0]], dtype=float))  # fmt: skip


def _bent(degrees: np.ndarray) -> np.ndarray:
    """Positions of ``CHAIN`` with its middle joint bent ``degrees`` about z, frame by frame."""
    local = np.zeros((len(degrees), 4, 4))
    local[..., 0] = 1.0
    local[:, 1] = Rotation.from_rotvec(np.radians(degrees)[:, None] * [0.0, 0.0, 1.0]).as_quat(
        scalar_first=True
    )
    return forward_kinematics(CHAIN, local, np.zeros((len(degrees), 3)))


def test_a_chain_bent_within_the_real_range_stays_in_and_one_bent_further_does_not() -> None:
    real = [_bent(np.linspace(-30, 30, 61)), _bent(np.linspace(30, -30, 61))]
    joint_range = JointRange.fit(real, CHAIN)
    assert list(joint_range.joints) == [0, 1, 2]  # the tip is a leaf: nothing to rotate
    assert joint_range.limit_deg[1] == pytest.approx(np.quantile(np.abs(np.linspace(-30, 30, 61)), 0.99))
    assert joint_range.limit_deg[[0, 2]] == pytest.approx([0.0, 0.0], abs=1e-5)
    inside = joint_range.outside([_bent(np.full(10, 20.0))], CHAIN)
    assert inside == pytest.approx([0.0])
    # Bent 60°: the middle joint, one of three, is out in every frame.
    assert joint_range.outside([_bent(np.full(10, 60.0))], CHAIN) == pytest.approx([1 / 3])


def test_a_range_needs_real_clips() -> None:
    with pytest.raises(ConfigError, match="real clips"):
        JointRange.fit([], CHAIN)


def _pelvis_turned(motion: Motion, pelvis: int, spine: int) -> np.ndarray:
    """``motion`` with its pelvis turned half round about the spine's bone and every child of the pelvis
    turned back: the torso and the legs keep their rotations, the two hips change sides."""
    rest, local, root, _ = joints_to_rotations(motion)
    axis = rest.offsets[spine] / np.linalg.norm(rest.offsets[spine])
    half = Rotation.from_rotvec(np.pi * axis)
    turned = local.copy()
    turned[:, pelvis] = (Rotation.from_quat(local[:, pelvis], scalar_first=True) * half).as_quat(
        scalar_first=True
    )
    for c in rest.children(pelvis):
        turned[:, c] = (half.inv() * Rotation.from_quat(local[:, c], scalar_first=True)).as_quat(
            scalar_first=True
        )
    return forward_kinematics(rest, turned, root)


def test_real_walks_stay_in_the_range_of_other_walks_and_a_pelvis_turned_half_round_does_not(
    bandai_dir,
) -> None:
    motions = [read_motion(p) for p in sorted((bandai_dir / "data").glob("dataset-2_walk_*_00[12].bvh"))]
    motions = [m.without_joints(["joint_Root"]) for m in motions]  # the rig's root stays at the origin
    motions = [Motion(m.joints[:120], m.fps, m.skeleton) for m in motions]
    skel = motions[0].skeleton
    joint_range = JointRange.fit([m.joints for m in motions[::2]], skel)
    held = motions[1::2]
    real = joint_range.outside([m.joints for m in held], skel)
    assert len(held) == 7 and real.mean() < 3 * (1 - RANGE_QUANTILE)
    hips = hip_pair(skel)
    pelvis = int(skel.parents[hips[0]])
    (spine,) = [c for c in skel.children(pelvis) if c not in hips]
    crossed = [_pelvis_turned(m, pelvis, spine) for m in held]
    left, right = hips
    for m, c in zip(held, crossed, strict=True):  # the hips changed sides; the head stayed where it was
        assert np.all(np.sum((c[:, left] - c[:, right]) * (m.joints[:, left] - m.joints[:, right]), -1) < 0)
        head = skel.names.index("Head")
        assert np.abs(c[:, head] - m.joints[:, head]).max() < 1e-3
    # The turned joints leave the range: at least four of the sixteen rotating joints' worth per clip
    # (measured 0.28-0.31; the other walks' own 0.002-0.029).
    rotating = len(joint_range.joints)
    assert joint_range.outside(crossed, skel).min() >= 4 / rotating - 0.01
