"""Each evaluation metric on data whose answer is known."""

from __future__ import annotations

import itertools
import math

import numpy as np
import pytest
from scipy.stats import special_ortho_group

from engine.errors import ConfigError
from engine.metrics.accuracy import recognition_accuracy
from engine.metrics.apd import apd, n_apd
from engine.metrics.diversity import diversity, multimodality
from engine.metrics.fid import fid, frechet_distance
from engine.metrics.modes import mode_apd, mode_homogeneity, mode_purity
from engine.metrics.reconstruction import mpjpe
from engine.metrics.stats import mean_ci95, summarize
from engine.metrics.trajectory import control_targets, end_point_errors, root_travel


def test_accuracy_counts_matches() -> None:
    assert recognition_accuracy(np.array([0, 1, 2, 2]), np.array([0, 1, 1, 2])) == 0.75
    with pytest.raises(ConfigError):
        recognition_accuracy(np.array([0, 1]), np.array([0]))


def test_fid_identical_sets_is_zero() -> None:
    feats = np.random.default_rng(0).normal(size=(500, 30))
    assert fid(feats, feats) == pytest.approx(0.0, abs=1e-6)


def test_fid_shifted_set_is_squared_shift() -> None:
    feats = np.random.default_rng(1).normal(size=(400, 8))
    shift = np.arange(8) * 0.3
    assert fid(feats, feats + shift) == pytest.approx(float(shift @ shift), rel=1e-6, abs=1e-6)


def test_frechet_distance_closed_form_for_commuting_covariances() -> None:
    a, b = np.array([1.0, 4.0, 9.0]), np.array([4.0, 1.0, 1.0])
    rot = special_ortho_group.rvs(3, random_state=3)
    mu1, mu2 = np.array([1.0, 0.0, 0.0]), np.array([0.0, 2.0, 0.0])
    expected = 5.0 + np.sum((np.sqrt(a) - np.sqrt(b)) ** 2)  # ‖Δμ‖² + Σ(√a − √b)²
    got = frechet_distance(mu1, rot @ np.diag(a) @ rot.T, mu2, rot @ np.diag(b) @ rot.T)
    assert got == pytest.approx(expected, rel=1e-9)


def test_fid_of_samples_approaches_closed_form() -> None:
    rng = np.random.default_rng(2)
    x = rng.normal(size=(200_000, 2)) * [1.0, 2.0]
    y = rng.normal(size=(200_000, 2)) * [3.0, 2.0] + [1.0, 0.0]
    assert fid(x, y) == pytest.approx(1.0 + (1.0 - 3.0) ** 2, rel=0.02)


def test_diversity_of_equidistant_points() -> None:
    simplex = 3.0 * np.eye(5)  # every pair at distance 3√2
    assert diversity(simplex, np.random.default_rng(0)) == pytest.approx(3.0 * math.sqrt(2.0))


def test_diversity_of_gaussian_matches_expected_distance() -> None:
    f = 6
    feats = np.random.default_rng(4).normal(size=(20_000, f))
    expected = 2.0 * math.gamma((f + 1) / 2) / math.gamma(f / 2)  # E‖x − y‖, x, y ~ N(0, I_f)
    got = diversity(feats, np.random.default_rng(5), n_pairs=50_000)
    assert got == pytest.approx(expected, rel=0.02)


def test_diversity_depends_only_on_the_rng_given() -> None:
    feats = np.random.default_rng(6).normal(size=(50, 4))
    one = diversity(feats, np.random.default_rng(7))
    assert one == diversity(feats, np.random.default_rng(7))
    assert one != diversity(feats, np.random.default_rng(8))


def test_multimodality_averages_actions() -> None:
    feats = np.vstack([np.eye(4) / math.sqrt(2.0), 3.0 * np.eye(4) / math.sqrt(2.0) + 100.0])
    labels = np.repeat([0, 1], 4)
    assert multimodality(feats, labels, np.random.default_rng(0)) == pytest.approx(2.0)


def _apd_by_definition(m: np.ndarray) -> float:
    """Paper's formula, written with loops."""
    n = len(m)
    total = sum(
        math.sqrt(sum(float(np.sum((m[i, t] - m[j, t]) ** 2)) for t in range(m.shape[1])))
        for i, j in itertools.permutations(range(n), 2)
    )
    return total / (n * (n - 1))


def test_apd_matches_the_definition() -> None:
    m = np.random.default_rng(9).normal(size=(6, 5, 4, 3))
    assert apd(m) == pytest.approx(_apd_by_definition(m))
    line = np.array([0.0, 1.0, 3.0]).reshape(3, 1, 1, 1)
    assert apd(line) == pytest.approx(2.0)


def test_n_apd_is_ratio_to_real() -> None:
    rng = np.random.default_rng(10)
    real = {0: rng.normal(size=(8, 5, 2, 3)), 1: rng.normal(size=(8, 5, 2, 3))}
    gen = {0: 2.0 * real[0], 1: 4.0 * real[1]}
    assert n_apd(gen, real) == pytest.approx(3.0)
    # An action whose real motions are all the same clip has no spread to normalise by.
    same = {0: real[0], 1: np.repeat(real[1][:1], 8, axis=0)}
    assert n_apd(gen, same) == pytest.approx(2.0)
    assert np.isnan(n_apd({1: gen[1]}, same))


def test_mode_homogeneity_known_clusters() -> None:
    motions = np.array([0.0, 1.0, 10.0, 11.0]).reshape(4, 1, 1, 1)
    # APD = (1 + 10 + 11 + 9 + 10 + 1) / 6 = 7; mode-APD = (2·1 + 2·1) / 4 = 1
    assert mode_apd(motions, np.array([0, 0, 1, 1])) == pytest.approx(1.0)
    assert mode_homogeneity({0: motions}, {0: np.array([0, 0, 1, 1])}) == pytest.approx(100.0 * 6.0 / 7.0)
    assert mode_homogeneity({0: motions}, {0: np.zeros(4, int)}) == pytest.approx(0.0)


def test_mode_purity_permuted_and_independent_labels() -> None:
    styles = np.repeat(["calm", "angry", "tired"], 40)
    modes = np.repeat([2, 0, 1], 40)
    assert mode_purity({0: modes}, {0: styles}) == pytest.approx((1.0, 1.0))
    noise = np.random.default_rng(11).integers(0, 3, size=120)
    nmi, ari = mode_purity({0: noise}, {0: styles})
    assert nmi < 0.1 and abs(ari) < 0.05


def test_mpjpe_of_a_known_offset() -> None:
    truth = np.random.default_rng(12).normal(size=(2, 7, 5, 3))
    assert mpjpe(truth + np.array([0.03, 0.04, 0.0]), truth) == pytest.approx(0.05)
    mask = np.zeros((2, 7), bool)
    mask[:, :3] = True
    shifted = truth.copy()
    shifted[:, 3:] += 1.0  # masked-out frames must not count
    assert mpjpe(shifted, truth, mask) == pytest.approx(0.0)


def test_end_point_errors_and_travel_in_metres() -> None:
    traj = np.zeros((2, 4, 3))
    traj[0, -1] = [3.0, 0.0, 4.0]
    traj[1, -1] = [0.0, 0.0, 1.0]
    np.testing.assert_allclose(end_point_errors(traj, np.zeros((2, 3))), [5.0, 1.0])
    np.testing.assert_allclose(root_travel(traj), [5.0, 1.0])
    lowered = traj + np.array([0.2, -0.07, 0.0])  # the whole path moved: the same displacement
    np.testing.assert_allclose(
        end_point_errors(lowered, np.array([[3.0, 0.0, 4.0], [0.0, 0.0, 0.0]])), [0.0, 1.0]
    )


def test_control_targets_inside_and_outside_the_range() -> None:
    ends = np.array([[0.0, 0.0, 1.0], [1.0, 0.0, 0.0], [0.0, 0.1, -2.0]])
    inside, outside = control_targets(ends, n_codes=5, rng=np.random.default_rng(0), n_points=10)
    assert inside.shape == outside.shape == (5, 10, 3)
    real = {tuple(e) for e in ends}
    assert all(tuple(row[0]) in real and tuple(row[-1]) in real for row in inside)
    np.testing.assert_allclose(inside[:, 1] - inside[:, 0], (inside[:, -1] - inside[:, 0]) / 9, atol=1e-12)
    np.testing.assert_allclose(np.linalg.norm(outside[..., [0, 2]], axis=-1), 3.0)  # 1.5 × farthest (2 m)
    np.testing.assert_allclose(outside[..., 1], inside[..., 1])


def test_mean_ci95() -> None:
    mean, ci = mean_ci95([1.0, 2.0, 3.0, 4.0])
    assert mean == 2.5
    assert ci == pytest.approx(1.96 * np.std([1, 2, 3, 4], ddof=1) / 2.0)
    assert mean_ci95([7.0]) == (7.0, 0.0)
    table = summarize([{"fid": 1.0, "apd": 2.0}, {"fid": 3.0, "apd": 2.0}])
    assert table["fid"]["mean"] == 2.0 and table["apd"]["ci95"] == 0.0
