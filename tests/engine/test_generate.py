"""Generation API on the tiny trained model: decode, end locations, sampling, interpolation, encode."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from engine.errors import ConfigError
from engine.generate import (
    action_index,
    decode,
    decode_array,
    decode_batch,
    encode,
    interpolate,
    interpolation_codes,
    neighbours,
    resolve_ends,
    sample,
)
from engine.generate._decode import display_lift
from engine.modelio import LoadedModel, load_model
from engine.motion.motion import Motion
from engine.motion.resample import resample_motion
from engine.motion.skeleton import Skeleton


@pytest.fixture(scope="module")
def loaded(tiny_model_dir) -> LoadedModel:
    """The tiny model with its latent bank."""
    return load_model(tiny_model_dir)


def _code(loaded: LoadedModel, i: int) -> np.ndarray:
    return np.asarray(loaded.bank.codes[i], dtype=np.float32)


def test_decode_returns_a_motion_with_provenance(loaded):
    i = int(loaded.bank.indices_of(1)[0])
    motion = decode(loaded, _code(loaded, i), loaded.action_names[1], mode=2, seed=7)
    assert motion.joints.shape == (loaded.window, loaded.skeleton.n_joints, 3)
    assert motion.fps == loaded.fps and motion.skeleton is loaded.skeleton
    assert motion.action == loaded.action_names[1]
    assert motion.meta["code"] == pytest.approx(_code(loaded, i).tolist())
    assert motion.meta["end"] == pytest.approx(loaded.bank.ends[i].tolist(), abs=1e-6)
    assert (motion.meta["mode"], motion.meta["seed"], motion.meta["model"]) == (2, 7, str(loaded.path))
    same = decode(loaded, _code(loaded, i), 1)
    np.testing.assert_array_equal(same.joints, motion.joints)


def test_decoded_motion_starts_at_display_height(loaded):
    codes = loaded.bank.codes[:4]
    joints, trajectory = decode_array(loaded, codes, loaded.bank.actions[:4], loaded.bank.ends[:4])
    np.testing.assert_array_equal(trajectory[:, 0, [0, 2]], 0.0)
    lowered = loaded.root_height - trajectory[:, 0, 1]  # the foot clean-up only ever lowers a clip
    assert np.all(lowered >= 0) and np.all(lowered < 0.25)
    # root-relative poses: the root is the trajectory, lowered onto the floor together with the body
    np.testing.assert_allclose(joints[:, :, loaded.skeleton.root], trajectory, atol=1e-5)


def test_decode_batch_matches_single_decodes(loaded):
    idx = loaded.bank.indices_of(0)[:5]
    motions = decode_batch(loaded, loaded.bank.codes[idx], 0)
    assert len(motions) == 5
    for i, m in zip(idx, motions, strict=True):
        np.testing.assert_allclose(m.joints, decode(loaded, _code(loaded, i), 0).joints, atol=1e-5)


def test_end_location_is_predicted_smoothly_from_the_bank(loaded):
    idx = loaded.bank.indices_of(2)
    a, b = _code(loaded, idx[0]), _code(loaded, idx[1])
    np.testing.assert_allclose(resolve_ends(loaded, a[None], 2, None)[0], loaded.bank.ends[idx[0]], atol=1e-6)
    path = interpolation_codes(a, b, 201, "linear", np.zeros_like(a))
    ends = resolve_ends(loaded, path, 2, None)
    jumps = np.linalg.norm(np.diff(ends, axis=0), axis=1)
    span = np.linalg.norm(loaded.bank.ends[idx].max(axis=0) - loaded.bank.ends[idx].min(axis=0))
    # A 1-NN rule would jump by a whole neighbour's difference in one step; the blend moves in small steps.
    assert jumps.max() < 0.05 * max(span, 1e-3)
    decoded = decode(loaded, a, 2)
    given = decode(loaded, a, 2, end=loaded.bank.ends[idx[0]])
    np.testing.assert_allclose(decoded.joints, given.joints, atol=1e-5)


def test_a_given_end_location_is_reached_by_the_generated_root(loaded):
    action = 0
    code = loaded.bank.codes[loaded.bank.indices_of(action)[0]]
    predicted = resolve_ends(loaded, code[None], action, None)
    target = predicted[0] + np.float32([0.4, 0.0, -0.3])
    lift = display_lift(loaded)
    root = loaded.skeleton.root
    steered, _ = decode_array(loaded, code[None], np.array([action]), target[None])
    default, _ = decode_array(loaded, code[None], np.array([action]), predicted)
    miss = np.linalg.norm(steered[0, -1, root] - lift - target)
    assert miss < 0.1 < np.linalg.norm(default[0, -1, root] - lift - target)


def test_floor_end_takes_height_from_the_bank(loaded):
    code = _code(loaded, 0)
    action = int(loaded.bank.actions[0])
    end = resolve_ends(loaded, code[None], action, [1.5, -0.5])[0]
    predicted = loaded.bank.end_location(code[None], action)[0]
    np.testing.assert_allclose(end, [1.5, predicted[1], -0.5], atol=1e-6)
    with pytest.raises(ConfigError, match="end"):
        resolve_ends(loaded, code[None], action, [1.0, 2.0, 3.0, 4.0])


def test_unknown_actions_and_bad_codes_raise(loaded):
    with pytest.raises(ConfigError, match="unknown action 'fly'"):
        action_index(loaded, "fly")
    with pytest.raises(ConfigError, match="out of range"):
        decode(loaded, _code(loaded, 0), len(loaded.action_names))
    with pytest.raises(ConfigError, match="values"):
        decode(loaded, np.zeros(loaded.config.latent_dim + 1), 0)


@pytest.mark.parametrize("strategy", ["mode_preserving", "conventional"])
def test_sample_draws_from_the_mode_model_and_keeps_mode_indices(loaded, strategy):
    samples = sample(loaded, 1, 6, 123, strategy=strategy)
    codes, modes = loaded.bank.modes[1].sample(6, np.random.default_rng(123), strategy=strategy)
    np.testing.assert_allclose(np.stack([s.code for s in samples]), codes, atol=1e-6)
    assert [s.mode for s in samples] == modes.tolist()
    assert all(s.motion.meta["mode"] == s.mode and s.motion.meta["seed"] == 123 for s in samples)
    if strategy == "conventional":
        assert {s.mode for s in samples} == {-1}


def test_sample_one_mode_and_weights(loaded):
    k = loaded.bank.modes[0].n_modes_
    last = k - 1
    assert {s.mode for s in sample(loaded, 0, 4, np.random.default_rng(1), "mode", mode=last)} == {last}
    weights = np.eye(k)[0]
    assert {s.mode for s in sample(loaded, 0, 4, 2, "weights", weights=weights)} == {0}
    with pytest.raises(ConfigError):
        sample(loaded, 0, 2, 0, "mode", mode=k)
    with pytest.raises(ConfigError):
        sample(loaded, 0, 2, 0, "nearest")


def test_sample_with_given_end_uses_it(loaded):
    (s,) = sample(loaded, 0, 1, 5, end=[0.3, 0.0, 1.2])
    np.testing.assert_array_equal(s.end, np.float32([0.3, 0.0, 1.2]))


@pytest.mark.parametrize("method", ["linear", "slerp"])
def test_interpolation_endpoints_equal_decodes(loaded, method):
    idx = loaded.bank.indices_of(0)
    a, b = _code(loaded, idx[0]), _code(loaded, idx[-1])
    steps = interpolate(loaded, a, b, 0, 5, method=method)
    assert len(steps) == 5
    np.testing.assert_array_equal(steps[0].motion.joints, decode(loaded, a, 0).joints)
    np.testing.assert_array_equal(steps[-1].motion.joints, decode(loaded, b, 0).joints)
    ends = np.stack([s.end for s in steps])
    np.testing.assert_allclose(ends[2], (ends[0] + ends[-1]) / 2, atol=1e-6)
    np.testing.assert_allclose(ends[0], loaded.bank.ends[idx[0]], atol=1e-6)


def test_interpolation_code_paths():
    a, b, centre = np.array([2.0, 0.0, 1.0]), np.array([0.0, 4.0, 1.0]), np.array([0.0, 0.0, 1.0])
    linear = interpolation_codes(a, b, 5, "linear", centre)
    np.testing.assert_allclose(linear[2], [1.0, 2.0, 1.0])
    slerp = interpolation_codes(a, b, 5, "slerp", centre)
    rel = slerp - centre
    np.testing.assert_allclose(np.linalg.norm(rel, axis=1), [2.0, 2.5, 3.0, 3.5, 4.0], rtol=1e-6)
    angles = np.degrees(np.arctan2(rel[:, 1], rel[:, 0]))
    np.testing.assert_allclose(angles, [0.0, 22.5, 45.0, 67.5, 90.0], atol=1e-4)
    np.testing.assert_array_equal(slerp[[0, -1]], np.float32([a, b]))


def test_neighbours_stay_within_the_radius(loaded):
    centre = _code(loaded, 3)
    action = int(loaded.bank.actions[3])
    near = neighbours(loaded, centre, action, 8, 0.3, np.random.default_rng(0))
    distances = np.linalg.norm(np.stack([s.code for s in near]) - centre, axis=1)
    assert len(near) == 8 and distances.max() <= 0.3 + 1e-5 and distances.min() > 0
    assert all(0 <= s.mode < loaded.bank.modes[action].n_modes_ for s in near)
    (same,) = neighbours(loaded, centre, action, 1, 0.0, 0)
    np.testing.assert_array_equal(same.motion.joints, decode(loaded, centre, action).joints)


def test_encode_reproduces_the_bank_codes_and_guesses_the_action(loaded, procedural_clips):
    by_source = {c.meta["source"]: c for c in procedural_clips}
    hits = 0
    picks = range(0, len(loaded.bank.codes), max(1, len(loaded.bank.codes) // 12))
    for i in picks:
        clip = by_source[str(loaded.bank.sources[i])]
        code, guess = encode(loaded, dataclasses.replace(clip, action=None))
        np.testing.assert_allclose(code, loaded.bank.codes[i], atol=1e-4)
        hits += guess == int(loaded.bank.actions[i])
    assert hits >= 0.8 * len(picks)


def test_encode_resamples_to_the_model_rate(loaded, procedural_clips):
    clip = procedural_clips[0]
    code, _ = encode(loaded, clip)
    faster, _ = encode(loaded, resample_motion(clip, clip.fps * 3))
    spread = np.linalg.norm(loaded.bank.codes.std(axis=0))
    assert np.linalg.norm(faster - code) < 0.1 * spread


def test_encode_rejects_another_skeleton(loaded, procedural_clips):
    clip = procedural_clips[0]
    names = tuple(f"X{n}" for n in clip.skeleton.names)
    other = Skeleton(names, clip.skeleton.parents, clip.skeleton.offsets)
    with pytest.raises(ConfigError, match=r"XHips.*Hips"):
        encode(loaded, Motion(clip.joints, clip.fps, other))


def test_encode_drops_extra_joints_the_model_does_not_have(loaded, procedural_clips):
    clip = procedural_clips[0]
    skel = clip.skeleton
    # A Bandai-style ground-projected root above the model's root joint.
    ground = np.concatenate([clip.joints[:, :1] * np.float32([1, 0, 1]), clip.joints], axis=1)
    extra = Skeleton(
        ("Ground", *skel.names),
        np.concatenate([[-1], np.where(skel.parents < 0, 0, skel.parents + 1)]),
        np.concatenate([np.zeros((1, 3)), skel.offsets]),
    )
    code, _ = encode(loaded, clip)
    with_ground, _ = encode(loaded, Motion(ground, clip.fps, extra))
    np.testing.assert_allclose(with_ground, code, atol=1e-5)
