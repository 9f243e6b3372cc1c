"""Evaluate an unconditional MoDi model with the repeat/rng scheme of ``evaluate.evaluate_sets``.

Each repeat samples ``n_per_action`` × actions motions from the prior (ψ = 1) and labels them with the
classifier (or, without one, with their nearest bank codes), so FID, KID, precision/recall, diversity,
the predicted-action shares and their KL to real, and the physical metrics compare the generated set with
the same real windows every kind is compared with. Accuracy is left out: the labels are the classifier's
own predictions. Held-out clips are inverted in W+ once, for the inversion error.
"""

from __future__ import annotations

import logging
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from engine.errors import ConfigError
from engine.generators.modi import ModiGenerator, decode_display, invert_motions
from engine.generators.modi_latent import INVERT_STEPS, sample_w
from engine.metrics.classifier import Classifier
from engine.metrics.evaluate import check_compatible, evaluate_sets, report
from engine.metrics.stats import mean_ci95
from engine.metrics.unconditional import classify_joints
from engine.motion.motion import Motion
from engine.motion.skeleton import Skeleton
from engine.train.windows import canonicalize, prepare_clips

log = logging.getLogger(__name__)

NOT_APPLICABLE = ("accuracy", "mode_homogeneity", "style_nmi", "style_ari", "end_error_m", "control_accuracy")
#: Held-out clips inverted for the inversion error.
N_INVERSIONS = 40


def _windows(generator: ModiGenerator, codes: np.ndarray, window: int) -> tuple[np.ndarray, np.ndarray]:
    """Canonical centre windows (N, window, J, 3) of the codes' motions as shown, and their frame-0 root
    heights (N,)."""
    joints = decode_display(generator.loaded, codes)
    start = (joints.shape[1] - window) // 2
    pieces = joints[:, start : start + window]
    root = generator.skeleton.root
    canon = np.stack([canonicalize(p, generator.skeleton)[0] for p in pieces]).astype(np.float32)
    return canon, pieces[:, 0, root, 1].astype(np.float32)


def evaluate_modi(
    generator: ModiGenerator,
    real_clips: Sequence[Motion],
    classifier: Classifier | None,
    *,
    repeats: int = 10,
    n_per_action: int = 50,
    seed: int = 0,
    truncation: float = 1.0,
    n_inversions: int = N_INVERSIONS,
    inversion_steps: int = INVERT_STEPS,
    progress: Callable[[str, float], None] | None = None,
    cancel: Callable[[], bool] | None = None,
) -> dict[str, Any]:
    """``{"real", "generated", "per_action", "meta"}`` like ``evaluate``, for an unconditional model whose
    samples are truncated by ``truncation`` ψ (1: none)."""
    if repeats < 1 or n_per_action < 2:
        raise ConfigError(f"need repeats >= 1 and n_per_action >= 2, got {repeats}, {n_per_action}")
    names = generator.label_names
    spec = evaluable_spec(generator, classifier)
    window = spec.window
    check_compatible(spec, real_clips, classifier)
    prepared = prepare_clips(real_clips, names, generator.fps, window)
    to_model = None if classifier is None else np.array([names.index(a) if a in names else -1
                                                         for a in classifier.action_names])  # fmt: skip

    def generate(actions: np.ndarray, n: int, rng: np.random.Generator) -> tuple[np.ndarray, ...]:
        codes = sample_w(generator.loaded.model, n * len(actions), int(rng.integers(2**31)), truncation)
        windows, heights = _windows(generator, codes, window)
        if to_model is None:
            labels = generator.labels_of(codes)
        else:
            labels = to_model[classify_joints(classifier, windows, generator.skeleton)[1]]
        return windows, labels, heights

    real_runs, gen_runs = evaluate_sets(
        prepared, classifier, generate, names=names, repeats=repeats, n_per_action=n_per_action,
        seed=seed, progress=progress, cancel=cancel,
    )  # fmt: skip
    for row in gen_runs:
        row.pop("accuracy", None)
    result = report(real_runs, gen_runs)
    trained = set(generator.loaded.provenance.get("train_sources", []))
    held = [c for c in real_clips if str(c.meta.get("source", "")) not in trained]
    picked = held[:: max(1, len(held) // n_inversions)][:n_inversions] if n_inversions else []
    if picked:
        errors = invert_motions(generator.loaded, picked, "W+", inversion_steps, cancel=cancel).errors
        mean, ci = mean_ci95(errors)
        result["generated"]["inversion_error_m"] = {"mean": mean, "ci95": ci}
    result["meta"] = {
        "model": str(generator.path),
        "arch": "modi",
        "classifier": None if classifier is None else str(classifier.path),
        "classifier_test_accuracy": None if classifier is None else classifier.test_accuracy,
        "n_real_clips": len(real_clips),
        "n_inverted_clips": len(picked),
        "inversion_steps": inversion_steps,
        "inverted_held_out": bool(trained),
        "actions": [names[a] for a in np.unique(prepared.actions)],
        "repeats": repeats,
        "n_per_action": n_per_action,
        "seed": seed,
        "window": window,
        "fps": generator.fps,
        "truncation": truncation,
        "labels": "classifier predictions" if classifier is not None else "nearest bank codes",
        "not_applicable": list(NOT_APPLICABLE),
        "ci": "95% interval 1.96·s/√n over repeats (inversion: over clips)",
    }
    return result


@dataclass(frozen=True)
class EvaluableSpec:
    """What ``check_compatible`` reads of the model: skeleton, labels, and the window its motions are cut
    to (the classifier's)."""

    skeleton: Skeleton
    action_names: list[str]
    window: int
    fps: float


def evaluable_spec(generator: ModiGenerator, classifier: Classifier | None) -> EvaluableSpec:
    """The model as evaluated: its motions' centre windows of the classifier's length."""
    window = generator.window if classifier is None else classifier.config.window
    if window > generator.window:
        raise ConfigError(f"the classifier reads {window} frames, the model makes {generator.window}")
    return EvaluableSpec(generator.skeleton, generator.label_names, window, generator.fps)
