"""PCA / t-SNE / UMAP maps: forward and inverse against exact answers, storage without pickles."""

from __future__ import annotations

import io
from collections.abc import Iterator

import numpy as np
import pytest
from sklearn.neighbors import KNeighborsClassifier
from threadpoolctl import threadpool_limits

from engine.errors import ConfigError, ModelFormatError
from engine.latent.projection import (
    PCAProjection,
    Projection,
    TSNEProjection,
    make_projection,
)


def clusters(n_per: int = 70, dim: int = 12, seed: int = 0) -> tuple[np.ndarray, np.ndarray]:
    """Three separated clusters: codes (3 n_per, dim) float32 and labels."""
    rng = np.random.default_rng(seed)
    centers = rng.normal(0.0, 6.0, (3, dim))
    labels = np.repeat(np.arange(3), n_per)
    return (centers[labels] + rng.normal(size=(len(labels), dim))).astype(np.float32), labels


@pytest.fixture(scope="module", autouse=True)
def one_thread() -> Iterator[None]:
    """OpenMP and BLAS on one thread: on a busy 2-core machine their spinning threads slow t-SNE 10x."""
    with threadpool_limits(1):
        yield


@pytest.fixture(scope="module")
def data() -> tuple[np.ndarray, np.ndarray]:
    return clusters()


@pytest.fixture(scope="module")
def fitted(data: tuple[np.ndarray, np.ndarray]) -> dict[str, Projection]:
    codes = data[0]
    return {name: make_projection(name, seed=0).fit(codes) for name in ("pca", "tsne", "umap")}


def stored(projection: Projection) -> Projection:
    """The projection after a trip through an .npz file read with allow_pickle=False."""
    buffer = io.BytesIO()
    np.savez(buffer, **projection.to_arrays("p/"))
    buffer.seek(0)
    with np.load(buffer, allow_pickle=False) as npz:
        return Projection.from_arrays("p/", {key: npz[key] for key in npz.files})


def test_pca_matches_svd_and_inverts_exactly(data: tuple[np.ndarray, np.ndarray]) -> None:
    codes = data[0].astype(np.float64)
    pca = make_projection("pca").fit(data[0])
    assert isinstance(pca, PCAProjection)
    centered = codes - codes.mean(axis=0)
    top = np.linalg.svd(centered, full_matrices=False)[2][:2]
    np.testing.assert_allclose(np.abs(pca.components_ @ top.T), np.eye(2), atol=1e-8)
    np.testing.assert_allclose(pca.embedding_, centered @ pca.components_.T, atol=1e-9)
    points = np.random.default_rng(0).normal(scale=5.0, size=(50, 2))
    np.testing.assert_allclose(pca.transform(pca.inverse_transform(points)), points, atol=1e-9)
    np.testing.assert_allclose(pca.inverse_transform(pca.embedding_[:10]), codes[:10], atol=1e-9)


def test_pca_inverse_fills_other_dims_from_local_codes() -> None:
    rng = np.random.default_rng(5)
    plane = rng.uniform(-3.0, 3.0, (800, 2))
    height = 0.5 * np.sin(plane[:, 0]) + 0.5 * np.cos(plane[:, 1])  # off-plane, a function of position
    pca = make_projection("pca").fit(np.column_stack([plane, height]))
    queries = rng.uniform(-2.5, 2.5, (100, 2))
    codes = pca.inverse_transform(pca.transform(np.column_stack([queries, np.zeros(100)])))
    truth = 0.5 * np.sin(codes[:, 0]) + 0.5 * np.cos(codes[:, 1])
    error, flat_error = np.abs(codes[:, 2] - truth), np.abs(pca.mean_[2] - truth)
    assert error.mean() < 0.2 * flat_error.mean()


@pytest.mark.parametrize("name", ["pca", "tsne", "umap"])
def test_maps_separate_clusters(
    fitted: dict[str, Projection], data: tuple[np.ndarray, np.ndarray], name: str
) -> None:
    labels = data[1]
    embedding = fitted[name].embedding_
    assert embedding.shape == (len(labels), 2) and np.all(np.isfinite(embedding))
    classifier = KNeighborsClassifier(5).fit(embedding[::2], labels[::2])
    assert classifier.score(embedding[1::2], labels[1::2]) > 0.95


@pytest.mark.parametrize("name", ["pca", "tsne", "umap"])
def test_reference_codes_are_recovered(
    fitted: dict[str, Projection], data: tuple[np.ndarray, np.ndarray], name: str
) -> None:
    projection = fitted[name]
    ref = data[0][:5] + np.float32(0.05)
    back = projection.inverse_transform(projection.transform(ref), codes_ref=ref)
    np.testing.assert_allclose(back, ref, atol=1e-6)
    with pytest.raises(ConfigError):
        projection.inverse_transform(np.zeros((2, 2)), codes_ref=ref)


@pytest.mark.parametrize("name", ["tsne", "umap"])
def test_neighbour_maps_are_exact_on_bank_codes_and_continuous(
    fitted: dict[str, Projection], data: tuple[np.ndarray, np.ndarray], name: str
) -> None:
    projection = stored(fitted[name])
    codes, labels = data
    np.testing.assert_allclose(projection.transform(codes[:20]), projection.embedding_[:20], atol=1e-9)
    np.testing.assert_allclose(
        projection.inverse_transform(projection.embedding_[:20]), codes[:20], atol=1e-6
    )
    for i, j in [(0, 5), (3, 40), (80, 150)]:
        a, b = projection.embedding_[i], projection.embedding_[j]
        path = a + np.linspace(0, 1, 1001)[:, None] * (b - a)
        nearest = codes[np.argmin(((path[:, None] - projection.embedding_[None]) ** 2).sum(-1), axis=1)]
        walked = projection.inverse_transform(path)
        np.testing.assert_allclose(walked[[0, -1]], codes[[i, j]], atol=1e-6)
        # Within a cluster the blend moves smoothly; across an empty gap it is continuous but steep.
        bound = 0.05 if labels[i] == labels[j] else 0.5
        assert np.abs(np.diff(walked, axis=0)).max() < bound * np.abs(np.diff(nearest, axis=0)).max()


@pytest.mark.parametrize("name", ["tsne", "umap"])
def test_new_codes_land_near_their_cluster(
    fitted: dict[str, Projection], data: tuple[np.ndarray, np.ndarray], name: str
) -> None:
    codes, labels = data
    projection = fitted[name]
    fresh = codes[labels == 2][:10] + np.random.default_rng(1).normal(scale=0.1, size=(10, codes.shape[1]))
    classifier = KNeighborsClassifier(5).fit(projection.embedding_, labels)
    assert np.all(classifier.predict(projection.transform(fresh)) == 2)


@pytest.mark.parametrize("name", ["pca", "tsne"])
def test_fits_are_deterministic_for_a_seed(data: tuple[np.ndarray, np.ndarray], name: str) -> None:
    codes = data[0][::3]
    first = make_projection(name, seed=3).fit(codes).embedding_
    np.testing.assert_array_equal(first, make_projection(name, seed=3).fit(codes).embedding_)


@pytest.mark.parametrize("name", ["pca", "tsne", "umap"])
def test_storage_round_trip(
    fitted: dict[str, Projection], data: tuple[np.ndarray, np.ndarray], name: str
) -> None:
    projection = fitted[name]
    arrays = projection.to_arrays("p/")
    assert all(np.asarray(value).dtype.kind != "O" for value in arrays.values())
    back = stored(projection)
    assert type(back) is type(projection) and back.params() == projection.params()
    np.testing.assert_array_equal(back.embedding_, projection.embedding_)
    np.testing.assert_array_equal(back.codes_, projection.codes_)
    points = projection.embedding_[:7] + 0.3
    np.testing.assert_array_equal(back.transform(data[0][:7] + 0.1), projection.transform(data[0][:7] + 0.1))
    np.testing.assert_array_equal(back.inverse_transform(points), projection.inverse_transform(points))


def test_bad_names_inputs_and_files(fitted: dict[str, Projection]) -> None:
    with pytest.raises(ConfigError):
        make_projection("isomap")
    with pytest.raises(ConfigError):
        TSNEProjection().transform(np.zeros((1, 12)))
    with pytest.raises(ConfigError):
        make_projection("pca").fit(np.zeros((2, 12)))
    with pytest.raises(ConfigError):
        fitted["pca"].transform(np.zeros((3, 5)))
    arrays = fitted["pca"].to_arrays("p/")
    del arrays["p/components"]
    with pytest.raises(ModelFormatError):
        Projection.from_arrays("p/", arrays)
    arrays = fitted["tsne"].to_arrays("p/")
    arrays["p/name"] = np.asarray("isomap")
    with pytest.raises(ModelFormatError):
        Projection.from_arrays("p/", arrays)
    with pytest.raises(ModelFormatError):
        PCAProjection.from_arrays("p/", fitted["tsne"].to_arrays("p/"))


def test_past_max_fit_a_map_is_fitted_on_a_sample_and_places_every_other_code() -> None:
    codes, labels = clusters(n_per=200)
    whole = TSNEProjection(seed=0, max_fit=90).fit(codes)
    assert whole.embedding_.shape == (600, 2)
    np.testing.assert_array_equal(whole.codes_, codes)
    rows = np.sort(np.random.default_rng(0).choice(600, 90, replace=False))
    alone = TSNEProjection(seed=0).fit(codes[rows])  # the sample, fitted by itself, lies where it was
    np.testing.assert_allclose(whole.embedding_[rows], alone.embedding_, atol=1e-6)
    others = np.setdiff1d(np.arange(600), rows)
    classifier = KNeighborsClassifier(5).fit(whole.embedding_[rows], labels[rows])
    assert np.all(classifier.predict(whole.embedding_[others]) == labels[others])
    assert stored(whole).max_fit == 90
    assert TSNEProjection().max_fit == 10_000 and PCAProjection().max_fit is None
    with pytest.raises(ConfigError, match="max_fit must be at least 3"):
        TSNEProjection(max_fit=2)
