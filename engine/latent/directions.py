"""Edit directions in a code space: the normal of a linear SVM separating the codes of one metadata label
from the rest (e.g. style = elderly), or the ridge-regression direction of a scalar attribute (e.g. speed),
as InterFaceGAN does for images and MoDi for motion (paper §4.3). Works on any kind's bank codes."""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
from sklearn.linear_model import RidgeCV
from sklearn.model_selection import KFold, StratifiedKFold, cross_val_score
from sklearn.svm import LinearSVC

from engine.errors import ConfigError

#: Fewest codes a label needs on each side of its SVM.
MIN_PER_LABEL = 5
#: Folds of the cross-validated score each direction reports, shuffled with this seed (a bank is stored
#: in clip order, so unshuffled folds would each hold out whole actions).
FOLDS = 3
FOLD_SEED = 0


@dataclass(frozen=True)
class EditDirection:
    """A unit ``normal`` (D,) in code space; ``amount`` 1 moves a code by ``scale``, the spread (standard
    deviation) of the codes along it. ``score``: cross-validated balanced accuracy of the label's SVM, or
    R² of the attribute's regression (how much the direction is worth trusting)."""

    name: str
    normal: np.ndarray
    scale: float
    score: float
    n_codes: int

    def apply(self, codes: np.ndarray, amount: float) -> np.ndarray:
        """Codes (N, D) or (D,) moved ``amount`` spreads along the direction; codes of k stacked D-vectors
        (MoDi's W+) move every one of them alike."""
        if not np.isfinite(amount):
            raise ConfigError(f"edit amount must be finite, got {amount}")
        x = np.asarray(codes, dtype=np.float32)
        d = len(self.normal)
        if x.shape[-1] % d:
            raise ConfigError(f"{self.name}: codes have {x.shape[-1]} values, the direction {d}")
        step = np.tile(self.normal.astype(np.float32), x.shape[-1] // d)
        return (x + np.float32(amount * self.scale) * step).astype(np.float32)


def _unit(vector: np.ndarray) -> np.ndarray:
    norm = float(np.linalg.norm(vector))
    if norm == 0.0 or not np.isfinite(norm):
        raise ConfigError("the codes give no direction (a constant label or attribute?)")
    return (vector / norm).astype(np.float32)


def _label_folds(counts: np.ndarray) -> StratifiedKFold:
    return StratifiedKFold(int(min(FOLDS, counts.min())), shuffle=True, random_state=FOLD_SEED)


def label_directions(
    codes: np.ndarray, meta: Sequence[Mapping[str, Any]], key: str, min_per_label: int = MIN_PER_LABEL
) -> list[EditDirection]:
    """One direction per value of metadata ``key`` held by at least ``min_per_label`` codes (codes
    without the key are left out): the normal of a class-balanced linear SVM, that value against the rest."""
    x = np.asarray(codes, dtype=np.float64)
    holders = np.array([i for i, m in enumerate(meta) if m.get(key) is not None], dtype=np.int64)
    if len(holders) == 0:
        return []
    values = np.array([str(meta[i][key]) for i in holders])
    out = []
    for value in sorted(set(values)):
        y = values == value
        counts = np.array([y.sum(), (~y).sum()])
        if counts.min() < min_per_label:
            continue
        svm = LinearSVC(C=1.0, class_weight="balanced", max_iter=20_000)
        folds = _label_folds(counts)
        score = cross_val_score(svm, x[holders], y, cv=folds, scoring="balanced_accuracy").mean()
        normal = _unit(svm.fit(x[holders], y).coef_[0])
        spread = float(np.std(x[holders] @ normal))
        out.append(EditDirection(f"{key}={value}", normal, spread, float(score), len(holders)))
    return out


def attribute_direction(codes: np.ndarray, values: np.ndarray, name: str) -> EditDirection:
    """The direction along which a scalar attribute (N,) of the codes (N, D) grows: a ridge regression's
    coefficients (penalty by cross-validation), scaled to the codes' spread along it."""
    x, y = np.asarray(codes, dtype=np.float64), np.asarray(values, dtype=np.float64)
    if x.ndim != 2 or y.shape != (len(x),) or len(x) < 2 * FOLDS or not np.all(np.isfinite(y)):
        raise ConfigError(f"{name}: need (N, D) codes and N finite values, N >= {2 * FOLDS}")
    ridge = RidgeCV(alphas=np.logspace(-3, 3, 13))
    folds = KFold(FOLDS, shuffle=True, random_state=FOLD_SEED)
    score = cross_val_score(ridge, x, y, cv=folds, scoring="r2").mean()
    normal = _unit(ridge.fit(x, y).coef_)
    return EditDirection(name, normal, float(np.std(x @ normal)), float(score), len(x))


def fit_directions(
    codes: np.ndarray,
    meta: Sequence[Mapping[str, Any]],
    keys: Sequence[str] = ("style",),
    attributes: Mapping[str, np.ndarray] | None = None,
) -> dict[str, EditDirection]:
    """Every label direction of metadata ``keys`` and every scalar ``attributes`` direction, by name."""
    found = [d for key in keys for d in label_directions(codes, meta, key)]
    found += [attribute_direction(codes, v, name) for name, v in (attributes or {}).items()]
    return {d.name: d for d in found}
