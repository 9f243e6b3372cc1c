"""Physical-plausibility metrics on clips whose answers are known by construction."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from engine.metrics import physics
from engine.motion.contact import (
    ankle_pair,
    contact_labels,
    foot_joints,
    foot_lines,
    hand_joints,
    hip_pair,
    leg_chains,
    pelvis_joint,
    shoulder_pair,
)
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
    assert foot_lines(skel) == [(5, 6)]  # the ankle and the toe below it
    assert pelvis_joint(skel) == 0  # one leg: no pair of hips, so the root


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
    assert physics.foot_skate([clip], [6], FPS, tol=0.15) == pytest.approx(2.0 * 19 / 39)  # 10 cm is planted


def test_foot_pop_is_the_99th_percentile_of_vertical_foot_speed() -> None:
    steady = standing(101)
    steady[:, 5:, 1] += np.arange(101)[:, None] * 0.4 / FPS  # feet rise at 0.4 m/s throughout
    assert physics.foot_pop([steady], [5, 6], FPS) == pytest.approx(0.4)
    assert physics.foot_pop([standing()], [5, 6], FPS) == 0.0
    smooth, popped = standing(201), standing(201)
    smooth[100:106, 6, 1] = np.linspace(0.0, 0.1, 6)  # a toe lifted 10 cm over 5 frames (0.4 m/s)...
    smooth[106:, 6, 1] = 0.1
    popped[100:, 6, 1] = 0.1  # ...and one released from the floor in a single frame (2 m/s)
    # 800 steps over the two feet joints: 5 at 0.4 m/s and 1 at 2 m/s, the rest still
    speeds = np.r_[np.zeros(794), np.full(5, 0.4), 2.0]
    assert physics.foot_pop([smooth, popped], [5, 6], FPS) == pytest.approx(np.quantile(speeds, 0.99))
    stepping, popping = standing(201), standing(201)  # a toe stepping every second: ramps against jumps
    for start in range(0, 200, 20):
        stepping[start : start + 6, 6, 1] = np.r_[np.linspace(0.0, 0.1, 5), 0.1]
        stepping[start + 6 : start + 11, 6, 1] = np.linspace(0.1, 0.0, 5)
        popping[start + 1 : start + 10, 6, 1] = 0.1
    assert physics.foot_pop([stepping], [6], FPS) == pytest.approx(0.5)
    assert physics.foot_pop([popping], [6], FPS) == pytest.approx(2.0)


def test_real_feet_lift_and_land_faster_in_runs_than_in_walks(bandai_dir) -> None:
    pops = {}
    for action in ("walk", "run"):
        clips = [
            read_motion(p) for p in sorted((bandai_dir / "data").glob(f"dataset-2_{action}_*_00[12].bvh"))
        ]
        feet = foot_joints(clips[0].skeleton)
        pops[action] = physics.foot_pop([c.joints for c in clips], feet, clips[0].fps)
    assert 0.3 < pops["walk"] < 1.5 and pops["run"] > 1.5 * pops["walk"]


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
    split = standing()
    split[5:14, :, 1] += 0.2
    split[15:24, :, 1] += 0.2  # two 9-frame spells, one frame down between them
    batch = np.stack([up, short, standing(), split, up])
    np.testing.assert_array_equal(physics.floats(batch, [5, 6], FPS), [True, False, False, False, True])


def test_limb_speed_amplitude_and_jerk_of_known_motion() -> None:
    t = np.arange(200) / FPS
    clip = standing(200)
    amp, freq = 0.2, 1.0
    clip[:, 2, 1] += amp * np.sin(2 * np.pi * freq * t)  # waving hand, whole periods
    assert physics.oscillation_amplitude(clip, [2], 0) == pytest.approx(amp / np.sqrt(2), rel=1e-3)
    # mean |d/dt| of a sine: 4·A·f per period (sampled finely enough to be within 1 %)
    assert physics.limb_speed(clip, [2], FPS) == pytest.approx(4 * amp * freq, rel=0.01)
    assert physics.limb_speed(clip, [2], FPS, last=1 / 3) == pytest.approx(4 * amp * freq, rel=0.03)
    stops = clip.copy()
    stops[100:, 2] = stops[100, 2]  # the hand waves for 5 s, then holds
    assert physics.limb_speed(stops, [2], FPS) == pytest.approx(2 * amp * freq, rel=0.02)  # half of it
    assert physics.limb_speed(stops, [2], FPS, last=1 / 3) == 0.0  # ...and none of it late
    cubic = standing(10)
    cubic[:, :, 0] += (np.arange(10) / FPS)[:, None] ** 3  # x = t³: jerk 6 m/s³ everywhere
    assert physics.mean_jerk(cubic, FPS) == pytest.approx(6.0)


def test_hand_rhythm_is_the_frequency_the_hand_shakes_at() -> None:
    t = np.arange(61) / FPS  # 60 frame steps: 3 s
    for freq in (2 / 3, 2.0):  # whole periods
        clip = standing(61)
        clip[:, 2, 1] += 0.1 * np.sin(2 * np.pi * freq * t)
        clip[:, :, 0] += 1.3 * t[:, None]  # walking on at a steady pace changes nothing
        assert physics.limb_rhythm(clip, [2], 0, FPS) == pytest.approx(freq, abs=1e-6)
    off_bin = standing(61)
    off_bin[:, 2, 1] += 0.1 * np.sin(2 * np.pi * 1.75 * t)
    assert physics.limb_rhythm(off_bin, [2], 0, FPS) == pytest.approx(1.75, abs=0.05)
    sweep_and_shake = standing(61)  # the same speed in a 2/3 Hz sweep and a 2 Hz shake: equal power
    sweep_and_shake[:, 2, 1] += 0.3 * np.sin(2 * np.pi * 2 / 3 * t) + 0.1 * np.sin(2 * np.pi * 2.0 * t)
    power = np.sinc(np.array([2 / 3, 2.0]) / FPS) ** 2  # a frame difference's gain on each speed
    expected = (power @ [2 / 3, 2.0]) / power.sum()  # about 4/3
    assert physics.limb_rhythm(sweep_and_shake, [2], 0, FPS) == pytest.approx(expected, abs=1e-6)
    assert np.isnan(physics.limb_rhythm(standing(61), [2], 0, FPS))  # a still hand has no rhythm


def test_real_waves_shake_the_hands_faster_than_raise_ups_lift_them(bandai_dir) -> None:
    rhythms = {}
    for action in ("wave-right-hand", "raise-up-right-hand"):
        paths = sorted((bandai_dir / "data").glob(f"dataset-2_{action}_*_00[12].bvh"))
        clips = [read_motion(p) for p in paths]
        row = physics.physics_metrics([c.joints for c in clips], clips[0].skeleton, clips[0].fps)
        rhythms[action] = row["hand_rhythm_hz"]
    assert (
        rhythms["wave-right-hand"] > 1.5 and rhythms["wave-right-hand"] > 1.5 * rhythms["raise-up-right-hand"]
    )


def test_physics_metrics_row() -> None:
    row = physics.physics_metrics([standing(), standing()], skeleton(), FPS)
    assert set(row) == {
        "bone_length_cv",
        "foot_skate_m_s",
        "foot_pop_m_s",
        "floor_penetration",
        "floor_depth_m",
        "float_share",
        "hand_speed_m_s",
        "hand_amplitude_m",
        "late_hand_speed_m_s",
        "foot_speed_m_s",
        "foot_amplitude_m",
        "jerk_m_s3",
        "pelvis_height_m",
    }
    assert row["hand_speed_m_s"] == 0.0 and row["float_share"] == 0.0
    assert row["pelvis_height_m"] == pytest.approx(1.0)  # no pair of legs: the root, 1 m up


def test_pelvis_height_sees_a_body_lowered_onto_its_drawn_up_feet() -> None:
    """The mean pelvis height over frames, then over clips: a clip crouched 0.4 m for half its frames reads
    0.8 m where the standing one reads 1.0, while its feet stay on the floor."""
    crouched = standing()
    crouched[20:, :5, 1] -= 0.4  # root, spine, hand, hip and knee lowered; the ankle and toe stay put
    assert physics.pelvis_height([standing()], 0) == pytest.approx(1.0)
    assert physics.pelvis_height([crouched], 0) == pytest.approx(0.8)
    assert physics.pelvis_height([standing(), crouched], 0) == pytest.approx(0.9)
    assert physics.foot_skate([crouched], [5, 6], FPS) == 0.0


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


def _torso(twist_deg: float, t: int = 10) -> np.ndarray:
    """(t, 5, 3): a pelvis (0), hips (1, 2) on the z axis and shoulders (3, 4) above them, the shoulders'
    axis turned ``twist_deg`` about +y from the hips'."""
    clip = np.zeros((t, 5, 3))
    clip[:, :, 1] = [0.9, 0.9, 0.9, 1.4, 1.4]
    clip[:, 1, 2], clip[:, 2, 2] = 0.1, -0.1
    turn = Rotation.from_euler("y", twist_deg, degrees=True)
    clip[:, 3, ::2] = turn.apply([0.0, 0.0, 0.2])[::2]
    clip[:, 4] = clip[:, 3] * [-1, 1, -1]
    return clip


def test_torso_twist_is_the_angle_between_the_shoulders_and_the_hips() -> None:
    assert np.allclose(physics.torso_twists(_torso(0.0), (1, 2), (3, 4)), 0.0)
    assert np.allclose(physics.torso_twists(_torso(30.0), (1, 2), (3, 4)), 30.0)  # about +y
    assert np.allclose(physics.torso_twists(_torso(-30.0), (1, 2), (3, 4)), -30.0)
    assert np.allclose(physics.torso_twists(_torso(170.0), (1, 2), (3, 4)), 170.0)
    # the mean absolute angle over every frame of every clip
    assert physics.torso_twist([_torso(20.0), _torso(-40.0, t=30)], (1, 2), (3, 4)) == pytest.approx(35.0)
    assert physics.torso_twist([], (1, 2), (3, 4)) == 0.0


def test_shoulders_are_the_tops_of_the_arms_on_the_hips_sides() -> None:
    # arms listed right first, fingers under the right hand; left is +x in the rest pose
    names = ("Hips", "Spine", "Chest", "Neck", "RightArm", "RightHand", "RightHandIndex", "LeftArm")
    names += ("LeftHand", "LeftUpLeg", "LeftLeg", "LeftFoot", "RightUpLeg", "RightLeg", "RightFoot")
    parents = np.array([-1, 0, 1, 2, 2, 4, 5, 2, 7, 0, 9, 10, 0, 12, 13])
    offsets = np.zeros((15, 3))
    offsets[[1, 2, 3]] = [0, 0.2, 0]
    offsets[[4, 7]] = [[-0.2, 0, 0], [0.2, 0, 0]]
    offsets[[5, 6, 8]] = [[-0.5, 0, 0], [-0.1, 0, 0], [0.5, 0, 0]]
    offsets[[9, 12]] = [[0.1, 0, 0], [-0.1, 0, 0]]
    offsets[[10, 11, 13, 14]] = [0, -0.45, 0]
    skel = Skeleton(names, parents, offsets)
    assert hip_pair(skel) == (9, 12)
    assert ankle_pair(skel) == (11, 14)
    assert foot_lines(skel) == []  # no joint below either ankle
    assert shoulder_pair(skel) == (7, 4)  # the left arm's top first, as the left hip
    one_arm = Skeleton(names[:7] + names[9:], np.array([-1, 0, 1, 2, 2, 4, 5, 0, 7, 8, 0, 10, 11]),
                       np.delete(offsets, [7, 8], axis=0))  # fmt: skip
    assert shoulder_pair(one_arm) is None
    row = physics.physics_metrics([np.repeat(skel.rest_positions()[None], 10, axis=0)], skel, FPS)
    assert row["torso_twist_deg"] == pytest.approx(0.0)


def test_real_walks_keep_the_shoulders_over_the_hips_and_a_twisted_chest_does_not(bandai_dir) -> None:
    clips = [read_motion(p) for p in sorted((bandai_dir / "data").glob("dataset-2_walk_*_001.bvh"))]
    skel = clips[0].skeleton
    hips, shoulders = hip_pair(skel), shoulder_pair(skel)
    assert [skel.names[j] for j in (*hips, *shoulders)] == [
        "UpperLeg_L",
        "UpperLeg_R",
        "Shoulder_L",
        "Shoulder_R",
    ]
    real = physics.torso_twist([c.joints for c in clips], hips, shoulders)
    assert len(clips) == 7 and real < 12.0  # one walk per style: 6.8° (2.2° to 13.7°)
    chest = int(skel.parents[shoulders[0]])
    above = [j for j in range(skel.n_joints) if j != chest and _below(skel.parents, j, chest)]
    twisted = []
    for c in clips:  # everything above the chest turned 30° about the chest's vertical
        pos = c.joints.copy()
        local = pos[:, above] - pos[:, chest : chest + 1]
        turn = Rotation.from_euler("y", 30, degrees=True)
        pos[:, above] = turn.apply(local.reshape(-1, 3)).reshape(local.shape) + pos[:, chest : chest + 1]
        twisted.append(pos)
    assert physics.torso_twist(twisted, hips, shoulders) > real + 15.0  # measured 29.1


def _feet_swinging(alternate: bool, frames: int = 61) -> np.ndarray:
    """(frames, 3, 3): a root walking along x at 1 m/s, two ankles either side swinging 0.2 m fore and aft
    at 1 Hz (20 fps), in turn or together."""
    t = np.arange(frames) / FPS
    clip = np.zeros((frames, 3, 3))
    clip[:, :, 0] = t[:, None]
    clip[:, 1, 2], clip[:, 2, 2] = 0.1, -0.1
    swing = 0.2 * np.sin(2 * np.pi * t)
    clip[:, 1, 0] += swing
    clip[:, 2, 0] += -swing if alternate else swing
    return clip


def test_foot_sync_is_minus_one_for_alternating_feet_and_one_for_a_hop() -> None:
    walk, hop = _feet_swinging(True), _feet_swinging(False)
    still = _feet_swinging(True)
    still[:, 1:] = still[:, 0:1] + [[0.0, 0.0, 0.1], [0.0, 0.0, -0.1]]  # carried along with the root
    np.testing.assert_allclose(physics.foot_syncs([walk, hop], (1, 2), 0), [-1.0, 1.0], atol=1e-12)
    assert np.isnan(physics.foot_syncs([still], (1, 2), 0)).all()
    assert physics.foot_sync([walk, still, hop, hop], (1, 2), 0) == pytest.approx(1 / 3)  # still left out
    assert np.isnan(physics.foot_sync([still], (1, 2), 0))


def test_real_gaits_alternate_their_feet(bandai_dir) -> None:
    paths = sorted((bandai_dir / "data").glob("dataset-2_walk_*_00[12].bvh"))
    paths += sorted((bandai_dir / "data").glob("dataset-2_run_*_00[12].bvh"))
    clips = [read_motion(p) for p in paths]
    skel = clips[0].skeleton
    ankles = ankle_pair(skel)
    assert [skel.names[j] for j in ankles] == ["Foot_L", "Foot_R"]
    pelvis = int(skel.parents[hip_pair(skel)[0]])
    assert skel.names[pelvis] == "Hips" and skel.root != pelvis  # the rig's root stays at the origin
    assert pelvis_joint(skel) == pelvis
    syncs = physics.foot_syncs([c.joints for c in clips], ankles, pelvis)
    assert len(clips) == 28 and (syncs < 0).all()
    row = physics.physics_metrics([c.joints for c in clips], skel, clips[0].fps)
    assert row["foot_sync"] == pytest.approx(np.mean(syncs))


def _below(parents: np.ndarray, j: int, ancestor: int) -> bool:
    """Whether joint ``j`` lies in the subtree of ``ancestor``."""
    while j >= 0:
        if j == ancestor:
            return True
        j = int(parents[j])
    return False


def _stepping(toes_forward: bool, frames: int = 41) -> np.ndarray:
    """(frames, 3, 3): a root walking along +z at 1 m/s, an ankle 10 cm up and its toe on the floor 12 cm
    ahead of it (or behind), planted for the first half of each second and lifted 20 cm for the rest."""
    t = np.arange(frames) / FPS
    clip = np.zeros((frames, 3, 3))
    clip[:, :, 2] = t[:, None]
    lifted = (t % 1.0) >= 0.5
    clip[:, 1, 1] = 0.1 + 0.2 * lifted
    clip[:, 2, 1] = 0.2 * lifted
    clip[:, 2, 2] += 0.12 if toes_forward else -0.12
    return clip


def test_feet_backward_counts_planted_feet_pointing_against_travel() -> None:
    forward, backward = _stepping(True), _stepping(False)
    assert physics.feet_backward([forward], [(1, 2)], 0, FPS) == 0.0
    assert physics.feet_backward([backward], [(1, 2)], 0, FPS) == 1.0
    assert physics.feet_backward([forward, backward], [(1, 2)], 0, FPS) == pytest.approx(0.5)
    swung = backward.copy()
    swung[:, 2, 2] = forward[:, 2, 2]
    lifted = swung[:, 2, 1] > 0.1
    swung[lifted, 2, 2] = backward[lifted, 2, 2]  # backwards only while in the air: not counted
    assert physics.feet_backward([swung], [(1, 2)], 0, FPS) == 0.0
    standing = forward.copy()
    standing[:, :, 2] -= np.arange(len(standing))[:, None] / FPS  # the same feet, no travel
    assert np.isnan(physics.feet_backward([standing], [(1, 2)], 0, FPS))


def test_real_gaits_put_their_feet_down_pointing_forwards(bandai_dir) -> None:
    paths = sorted((bandai_dir / "data").glob("dataset-2_walk_*_00[12].bvh"))
    paths += sorted((bandai_dir / "data").glob("dataset-2_run_*_00[12].bvh"))
    clips = [read_motion(p) for p in paths]
    skel = clips[0].skeleton
    row = physics.physics_metrics([c.joints for c in clips], skel, clips[0].fps)
    assert row["feet_backward"] < 0.01
    turned = []  # every foot turned round about its ankle, seen from above
    for clip in clips:
        joints = clip.joints.copy()
        for _, _, ankle, below in leg_chains(skel):
            joints[:, below, ::2] = 2 * joints[:, ankle : ankle + 1, ::2] - joints[:, below, ::2]
        turned.append(joints)
    assert physics.physics_metrics(turned, skel, clips[0].fps)["feet_backward"] > 0.99
