"""Engine helpers of the explorer: chaining motions, neighbours, covering subsets, windows, cross-action,
the selection summary and the local mode."""

from __future__ import annotations

import numpy as np
import pytest

from engine.errors import ConfigError
from engine.generate import (
    bank_window,
    chain_motions,
    decode,
    encode_windows,
    interpolate_across,
    step_actions,
    window_starts,
)
from engine.latent.modes import ModeModel
from engine.latent.neighbours import nearest, selection_summary, spread_subset
from engine.modelio import LoadedModel, load_model
from engine.motion.motion import Motion
from engine.motion.resample import resample_motion
from engine.train.windows import canonicalize


@pytest.fixture(scope="module")
def loaded(tiny_model_dir) -> LoadedModel:
    """The tiny model with its latent bank."""
    return load_model(tiny_model_dir)


def _turned(motion: Motion, yaw: float, shift: np.ndarray) -> Motion:
    c, s = np.cos(yaw), np.sin(yaw)
    rot = np.array([[c, 0.0, s], [0.0, 1.0, 0.0], [-s, 0.0, c]])
    return motion.with_joints((motion.joints @ rot.T + shift).astype(np.float32))


def test_chained_steps_start_where_and_facing_how_the_last_ended(procedural_clips) -> None:
    walk = next(m for m in procedural_clips if m.action == "walk")
    a = _turned(walk, 0.7, np.array([2.0, 0.0, -1.0]))
    b = _turned(walk, -1.2, np.array([-5.0, 0.0, 3.0]))
    chained, transforms = chain_motions([a, b])
    assert chained.n_frames == a.n_frames + b.n_frames
    np.testing.assert_allclose(chained.joints[: a.n_frames], a.joints, atol=1e-5)
    root = walk.skeleton.root
    second = chained.joints[a.n_frames :]
    np.testing.assert_allclose(second[0, root, [0, 2]], a.joints[-1, root, [0, 2]], atol=1e-4)
    yaw_end = canonicalize(a.joints[-1:], walk.skeleton)[1]
    yaw_start = canonicalize(second[:1], walk.skeleton)[1]
    assert abs(np.angle(np.exp(1j * (yaw_end - yaw_start)))) < 1e-4
    # a rigid move: bone lengths and heights are kept
    np.testing.assert_allclose(second[..., 1], b.joints[..., 1], atol=1e-5)
    np.testing.assert_allclose(np.linalg.det(transforms[1][:3, :3]), 1.0, atol=1e-9)
    with pytest.raises(ConfigError):
        chain_motions([])


def test_nearest_is_in_the_full_space_and_skips_the_query() -> None:
    rng = np.random.default_rng(0)
    codes = rng.standard_normal((200, 16))
    idx, dist = nearest(codes, codes[7], 5, exclude=7)
    brute = np.argsort(np.linalg.norm(codes - codes[7], axis=1))[1:6]
    np.testing.assert_array_equal(idx, brute)
    assert np.all(np.diff(dist) >= 0) and 7 not in idx
    with pytest.raises(ConfigError):
        nearest(codes, codes[0, :3], 2)


def test_spread_subset_covers_groups_in_proportion() -> None:
    rng = np.random.default_rng(1)
    codes = rng.standard_normal((100, 4))
    groups = np.array([0] * 80 + [1] * 15 + [2] * 5)
    picked = spread_subset(codes, groups, 12)
    assert len(picked) == 12 and len(set(picked.tolist())) == 12
    counts = np.bincount(groups[picked], minlength=3)
    assert counts[0] >= 8 and counts[1] >= 1 and counts[2] >= 1
    # farther apart than the first 12 codes of group 0
    spread = np.linalg.norm(codes[picked[groups[picked] == 0]] - codes[:80].mean(0), axis=1).mean()
    assert spread > np.linalg.norm(codes[:8] - codes[:80].mean(0), axis=1).mean() * 0.9
    np.testing.assert_array_equal(spread_subset(codes[:5], groups[:5], 12), np.arange(5))


def test_window_starts_cover_the_clip() -> None:
    np.testing.assert_array_equal(window_starts(200, 60, 30), [0, 30, 60, 90, 120, 140])
    np.testing.assert_array_equal(window_starts(40, 60, 30), [0])
    with pytest.raises(ConfigError):
        window_starts(100, 60, 0)


def test_a_long_clip_encodes_as_a_path_of_windows(loaded, procedural_clips) -> None:
    long = procedural_clips[0]
    long = long.with_joints(np.concatenate([long.joints] * 3))
    windows = encode_windows(loaded, long, stride=20)
    moved = resample_motion(long, loaded.fps) if abs(long.fps - loaded.fps) > 1e-6 else long
    np.testing.assert_array_equal(windows.starts, window_starts(moved.n_frames, loaded.window, 20))
    assert windows.codes.shape == (len(windows.starts), loaded.config.latent_dim)
    assert np.all(np.isfinite(windows.codes)) and windows.stride == 20
    assert set(windows.actions.tolist()) <= set(range(len(loaded.action_names)))


def test_bank_window_is_the_canonical_centre_window(loaded, procedural_clips) -> None:
    clip = procedural_clips[0]
    shown = bank_window(loaded, clip)
    assert shown.n_frames <= loaded.window
    root = shown.joints[0, shown.skeleton.root]
    np.testing.assert_allclose(root[[0, 2]], [0.0, 0.0], atol=1e-5)
    np.testing.assert_allclose(root[1], loaded.root_height, atol=1e-5)
    assert abs(canonicalize(shown.joints[:1], shown.skeleton)[1]) < 1e-4


def test_cross_action_strip_keeps_each_endpoints_action(loaded) -> None:
    bank = loaded.bank
    a, b = int(bank.indices_of(0)[0]), int(bank.indices_of(1)[0])
    samples = interpolate_across(loaded, bank.codes[a], 0, bank.codes[b], 1, 5, bank.ends[a], bank.ends[b])
    assert samples[0].action == 0 and samples[-1].action == 1
    np.testing.assert_allclose(
        samples[0].motion.joints, decode(loaded, bank.codes[a], 0, bank.ends[a : a + 1]).joints, atol=1e-6
    )
    np.testing.assert_allclose(
        samples[-1].motion.joints, decode(loaded, bank.codes[b], 1, bank.ends[b : b + 1]).joints, atol=1e-6
    )
    # the rule: the likelier action under the two mode mixtures; near each end it is that end's action
    codes = np.stack([s.code for s in samples])
    actions = step_actions(loaded, codes, 0, 1)
    assert [s.action for s in samples] == actions.tolist()
    near_a = step_actions(loaded, np.stack([bank.codes[a], bank.codes[a], bank.codes[b]]), 0, 1)
    assert near_a[1] == 0


def test_selection_summary_is_centroid_majority_and_mean_distance(loaded) -> None:
    bank = loaded.bank
    walk = bank.indices_of(0)[:3]
    picked = np.concatenate([walk, bank.indices_of(1)[:1]])
    centre, action, radius = selection_summary(bank, picked)
    codes = bank.codes[picked].astype(np.float64)
    np.testing.assert_allclose(centre, codes.mean(axis=0), rtol=1e-6)
    assert action == 0  # three of four are walks
    assert radius == pytest.approx(np.mean([np.linalg.norm(c - codes.mean(axis=0)) for c in codes]))
    one = selection_summary(bank, picked[:1])
    same = bank.codes[bank.indices_of(0)].astype(np.float64)
    assert one[2] == pytest.approx(
        0.25 * np.median(np.linalg.norm(same - same.mean(axis=0), axis=1)), rel=1e-6
    )
    with pytest.raises(ConfigError, match="select codes first"):
        selection_summary(bank, [])


def test_a_one_gaussian_mode_model_is_the_maximum_likelihood_fit() -> None:
    codes = np.random.default_rng(0).normal([1.0, -2.0], [0.5, 2.0], size=(4000, 2))
    mode = ModeModel(k_range=(1, 1)).fit(codes)
    assert mode.n_modes_ == 1 and mode.sizes().tolist() == [4000]
    np.testing.assert_allclose(mode.means_[0], [1.0, -2.0], atol=0.1)
    np.testing.assert_allclose(np.sqrt(np.diag(mode.covariances_[0])), [0.5, 2.0], rtol=0.05)
    np.testing.assert_allclose(mode.covariances_[0], np.cov(codes.T, bias=True) + 1e-6 * np.eye(2), rtol=1e-9)
    drawn, labels = mode.sample(5, np.random.default_rng(1), strategy="mode", mode=0)
    assert drawn.shape == (5, 2) and set(labels.tolist()) == {0}
