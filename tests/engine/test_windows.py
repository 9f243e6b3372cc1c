"""Training windows: random starts, padding, canonical facing, stored rotation, left/right heuristics."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from engine.errors import DataError
from engine.motion.bvh import read_bvh
from engine.motion.motion import Motion
from engine.motion.skeleton import Skeleton
from engine.train.windows import canonicalize, crop_windows, left_right_pairs, prepare_clips
from tests.fixtures.procedural import PROCEDURAL_ACTIONS, procedural_skeleton

pytestmark = pytest.mark.usefixtures("torch_single_thread")


def _clip(frames: int, action: str = "walk", seed: int = 0) -> Motion:
    rng = np.random.default_rng(seed)
    joints = rng.normal(size=(frames, 11, 3)).astype(np.float32)
    return Motion(joints, 20.0, procedural_skeleton(), action=action)


def test_every_valid_start_is_reachable_and_uniform() -> None:
    prepared = prepare_clips([_clip(65)], PROCEDURAL_ACTIONS, 20.0, 60)
    batch = crop_windows(prepared, np.zeros(1200, dtype=int), np.random.default_rng(1))
    counts = np.bincount(batch.starts, minlength=6)
    assert len(counts) == 6  # starts 0..5 inclusive (65 − 60 = 5 is the last valid one)
    assert counts.min() > 150  # expected 200 each
    assert batch.mask.all()


def test_window_content_is_the_cropped_clip_in_canonical_frame() -> None:
    clip = _clip(80)
    prepared = prepare_clips([clip], PROCEDURAL_ACTIONS, 20.0, 60)
    batch = crop_windows(prepared, [0, 0, 0], np.random.default_rng(2))
    restored = batch.restore(batch.joints)
    for b in range(3):
        s = batch.starts[b]
        np.testing.assert_allclose(restored[b], clip.joints[s : s + 60], atol=1e-5)
        np.testing.assert_allclose(batch.joints[b, 0, 0], 0.0, atol=1e-6)


def test_short_clip_is_padded_with_its_last_frame_and_masked() -> None:
    clip = _clip(40)
    prepared = prepare_clips([clip], PROCEDURAL_ACTIONS, 20.0, 60)
    batch = crop_windows(prepared, [0], np.random.default_rng(0))
    assert batch.starts[0] == 0
    assert batch.mask[0].sum() == 40 and not batch.mask[0, 40:].any()
    np.testing.assert_array_equal(batch.joints[0, 40:], np.broadcast_to(batch.joints[0, 39], (20, 11, 3)))
    np.testing.assert_allclose(batch.ends[0], batch.joints[0, 39, 0])


def test_centre_crop_without_rng() -> None:
    prepared = prepare_clips([_clip(100)], PROCEDURAL_ACTIONS, 20.0, 60)
    assert crop_windows(prepared, [0], None).starts[0] == 20


def _standing(skeleton: Skeleton) -> np.ndarray:
    """(1, J, 3) rest pose (faces +z, left is +x)."""
    pos = np.zeros((skeleton.n_joints, 3))
    for j, p in enumerate(skeleton.parents):
        pos[j] = skeleton.offsets[j] + (pos[p] if p >= 0 else 0.0)
    return pos[None]


@pytest.mark.parametrize("yaw", [0.0, 0.7, -2.0, np.pi / 2, 3.0])
def test_canonical_facing_known_answer(yaw: float) -> None:
    skeleton = procedural_skeleton()
    rest = _standing(skeleton)
    shift = np.array([3.0, 0.5, -1.0])
    turned = Rotation.from_euler("y", yaw).apply(rest.reshape(-1, 3)).reshape(rest.shape) + shift
    canon, found = canonicalize(turned.astype(np.float32), skeleton)
    assert np.isclose(np.angle(np.exp(1j * (found - yaw))), 0.0, atol=1e-5)
    np.testing.assert_allclose(canon, rest - rest[:, :1], atol=1e-5)
    left, right = skeleton.index("LeftUpLeg"), skeleton.index("RightUpLeg")
    assert canon[0, left, 0] > 0 > canon[0, right, 0]


def test_canonical_facing_of_a_rotated_walk_heads_along_plus_z(procedural_clips: list[Motion]) -> None:
    walk = next(c for c in procedural_clips if c.meta["style"] == "march")
    canon, _ = canonicalize(walk.joints, walk.skeleton)
    travel = canon[-1, 0] - canon[0, 0]
    assert travel[2] > 0.5 and abs(travel[0]) < 0.05 * travel[2]


def test_left_right_pairs_by_name_and_fallback() -> None:
    names = ("Hips", "Spine", "UpperLeg_L", "UpperLeg_R", "Shoulder_L", "Shoulder_R")
    offsets = [(0, 1, 0), (0, 0.2, 0), (0.1, 0, 0), (-0.1, 0, 0), (0.2, 0.3, 0), (-0.2, 0.3, 0)]
    bandai_like = Skeleton(names, np.array([-1, 0, 0, 0, 1, 1]), np.array(offsets))
    assert left_right_pairs(bandai_like) == [(2, 3), (4, 5)]
    anonymous = Skeleton(("a", "b", "c", "d"), np.array([-1, 0, 0, 0]), np.array(offsets[:4]))
    assert left_right_pairs(anonymous) == [(2, 3)]


def test_real_skeleton_left_right_pairs(bandai_dir) -> None:
    first = sorted((bandai_dir / "data").glob("*.bvh"))[0]
    skeleton = read_bvh(first).skeleton
    pairs = left_right_pairs(skeleton)
    assert {(skeleton.names[a], skeleton.names[b]) for a, b in pairs} >= {
        (n.replace("_R", "_L"), n) for n in skeleton.names if n.startswith("UpperLeg") and n.endswith("_R")
    }
    assert len(pairs) == 2


def test_prepare_clips_rejects_bad_labels_and_skeletons() -> None:
    with pytest.raises(DataError, match="not one of"):
        prepare_clips([_clip(30, action="swim")], PROCEDURAL_ACTIONS, 20.0, 60)
    other = Skeleton(("r", "a"), np.array([-1, 0]), np.zeros((2, 3)))
    odd = Motion(np.zeros((30, 2, 3), np.float32), 20.0, other, action="walk", meta={"source": "odd.bvh"})
    with pytest.raises(DataError, match=r"odd\.bvh: skeleton differs"):
        prepare_clips([_clip(30), odd], PROCEDURAL_ACTIONS, 20.0, 60)


def test_prepare_clips_resamples_to_model_fps() -> None:
    clip = _clip(61)
    fast = Motion(clip.joints, 40.0, clip.skeleton, action="walk")
    prepared = prepare_clips([fast], PROCEDURAL_ACTIONS, 20.0, 60)
    assert len(prepared.joints[0]) == 31
    np.testing.assert_allclose(prepared.joints[0][-1], clip.joints[-1], atol=1e-5)
