"""Evaluate an Action2Motion model with the metrics and repeat/rng scheme of ``evaluate.evaluate``.

Both run ``evaluate.evaluate_sets``, so for the same clips, classifier and seed the real row is identical
and the generated rows of ODMO and A2M are compared against the same real windows. Mode, style and
end-point metrics do not apply to A2M (its samples come from its learned prior by default; it takes no
end location) and are listed in ``meta["not_applicable"]``.
"""

from __future__ import annotations

import logging
from collections.abc import Callable, Sequence
from typing import Any

import numpy as np
import torch

from engine.errors import ConfigError
from engine.generators.a2m import A2mGenerator, LoadedA2m, generate_a2m
from engine.generators.base import SampleRequest, check_psi, require
from engine.metrics.classifier import Classifier
from engine.metrics.evaluate import (
    EVAL_STRATEGIES,
    check_compatible,
    evaluate_sets,
    reconstruction_metrics,
    report,
)
from engine.metrics.features import canonical_windows, root_heights
from engine.metrics.unconditional import classify_joints
from engine.model.a2m import A2mModel
from engine.motion.motion import Motion
from engine.motion.skeleton import Skeleton
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


def prior_accuracy(
    model: A2mModel,
    skeleton: Skeleton,
    action_names: Sequence[str],
    classifier: Classifier,
    n_per_action: int = 20,
    seed: int = 0,
) -> float:
    """Share of ``n_per_action`` motions per action of ``action_names`` (the model's), drawn from the
    model's learned prior with ``seed``, that ``classifier`` reads as their action: a score to choose a
    training epoch by, which no held-out clip enters."""
    device = next(model.parameters()).device
    generator = torch.Generator(device).manual_seed(seed)
    actions = torch.arange(len(action_names), device=device).repeat_interleave(n_per_action)
    with torch.no_grad():
        joints, _ = model.sample(actions, generator)
    _, predicted = classify_joints(classifier, joints.cpu().numpy(), skeleton)
    wanted = np.repeat(np.asarray(action_names), n_per_action)
    return float(np.mean(np.asarray(classifier.action_names)[predicted] == wanted))


def a2m_reconstruct(loaded: LoadedA2m, batch: WindowBatch) -> np.ndarray:
    """Joints (B, T, J, 3) of real windows rebuilt free-running from their posterior means z_1..z_T."""
    device = next(loaded.model.parameters()).device
    with torch.inference_mode():
        joints = torch.from_numpy(np.ascontiguousarray(batch.joints, np.float32)).to(device)
        actions = torch.from_numpy(np.asarray(batch.actions, np.int64)).to(device)
        out = loaded.model(joints, actions, teacher=False, generator=None)
    return out.joints.cpu().numpy()


def _reconstruction(
    loaded: LoadedA2m, batch: WindowBatch, classifier: Classifier | None, names: list[str]
) -> dict[str, float]:
    return reconstruction_metrics(a2m_reconstruct(loaded, batch), batch, classifier, names, loaded.skeleton)


def _generated_windows(
    loaded: LoadedA2m, actions: np.ndarray, n: int, rng: np.random.Generator, psi: float, strategy: str
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Canonical windows (N, T, J, 3), labels (N,) and root heights of ``n`` motions per action sampled
    with ``strategy`` at truncation ``psi``.

    From the prior, one draw of ``rng`` seeds the torch generator the sampling runs on; from the bank's
    modes, one draw per action seeds ``A2mGenerator.sample``.
    """
    if strategy != "prior":
        sampler = A2mGenerator(loaded)
        found = [
            sampler.sample(
                SampleRequest(loaded.action_names[a], n, int(rng.integers(2**31)), strategy, truncation=psi)
            )
            for a in actions
        ]
        motions = [s.motion for samples in found for s in samples]  # at display height already
        labels = np.repeat(np.asarray(actions, dtype=np.int64), n)
        return canonical_windows(motions, loaded.window), labels, root_heights(motions)
    generator = torch.Generator(next(loaded.model.parameters()).device)
    generator.manual_seed(int(rng.integers(2**63)))
    motions, labels = [], []
    for a in actions:
        joints, _ = generate_a2m(loaded, int(a), n, generator, psi=psi)
        motions.extend(Motion(j, loaded.fps, loaded.skeleton) for j in joints)
        labels.extend([int(a)] * n)
    heights = root_heights(motions) + np.float32(loaded.root_height)  # the model's origin is frame 0's root
    return canonical_windows(motions, loaded.window), np.array(labels), heights


def evaluate_a2m(
    loaded: LoadedA2m,
    real_clips: Sequence[Motion],
    classifier: Classifier | None,
    *,
    repeats: int = 10,
    n_per_action: int = 50,
    seed: int = 0,
    truncation: float = 1.0,
    strategy: str = "prior",
    progress: Callable[[str, float], None] | None = None,
    cancel: Callable[[], bool] | None = None,
) -> dict[str, Any]:
    """``{"real": {METRIC: {"mean", "ci95"}}, "generated": {...}, "meta": {...}}`` like ``evaluate``.

    Generated: accuracy, FID, diversity, multimodality, APD, n-APD of ``n_per_action`` motions per action
    sampled with ``strategy`` (the learned prior, the paper's; or the bank's modes, "mode_preserving" or
    "conventional", as ODMO samples) at ``truncation`` ψ (1: the paper's sampling) against real set A,
    and the reconstruction error on the clips the model did not train on.
    """
    if repeats < 1 or n_per_action < 2:
        raise ConfigError(f"need repeats >= 1 and n_per_action >= 2, got {repeats}, {n_per_action}")
    check_psi(truncation)
    choices = ("prior", *EVAL_STRATEGIES)
    if strategy not in choices:
        raise ConfigError(f"unknown strategy {strategy!r} for evaluation; choose from {', '.join(choices)}")
    if strategy != "prior":
        require(A2mGenerator(loaded), "modes", f"sample {strategy.replace('_', '-')} codes from modes")
    check_compatible(loaded, real_clips, classifier)
    names = list(loaded.action_names)
    prepared = prepare_clips(real_clips, names, loaded.fps, loaded.window)
    trained = set(loaded.provenance.get("train_sources", []))
    held = np.array([i for i, s in enumerate(prepared.sources) if s not in trained], dtype=np.int64)
    if len(held) == 0:
        log.warning("every real clip is a training clip of the model; reconstruction is on training clips")
    recon_idx = held if len(held) else np.arange(len(real_clips))
    log.info("evaluating the A2M model %s", loaded.path)
    real_runs, gen_runs = evaluate_sets(
        prepared,
        classifier,
        lambda actions, n, rng: _generated_windows(loaded, actions, n, rng, truncation, strategy),
        names=names,
        repeats=repeats,
        n_per_action=n_per_action,
        seed=seed,
        extra=lambda rng: _reconstruction(loaded, crop_windows(prepared, recon_idx, rng), classifier, names),
        progress=progress,
        cancel=cancel,
    )
    meta = {
        "model": str(loaded.path),
        "arch": "a2m",
        "classifier": None if classifier is None else str(classifier.path),
        "classifier_test_accuracy": None if classifier is None else classifier.test_accuracy,
        "n_real_clips": len(real_clips),
        "n_reconstruction_clips": len(recon_idx),
        "reconstruction_held_out": bool(len(held)),
        "actions": [names[a] for a in np.unique(prepared.actions)],
        "repeats": repeats,
        "n_per_action": n_per_action,
        "seed": seed,
        "truncation": truncation,
        "strategy": strategy,
        "window": loaded.window,
        "fps": loaded.fps,
        "not_applicable": list(NOT_APPLICABLE),
        "ci": "95% interval 1.96·s/√n over repeats",
    }
    return report(real_runs, gen_runs) | {"meta": meta}
