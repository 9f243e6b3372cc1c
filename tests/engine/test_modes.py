"""Mode discovery and sampling against planted clusters and counting statistics."""

from __future__ import annotations

from collections.abc import Iterator

import numpy as np
import pytest
from scipy.stats import chisquare
from sklearn.base import clone
from sklearn.exceptions import NotFittedError
from sklearn.metrics import adjusted_rand_score
from sklearn.utils.validation import check_is_fitted
from threadpoolctl import threadpool_limits

from engine.errors import ConfigError
from engine.latent.modes import ModeModel, choose_k


def planted(
    sizes: list[int], dim: int = 20, spread: float = 8.0, seed: int = 0
) -> tuple[np.ndarray, np.ndarray]:
    """Well-separated Gaussian clusters: codes (N, dim) and their true cluster (N,)."""
    rng = np.random.default_rng(seed)
    centers = rng.normal(0.0, spread, (len(sizes), dim))
    truth = np.repeat(np.arange(len(sizes)), sizes)
    return centers[truth] + rng.normal(size=(len(truth), dim)), truth


@pytest.fixture(scope="module", autouse=True)
def one_thread() -> Iterator[None]:
    """OpenMP and BLAS on one thread: on a busy 2-core machine their spinning threads slow t-SNE 10x."""
    with threadpool_limits(1):
        yield


@pytest.fixture(scope="module")
def three() -> tuple[np.ndarray, np.ndarray, ModeModel]:
    codes, truth = planted([120, 80, 100])
    return codes, truth, ModeModel(seed=0).fit(codes)


def test_recovers_planted_clusters(three: tuple[np.ndarray, np.ndarray, ModeModel]) -> None:
    codes, truth, model = three
    assert model.k_chosen_ == 3 and model.n_modes_ == 3
    assert adjusted_rand_score(truth, model.labels_) > 0.9
    assert sorted(model.silhouette_) == list(range(3, 12))
    assert model.silhouette_[3] == max(model.silhouette_.values())
    np.testing.assert_allclose(np.sort(model.weights_), np.sort([120, 80, 100]) / 300, atol=0.02)
    np.testing.assert_array_equal(model.predict(codes), model.labels_)
    np.testing.assert_array_equal(model.sizes(), np.bincount(model.labels_))
    np.testing.assert_allclose(model.conventional_mean_, codes.mean(axis=0))


def test_recovers_five_clusters() -> None:
    codes, truth = planted([60] * 5, seed=1)
    model = ModeModel(seed=0).fit(codes)
    assert model.k_chosen_ == 5
    assert adjusted_rand_score(truth, model.labels_) > 0.9


def test_deterministic_for_a_seed() -> None:
    codes, _ = planted([50, 50, 50], spread=1.5, seed=2)
    a, b = ModeModel(k_range=(3, 5), seed=7).fit(codes), ModeModel(k_range=(3, 5), seed=7).fit(codes)
    np.testing.assert_array_equal(a.means_, b.means_)
    np.testing.assert_array_equal(a.labels_, b.labels_)
    assert a.silhouette_ == b.silhouette_


def test_choose_k_rule() -> None:
    assert choose_k({3: 0.5, 4: 0.6, 5: 0.8, 6: 0.6}) == 5
    assert choose_k({3: 0.8, 4: 0.6}) == 3
    assert choose_k({3: 0.50, 4: 0.52}) == 3  # 0.50 > 0.95 × 0.52: a small rise does not count
    assert choose_k({3: 0.3, 4: 0.5, 5: 0.7}) == 5  # never drops: the best
    assert choose_k({3: float("nan"), 4: 0.2, 5: 0.4}) == 5
    assert choose_k({3: float("nan"), 4: float("nan")}) is None


def test_small_components_are_dropped_and_weights_renormalised() -> None:
    codes, truth = planted([100, 100, 6], seed=3)
    model = ModeModel(seed=0).fit(codes)
    assert model.k_chosen_ == 3
    assert model.n_modes_ == 2
    assert model.weights_.sum() == pytest.approx(1.0)
    np.testing.assert_allclose(model.weights_, [0.5, 0.5], atol=0.03)
    assert set(model.labels_) == {0, 1}
    assert adjusted_rand_score(truth[truth < 2], model.labels_[truth < 2]) == pytest.approx(1.0)


@pytest.mark.parametrize("n", [1, 2, 5, 9])
def test_tiny_actions_get_one_conventional_mode(n: int) -> None:
    codes, _ = planted([n], seed=4)
    model = ModeModel(seed=0).fit(codes)
    assert model.n_modes_ == 1
    np.testing.assert_allclose(model.means_[0], codes.mean(axis=0))
    np.testing.assert_allclose(model.covariances_[0], model.conventional_cov_)
    assert all(np.isnan(model.silhouette_[k]) for k in range(max(n, 3), 12))
    samples, modes = model.sample(4, np.random.default_rng(0))
    assert samples.shape == (4, 20) and np.all(modes == 0)


def test_fit_rejects_bad_input() -> None:
    with pytest.raises(ConfigError):
        ModeModel().fit(np.zeros((0, 4)))
    with pytest.raises(ConfigError):
        ModeModel().fit(np.zeros(5))
    with pytest.raises(ConfigError):
        ModeModel(k_range=(5, 3)).fit(np.ones((20, 3)))


def test_mode_preserving_sampling_follows_weights(three: tuple[np.ndarray, np.ndarray, ModeModel]) -> None:
    _, _, model = three
    n = 30_000
    codes, modes = model.sample(n, np.random.default_rng(1))
    assert codes.shape == (n, 20) and codes.dtype == np.float32
    assert chisquare(np.bincount(modes, minlength=3), model.weights_ * n).pvalue > 1e-3
    for k in range(3):
        np.testing.assert_allclose(codes[modes == k].mean(axis=0), model.means_[k], atol=0.1)
    again, again_modes = model.sample(n, np.random.default_rng(1))
    np.testing.assert_array_equal(codes, again)
    np.testing.assert_array_equal(modes, again_modes)


def test_user_weights_one_mode_and_conventional(three: tuple[np.ndarray, np.ndarray, ModeModel]) -> None:
    _, _, model = three
    rng = np.random.default_rng(2)
    _, modes = model.sample(20_000, rng, strategy="weights", weights=np.array([2.0, 0.0, 6.0]))
    counts = np.bincount(modes, minlength=3)
    assert counts[1] == 0
    assert chisquare(counts[[0, 2]], np.array([0.25, 0.75]) * 20_000).pvalue > 1e-3
    codes, modes = model.sample(500, rng, strategy="mode", mode=1)
    assert np.all(modes == 1)
    np.testing.assert_allclose(codes.mean(axis=0), model.means_[1], atol=0.3)
    codes, modes = model.sample(20_000, rng, strategy="conventional")
    assert np.all(modes == -1)
    np.testing.assert_allclose(np.cov(codes, rowvar=False), model.conventional_cov_, atol=2.0)
    assert model.sample(0, rng)[0].shape == (0, 20)


@pytest.mark.parametrize(
    ("strategy", "kwargs"),
    [
        ("weights", {"weights": np.array([1.0, -1.0, 1.0])}),
        ("weights", {"weights": np.zeros(3)}),
        ("weights", {"weights": np.ones(2)}),
        ("weights", {}),
        ("mode", {"mode": 3}),
        ("mode", {}),
        ("nearest", {}),
    ],
)
def test_sampling_rejects_bad_requests(
    three: tuple[np.ndarray, np.ndarray, ModeModel], strategy: str, kwargs: dict
) -> None:
    with pytest.raises(ConfigError):
        three[2].sample(3, np.random.default_rng(0), strategy=strategy, **kwargs)


def test_arrays_round_trip(three: tuple[np.ndarray, np.ndarray, ModeModel]) -> None:
    model = three[2]
    arrays = model.to_arrays("m/")
    assert all(np.asarray(v).dtype.kind != "O" for v in arrays.values())
    back = ModeModel.from_arrays("m/", arrays)
    for name in ("weights_", "means_", "covariances_", "labels_", "conventional_mean_", "conventional_cov_"):
        np.testing.assert_array_equal(getattr(back, name), getattr(model, name))
    assert back.silhouette_ == model.silhouette_ and back.k_chosen_ == model.k_chosen_


def test_mode_model_is_a_scikit_learn_estimator(three: tuple[np.ndarray, np.ndarray, ModeModel]) -> None:
    codes, _, fitted = three
    fresh = clone(ModeModel(k_range=(3, 5), seed=7))
    assert fresh.get_params() == {
        "k_range": (3, 5), "ratio": 0.95, "min_members": 10, "seed": 7, "silhouette_sample": 5000,
        "covariance": "full",
    }  # fmt: skip
    with pytest.raises(NotFittedError):
        check_is_fitted(fresh)
    check_is_fitted(fitted)
    assert fresh.fit(codes) is fresh and fresh.k_chosen_ == 3


def test_one_gaussian_mode_model_fits_no_mixture() -> None:
    codes = np.random.default_rng(3).normal(size=(50, 4))
    model = ModeModel(k_range=(1, 1)).fit(codes)
    assert model.n_modes_ == 1 and model.k_chosen_ == 1 and np.isnan(model.silhouette_[1])
    np.testing.assert_allclose(model.means_[0], codes.mean(axis=0))
    np.testing.assert_array_equal(model.labels_, np.zeros(50))


def test_diagonal_modes_fit_sample_and_store_only_their_diagonals() -> None:
    rng = np.random.default_rng(0)
    centres = np.array([[0.0] * 40, [6.0] * 40])
    codes = np.concatenate([c + rng.standard_normal((150, 40)) * np.linspace(0.5, 1.5, 40) for c in centres])
    model = ModeModel(k_range=(2, 3), covariance="diag").fit(codes)
    assert model.n_modes_ == 2
    for cov in (*model.covariances_, model.conventional_cov_):
        np.testing.assert_array_equal(cov, np.diag(np.diag(cov)))  # axis-aligned
    spread = np.sqrt(np.diag(model.covariances_[0]))
    np.testing.assert_allclose(spread, np.linspace(0.5, 1.5, 40), rtol=0.25)
    arrays = model.to_arrays("m/")
    assert arrays["m/covariances"].shape == (2, 40) and arrays["m/conventional_cov"].shape == (40,)
    again = ModeModel.from_arrays("m/", arrays)
    np.testing.assert_array_equal(again.covariances_, model.covariances_)
    np.testing.assert_array_equal(again.predict(codes), model.predict(codes))
    drawn, _ = again.sample(500, np.random.default_rng(1))
    assert drawn.shape == (500, 40) and again.problem() is None
    full = ModeModel(k_range=(2, 2)).fit(codes).to_arrays("f/")
    del full["f/covariance"]  # a bank written before the option: full covariances
    assert ModeModel.from_arrays("f/", full).covariance == "full"
    with pytest.raises(ConfigError, match="covariance must be one of"):
        ModeModel(covariance="spherical").fit(codes)
