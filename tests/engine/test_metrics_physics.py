"""Physical-plausibility metrics on clips whose answers are known by construction."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from engine.metrics import physics
from engine.motion.contact import contact_labels, foot_joints, hand_joints, leg_chains
from engine.motion.formats import read_motion
from engine.motion.skeleton import Skeleton

FPS = 20.0
# root, spine, hand (child of spine), hip_L, knee_L, Foot_L, Toes_L
NAMES = ("Hips", "Spine", "Hand_L", "UpperLeg_L", "LowerLeg_L", "Foot_L", "Toes_L")
PARENTS = np.array([-1, 0, 1, 0, 3, 4, 5])
OFFSETS = np.array(
    [[0, 1.0, 0], [0, 0.3, 0], [0.5, 0, 0], [0.1, -0.05, 0], [0, -0.45, 0], [0, -0.45, 0], [0, -0.05, 0.1]]
)


def skeleton() -> Skeleton:
    return Skeleton(NAMES, PARENTS, OFFSETS)


def standing(t: int = 40) -> np.ndarray:
    """A still rest pose: toes at y = 0.0, ankle at 0.05."""
    rest = np.zeros((7, 3))
    for j, p in enumerate(PARENTS):
        rest[j] = OFFSETS[j] + (rest[p] if p >= 0 else 0.0)
    return np.repeat(rest[None], t, axis=0)


def test_joint_lookups_by_name() -> None:
    skel = skeleton()
    assert foot_joints(skel) == [5, 6]
    assert hand_joints(skel) == [2]
    assert leg_chains(skel) == [(3, 4, 5, [6])]


def test_a_stretched_bone_has_the_cv_of_its_lengths() -> None:
    clip = standing()
    clip[::2, 2, 0] += 0.1  # hand bone alternates 0.5 and 0.6 m
    lengths = np.where(np.arange(40) % 2 == 0, 0.6, 0.5)
    assert physics.bone_length_cv(clip, PARENTS) == pytest.approx(lengths.std() / lengths.mean())
    assert physics.bone_length_cv(standing(), PARENTS) == pytest.approx(0.0, abs=1e-9)
    assert physics.median_bone_length_cv([clip, standing(), standing()], PARENTS) == pytest.approx(
        0.0, abs=1e-9
    )


def test_a_sliding_foot_skates_at_its_speed() -> None:
    clip = standing()
    clip[:, :, 0] += np.arange(40)[:, None] * 0.3 / FPS  # whole body slides at 0.3 m/s along x
    assert physics.foot_skate([clip], [5, 6], FPS) == pytest.approx(0.3)
    assert physics.foot_skate([standing()], [5, 6], FPS) == pytest.approx(0.0)
    lifted = clip.copy()
    lifted[:, 5:, 1] += 0.2  # feet lifted above the tolerance: only the lowest counts as planted
    assert physics.foot_skate([lifted], [5, 6], FPS) == pytest.approx(0.3)


def test_a_foot_that_swings_high_is_not_planted() -> None:
    clip = standing()
    clip[20:, 6, 1] += 0.1  # toe up from frame 20 and moving fast
    clip[20:, 6, 0] += np.arange(20) * 0.1
    assert physics.foot_skate([clip], [6], FPS) == pytest.approx(0.0)


def test_a_sinking_clip_penetrates_the_floor() -> None:
    clip = standing()
    clip[:, :, 1] -= np.linspace(0.0, 0.1, 40)[:, None]  # toes sink to 10 cm under the floor
    share, depth = physics.floor_penetration([clip], [5, 6])
    assert share == pytest.approx(np.mean(np.linspace(0.0, 0.1, 40) > 0.02))
    assert depth == pytest.approx(0.1)
    assert physics.floor_penetration([standing()], [5, 6]) == pytest.approx((0.0, 0.0), abs=1e-9)


def test_a_floating_clip_floats_for_half_a_second() -> None:
    up = standing()
    up[10:20, :, 1] += 0.2  # 10 frames = 0.5 s at 20 fps
    short = standing()
    short[10:19, :, 1] += 0.2  # 9 frames
    assert physics.floats(up, [5, 6], FPS)
    assert not physics.floats(short, [5, 6], FPS)
    assert physics.float_share([up, short, standing(), up], [5, 6], FPS) == pytest.approx(0.5)


def test_limb_speed_amplitude_and_jerk_of_known_motion() -> None:
    t = np.arange(200) / FPS
    clip = standing(200)
    amp, freq = 0.2, 1.0
    clip[:, 2, 1] += amp * np.sin(2 * np.pi * freq * t)  # waving hand, whole periods
    assert physics.oscillation_amplitude(clip, [2], 0) == pytest.approx(amp / np.sqrt(2), rel=1e-3)
    # mean |d/dt| of a sine: 4·A·f per period (sampled finely enough to be within 1 %)
    assert physics.limb_speed(clip, [2], FPS) == pytest.approx(4 * amp * freq, rel=0.01)
    cubic = standing(10)
    cubic[:, :, 0] += (np.arange(10) / FPS)[:, None] ** 3  # x = t³: jerk 6 m/s³ everywhere
    assert physics.mean_jerk(cubic, FPS) == pytest.approx(6.0)


def test_physics_metrics_row() -> None:
    row = physics.physics_metrics([standing(), standing()], skeleton(), FPS)
    assert set(row) == {
        "bone_length_cv",
        "foot_skate_m_s",
        "floor_penetration",
        "floor_depth_m",
        "float_share",
        "hand_speed_m_s",
        "hand_amplitude_m",
        "foot_speed_m_s",
        "foot_amplitude_m",
        "jerk_m_s3",
    }
    assert row["hand_speed_m_s"] == 0.0 and row["float_share"] == 0.0


def test_contact_labels_need_low_and_slow() -> None:
    clip = standing()
    clip[20:, 6, 1] += 0.1  # toe lifted
    clip[:, 5, 0] += np.arange(40) * 0.05  # ankle slides at 1 m/s
    labels = contact_labels(clip, FPS, [5, 6], np.array([0.05, 0.0]))
    assert labels.shape == (40, 2)
    assert not labels[:, 0].any()
    assert labels[:20, 1].all() and not labels[20:, 1].any()


def _walker(crab_deg: float, speed: float = 1.2, sway: float = 0.0, t: int = 40) -> np.ndarray:
    """Root (0) and two hips (1, 2) walking along +x, the hip axis turned ``crab_deg`` from +z, the root
    swaying ``sway`` metres sideways at 2 Hz (a stride's sway)."""
    time = np.arange(t) / FPS
    clip = np.zeros((t, 3, 3))
    clip[:, 0, 0] = speed * time
    clip[:, 0, 2] = sway * np.sin(2 * np.pi * 2.0 * time)
    clip[:, 0, 1] = 0.9
    half = 0.1 * np.array([np.sin(np.radians(crab_deg)), 0.0, np.cos(np.radians(crab_deg))])
    clip[:, 1], clip[:, 2] = clip[:, 0] + half, clip[:, 0] - half
    return clip


def test_heading_is_the_angle_between_facing_and_travel() -> None:
    assert physics.heading_error([_walker(0.0)], (1, 2), 0, FPS) == pytest.approx(0.0, abs=1e-9)
    assert physics.heading_error([_walker(30.0)], (1, 2), 0, FPS) == pytest.approx(30.0)
    assert physics.heading_error([_walker(-30.0)], (2, 1), 0, FPS) == pytest.approx(30.0)  # either hip first
    assert physics.heading_error([_walker(90.0)], (1, 2), 0, FPS) == pytest.approx(90.0)  # side-stepping
    # a 5 cm sway at 2 Hz is a stride's, not a heading: over half a second it cancels
    assert physics.heading_error([_walker(0.0, sway=0.05)], (1, 2), 0, FPS) < 1.0
    # standing still has no direction of travel; slow spans and standing clips do not count
    still = _walker(45.0, speed=0.0)
    assert physics.heading_errors(still, (1, 2), 0, FPS).size == 0
    assert physics.heading_error([still, _walker(10.0)], (1, 2), 0, FPS) == pytest.approx(10.0)
    assert physics.heading_error([still], (1, 2), 0, FPS) == 0.0


def test_heading_is_in_the_row_of_a_skeleton_with_two_legs() -> None:
    names = ("Hips", "UpperLeg_L", "LowerLeg_L", "Foot_L", "UpperLeg_R", "LowerLeg_R", "Foot_R")
    parents = np.array([-1, 0, 1, 2, 0, 4, 5])
    offsets = np.array(
        [[0, 0.9, 0], [0, 0, 0.1], [0, -0.4, 0], [0, -0.4, 0], [0, 0, -0.1], [0, -0.4, 0], [0, -0.4, 0]]
    )
    walk = np.zeros((40, 7, 3))
    walk[:, [0, 1, 4]] = _walker(20.0)
    walk[:, [2, 3]] = walk[:, [1]] - [0, 0.4, 0]
    walk[:, [5, 6]] = walk[:, [4]] - [0, 0.4, 0]
    row = physics.physics_metrics([walk], Skeleton(names, parents, offsets), FPS)
    assert row["heading_error_deg"] == pytest.approx(20.0)


def test_real_walks_face_where_they_go_and_a_turned_body_does_not(bandai_dir) -> None:
    clips = [read_motion(p) for p in sorted((bandai_dir / "data").glob("dataset-2_walk_*.bvh"))[:6]]
    skel = clips[0].skeleton
    (hip_a, *_), (hip_b, *_) = leg_chains(skel)
    root = int(skel.parents[hip_a])  # the pelvis: the raw files' root joint stays at the origin
    real = physics.heading_error([c.joints for c in clips], (hip_a, hip_b), root, clips[0].fps)
    assert real < 12.0  # measured 7.5° over 60 walks
    turned = []
    for c in clips:  # the body turned 30° about its root, the root's path kept: a crab-walk
        local = c.joints - c.joints[:, root : root + 1]
        turned.append(
            Rotation.from_euler("y", 30, degrees=True).apply(local.reshape(-1, 3)).reshape(local.shape)
        )
        turned[-1] += c.joints[:, root : root + 1]
    crab = physics.heading_error(turned, (hip_a, hip_b), root, clips[0].fps)
    assert crab > real + 15.0  # measured 28.0 against 8.4
