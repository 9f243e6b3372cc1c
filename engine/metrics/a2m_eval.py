"""Evaluate the Action2Motion baseline with the metrics and repeat/rng scheme of ``evaluate.evaluate``.

Every repeat r uses ``numpy.random.default_rng([seed, r])`` and draws the real sets A and B exactly as
``evaluate`` does, so for the same clips, classifier and seed the real row is identical and the generated
rows of ODMO and A2M are compared against the same real windows. Mode, style and end-point metrics do not
apply to A2M (no code space, no end location) and are listed in ``meta["not_applicable"]``.
"""

from __future__ import annotations

import logging
from collections.abc import Callable, Sequence
from typing import Any

import numpy as np
import torch

from engine.a2m_io import LoadedA2m, generate_a2m
from engine.errors import CancelledError, ConfigError
from engine.metrics.accuracy import recognition_accuracy
from engine.metrics.apd import apd, n_apd
from engine.metrics.classifier import Classifier
from engine.metrics.diversity import diversity, multimodality
from engine.metrics.evaluate import check_compatible
from engine.metrics.features import canonical_windows
from engine.metrics.fid import fid
from engine.metrics.reconstruction import mpjpe
from engine.metrics.stats import summarize
from engine.motion.motion import Motion
from engine.train.windows import WindowBatch, crop_windows, prepare_clips

log = logging.getLogger(__name__)

NOT_APPLICABLE = (
    "mode_homogeneity",
    "style_nmi",
    "style_ari",
    "end_error_m",
    "end_error_pct",
    "end_error_out_m",
    "end_error_out_pct",
    "control_accuracy",
    "control_accuracy_out",
)


def _pick(labels: np.ndarray, actions: np.ndarray, n: int, rng: np.random.Generator) -> np.ndarray:
    """``n`` clip indices per action, without replacement when the action has that many clips."""
    picks = []
    for a in actions:
        idx = np.flatnonzero(labels == a)
        picks.append(rng.choice(idx, size=n, replace=len(idx) < n))
    return np.concatenate(picks)


def _groups(windows: np.ndarray, labels: np.ndarray) -> dict[int, np.ndarray]:
    """Windows (N, T, J, 3) of each action with at least two of them."""
    return {int(a): windows[labels == a] for a in np.unique(labels) if np.count_nonzero(labels == a) >= 2}


def _metrics(
    windows: np.ndarray,
    mask: np.ndarray | None,
    labels: np.ndarray,
    reference: WindowBatch,
    classifier: Classifier | None,
    names: list[str],
    rng: np.random.Generator,
) -> dict[str, float]:
    """Accuracy, FID, diversity, multimodality (classifier features), APD and n-APD against ``reference``."""
    out: dict[str, float] = {}
    ref_joints, ref_labels = np.asarray(reference.joints, np.float32), np.asarray(reference.actions)
    if classifier is not None:
        ref_features = classifier.classify(ref_joints, reference.mask)[0]
        feats, pred = classifier.classify(windows, mask)
        to_model = np.array([names.index(a) if a in names else -1 for a in classifier.action_names])
        out["accuracy"] = recognition_accuracy(to_model[pred], labels)
        out["fid"] = fid(feats, ref_features)
        out["diversity"] = diversity(feats, rng)
        out["multimodality"] = multimodality(feats, labels, rng)
    groups = _groups(windows, labels)
    out["apd"] = float(np.mean([apd(g) for g in groups.values()]))
    out["n_apd"] = n_apd(groups, _groups(ref_joints, ref_labels))
    return out


def a2m_reconstruction_error(loaded: LoadedA2m, batch: WindowBatch) -> float:
    """MPJPE (metres) of real windows rebuilt free-running from their posterior means z_1..z_T."""
    device = next(loaded.model.parameters()).device
    with torch.inference_mode():
        joints = torch.from_numpy(np.ascontiguousarray(batch.joints, np.float32)).to(device)
        actions = torch.from_numpy(np.asarray(batch.actions, np.int64)).to(device)
        out = loaded.model(joints, actions, teacher=False, generator=None)
    return mpjpe(out.joints.cpu().numpy(), batch.joints, batch.mask)


def _generated_windows(
    loaded: LoadedA2m, actions: np.ndarray, n: int, generator: torch.Generator
) -> tuple[np.ndarray, np.ndarray]:
    """Canonical windows (N, T, J, 3) and labels (N,) of ``n`` sampled motions per action."""
    motions, labels = [], []
    for a in actions:
        joints = generate_a2m(loaded, int(a), n, generator)
        motions.extend(Motion(j, loaded.fps, loaded.skeleton) for j in joints)
        labels.extend([int(a)] * n)
    return canonical_windows(motions, loaded.window), np.array(labels)


def evaluate_a2m(
    loaded: LoadedA2m,
    real_clips: Sequence[Motion],
    classifier: Classifier | None,
    *,
    repeats: int = 10,
    n_per_action: int = 50,
    seed: int = 0,
    progress: Callable[[str, float], None] | None = None,
    cancel: Callable[[], bool] | None = None,
) -> dict[str, Any]:
    """``{"real": {METRIC: {"mean", "ci95"}}, "generated": {...}, "meta": {...}}`` like ``evaluate``.

    Generated: accuracy, FID, diversity, multimodality, APD, n-APD of ``n_per_action`` sampled motions per
    action against real set A, and the reconstruction error on the clips the model did not train on.
    """
    if repeats < 1 or n_per_action < 2:
        raise ConfigError(f"need repeats >= 1 and n_per_action >= 2, got {repeats}, {n_per_action}")
    check_compatible(loaded, real_clips, classifier)  # type: ignore[arg-type]  # reads only shared fields
    names = list(loaded.action_names)
    prepared = prepare_clips(real_clips, names, loaded.fps, loaded.window)
    labels = prepared.actions
    actions = np.unique(labels)
    trained = set(loaded.provenance.get("train_sources", []))
    held = np.array([i for i, s in enumerate(prepared.sources) if s not in trained], dtype=np.int64)
    if len(held) == 0:
        log.warning("every real clip is a training clip of the model; reconstruction is on training clips")
    recon_idx = held if len(held) else np.arange(len(real_clips))
    real_runs, gen_runs = [], []
    for r in range(repeats):
        if cancel is not None and cancel():
            raise CancelledError("evaluation cancelled")
        rng = np.random.default_rng([seed, r])
        sets = [crop_windows(prepared, _pick(labels, actions, n_per_action, rng), rng) for _ in range(2)]
        real_runs.append(
            _metrics(sets[0].joints, sets[0].mask, sets[0].actions, sets[1], classifier, names, rng)
        )
        generator = torch.Generator(next(loaded.model.parameters()).device)
        generator.manual_seed(int(rng.integers(2**63)))
        gen, gen_labels = _generated_windows(loaded, actions, n_per_action, generator)
        gen_metrics = _metrics(gen, None, gen_labels, sets[0], classifier, names, rng)
        gen_metrics["reconstruction_error_m"] = a2m_reconstruction_error(
            loaded, crop_windows(prepared, recon_idx, rng)
        )
        gen_runs.append(gen_metrics)
        log.info("A2M evaluation repeat %d/%d done", r + 1, repeats)
        if progress is not None:
            progress("evaluating", (r + 1) / repeats)
    meta = {
        "model": str(loaded.path),
        "arch": "a2m",
        "classifier": None if classifier is None else str(classifier.path),
        "classifier_test_accuracy": None if classifier is None else classifier.test_accuracy,
        "n_real_clips": len(real_clips),
        "n_reconstruction_clips": len(recon_idx),
        "reconstruction_held_out": bool(len(held)),
        "actions": [names[a] for a in actions],
        "repeats": repeats,
        "n_per_action": n_per_action,
        "seed": seed,
        "window": loaded.window,
        "fps": loaded.fps,
        "not_applicable": list(NOT_APPLICABLE),
        "ci": "95% interval 1.96·s/√n over repeats",
    }
    return {"real": summarize(real_runs), "generated": summarize(gen_runs), "meta": meta}
