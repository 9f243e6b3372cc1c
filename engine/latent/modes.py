"""Per-action motion modes: Gaussian mixtures chosen by silhouette, and sampling from them."""

from __future__ import annotations

import logging
import warnings
from dataclasses import dataclass

import numpy as np
from scipy.stats import multivariate_normal
from sklearn.exceptions import ConvergenceWarning
from sklearn.metrics import silhouette_score
from sklearn.mixture import GaussianMixture

from engine.errors import ConfigError, ModelFormatError

log = logging.getLogger(__name__)

STRATEGIES = ("mode_preserving", "conventional", "mode", "weights")
REG_COVAR = 1e-6  # added to every covariance diagonal, as sklearn's GaussianMixture does by default


@dataclass
class ModeModel:
    """One action's modes: a Gaussian mixture over its codes plus the one-Gaussian ("conventional") fit.

    Attributes
    ----------
    weights : (K,) mixture weights, renormalised after dropping small components.
    means : (K, D); covariances : (K, D, D) full.
    labels : (N,) mode index of each of the action's training codes.
    silhouette : every K tried -> silhouette score (nan where undefined or not fitted).
    k_chosen : the K the selection rule picked, before dropping (1 when no K could be scored).
    conventional_mean : (D,); conventional_cov : (D, D).
    """

    weights: np.ndarray
    means: np.ndarray
    covariances: np.ndarray
    labels: np.ndarray
    silhouette: dict[int, float]
    k_chosen: int
    conventional_mean: np.ndarray
    conventional_cov: np.ndarray

    @property
    def n_modes(self) -> int:
        """Number of modes kept."""
        return len(self.weights)

    def sizes(self) -> np.ndarray:
        """(K,) number of training codes assigned to each mode."""
        return np.bincount(self.labels, minlength=self.n_modes)

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
        dim = self.means.shape[1]
        if strategy == "conventional":
            codes = rng.multivariate_normal(self.conventional_mean, self.conventional_cov, size=n)
            return codes.reshape(n, dim).astype(np.float32), np.full(n, -1, dtype=np.int64)
        if strategy == "mode_preserving":
            probs = self.weights
        elif strategy == "weights":
            probs = self._user_weights(weights)
        elif strategy == "mode":
            if mode is None or not 0 <= int(mode) < self.n_modes:
                raise ConfigError(f"mode must be in 0..{self.n_modes - 1}, got {mode}")
            probs = np.eye(self.n_modes)[int(mode)]
        else:
            raise ConfigError(f"unknown sampling strategy {strategy!r}; expected one of {STRATEGIES}")
        modes = rng.choice(self.n_modes, size=n, p=probs).astype(np.int64)
        codes = np.empty((n, dim), dtype=np.float64)
        for k in range(self.n_modes):
            chosen = modes == k
            if chosen.any():
                codes[chosen] = rng.multivariate_normal(self.means[k], self.covariances[k], size=chosen.sum())
        return codes.astype(np.float32), modes

    def _user_weights(self, weights: np.ndarray | None) -> np.ndarray:
        """Validated, normalised user weights (K,)."""
        if weights is None:
            raise ConfigError('strategy "weights" needs weights')
        w = np.asarray(weights, dtype=np.float64)
        if w.shape != (self.n_modes,):
            raise ConfigError(f"need {self.n_modes} weights, got shape {w.shape}")
        if not np.all(np.isfinite(w)) or np.any(w < 0):
            raise ConfigError("weights must be finite and non-negative")
        if w.sum() <= 0:
            raise ConfigError("weights must not all be zero")
        return w / w.sum()

    def log_responsibilities(self, codes: np.ndarray) -> np.ndarray:
        """(M, K) log of weight × density of each code under each mode (unnormalised)."""
        x = _check_codes(codes, self.means.shape[1])
        return np.stack(
            [
                np.log(w) + multivariate_normal(mean, cov).logpdf(x).reshape(len(x))
                for w, mean, cov in zip(self.weights, self.means, self.covariances, strict=True)
            ],
            axis=1,
        )

    def predict(self, codes: np.ndarray) -> np.ndarray:
        """(M,) most probable mode of each code (M, D)."""
        return np.argmax(self.log_responsibilities(codes), axis=1).astype(np.int64)

    def problem(self) -> str | None:
        """What makes these modes unusable for sampling (non-finite or negative weights, covariances that
        are not symmetric positive definite), or None."""
        w = np.asarray(self.weights, dtype=np.float64)
        if not np.all(np.isfinite(w)) or np.any(w < 0) or abs(w.sum() - 1.0) > 1e-3:
            return f"mixture weights must be finite, non-negative and sum to 1, got {w.tolist()}"
        for name in ("means", "conventional_mean"):
            if not np.all(np.isfinite(getattr(self, name))) or np.abs(getattr(self, name)).max() > 1e6:
                return f"{name} must be finite numbers of sensible size (|x| <= 1e6)"
        pairs = (("covariances", self.covariances), ("conventional_cov", self.conventional_cov[None]))
        for name, covs in pairs:
            c = np.asarray(covs, dtype=np.float64)
            if not np.all(np.isfinite(c)) or not np.allclose(c, np.swapaxes(c, 1, 2), atol=1e-6, rtol=1e-4):
                return f"{name} must be finite and symmetric"
            if np.abs(c).max() > 1e12 or np.any(np.linalg.eigvalsh(c)[:, 0] <= 0):
                return f"{name} must be positive definite"
        return None

    def to_arrays(self, prefix: str) -> dict[str, np.ndarray]:
        """Plain arrays (no objects) under keys starting with ``prefix``."""
        ks = sorted(self.silhouette)
        return {
            f"{prefix}weights": self.weights,
            f"{prefix}means": self.means,
            f"{prefix}covariances": self.covariances,
            f"{prefix}labels": self.labels,
            f"{prefix}silhouette_k": np.asarray(ks, dtype=np.int64),
            f"{prefix}silhouette_score": np.asarray([self.silhouette[k] for k in ks], dtype=np.float64),
            f"{prefix}k_chosen": np.asarray(self.k_chosen, dtype=np.int64),
            f"{prefix}conventional_mean": self.conventional_mean,
            f"{prefix}conventional_cov": self.conventional_cov,
        }

    @classmethod
    def from_arrays(cls, prefix: str, arrays: dict[str, np.ndarray]) -> ModeModel:
        """Rebuild from :meth:`to_arrays` output; ModelFormatError for missing keys or bad shapes."""
        try:
            model = cls(
                weights=arrays[f"{prefix}weights"],
                means=arrays[f"{prefix}means"],
                covariances=arrays[f"{prefix}covariances"],
                labels=arrays[f"{prefix}labels"],
                silhouette={
                    int(k): float(s)
                    for k, s in zip(
                        arrays[f"{prefix}silhouette_k"], arrays[f"{prefix}silhouette_score"], strict=True
                    )
                },
                k_chosen=int(arrays[f"{prefix}k_chosen"]),
                conventional_mean=arrays[f"{prefix}conventional_mean"],
                conventional_cov=arrays[f"{prefix}conventional_cov"],
            )
        except KeyError as exc:
            raise ModelFormatError(f"mode model is missing {exc.args[0]!r}") from exc
        except (TypeError, ValueError) as exc:
            raise ModelFormatError(f"mode model {prefix!r} is malformed: {exc}") from exc
        k, d = model.means.shape if model.means.ndim == 2 else (-1, -1)
        if (
            k < 1
            or model.weights.shape != (k,)
            or model.covariances.shape != (k, d, d)
            or model.conventional_mean.shape != (d,)
            or model.conventional_cov.shape != (d, d)
            or model.labels.ndim != 1
            or (len(model.labels) and (model.labels.min() < 0 or model.labels.max() >= k))
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


def _fit_gmm(x: np.ndarray, k: int, seed: int) -> GaussianMixture:
    """A full-covariance mixture of ``k`` Gaussians; non-convergence is logged, not raised."""
    gmm = GaussianMixture(n_components=k, covariance_type="full", reg_covar=REG_COVAR, random_state=seed)
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always", ConvergenceWarning)
        gmm.fit(x)
    for warning in caught:
        log.warning("GMM with K=%d: %s", k, warning.message)
    return gmm


def single_gaussian(
    codes: np.ndarray, silhouette: dict[int, float] | None = None, k_chosen: int = 1
) -> ModeModel:
    """One mode: the Gaussian (maximum-likelihood mean and covariance, ``REG_COVAR`` on the diagonal) of
    codes (N, D), e.g. a local mode fitted to a selection."""
    x = _check_codes(codes)
    if len(x) == 0:
        raise ConfigError("cannot fit a Gaussian to no codes")
    mean = x.mean(axis=0)
    cov = np.cov(x, rowvar=False, bias=True).reshape(x.shape[1], x.shape[1]) + REG_COVAR * np.eye(x.shape[1])
    return ModeModel(
        weights=np.ones(1),
        means=mean[None],
        covariances=cov[None],
        labels=np.zeros(len(x), dtype=np.int64),
        silhouette={} if silhouette is None else silhouette,
        k_chosen=k_chosen,
        conventional_mean=mean,
        conventional_cov=cov,
    )


def discover_modes(
    codes: np.ndarray,
    k_range: tuple[int, int] = (3, 11),
    ratio: float = 0.95,
    min_members: int = 10,
    seed: int = 0,
    silhouette_sample: int | None = 5000,
) -> ModeModel:
    """Find one action's modes in its codes (N, D).

    Fits a GMM for every K in ``k_range`` (inclusive) and scores it by silhouette, picks K with
    :func:`choose_k`, drops components with fewer than ``min_members`` codes and renormalises the weights.
    Ks larger than N are recorded as nan. When no K can be scored, or no component keeps enough members,
    the model has one mode equal to the conventional Gaussian. Silhouettes of more than
    ``silhouette_sample`` codes are estimated on a seeded subsample (None: always exact).
    """
    x = _check_codes(codes)
    if len(x) == 0:
        raise ConfigError("cannot discover modes of an action with no codes")
    k_min, k_max = k_range
    if not 1 <= k_min <= k_max:
        raise ConfigError(f"k_range must satisfy 1 <= min <= max, got {k_range}")
    if not ratio > 0.0:
        raise ConfigError(f"ratio must be positive, got {ratio}")
    fits: dict[int, GaussianMixture] = {}
    scores: dict[int, float] = {}
    for k in range(k_min, k_max + 1):
        if k > len(x):
            scores[k] = float("nan")
            continue
        fits[k] = _fit_gmm(x, k, seed)
        scores[k] = _silhouette(x, fits[k].predict(x), silhouette_sample, seed)
    chosen = choose_k(scores, ratio)

    single = single_gaussian(x, scores, 1 if chosen is None else chosen)
    conv_mean, conv_cov = single.conventional_mean, single.conventional_cov
    if chosen is None:
        log.info("no K in %s could be scored for %d codes: one mode", k_range, len(x))
        return single
    gmm = fits[chosen]
    counts = np.bincount(gmm.predict(x), minlength=chosen)
    keep = np.flatnonzero(counts >= min_members)
    if len(keep) == 0:
        log.info("no mode of K=%d has %d members: one mode", chosen, min_members)
        return single
    model = ModeModel(
        weights=gmm.weights_[keep] / gmm.weights_[keep].sum(),
        means=gmm.means_[keep],
        covariances=gmm.covariances_[keep],
        labels=np.zeros(len(x), dtype=np.int64),
        silhouette=scores,
        k_chosen=chosen,
        conventional_mean=conv_mean,
        conventional_cov=conv_cov,
    )
    model.labels = model.predict(x)
    return model
