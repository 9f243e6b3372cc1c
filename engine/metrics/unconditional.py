"""Set metrics that need no action condition: KID, precision and recall on classifier features, and the
distribution of predicted actions against real; and classifying generated joints of any length."""

from __future__ import annotations

import numpy as np
from scipy.spatial.distance import cdist

from engine.errors import ConfigError
from engine.metrics.classifier import Classifier
from engine.motion.skeleton import Skeleton
from engine.train.windows import canonicalize

#: Neighbours whose distance sets a sample's ball in precision and recall (Kynkäänniemi et al. 2019).
PR_NEIGHBOURS = 3
#: Probability added to every action share before the KL, so an action never generated costs a finite,
#: large amount instead of infinity.
SHARE_FLOOR = 1e-3


def kid(features_a: np.ndarray, features_b: np.ndarray) -> float:
    """Kernel Inception Distance (Bińkowski et al. 2018): the unbiased squared MMD of two feature sets
    (N, F), (M, F) under the cubic polynomial kernel k(x, y) = (x·y / F + 1)³."""
    a, b = np.asarray(features_a, np.float64), np.asarray(features_b, np.float64)
    if a.ndim != 2 or b.ndim != 2 or a.shape[1] != b.shape[1] or len(a) < 2 or len(b) < 2:
        raise ConfigError(f"KID needs two (N >= 2, F) feature sets, got {a.shape} and {b.shape}")
    f = a.shape[1]
    k_aa, k_bb, k_ab = ((x @ y.T / f + 1.0) ** 3 for x, y in ((a, a), (b, b), (a, b)))
    n, m = len(a), len(b)
    within_a = (k_aa.sum() - np.trace(k_aa)) / (n * (n - 1))
    within_b = (k_bb.sum() - np.trace(k_bb)) / (m * (m - 1))
    return float(within_a + within_b - 2.0 * k_ab.mean())


def precision_recall(real: np.ndarray, generated: np.ndarray, k: int = PR_NEIGHBOURS) -> tuple[float, float]:
    """Improved precision and recall (Kynkäänniemi et al. 2019) of feature sets (N, F), (M, F): the share
    of generated samples inside some real sample's k-NN ball, and of real samples inside a generated one's."""
    a, b = np.asarray(real, np.float64), np.asarray(generated, np.float64)
    if a.ndim != 2 or b.ndim != 2 or a.shape[1] != b.shape[1] or min(len(a), len(b)) <= k:
        raise ConfigError(
            f"precision/recall needs two sets of more than {k} features, got {a.shape}, {b.shape}"
        )

    def radii(x: np.ndarray) -> np.ndarray:
        return np.sort(cdist(x, x), axis=1)[:, k]  # column 0 is the sample itself

    across = cdist(b, a)
    precision = float(np.mean((across <= radii(a)[None, :]).any(axis=1)))
    recall = float(np.mean((radii(b)[None, :] >= across.T).any(axis=1)))
    return precision, recall


def action_shares(labels: np.ndarray, n_actions: int) -> np.ndarray:
    """(A,) share of each action among ``labels`` (indices; −1, not an action, counts in none)."""
    x = np.asarray(labels, dtype=np.int64)
    counts = np.bincount(x[x >= 0], minlength=n_actions)[:n_actions].astype(np.float64)
    return counts / max(len(x), 1)


def action_kl(real_labels: np.ndarray, predicted: np.ndarray, n_actions: int) -> float:
    """KL(real ‖ generated) of the action histograms: the real clips' labels against the classifier's
    predictions on generated motions (shares floored at ``SHARE_FLOOR``, then renormalised)."""
    p, q = (action_shares(x, n_actions) + SHARE_FLOOR for x in (real_labels, predicted))
    p, q = p / p.sum(), q / q.sum()
    return float(np.sum(p * np.log(p / q)))


def classify_joints(
    classifier: Classifier, joints: np.ndarray, skeleton: Skeleton
) -> tuple[np.ndarray, np.ndarray]:
    """Classifier features (N, F) and predictions (N,; the classifier's action indices) of motions
    (N, T, J, 3): each one's centre window of the classifier's length, canonicalised as it was trained."""
    x = np.asarray(joints, dtype=np.float32)
    window = classifier.config.window
    if x.ndim != 4 or x.shape[1] < window:
        raise ConfigError(f"motions must be (N, T >= {window}, J, 3) for the classifier, got {x.shape}")
    start = (x.shape[1] - window) // 2
    windows = np.stack([canonicalize(m[start : start + window], skeleton)[0] for m in x]) if len(x) else x
    return classifier.classify(windows.astype(np.float32))
