"""Evaluate a DVGAN model: generated windows against real ones (``evaluate.evaluate_sets``), completion
error against a zero-velocity baseline, and the drift of long sequences.

- Windows: ``sample(frames=W)`` of the classifier's window W, from the top-level code N(0, I), so the
  RNN's windows are what ``odmo sample --frames W`` writes.
- Completion (the paper's Table 3, in joint positions): each held-out clip long enough gives one prefix
  of ``prefix_frames`` frames from its middle; the error at a horizon is the mean joint distance (m)
  between the real frame and the model's frame that many milliseconds after the prefix's last frame,
  averaged over ``n_futures`` continuations; zero velocity repeats the prefix's last frame.
- Long sequences: ``frames`` frames per action cut into windows of the classifier's length; the
  physical metrics over those windows (floating: the share of windows), the worst bone's length
  variation over the whole length, the root height per window against the real clips' range, and the
  share of windows the classifier recognises as the action.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from typing import TYPE_CHECKING, Any

import numpy as np

from engine.errors import ConfigError
from engine.generators.base import SampleRequest
from engine.metrics.evaluate import check_compatible, evaluate_sets, report
from engine.metrics.modi_eval import EvaluableSpec
from engine.metrics.physics import bone_length_cv, physics_metrics
from engine.metrics.unconditional import classify_joints
from engine.motion.resample import resample_motion
from engine.train.windows import canonicalize, prepare_clips

if TYPE_CHECKING:
    from engine.generators.dvgan import DvganGenerator
    from engine.metrics.classifier import Classifier
    from engine.motion.motion import Motion

HORIZONS_MS = (80, 160, 320, 400)


def evaluable_spec(generator: DvganGenerator, classifier: Classifier | None) -> EvaluableSpec:
    """The model as evaluated: motions of the classifier's window (the model's own without one)."""
    window = generator.window if classifier is None else classifier.config.window
    return EvaluableSpec(generator.skeleton, generator.label_names, window, generator.fps)


def _canonical(motions: Sequence[Motion]) -> tuple[np.ndarray, np.ndarray]:
    root = motions[0].skeleton.root
    canon = np.stack([canonicalize(m.joints, m.skeleton)[0] for m in motions]).astype(np.float32)
    return canon, np.array([m.joints[0, root, 1] for m in motions], np.float32)


def evaluate_dvgan(
    generator: DvganGenerator,
    real_clips: Sequence[Motion],
    classifier: Classifier | None,
    *,
    repeats: int = 10,
    n_per_action: int = 50,
    seed: int = 0,
    progress: Callable[[str, float], None] | None = None,
    cancel: Callable[[], bool] | None = None,
) -> dict[str, Any]:
    """``{"real", "generated", "per_action", "meta"}`` like ``evaluate``, for generated windows."""
    if repeats < 1 or n_per_action < 2:
        raise ConfigError(f"need repeats >= 1 and n_per_action >= 2, got {repeats}, {n_per_action}")
    names = generator.label_names
    spec = evaluable_spec(generator, classifier)
    check_compatible(spec, real_clips, classifier)
    prepared = prepare_clips(real_clips, names, generator.fps, spec.window)

    def generate(actions: np.ndarray, n: int, rng: np.random.Generator) -> tuple[np.ndarray, ...]:
        motions, labels = [], []
        for a in actions:
            request = SampleRequest(names[int(a)], n, int(rng.integers(2**31)))
            motions += [s.motion for s in generator.sample(request, frames=spec.window)]
            labels += [int(a)] * n
        windows, heights = _canonical(motions)
        return windows, np.array(labels), heights

    real_runs, gen_runs = evaluate_sets(
        prepared, classifier, generate, names=names, repeats=repeats, n_per_action=n_per_action,
        seed=seed, progress=progress, cancel=cancel,
    )  # fmt: skip
    result = report(real_runs, gen_runs)
    result["meta"] = {
        "model": str(generator.path),
        "arch": "dvgan",
        "classifier": None if classifier is None else str(classifier.path),
        "classifier_test_accuracy": None if classifier is None else classifier.test_accuracy,
        "n_real_clips": len(real_clips),
        "actions": [names[a] for a in np.unique(prepared.actions)],
        "repeats": repeats,
        "n_per_action": n_per_action,
        "seed": seed,
        "window": spec.window,
        "fps": generator.fps,
        "ci": "95% interval 1.96·s/√n over repeats",
    }
    return result


def completion_errors(
    generator: DvganGenerator,
    clips: Sequence[Motion],
    *,
    prefix_frames: int = 20,
    horizons_ms: Sequence[int] = HORIZONS_MS,
    n_futures: int = 4,
    seed: int = 0,
) -> dict[str, dict[str, Any]]:
    """Per action: ``{"model": {ms: m}, "zero_velocity": {ms: m}, "n_clips": n}`` (see the module)."""
    steps = [max(1, round(ms / 1000 * generator.fps)) for ms in horizons_ms]
    errors: dict[str, dict[str, list[list[float]]]] = {}
    for k, clip in enumerate(clips):
        moved = resample_motion(clip, generator.fps)
        need = prefix_frames + steps[-1]
        if moved.n_frames < need:
            continue
        start = (moved.n_frames - need) // 2
        prefix = moved.with_joints(moved.joints[start : start + prefix_frames])
        truth = moved.joints[start + prefix_frames - 1 : start + need]
        futures = generator.complete(prefix, steps[-1], n_futures, seed + k, clip.action)
        made = np.stack([f.joints[prefix_frames - 1 :] for f in futures])  # (K, 1 + H, J, 3)
        row = errors.setdefault(clip.action, {"model": [], "zero_velocity": []})
        row["model"].append([float(np.linalg.norm(made[:, s] - truth[s], axis=-1).mean()) for s in steps])
        row["zero_velocity"].append(
            [float(np.linalg.norm(truth[0] - truth[s], axis=-1).mean()) for s in steps]
        )
    return {
        action: {
            side: dict(zip(map(str, horizons_ms), np.mean(rows[side], axis=0).tolist(), strict=True))
            for side in ("model", "zero_velocity")
        }
        | {"n_clips": len(rows["model"])}
        for action, rows in errors.items()
    }


def long_sequences(
    generator: DvganGenerator,
    real_clips: Sequence[Motion],
    classifier: Classifier | None,
    *,
    frames: int = 3000,
    seed: int = 0,
) -> dict[str, dict[str, float]]:
    """Per action, one ``frames``-frame sequence: physical metrics over its whole length, the range of its
    root height over windows of the classifier's length against the real clips', and the share of those
    windows recognised as the action (``accuracy``; NaN without a classifier)."""
    window = evaluable_spec(generator, classifier).window
    root = generator.skeleton.root
    real_heights = np.concatenate([resample_motion(c, generator.fps).joints[:, root, 1] for c in real_clips])
    low, high = np.percentile(real_heights, [1, 99])
    out = {}
    for action in generator.label_names:
        [sample] = generator.sample(SampleRequest(action, 1, seed), frames=frames)
        joints = sample.motion.joints
        pieces = joints[: len(joints) // window * window].reshape(-1, window, *joints.shape[1:])
        heights = pieces[:, :, root, 1].mean(axis=1)
        row = physics_metrics(list(pieces), generator.skeleton, generator.fps)
        row |= {
            "bone_length_cv_whole": bone_length_cv(joints, generator.skeleton.parents),
            "root_height_min_m": float(heights.min()),
            "root_height_max_m": float(heights.max()),
            "windows_in_real_height_range": float(np.mean((heights >= low) & (heights <= high))),
            "accuracy": float("nan"),
        }
        if classifier is not None:
            _, predicted = classify_joints(classifier, pieces, generator.skeleton)
            row["accuracy"] = float(np.mean(np.array(classifier.action_names)[predicted] == action))
        out[action] = row
    return out
