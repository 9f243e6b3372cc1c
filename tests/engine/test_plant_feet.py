"""Decode-time foot clean-up: planted feet pinned to the floor with the leg re-solved by two-bone IK."""

from __future__ import annotations

import numpy as np
import pytest

from engine.metrics.physics import floats
from engine.motion.ik import (
    PLANT_RAMP,
    PLANT_REACH,
    PLANT_SLACK,
    joints_to_rotations,
    lower_to_floor,
    plant_feet,
)
from engine.motion.motion import Motion
from engine.motion.rotations import forward_kinematics
from tests.engine.test_metrics_physics import FPS, OFFSETS, PARENTS, skeleton, standing

FEET = [5, 6]  # Foot_L (ankle), Toes_L
HEIGHTS = np.array([0.05, 0.0])  # their resting heights in ``standing``


def _lengths(joints: np.ndarray) -> np.ndarray:
    kids = np.flatnonzero(PARENTS >= 0)
    return np.linalg.norm(joints[..., kids, :] - joints[..., PARENTS[kids], :], axis=-1)


def _sliding(t: int = 40, speed: float = 0.3, hip_height: float = 0.85) -> np.ndarray:
    """A body sliding ``speed`` m/s along z with the hip ``hip_height`` above the ankle (0.9: a straight
    leg; less: a bent knee) and the toe hovering 1 cm above the floor; every bone at its rest length."""
    clip = np.zeros((t, 7, 3))
    slide = np.arange(t) * speed / FPS - 0.2
    ankle = np.stack([np.full(t, 0.1), np.full(t, 0.06), slide], axis=1)
    hip = ankle + np.array([0.0, hip_height, 0.0])
    clip[:, 3], clip[:, 5] = hip, ankle
    clip[:, 4] = hip + np.array([0.0, -hip_height / 2, np.sqrt(max(0.45**2 - (hip_height / 2) ** 2, 0.0))])
    clip[:, 6] = ankle + OFFSETS[6]
    clip[:, 0] = hip - OFFSETS[3]
    clip[:, 1] = clip[:, 0] + OFFSETS[1]
    clip[:, 2] = clip[:, 1] + OFFSETS[2]
    return clip


def test_a_planted_sliding_foot_is_pinned_and_the_leg_keeps_its_bones() -> None:
    clip = _sliding()
    contact = np.zeros((1, 40, 2), bool)
    contact[0, 10:30, 1] = True  # toe planted for a second
    out = plant_feet(clip[None], contact, skeleton(), FEET, HEIGHTS, ground=False)[0]
    toe = out[10:30, 6]
    assert np.ptp(toe[:, [0, 2]], axis=0).max() < 1e-9  # still on the floor plane
    np.testing.assert_allclose(toe[:, 1], 0.0, atol=1e-9)  # at its resting height
    np.testing.assert_allclose(toe[:, [0, 2]], np.broadcast_to(clip[10:30, 6, [0, 2]].mean(0), (20, 2)))
    np.testing.assert_allclose(_lengths(out)[:, 2:], _lengths(clip)[:, 2:], atol=1e-9)  # leg bones kept
    np.testing.assert_allclose(out[:, :4], clip[:, :4])  # hip and above untouched
    far = list(range(0, 10 - PLANT_RAMP)) + list(range(30 + PLANT_RAMP, 40))
    np.testing.assert_allclose(out[far], clip[far], atol=1e-9)  # away from the contact nothing moves
    # the foot moves rigidly: the ankle-to-toe bone keeps its direction
    np.testing.assert_allclose(out[:, 6] - out[:, 5], clip[:, 6] - clip[:, 5], atol=1e-9)


def test_a_foot_that_slides_far_is_held_no_further_than_the_reach_from_where_it_was_decoded() -> None:
    clip = _sliding(speed=1.5, hip_height=0.8)  # 1.4 m of sliding over one contact
    contact = np.zeros((1, 40, 2), bool)
    contact[0, 10:30, 1] = True
    out = plant_feet(clip[None], contact, skeleton(), FEET, HEIGHTS, ground=False)[0]
    raw, toe = clip[10:30, 6, [0, 2]], out[10:30, 6, [0, 2]]
    to_mean = raw.mean(0) - raw
    far = np.linalg.norm(to_mean, axis=1)
    expected = raw + to_mean * (np.minimum(far, PLANT_REACH) / far)[:, None]
    np.testing.assert_allclose(toe, expected, atol=1e-9)
    held = far <= PLANT_REACH
    assert 0 < held.sum() < 20  # pinned at the contact's mean while within reach, dragged beyond it
    np.testing.assert_allclose(toe[held], np.broadcast_to(raw.mean(0), (held.sum(), 2)), atol=1e-9)
    np.testing.assert_allclose(_lengths(out)[:, 2:], _lengths(clip)[:, 2:], atol=1e-9)


def test_across_a_short_gap_the_shift_passes_linearly_from_one_contact_to_the_next() -> None:
    clip = _sliding()
    contact = np.zeros((1, 40, 2), bool)
    contact[0, 5:18, 1] = contact[0, 21:34, 1] = True  # two contacts, three free frames between them
    out = plant_feet(clip[None], contact, skeleton(), FEET, HEIGHTS, ground=False)[0]
    raw = clip[:, 6, [0, 2]]
    before, after = raw[5:18].mean(0) - raw[17], raw[21:34].mean(0) - raw[21]
    for frame, share in ((18, 1 / 4), (19, 2 / 4), (20, 3 / 4)):
        expected = raw[frame] + before + share * (after - before)
        np.testing.assert_allclose(out[frame, 6, [0, 2]], expected, atol=1e-9)
    steps = np.linalg.norm(np.diff(out[:, 6], axis=0), axis=1)
    slide = 0.3 / FPS
    # 0.2 m of shift change spread over the four steps of the gap, never in one frame
    assert steps.max() == pytest.approx(np.linalg.norm(after - before) / 4 + slide)


def test_a_contact_broken_for_two_frames_is_one_contact() -> None:
    clip = _sliding()
    contact = np.zeros((1, 40, 2), bool)
    contact[0, 5:18, 1] = contact[0, 20:33, 1] = True  # the contact head flickers off for two frames
    out = plant_feet(clip[None], contact, skeleton(), FEET, HEIGHTS, ground=False)[0]
    held = clip[5:33, 6, [0, 2]].mean(0)
    np.testing.assert_allclose(out[5:33, 6, [0, 2]], np.broadcast_to(held, (28, 2)), atol=1e-9)


def test_a_pin_past_a_straight_leg_s_reach_drags_the_foot_instead_of_lifting_it() -> None:
    clip = _sliding(speed=1.5, hip_height=0.9)  # the leg straight: any pin away from under the hip lifts it
    contact = np.zeros((1, 40, 2), bool)
    contact[0, 10:30, 1] = True
    out = plant_feet(clip[None], contact, skeleton(), FEET, HEIGHTS, ground=False)[0]
    np.testing.assert_allclose(_lengths(out)[:, 2:], _lengths(clip)[:, 2:], atol=1e-9)
    toe = out[10:30, 6]
    assert toe[:, 1].max() <= PLANT_SLACK + 1e-9  # lifted at most the slack, never 5 cm
    reachable = np.sqrt((0.9 + PLANT_SLACK) ** 2 - 0.91**2)  # the ankle comes down 1 cm, to the floor
    moved = np.linalg.norm(toe[:, [0, 2]] - clip[10:30, 6, [0, 2]], axis=1)
    assert moved.max() <= reachable + 1e-9 < PLANT_REACH
    # still held back as far as the leg allows: 1.4 m of sliding becomes under 1 m
    assert np.ptp(toe[:, 2]) < np.ptp(clip[10:30, 6, 2]) - 0.4


def test_the_cleaned_leg_is_one_a_bvh_holds() -> None:
    clip = _sliding()
    contact = np.zeros((1, 40, 2), bool)
    contact[0, 5:35, 1] = True
    out = plant_feet(clip[None], contact, skeleton(), FEET, HEIGHTS)[0]
    rest, local, root, _ = joints_to_rotations(Motion(out.astype(np.float32), FPS, skeleton()))
    np.testing.assert_allclose(forward_kinematics(rest, local, root), out, atol=1e-5)


def test_a_foot_under_the_floor_is_lifted_and_nothing_planted_moves_nothing() -> None:
    clip = standing()
    clip[:, 5:, 1] -= 0.04  # foot sunk 4 cm under its resting height
    none = np.zeros((1, 40, 2), bool)
    out = plant_feet(clip[None], none, skeleton(), FEET, HEIGHTS)[0]
    assert (out[:, 6, 1] >= -1e-9).all() and (out[:, 5, 1] >= 0.05 - 1e-9).all()
    clean = standing()
    np.testing.assert_allclose(plant_feet(clean[None], none, skeleton(), FEET, HEIGHTS)[0], clean, atol=1e-9)


def test_a_clip_whose_feet_never_come_down_is_lowered_onto_the_floor() -> None:
    clean = standing()
    bobbing = standing() + np.array([0.0, 0.15, 0.0])
    bobbing[:, :, 1] += 0.05 * np.sin(np.arange(40) / 3.0)[:, None]  # 10-20 cm up, never down
    assert floats(bobbing, FEET, FPS) and not floats(clean, FEET, FPS)
    batch = np.stack([clean, bobbing])
    lowered = lower_to_floor(batch, FEET, HEIGHTS)
    np.testing.assert_array_equal(lowered[0], clean)  # its toes reach the floor: left as it is
    drop = bobbing[:, 6, 1].min()
    np.testing.assert_allclose(lowered[1], bobbing - np.array([0.0, drop, 0.0]))  # rigidly, the whole clip
    assert lowered[1][:, 6, 1].min() == 0.0 and not floats(lowered[1], FEET, FPS)
    none = np.zeros((2, 40, 2), bool)
    out = plant_feet(batch, none, skeleton(), FEET, HEIGHTS)
    np.testing.assert_allclose(out, lowered, atol=1e-9)  # the clean-up lowers it before pinning
    np.testing.assert_allclose(plant_feet(batch, none, skeleton(), FEET, HEIGHTS, ground=False), batch)


def test_a_floating_clip_is_lowered_by_its_predicted_contacts_and_a_jump_or_a_step_is_not() -> None:
    """Three clips whose toes touch the floor somewhere (so the lowest-foot rule leaves them): a skipping
    gait that then stays 15 cm up while the model says its toe is planted, a jump (30 cm up for a second,
    planted only on the floor), and a shuffle 5 cm up (never 10 cm: it does not float)."""
    t = 40
    skip, jump, shuffle = standing(), standing(), standing()
    skip[3:, :, 1] += 0.15
    jump[10:31, :, 1] += 0.30
    shuffle[1:, :, 1] += 0.05
    batch = np.stack([skip, jump, shuffle])
    contact = np.zeros((3, t, 2), bool)
    contact[0, :3, 1] = contact[0, 20:35, 1] = True  # 3 frames on the floor, 15 at 15 cm
    contact[1, :10, 1] = contact[1, 31:, 1] = True
    contact[2, :, 1] = True
    assert floats(skip, FEET, FPS) and floats(jump, FEET, FPS) and not floats(shuffle, FEET, FPS)
    np.testing.assert_array_equal(lower_to_floor(batch, FEET, HEIGHTS), batch)  # every toe touches once
    lowered = lower_to_floor(batch, FEET, HEIGHTS, contact, FPS)
    np.testing.assert_allclose(lowered[0], skip - np.array([0.0, 0.15, 0.0]), atol=1e-12)  # median contact
    assert not floats(lowered[0], FEET, FPS)
    np.testing.assert_array_equal(lowered[1:], batch[1:])
    out = plant_feet(batch, contact, skeleton(), FEET, HEIGHTS, fps=FPS)
    np.testing.assert_allclose(out[0, 20:35, 6, 1], 0.0, atol=1e-9)  # planted toe on the floor
    assert (out[0, :, FEET, 1] >= HEIGHTS[:, None] - 1e-9).all()  # the first frames lifted back out
    np.testing.assert_allclose(_lengths(out), _lengths(batch), atol=1e-9)


def test_a_long_sequence_finds_its_floor_where_it_is_not_where_it_floats_elsewhere() -> None:
    """A 60-s stand whose body rises steadily to 0.6 m over the floor while the model says the toe is
    planted throughout: lowered clip-wide it would either stay up (the toe touches at the start) or be
    sunk by the median everywhere; over 4-s windows every frame's toe comes back to within 4 cm of the
    floor, never under it (each window is lowered to its lowest frame: at most 4 s of the 1 cm/s drift
    off). A 60-s stand on the floor with a 1-s jump is left as it is."""
    t = int(60 * FPS)
    rising = standing(t)
    rising[:, :, 1] += np.linspace(0.0, 0.6, t)[:, None]
    jump = standing(t)
    jump[600:620, :, 1] += 0.3
    contact = np.ones((2, t, 2), bool)
    contact[1, 600:620] = False
    batch = np.stack([rising, jump])
    lowered = lower_to_floor(batch, FEET, HEIGHTS, contact, FPS)
    toe = lowered[0, :, 6, 1]
    assert toe.min() >= -1e-12 and toe.max() <= 0.04 + 1e-9, (toe.min(), toe.max())
    np.testing.assert_allclose(lowered[0] - lowered[0, :, :1], rising - rising[:, :1], atol=1e-12)  # rigid
    np.testing.assert_array_equal(lowered[1], jump)
    clip_wide = lower_to_floor(batch, FEET, HEIGHTS, contact, None)  # without fps: one floor per clip
    assert np.abs(clip_wide[0, :, 6, 1]).max() > 0.5


def test_a_continuation_keeps_its_given_frames_and_holds_a_contact_where_they_planted_it() -> None:
    """A stand of 10 given frames, then 30 decoded ones sliding 0.1 m/s along z with the toe planted
    throughout (a bent knee): the given frames come back bit-identical and the toe stays where they put
    it (the whole contact's mean would have dragged it 5.8 cm on). A continuation floating 15 cm up with
    no contact is not lowered onto the floor (its given frames stand where they stand)."""
    sliding = _sliding(31, speed=0.1)  # knee bent, toe 1 cm over the floor
    clip = np.concatenate([np.repeat(sliding[:1], 10, axis=0), sliding[1:]])
    contact = np.ones((1, 40, 2), bool)
    out = plant_feet(clip[None], contact, skeleton(), FEET, HEIGHTS, fps=FPS, given=10)[0]
    np.testing.assert_array_equal(out[:10], clip[:10])
    held = clip[0, 6] - np.array([0.0, 0.01, 0.0])  # the given frames' floor point
    np.testing.assert_allclose(out[10:, 6], np.repeat(held[None], 30, axis=0), atol=1e-9)
    np.testing.assert_allclose(out[:, 0], clip[:, 0])  # the hips are not moved
    np.testing.assert_allclose(_lengths(out), _lengths(clip), atol=1e-9)
    whole = plant_feet(clip[None], contact, skeleton(), FEET, HEIGHTS, fps=FPS)[0]
    assert whole[0, 6, 2] - clip[0, 6, 2] > 0.05  # one contact pinned at its mean
    up = (standing() + np.array([0.0, 0.15, 0.0]))[None]
    none = np.zeros((1, 40, 2), bool)
    np.testing.assert_array_equal(plant_feet(up, none, skeleton(), FEET, HEIGHTS, fps=FPS, given=10), up)
    assert plant_feet(up, none, skeleton(), FEET, HEIGHTS, fps=FPS)[0, :, 6, 1].max() < 1e-9


def test_a_nearly_straight_leg_keeps_its_knee_forward_when_its_foot_is_moved_ahead() -> None:
    """Hip 0.9 m over the ankle, the knee 2 cm ahead of the line between them; the ankle pinned 0.3 m
    ahead and 15 cm up: the new hip-to-ankle line passes in front of the decoded knee, yet the knee
    bends forward of it (the side it was decoded on), never backwards, and both bones keep their
    lengths."""
    from engine.motion.ik import _two_bone

    hip, ankle = np.array([[0.0, 0.9, 0.0]]), np.array([[0.0, 0.05, 0.0]])
    knee = np.array([[0.0, 0.475, 0.02]])
    target = np.array([[0.0, 0.2, 0.3]])
    new_knee, reached = _two_bone(hip, knee, ankle, target)
    np.testing.assert_allclose(reached, target, atol=1e-9)
    np.testing.assert_allclose(np.linalg.norm(new_knee - hip), np.linalg.norm(knee - hip), atol=1e-9)
    np.testing.assert_allclose(np.linalg.norm(reached - new_knee), np.linalg.norm(ankle - knee), atol=1e-9)
    share = (hip[0, 1] - new_knee[0, 1]) / (hip[0, 1] - target[0, 1])
    assert new_knee[0, 2] > share * target[0, 2] + 0.05  # ahead of the hip-to-ankle line
