"""Physical-plausibility metrics on clips whose answers are known by construction."""

from __future__ import annotations

import numpy as np
import pytest

from engine.metrics import physics
from engine.motion.contact import contact_labels, foot_joints, hand_joints, leg_chains
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
