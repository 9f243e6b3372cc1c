"""Per-action motion modes: Gaussian mixtures chosen by silhouette, and sampling from them."""

from __future__ import annotations

import logging
import warnings
from typing import TYPE_CHECKING, Any, Self

import numpy as np

from engine.errors import ConfigError, ModelFormatError

if TYPE_CHECKING:
    from sklearn.mixture import GaussianMixture

log = logging.getLogger(__name__)

STRATEGIES = ("mode_preserving", "conventional", "mode", "weights")
COVARIANCES = ("full", "diag")
_PARAMS = ("k_range", "ratio", "min_members", "seed", "silhouette_sample", "covariance")
REG_COVAR = 1e-6  # added to every covariance diagonal, as sklearn's GaussianMixture does by default


class ModeModel:
    """One action's modes (scikit-learn estimator convention): ``fit`` finds a Gaussian mixture over the
    action's codes, chosen by silhouette, plus the one-Gaussian ("conventional") fit.

    ``get_params`` / ``set_params`` make it an estimator to ``sklearn.base.clone`` without subclassing
    ``BaseEstimator``, whose import (0.37 s) would be on the path of opening a bank in the app.

    Parameters: ``k_range`` (inclusive) of mixture sizes tried, the ``ratio`` of :func:`choose_k`,
    ``min_members`` a component needs to be kept, the ``seed``, and ``silhouette_sample`` (silhouettes of
    more codes are estimated on a seeded subsample; None: always exact). ``k_range=(1, 1)`` fits one
    Gaussian (e.g. a local mode of a selection). ``covariance`` "diag" fits axis-aligned Gaussians, for
    codes of hundreds of dimensions (MoDi's W), whose full covariances would weigh D² numbers a mode.

    Fitted attributes
    -----------------
    weights_ : (K,) mixture weights, renormalised after dropping small components.
    means_ : (K, D); covariances_ : (K, D, D) (diagonal ones held as full matrices; stored as diagonals).
    labels_ : (N,) mode index of each fitted code.
    silhouette_ : every K tried -> silhouette score (nan where undefined or not fitted).
    k_chosen_ : the K the selection rule picked, before dropping (1 when no K could be scored).
    conventional_mean_ : (D,); conventional_cov_ : (D, D), the maximum-likelihood Gaussian plus
    ``REG_COVAR`` on the diagonal.
    """

    weights_: np.ndarray
    means_: np.ndarray
    covariances_: np.ndarray
    labels_: np.ndarray
    silhouette_: dict[int, float]
    k_chosen_: int
    conventional_mean_: np.ndarray
    conventional_cov_: np.ndarray

    def __init__(
        self,
        k_range: tuple[int, int] = (3, 11),
        ratio: float = 0.95,
        min_members: int = 10,
        seed: int = 0,
        silhouette_sample: int | None = 5000,
        covariance: str = "full",
    ) -> None:
        self.k_range = k_range
        self.ratio = ratio
        self.min_members = min_members
        self.seed = seed
        self.silhouette_sample = silhouette_sample
        self.covariance = covariance

    def get_params(self, deep: bool = True) -> dict[str, Any]:
        """The constructor parameters (scikit-learn's estimator API)."""
        return {name: getattr(self, name) for name in _PARAMS}

    def set_params(self, **params: Any) -> Self:
        """Set constructor parameters (scikit-learn's estimator API); ValueError for unknown ones."""
        unknown = sorted(set(params) - set(_PARAMS))
        if unknown:
            raise ValueError(f"ModeModel has no parameters {unknown}; valid: {list(_PARAMS)}")
        for name, value in params.items():
            setattr(self, name, value)
        return self

    def __sklearn_tags__(self) -> Any:
        """scikit-learn's default estimator tags (what ``BaseEstimator`` would give), imported on use."""
        from sklearn.utils import Tags, TargetTags

        return Tags(estimator_type=None, target_tags=TargetTags(required=False))

    def fit(self, codes: np.ndarray) -> Self:
        """Fit to one action's codes (N, D): a GMM for every K in ``k_range`` scored by silhouette, K
        picked by :func:`choose_k`, components with fewer than ``min_members`` codes dropped and the
        weights renormalised. Ks larger than N are recorded as nan. When no K can be scored, or no
        component keeps enough members, the one mode is the conventional Gaussian."""
        x = _check_codes(codes)
        if len(x) == 0:
            raise ConfigError("cannot fit modes to no codes")
        k_min, k_max = self.k_range
        if not 1 <= k_min <= k_max:
            raise ConfigError(f"k_range must satisfy 1 <= min <= max, got {self.k_range}")
        if not self.ratio > 0.0:
            raise ConfigError(f"ratio must be positive, got {self.ratio}")
        if self.covariance not in COVARIANCES:
            raise ConfigError(f"covariance must be one of {', '.join(COVARIANCES)}, got {self.covariance!r}")
        fits: dict[int, GaussianMixture] = {}
        scores: dict[int, float] = {}
        for k in range(k_min, k_max + 1):
            if k == 1 or k > len(x):  # one cluster has no silhouette
                scores[k] = float("nan")
                continue
            fits[k] = _fit_gmm(x, k, self.seed, self.covariance)
            scores[k] = _silhouette(x, fits[k].predict(x), self.silhouette_sample, self.seed)
        chosen = choose_k(scores, self.ratio)
        self.silhouette_, self.k_chosen_ = scores, 1 if chosen is None else chosen
        self.conventional_mean_ = x.mean(axis=0)
        dim = x.shape[1]
        cov = np.cov(x, rowvar=False, bias=True).reshape(dim, dim) + REG_COVAR * np.eye(dim)
        if self.covariance == "diag":
            cov = np.diag(np.diag(cov))
        self.conventional_cov_ = cov
        keep = np.array([], dtype=np.int64)
        if chosen is not None:
            gmm = fits[chosen]
            keep = np.flatnonzero(np.bincount(gmm.predict(x), minlength=chosen) >= self.min_members)
        if len(keep) == 0:
            if k_max > 1:
                log.info("no usable mixture among K in %s for %d codes: one mode", self.k_range, len(x))
            self.weights_ = np.ones(1)
            self.means_, self.covariances_ = self.conventional_mean_[None], cov[None]
        else:
            self.weights_ = gmm.weights_[keep] / gmm.weights_[keep].sum()
            covariances = gmm.covariances_[keep]
            if self.covariance == "diag":
                covariances = np.stack([np.diag(c) for c in covariances])
            self.means_, self.covariances_ = gmm.means_[keep], covariances
        self.labels_ = np.zeros(len(x), dtype=np.int64)
        if self.n_modes_ > 1:
            self.labels_ = self.predict(x)
        return self

    @property
    def n_modes_(self) -> int:
        """Number of modes kept."""
        return len(self.weights_)

    def sizes(self) -> np.ndarray:
        """(K,) number of training codes assigned to each mode."""
        return np.bincount(self.labels_, minlength=self.n_modes_)

    def sample(
        self,
        n: int,
        rng: np.random.Generator,
        strategy: str = "mode_preserving",
        mode: int | None = None,
        weights: np.ndarray | None = None,
    ) -> tuple[np.ndarray, np.ndarray]:
        """Draw ``n`` codes; returns codes (n, D) float32 and their mode index (n,) (−1 for conventional).

        Strategies: "mode_preserving" (each sample's mode drawn from the mixture weights), "conventional"
        (the action's single Gaussian), "mode" (all from mode ``mode``), "weights" (modes drawn from the
        user's ``weights``, normalised).
        """
        if n < 0:
            raise ConfigError(f"number of samples must be non-negative, got {n}")
        dim = self.means_.shape[1]
        if strategy == "conventional":
            codes = rng.multivariate_normal(self.conventional_mean_, self.conventional_cov_, size=n)
            return codes.reshape(n, dim).astype(np.float32), np.full(n, -1, dtype=np.int64)
        if strategy == "mode_preserving":
            probs = self.weights_
        elif strategy == "weights":
            probs = self._user_weights(weights)
        elif strategy == "mode":
            if mode is None or not 0 <= int(mode) < self.n_modes_:
                raise ConfigError(f"mode must be in 0..{self.n_modes_ - 1}, got {mode}")
            probs = np.eye(self.n_modes_)[int(mode)]
        else:
            raise ConfigError(f"unknown sampling strategy {strategy!r}; expected one of {STRATEGIES}")
        modes = rng.choice(self.n_modes_, size=n, p=probs).astype(np.int64)
        codes = np.empty((n, dim), dtype=np.float64)
        for k in range(self.n_modes_):
            chosen = modes == k
            if chosen.any():
                mean, cov = self.means_[k], self.covariances_[k]
                codes[chosen] = rng.multivariate_normal(mean, cov, size=chosen.sum())
        return codes.astype(np.float32), modes

    def _user_weights(self, weights: np.ndarray | None) -> np.ndarray:
        """Validated, normalised user weights (K,)."""
        if weights is None:
            raise ConfigError('strategy "weights" needs weights')
        w = np.asarray(weights, dtype=np.float64)
        if w.shape != (self.n_modes_,):
            raise ConfigError(f"need {self.n_modes_} weights, got shape {w.shape}")
        if not np.all(np.isfinite(w)) or np.any(w < 0):
            raise ConfigError("weights must be finite and non-negative")
        if w.sum() <= 0:
            raise ConfigError("weights must not all be zero")
        return w / w.sum()

    def log_responsibilities(self, codes: np.ndarray) -> np.ndarray:
        """(M, K) log of weight × density of each code under each mode (unnormalised)."""
        from scipy.stats import multivariate_normal  # loaded on first use, not at start-up

        x = _check_codes(codes, self.means_.shape[1])
        return np.stack(
            [
                np.log(w) + multivariate_normal(mean, cov).logpdf(x).reshape(len(x))
                for w, mean, cov in zip(self.weights_, self.means_, self.covariances_, strict=True)
            ],
            axis=1,
        )

    def predict(self, codes: np.ndarray) -> np.ndarray:
        """(M,) most probable mode of each code (M, D)."""
        return np.argmax(self.log_responsibilities(codes), axis=1).astype(np.int64)

    def problem(self) -> str | None:
        """What makes these modes unusable for sampling (non-finite or negative weights, covariances that
        are not symmetric positive definite), or None."""
        w = np.asarray(self.weights_, dtype=np.float64)
        if not np.all(np.isfinite(w)) or np.any(w < 0) or abs(w.sum() - 1.0) > 1e-3:
            return f"mixture weights must be finite, non-negative and sum to 1, got {w.tolist()}"
        for name, values in (("means", self.means_), ("conventional_mean", self.conventional_mean_)):
            if not np.all(np.isfinite(values)) or np.abs(values).max() > 1e6:
                return f"{name} must be finite numbers of sensible size (|x| <= 1e6)"
        pairs = (("covariances", self.covariances_), ("conventional_cov", self.conventional_cov_[None]))
        for name, covs in pairs:
            c = np.asarray(covs, dtype=np.float64)
            if not np.all(np.isfinite(c)) or not np.allclose(c, np.swapaxes(c, 1, 2), atol=1e-6, rtol=1e-4):
                return f"{name} must be finite and symmetric"
            if np.abs(c).max() > 1e12 or np.any(np.linalg.eigvalsh(c)[:, 0] <= 0):
                return f"{name} must be positive definite"
        return None

    def to_arrays(self, prefix: str) -> dict[str, np.ndarray]:
        """Plain arrays (no objects) under keys starting with ``prefix``."""
        ks = sorted(self.silhouette_)
        diagonal = self.covariance == "diag"
        covariances = np.diagonal(self.covariances_, axis1=1, axis2=2) if diagonal else self.covariances_
        conventional = np.diag(self.conventional_cov_) if diagonal else self.conventional_cov_
        return {
            f"{prefix}weights": self.weights_,
            f"{prefix}means": self.means_,
            f"{prefix}covariance": np.asarray(self.covariance),
            f"{prefix}covariances": covariances,
            f"{prefix}labels": self.labels_,
            f"{prefix}silhouette_k": np.asarray(ks, dtype=np.int64),
            f"{prefix}silhouette_score": np.asarray([self.silhouette_[k] for k in ks], dtype=np.float64),
            f"{prefix}k_chosen": np.asarray(self.k_chosen_, dtype=np.int64),
            f"{prefix}conventional_mean": self.conventional_mean_,
            f"{prefix}conventional_cov": conventional,
        }

    @classmethod
    def from_arrays(cls, prefix: str, arrays: dict[str, np.ndarray]) -> ModeModel:
        """Rebuild from :meth:`to_arrays` output; ModelFormatError for missing keys or bad shapes."""
        covariance = str(arrays.get(f"{prefix}covariance", "full"))  # banks before the option are full
        if covariance not in COVARIANCES:
            raise ModelFormatError(f"mode model {prefix!r}: unknown covariance {covariance!r}")
        model = cls(covariance=covariance)
        try:
            model.weights_ = arrays[f"{prefix}weights"]
            model.means_ = arrays[f"{prefix}means"]
            model.covariances_ = arrays[f"{prefix}covariances"]
            model.labels_ = arrays[f"{prefix}labels"]
            scores = zip(arrays[f"{prefix}silhouette_k"], arrays[f"{prefix}silhouette_score"], strict=True)
            model.silhouette_ = {int(k): float(s) for k, s in scores}
            model.k_chosen_ = int(arrays[f"{prefix}k_chosen"])
            model.conventional_mean_ = arrays[f"{prefix}conventional_mean"]
            model.conventional_cov_ = arrays[f"{prefix}conventional_cov"]
            if covariance == "diag":
                model.covariances_ = np.stack([np.diag(c) for c in model.covariances_])
                model.conventional_cov_ = np.diag(model.conventional_cov_)
        except KeyError as exc:
            raise ModelFormatError(f"mode model is missing {exc.args[0]!r}") from exc
        except (TypeError, ValueError) as exc:
            raise ModelFormatError(f"mode model {prefix!r} is malformed: {exc}") from exc
        k, d = model.means_.shape if model.means_.ndim == 2 else (-1, -1)
        if (
            k < 1
            or model.weights_.shape != (k,)
            or model.covariances_.shape != (k, d, d)
            or model.conventional_mean_.shape != (d,)
            or model.conventional_cov_.shape != (d, d)
            or model.labels_.ndim != 1
            or (len(model.labels_) and (model.labels_.min() < 0 or model.labels_.max() >= k))
        ):
            raise ModelFormatError(f"mode model {prefix!r} has inconsistent shapes")
        return model


def _check_codes(codes: np.ndarray, dim: int | None = None) -> np.ndarray:
    """``codes`` as finite float64 (N, D), or ConfigError."""
    x = np.asarray(codes, dtype=np.float64)
    if x.ndim != 2 or (dim is not None and x.shape[1] != dim):
        raise ConfigError(f"codes must have shape (N, {dim if dim is not None else 'D'}), got {x.shape}")
    if not np.all(np.isfinite(x)):
        raise ConfigError("codes contain NaN or infinite values")
    return x


def _silhouette(x: np.ndarray, labels: np.ndarray, sample_size: int | None, seed: int) -> float:
    """Silhouette of a labelling, nan where it is undefined (fewer than 2 or more than N − 1 clusters)."""
    n_labels = len(np.unique(labels))
    if not 2 <= n_labels <= len(x) - 1:
        return float("nan")
    from sklearn.metrics import silhouette_score  # loaded on first fit, not at start-up

    if sample_size is not None and len(x) > sample_size:
        return float(silhouette_score(x, labels, sample_size=sample_size, random_state=seed))
    return float(silhouette_score(x, labels))


def choose_k(scores: dict[int, float], ratio: float = 0.95) -> int | None:
    """The first K with score[K] > ratio × score[K+1], else the best-scoring K (None: nothing scored)."""
    ks = sorted(k for k, s in scores.items() if np.isfinite(s))
    for k in ks:
        if k + 1 in scores and np.isfinite(scores[k + 1]) and scores[k] > ratio * scores[k + 1]:
            return k
    return max(ks, key=lambda k: scores[k]) if ks else None


def _fit_gmm(x: np.ndarray, k: int, seed: int, covariance: str = "full") -> GaussianMixture:
    """A mixture of ``k`` Gaussians (full or diagonal covariances); non-convergence is logged, not raised."""
    from sklearn.exceptions import ConvergenceWarning  # loaded on first fit, not at start-up
    from sklearn.mixture import GaussianMixture

    gmm = GaussianMixture(n_components=k, covariance_type=covariance, reg_covar=REG_COVAR, random_state=seed)
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always", ConvergenceWarning)
        gmm.fit(x)
    for warning in caught:
        log.warning("GMM with K=%d: %s", k, warning.message)
    return gmm
