"""2D maps of the latent codes (PCA, t-SNE, UMAP) with forward and inverse transforms, stored without pickles.

Every projection keeps the codes it was fit on (``codes_``) and their 2D positions (``embedding_``).
Where a map has no exact inverse (PCA: the off-plane part) or no usable forward map for new codes (t-SNE,
UMAP) the missing direction is a continuous inverse-distance-weighted blend of the k nearest neighbours
(:class:`engine.latent.geometry.NeighbourBlend`), exact on the fitted codes and their embedding.

Past ``max_fit`` codes (t-SNE and UMAP: 10,000 by default) a map is fitted on a seeded sample of that many
and every other code is placed by the neighbour blend of the sample's embedding, as umap's and openTSNE's
``transform`` place new points: fit time stops growing with the bank, and ``embedding_`` covers every code.

``inverse_transform(points2d, codes_ref)``: when reference codes (M, D) are given, each result keeps what
the map cannot show of its reference code: x = inverse(p) + (ref − inverse(transform(ref))), so that
``inverse_transform(transform(ref), ref) == ref`` and a drag that starts on a code starts exactly at it.
"""

from __future__ import annotations

import json
import logging
import warnings
from typing import Any, ClassVar, Self

import numpy as np

from engine.errors import ConfigError, ModelFormatError
from engine.latent.geometry import NeighbourBlend

log = logging.getLogger(__name__)


class Projection:
    """Base class: a fitted 2D map of latent codes (sklearn estimator convention)."""

    name: ClassVar[str] = ""
    registry: ClassVar[dict[str, type[Projection]]] = {}
    state_keys: ClassVar[tuple[str, ...]] = ()  # names of the arrays _state() returns
    default_max_fit: ClassVar[int | None] = None  # codes fitted at most; None: every code

    def __init__(self, seed: int = 0, k: int = 8, max_fit: int | None = None):
        self.seed = seed
        self.k = k
        self.max_fit = max_fit if max_fit is not None else self.default_max_fit
        if self.max_fit is not None and self.max_fit < 3:
            raise ConfigError(f"max_fit must be at least 3, got {self.max_fit}")
        self.codes_: np.ndarray | None = None
        self.embedding_: np.ndarray | None = None
        self._blends: dict[bool, NeighbourBlend] = {}

    def __init_subclass__(cls, **kwargs: Any):
        super().__init_subclass__(**kwargs)
        Projection.registry[cls.name] = cls

    def params(self) -> dict[str, Any]:
        """Constructor parameters (JSON-serialisable)."""
        return {"seed": self.seed, "k": self.k, "max_fit": self.max_fit}

    def fit(self, codes: np.ndarray) -> Self:
        """Fit the map to codes (N, D), on a sample of ``max_fit`` of them past that; sets ``codes_`` and
        ``embedding_`` (N, 2)."""
        x = np.asarray(codes)
        if x.ndim != 2 or len(x) < 3 or x.shape[1] < 2:
            raise ConfigError(f"a {self.name} map needs codes of shape (N >= 3, D >= 2), got {x.shape}")
        if not np.all(np.isfinite(x)):
            raise ConfigError("codes contain NaN or infinite values")
        if self.max_fit is None or len(x) <= self.max_fit:
            self._set_fitted(x, self._fit(x.astype(np.float64)))
            log.info("fitted the %s map of %d codes", self.name, len(x))
        else:
            rows = np.sort(np.random.default_rng(self.seed).choice(len(x), self.max_fit, replace=False))
            sample = self._fit(x[rows].astype(np.float64))
            self._set_fitted(x[rows], sample)
            embedding = self._transform(x.astype(np.float64))
            embedding[rows] = sample
            self._set_fitted(x, embedding)
            log.info(
                "fitted the %s map on %d of its %d codes, placed the rest", self.name, self.max_fit, len(x)
            )
        return self

    def _set_fitted(self, codes: np.ndarray, embedding: np.ndarray) -> None:
        """Install fitted codes and embedding, dropping neighbour lookups built for older ones."""
        self.codes_, self.embedding_ = codes, np.asarray(embedding, dtype=np.float64)
        self._blends = {}

    def _blend(self, inverse: bool) -> NeighbourBlend:
        """The neighbour blend from codes to the plane, or (``inverse``) from the plane to codes."""
        if inverse not in self._blends:
            codes, embedding = self._fitted()
            source, target = (embedding, codes) if inverse else (codes, embedding)
            self._blends[inverse] = NeighbourBlend(source, target, self.k)
        return self._blends[inverse]

    def _fit(self, x: np.ndarray) -> np.ndarray:
        """Fit on float64 codes (N, D) and return the embedding (N, 2)."""
        raise NotImplementedError

    def _fitted(self) -> tuple[np.ndarray, np.ndarray]:
        """(codes_, embedding_), or ConfigError when not fitted."""
        if self.codes_ is None or self.embedding_ is None:
            raise ConfigError(f"the {self.name} projection is not fitted")
        return self.codes_, self.embedding_

    def _check(self, values: np.ndarray, width: int, what: str) -> np.ndarray:
        """``values`` as float64 (M, width), or ConfigError."""
        array = np.asarray(values, dtype=np.float64)
        if array.ndim == 1 and array.shape == (width,):
            array = array[None]
        if array.ndim != 2 or array.shape[1] != width:
            raise ConfigError(f"{what} must have shape (M, {width}), got {array.shape}")
        if not np.all(np.isfinite(array)):
            raise ConfigError(f"{what} contain NaN or infinite values")
        return array

    def transform(self, codes: np.ndarray) -> np.ndarray:
        """Map codes (M, D) to the plane (M, 2)."""
        fit_codes, _ = self._fitted()
        return self._transform(self._check(codes, fit_codes.shape[1], "codes"))

    def _transform(self, x: np.ndarray) -> np.ndarray:
        """Default forward map: blend of the k nearest fit codes' embeddings."""
        return self._blend(inverse=False)(x)

    def inverse_transform(self, points2d: np.ndarray, codes_ref: np.ndarray | None = None) -> np.ndarray:
        """Codes (M, D) of plane points (M, 2); ``codes_ref`` (M, D) keeps their off-map part (see module)."""
        fit_codes, _ = self._fitted()
        points = self._check(points2d, 2, "points")
        codes = self._inverse(points)
        if codes_ref is not None:
            ref = self._check(codes_ref, fit_codes.shape[1], "reference codes")
            if len(ref) != len(points):
                raise ConfigError(f"{len(points)} points but {len(ref)} reference codes")
            codes = codes + (ref - self._inverse(self._transform(ref)))
        return codes

    def _inverse(self, points: np.ndarray) -> np.ndarray:
        """Default inverse: blend of the codes whose embeddings are nearest."""
        return self._blend(inverse=True)(points)

    def to_arrays(self, prefix: str) -> dict[str, np.ndarray]:
        """Fitted state as plain arrays under keys starting with ``prefix``."""
        fit_codes, embedding = self._fitted()
        return {
            f"{prefix}name": np.asarray(self.name),
            f"{prefix}params": np.asarray(json.dumps(self.params())),
            f"{prefix}codes": fit_codes,
            f"{prefix}embedding": embedding,
            **{f"{prefix}{key}": value for key, value in self._state().items()},
        }

    def learned_arrays(self) -> dict[str, np.ndarray]:
        """Every fitted array by name: the codes, the embedding and the subclass's state."""
        codes, embedding = self._fitted()
        return {"codes": codes, "embedding": embedding, **self._state()}

    def _state(self) -> dict[str, np.ndarray]:
        """Learned arrays beyond codes and embedding."""
        return {}

    def _restore(self, state: dict[str, np.ndarray]) -> None:
        """Set learned attributes from :meth:`_state` arrays."""

    @classmethod
    def from_arrays(cls, prefix: str, arrays: dict[str, np.ndarray]) -> Projection:
        """Rebuild a projection from :meth:`to_arrays` output; ModelFormatError when malformed."""
        try:
            name = str(arrays[f"{prefix}name"])
            params = json.loads(str(arrays[f"{prefix}params"]))
            subclass = Projection.registry[name]
            projection = subclass(**params)
            codes = np.asarray(arrays[f"{prefix}codes"])
            embedding = np.asarray(arrays[f"{prefix}embedding"])
            state_keys = subclass.state_keys
            projection._restore({key: np.asarray(arrays[f"{prefix}{key}"]) for key in state_keys})
        except KeyError as exc:
            raise ModelFormatError(f"projection {prefix!r} is missing {exc.args[0]!r}") from exc
        except (TypeError, ValueError) as exc:
            raise ModelFormatError(f"projection {prefix!r} is malformed: {exc}") from exc
        if cls is not Projection and not isinstance(projection, cls):
            raise ModelFormatError(f"projection {prefix!r} is {name!r}, not {cls.name!r}")
        if codes.ndim != 2 or embedding.shape != (len(codes), 2):
            raise ModelFormatError(
                f"projection {prefix!r}: codes {codes.shape} and embedding {embedding.shape}"
            )
        projection._set_fitted(codes, embedding)
        return projection


class PCAProjection(Projection):
    """The first two principal components; inverse fills the other dimensions from nearby codes.

    inverse(p) = mean + Cᵀp + (I − CᵀC)(local − mean), ``local`` being the blend of the codes whose
    embeddings are nearest p, so the result projects exactly onto p.
    """

    name = "pca"
    state_keys = ("components", "mean", "explained_variance_ratio")

    def __init__(self, seed: int = 0, k: int = 8, max_fit: int | None = None):
        super().__init__(seed, k, max_fit)
        self.components_: np.ndarray | None = None
        self.mean_: np.ndarray | None = None
        self.explained_variance_ratio_: np.ndarray | None = None

    def _fit(self, x: np.ndarray) -> np.ndarray:
        from sklearn.decomposition import PCA  # loaded on first fit, not at start-up

        pca = PCA(n_components=2, svd_solver="full", random_state=self.seed).fit(x)
        self.components_, self.mean_ = pca.components_, pca.mean_
        self.explained_variance_ratio_ = pca.explained_variance_ratio_
        return self._transform(x)

    def _transform(self, x: np.ndarray) -> np.ndarray:
        return (x - self.mean_) @ self.components_.T

    def _inverse(self, points: np.ndarray) -> np.ndarray:
        local = super()._inverse(points)
        offset = local - self.mean_
        off_plane = offset - (offset @ self.components_.T) @ self.components_
        return self.mean_ + points @ self.components_ + off_plane

    def _state(self) -> dict[str, np.ndarray]:
        return {
            "components": self.components_,
            "mean": self.mean_,
            "explained_variance_ratio": self.explained_variance_ratio_,
        }

    def _restore(self, state: dict[str, np.ndarray]) -> None:
        self.components_ = state["components"].astype(np.float64)
        self.mean_ = state["mean"].astype(np.float64)
        self.explained_variance_ratio_ = state["explained_variance_ratio"].astype(np.float64)
        if self.components_.ndim != 2 or self.components_.shape[0] != 2:
            raise ValueError(f"components have shape {self.components_.shape}")
        if self.mean_.shape != (self.components_.shape[1],):
            raise ValueError(f"mean has shape {self.mean_.shape}")


class TSNEProjection(Projection):
    """sklearn's t-SNE (seeded); new codes are placed, and points inverted, by neighbour blends."""

    name = "tsne"
    default_max_fit = 10_000

    def __init__(self, seed: int = 0, k: int = 8, perplexity: float = 30.0, max_fit: int | None = None):
        super().__init__(seed, k, max_fit)
        self.perplexity = perplexity

    def params(self) -> dict[str, Any]:
        return {**super().params(), "perplexity": self.perplexity}

    def _fit(self, x: np.ndarray) -> np.ndarray:
        perplexity = min(self.perplexity, (len(x) - 1) / 3.0)
        from sklearn.manifold import TSNE  # loaded on first fit, not at start-up

        tsne = TSNE(n_components=2, perplexity=perplexity, init="pca", random_state=self.seed)
        return tsne.fit_transform(x)


class UMAPProjection(Projection):
    """umap-learn's UMAP (seeded, imported lazily); codes are placed and points inverted by neighbour blends.

    umap's own model (numba graphs, a nearest-neighbour index) cannot be stored without pickle, and its
    transform and inverse_transform are too slow for clicks and drags (measured with umap-learn 0.5 on
    2 cores: transform of one code took seconds at N = 10k, and inverse_transform compiles a numba
    function on every call), so only the fitted embedding is kept: a fresh and a loaded map behave alike.
    """

    name = "umap"
    default_max_fit = 10_000

    def __init__(
        self,
        seed: int = 0,
        k: int = 8,
        n_neighbors: int = 15,
        min_dist: float = 0.1,
        max_fit: int | None = None,
    ):
        super().__init__(seed, k, max_fit)
        self.n_neighbors = n_neighbors
        self.min_dist = min_dist

    def params(self) -> dict[str, Any]:
        return {**super().params(), "n_neighbors": self.n_neighbors, "min_dist": self.min_dist}

    def _fit(self, x: np.ndarray) -> np.ndarray:
        with warnings.catch_warnings():
            # umap announces with an ImportWarning that TensorFlow (for ParametricUMAP, unused) is absent.
            warnings.simplefilter("ignore", ImportWarning)
            import umap  # lazy: importing umap compiles numba code

        reducer = umap.UMAP(
            n_components=2,
            n_neighbors=min(self.n_neighbors, len(x) - 1),
            min_dist=self.min_dist,
            random_state=self.seed,
        )
        return reducer.fit_transform(x)


def make_projection(name: str, seed: int = 0, **kw: Any) -> Projection:
    """An unfitted projection by name: "pca", "tsne" or "umap"."""
    if name not in Projection.registry:
        raise ConfigError(f"unknown projection {name!r}; expected one of {sorted(Projection.registry)}")
    return Projection.registry[name](seed=seed, **kw)
