"""Evaluate a model against a labelled folder of real clips: every metric as mean ± 95 % CI over repeats."""

from __future__ import annotations

import logging
from collections.abc import Callable, Sequence
from typing import Any, Protocol

import numpy as np
import torch

from engine.errors import CancelledError, ConfigError, DataError
from engine.generate import sample
from engine.generate._decode import decode_tensors, display_lift
from engine.metrics.accuracy import recognition_accuracy
from engine.metrics.apd import apd, n_apd
from engine.metrics.classifier import Classifier
from engine.metrics.diversity import diversity, multimodality
from engine.metrics.features import canonical_windows, root_heights
from engine.metrics.fid import fid
from engine.metrics.joint_range import JointRange
from engine.metrics.modes import mode_homogeneity, mode_purity
from engine.metrics.physics import physics_metrics
from engine.metrics.reconstruction import mpjpe
from engine.metrics.stats import summarize
from engine.metrics.trajectory import control_targets, end_point_errors, root_travel
from engine.metrics.unconditional import action_kl, action_shares, kid, precision_recall
from engine.modelio import LoadedModel
from engine.motion.motion import Motion
from engine.motion.skeleton import Skeleton
from engine.train.windows import PreparedClips, WindowBatch, canonicalize, crop_windows, prepare_clips

log = logging.getLogger(__name__)

EVAL_STRATEGIES = ("mode_preserving", "conventional")
CONTROL_POINTS = 10  # end points per code (paper: two real ends and eight between them)

GenerateFn = Callable[
    [np.ndarray, int, np.random.Generator], tuple[np.ndarray, np.ndarray, np.ndarray | None]
]
"""``(actions (A,), n per action, rng) -> (canonical windows (N, T, J, 3), labels (N,), frame-0 root
heights (N,) above the floor or None)``; with heights the physical metrics are measured too."""
PER_ACTION = "@"  # per-action metrics travel in the rows as "metric@action"
ExtraFn = Callable[[np.random.Generator], dict[str, float]]
"""``rng -> metrics`` added to a repeat's generated row, drawn after the set metrics."""


class ModelSpec(Protocol):
    """What ``check_compatible`` reads of a loaded model (ODMO or A2M)."""

    @property
    def skeleton(self) -> Skeleton: ...

    @property
    def action_names(self) -> Sequence[str]: ...

    @property
    def window(self) -> int: ...

    @property
    def fps(self) -> float: ...


def check_compatible(loaded: ModelSpec, clips: Sequence[Motion], classifier: Classifier | None) -> None:
    """ConfigError/DataError (one line) unless clips, model and classifier share skeleton and actions."""
    if not clips:
        raise DataError("the real folder has no clips")
    names = loaded.skeleton.names
    for clip in clips:
        if clip.skeleton.names != names:
            raise ConfigError(
                f"skeleton mismatch: the model has {len(names)} joints ({names[0]}, ...), a clip "
                f"({clip.meta.get('source', '?')}) has {clip.n_joints} ({clip.skeleton.names[0]}, ...)"
            )
        if clip.action not in loaded.action_names:
            raise ConfigError(
                f"action {clip.action!r} of {clip.meta.get('source', 'a clip')} is not one of the model's "
                f"actions ({', '.join(loaded.action_names)})"
            )
    if classifier is None:
        return
    unknown = sorted({c.action for c in clips} - set(classifier.action_names))
    if unknown:
        raise ConfigError(f"the classifier does not know the action(s) {', '.join(map(repr, unknown))}")
    if classifier.skeleton_names != tuple(names):
        raise ConfigError("the classifier's skeleton differs from the model's")
    if classifier.config.window != loaded.window or classifier.config.fps != loaded.fps:
        raise ConfigError(
            f"the classifier reads {classifier.config.window} frames at {classifier.config.fps} fps, "
            f"the model makes {loaded.window} at {loaded.fps}"
        )


def _pick(labels: np.ndarray, actions: np.ndarray, n: int, rng: np.random.Generator) -> np.ndarray:
    """``n`` clip indices per action (without replacement when the action has that many clips)."""
    picks = []
    for a in actions:
        idx = np.flatnonzero(labels == a)
        picks.append(rng.choice(idx, size=n, replace=len(idx) < n))
    return np.concatenate(picks)


def _by_action(windows: np.ndarray, labels: np.ndarray) -> dict[int, np.ndarray]:
    return {int(a): windows[labels == a] for a in np.unique(labels) if np.count_nonzero(labels == a) >= 2}


def _classify(
    classifier: Classifier, windows: np.ndarray, mask: np.ndarray | None, names: list[str]
) -> tuple[np.ndarray, np.ndarray]:
    """Features (N, F) and predictions (N,) as indices into the model's ``names`` (-1: not a model action)."""
    feats, pred = classifier.classify(windows, mask)
    to_model = np.array([names.index(a) if a in names else -1 for a in classifier.action_names])
    return feats, to_model[pred]


def _set_metrics(
    windows: np.ndarray,
    mask: np.ndarray | None,
    labels: np.ndarray,
    reference: dict[str, Any],
    classifier: Classifier | None,
    names: list[str],
    rng: np.random.Generator,
) -> dict[str, float]:
    """Classifier and APD metrics of one motion set against a reference real set."""
    out: dict[str, float] = {}
    if classifier is not None:
        feats, pred = _classify(classifier, windows, mask, names)
        out["accuracy"] = recognition_accuracy(pred, labels)
        for a in np.unique(labels):
            of_a = labels == a
            out[f"accuracy{PER_ACTION}{names[int(a)]}"] = recognition_accuracy(pred[of_a], labels[of_a])
        out["fid"] = fid(feats, reference["features"])
        out["kid"] = kid(feats, reference["features"])
        out["precision"], out["recall"] = precision_recall(reference["features"], feats)
        out["diversity"] = diversity(feats, rng)
        out["multimodality"] = multimodality(feats, labels, rng)
        out["action_kl"] = action_kl(reference["labels"], pred, len(names))
        shares = action_shares(pred, len(names))
        out.update({f"predicted_share{PER_ACTION}{n}": float(v) for n, v in zip(names, shares, strict=True)})
    groups = _by_action(windows, labels)
    out["apd"] = float(np.mean([apd(g) for g in groups.values()]))
    out["n_apd"] = n_apd(groups, reference["groups"])
    return out


def _clips(
    windows: np.ndarray, mask: np.ndarray | None, heights: np.ndarray | None = None
) -> list[np.ndarray]:
    """The (T, J, 3) clips of canonical windows without their padded frames, lifted to their root heights
    (floor y = 0) when ``heights`` are given."""
    lifted = np.array(windows, dtype=np.float32, copy=True)
    if heights is not None:
        lifted[..., 1] += np.asarray(heights, np.float32)[:, None, None]
    lengths = np.full(len(lifted), lifted.shape[1]) if mask is None else np.asarray(mask, bool).sum(axis=1)
    return [w[: max(int(n), 1)] for w, n in zip(lifted, lengths, strict=True)]


def _physics(
    windows: np.ndarray,
    mask: np.ndarray | None,
    labels: np.ndarray,
    heights: np.ndarray,
    prepared: PreparedClips,
    joint_range: JointRange,
) -> dict[str, float]:
    """Physical metrics of canonical windows lifted to their root heights (floor y = 0), with the share
    of joint rotations outside ``joint_range``, over the whole set and per action (``metric@action``);
    padded frames are left out."""
    clips = _clips(windows, mask, heights)
    outside = joint_range.outside(clips, prepared.skeleton)
    out = physics_metrics(clips, prepared.skeleton, prepared.fps) | {
        "joint_range_excess": float(outside.mean())
    }
    for a in np.unique(labels):
        of_a = np.asarray(labels) == a
        subset = [c for c, keep in zip(clips, of_a, strict=True) if keep]
        row = physics_metrics(subset, prepared.skeleton, prepared.fps)
        row["joint_range_excess"] = float(outside[of_a].mean())
        out.update({f"{k}{PER_ACTION}{prepared.action_names[int(a)]}": v for k, v in row.items()})
    return out


def _encode(loaded: LoadedModel, batch: WindowBatch) -> torch.Tensor:
    """(B, D) code means of a batch of real windows."""
    with torch.inference_mode():
        lmp = torch.from_numpy(np.ascontiguousarray(batch.lmp, np.float32))
        codes, _ = loaded.model.encode(lmp, torch.from_numpy(np.asarray(batch.mask, bool)))
    return codes


def reconstruct(loaded: LoadedModel, batch: WindowBatch) -> np.ndarray:
    """Joints (B, T, J, 3) of encode → decode (true action and end location), in the batch's frame."""
    codes = _encode(loaded, batch)
    ends = torch.from_numpy(np.ascontiguousarray(batch.ends, np.float32))
    recon = decode_tensors(loaded, codes, torch.from_numpy(np.asarray(batch.actions, np.int64)), ends)[0]
    return recon - display_lift(loaded)


def reconstruction_metrics(
    recon: np.ndarray,
    batch: WindowBatch,
    classifier: Classifier | None,
    names: list[str],
    skeleton: Skeleton,
) -> dict[str, float]:
    """MPJPE (metres) of reconstructions of a batch's real windows over its real frames, and with a
    classifier the share of them recognised as their true action (a decoder that loses an action's
    movement shows here, whatever the sampling does). The classifier reads each reconstruction in its
    own canonical frame (``canonicalize``), as it reads generated motions."""
    out = {"reconstruction_error_m": mpjpe(recon, batch.joints, batch.mask)}
    if classifier is not None:
        own = np.stack([canonicalize(j, skeleton)[0] for j in np.asarray(recon, np.float32)])
        pred = _classify(classifier, own.astype(np.float32), batch.mask, names)[1]
        out["reconstruction_accuracy"] = recognition_accuracy(pred, np.asarray(batch.actions))
    return out


def held_out(loaded: LoadedModel, sources: Sequence[str]) -> np.ndarray:
    """Indices of clips the model did not train on (bank entries marked ``split: train`` are excluded)."""
    trained: set[str] = set()
    if loaded.bank is not None:
        trained = {
            s for s, m in zip(loaded.bank.sources, loaded.bank.meta, strict=True) if m.get("split") == "train"
        }
    return np.array([i for i, s in enumerate(sources) if s not in trained], dtype=np.int64)


def _model_metrics(
    loaded: LoadedModel,
    batch: WindowBatch,
    styles: np.ndarray | None,
    classifier: Classifier | None,
    strategy: str,
    n_codes: int,
    rng: np.random.Generator,
) -> dict[str, float]:
    """Mode homogeneity, style purity and trajectory control on one crop of every real clip."""
    joints, labels = np.asarray(batch.joints, np.float32), np.asarray(batch.actions)
    codes_np = _encode(loaded, batch).numpy()
    bank = loaded.bank
    out: dict[str, float] = {}
    if bank is None:
        return out
    groups = _by_action(joints, labels)
    modes = {a: bank.modes[a].predict(codes_np[labels == a]) for a in groups if a in bank.modes}
    if modes:
        out["mode_homogeneity"] = mode_homogeneity({a: groups[a] for a in modes}, modes)
        if styles is not None:
            out["style_nmi"], out["style_ari"] = mode_purity(modes, {a: styles[labels == a] for a in modes})
    out.update(_control_metrics(loaded, groups, classifier, strategy, n_codes, rng))
    return out


def _control_metrics(
    loaded: LoadedModel,
    real: dict[int, np.ndarray],
    classifier: Classifier | None,
    strategy: str,
    n_codes: int,
    rng: np.random.Generator,
) -> dict[str, float]:
    """End-point error (m, % of the action's mean root travel) and accuracy for targets inside/outside."""
    bank, root = loaded.bank, loaded.skeleton.root
    if bank is None or not loaded.config.use_end_location:
        return {}
    err: dict[str, list[float]] = {"in": [], "out": []}
    pct: dict[str, list[float]] = {"in": [], "out": []}
    hits: dict[str, list[np.ndarray]] = {"in": [], "out": []}
    for a, windows in real.items():
        ends = bank.ends[bank.indices_of(a)]
        if a not in bank.modes or len(ends) < 2:
            continue
        codes, _ = bank.modes[a].sample(n_codes, rng, strategy=strategy)
        z = torch.from_numpy(np.repeat(np.asarray(codes, np.float32), CONTROL_POINTS, axis=0))
        travel = float(root_travel(windows[:, :, root]).mean())
        for key, targets in zip(
            ("in", "out"), control_targets(ends, n_codes, rng, CONTROL_POINTS), strict=True
        ):
            flat = targets.reshape(-1, 3).astype(np.float32)
            joints = decode_tensors(loaded, z, torch.full((len(z),), a), torch.from_numpy(flat))[0]
            joints = joints - display_lift(loaded)
            e = end_point_errors(joints[:, :, root], flat)
            err[key].append(float(e.mean()))
            pct[key].append(100.0 * float(e.mean()) / max(travel, 1e-6))
            if classifier is not None:
                windows_c = canonical_windows(
                    [Motion(j, loaded.fps, loaded.skeleton) for j in joints], classifier.config.window
                )
                hits[key].append(_classify(classifier, windows_c, None, list(loaded.action_names))[1] == a)
    if not err["in"]:
        return {}
    out = {}
    for key, suffix in (("in", ""), ("out", "_out")):
        out[f"end_error{suffix}_m"] = float(np.mean(err[key]))
        out[f"end_error{suffix}_pct"] = float(np.mean(pct[key]))
        if hits[key]:
            out[f"control_accuracy{suffix}"] = float(np.concatenate(hits[key]).mean())
    return out


def evaluate(
    loaded: LoadedModel,
    real_clips: Sequence[Motion],
    classifier: Classifier | None,
    *,
    repeats: int = 10,
    n_per_action: int = 50,
    seed: int = 0,
    strategy: str = "mode_preserving",
    progress: Callable[[str, float], None] | None = None,
    cancel: Callable[[], bool] | None = None,
) -> dict[str, Any]:
    """``{"real": {METRIC: {"mean", "ci95"}}, "generated": {...}, "meta": {...}}`` over ``repeats`` sets.

    Each repeat draws ``n_per_action`` real windows per action twice (sets A and B), generates
    ``n_per_action`` motions per action, and crops one window of every real clip for the model metrics.
    Real: accuracy/diversity/multimodality/APD of A, FID and n-APD of A against B. Generated: the same
    against A, plus mode homogeneity and style purity of the real clips grouped by the model's modes,
    reconstruction error (on the clips the model did not train on, when its bank says which), and trajectory
    control (``n_per_action // 10`` codes × 10 end points per action).
    Without a classifier the classifier metrics (accuracy, FID, diversity, multimodality) are left out.
    """
    if strategy not in EVAL_STRATEGIES:
        raise ConfigError(
            f"unknown strategy {strategy!r} for evaluation; choose from {', '.join(EVAL_STRATEGIES)}"
        )
    if repeats < 1 or n_per_action < 2:
        raise ConfigError(f"need repeats >= 1 and n_per_action >= 2, got {repeats}, {n_per_action}")
    check_compatible(loaded, real_clips, classifier)
    names = list(loaded.action_names)
    prepared = prepare_clips(real_clips, names, loaded.fps, loaded.window)
    actions = np.unique(prepared.actions)
    have_style = all("style" in c.meta for c in real_clips)
    styles = np.array([str(c.meta["style"]) for c in real_clips]) if have_style else None
    held = held_out(loaded, prepared.sources)
    if len(held) == 0:
        log.warning("every real clip is a training clip of the model; reconstruction is on training clips")
    recon_idx = held if len(held) else np.arange(len(real_clips))
    every_idx = np.arange(len(real_clips))
    n_codes = max(1, n_per_action // CONTROL_POINTS)

    def generate(wanted: np.ndarray, n: int, rng: np.random.Generator) -> tuple[np.ndarray, np.ndarray]:
        return _generate(loaded, wanted, n, strategy, rng)

    def model_metrics(rng: np.random.Generator) -> dict[str, float]:
        recon_batch = crop_windows(prepared, recon_idx, rng)
        recon = reconstruct(loaded, recon_batch)
        out = reconstruction_metrics(recon, recon_batch, classifier, names, loaded.skeleton)
        every = crop_windows(prepared, every_idx, rng)
        out.update(_model_metrics(loaded, every, styles, classifier, strategy, n_codes, rng))
        return out

    real_runs, gen_runs = evaluate_sets(
        prepared,
        classifier,
        generate,
        names=names,
        repeats=repeats,
        n_per_action=n_per_action,
        seed=seed,
        extra=model_metrics,
        progress=progress,
        cancel=cancel,
    )
    meta = {
        "model": str(loaded.path),
        "classifier": None if classifier is None else str(classifier.path),
        "classifier_test_accuracy": None if classifier is None else classifier.test_accuracy,
        "n_real_clips": len(real_clips),
        "n_reconstruction_clips": int(len(held) or len(real_clips)),
        "reconstruction_held_out": bool(len(held)),
        "actions": [names[a] for a in actions],
        "repeats": repeats,
        "n_per_action": n_per_action,
        "seed": seed,
        "strategy": strategy,
        "window": loaded.window,
        "fps": loaded.fps,
        "ci": "95% interval 1.96·s/√n over repeats",
    }
    return report(real_runs, gen_runs) | {"meta": meta}


def report(real_runs: list[dict[str, float]], gen_runs: list[dict[str, float]]) -> dict[str, Any]:
    """``{"real", "generated"}`` summaries of the set-wide metrics and ``{"per_action": {ACTION: {"real",
    "generated"}}}`` of the per-action ones (``metric@action`` keys of the rows)."""
    out: dict[str, Any] = {"per_action": {}}
    for side, runs in (("real", real_runs), ("generated", gen_runs)):
        plain = [{k: v for k, v in row.items() if PER_ACTION not in k} for row in runs]
        out[side] = summarize(plain)
        for metric, stats in summarize(runs).items():
            if PER_ACTION in metric:
                name, action = metric.split(PER_ACTION, 1)
                out["per_action"].setdefault(action, {"real": {}, "generated": {}})[side][name] = stats
    return out


def evaluate_sets(
    prepared: PreparedClips,
    classifier: Classifier | None,
    generate: GenerateFn,
    *,
    names: list[str],
    repeats: int,
    n_per_action: int,
    seed: int,
    extra: ExtraFn | None = None,
    progress: Callable[[str, float], None] | None = None,
    cancel: Callable[[], bool] | None = None,
) -> tuple[list[dict[str, float]], list[dict[str, float]]]:
    """Per-repeat metric rows ``(real, generated)`` of real set A against B and generated motions against A.

    Repeat r uses ``numpy.random.default_rng([seed, r])`` for, in this order: real sets A and B
    (``n_per_action`` windows per action each), A's set metrics, ``generate(actions, n_per_action, rng)``,
    the generated set's metrics, then ``extra(rng)``, whose metrics join the generated row. Both rows also
    get the physical metrics (``engine.metrics.physics``) when ``generate`` gives root heights, and the
    share of joint rotations outside the range of set B (``engine.metrics.joint_range``). Any model
    evaluated with the same clips, classifier and seed thus gets the same real row and the same set A.
    """
    labels = prepared.actions
    actions = np.unique(labels)
    real_runs, gen_runs = [], []
    for r in range(repeats):
        if cancel is not None and cancel():
            raise CancelledError("evaluation cancelled")
        rng = np.random.default_rng([seed, r])
        sets = [crop_windows(prepared, _pick(labels, actions, n_per_action, rng), rng) for _ in range(2)]
        ref = _reference(sets[1], classifier)
        real_runs.append(
            _set_metrics(sets[0].joints, sets[0].mask, sets[0].actions, ref, classifier, names, rng)
        )
        joint_range = JointRange.fit(_clips(sets[1].joints, sets[1].mask), prepared.skeleton)
        real_runs[-1].update(
            _physics(
                sets[0].joints, sets[0].mask, sets[0].actions, sets[0].origin[:, 1], prepared, joint_range
            )
        )
        ref = _reference(sets[0], classifier)
        gen, gen_labels, gen_heights = generate(actions, n_per_action, rng)
        gen_metrics = _set_metrics(gen, None, gen_labels, ref, classifier, names, rng)
        if gen_heights is not None:
            gen_metrics.update(_physics(gen, None, gen_labels, gen_heights, prepared, joint_range))
        if extra is not None:
            gen_metrics.update(extra(rng))
        gen_runs.append(gen_metrics)
        log.info("evaluation repeat %d/%d done", r + 1, repeats)
        if progress is not None:
            progress("evaluating", (r + 1) / repeats)
    return real_runs, gen_runs


def _reference(batch: WindowBatch, classifier: Classifier | None) -> dict[str, Any]:
    """What a set is compared with: the real set's classifier features and per-action windows."""
    joints, labels = np.asarray(batch.joints, np.float32), np.asarray(batch.actions)
    feats = None if classifier is None else classifier.classify(joints, batch.mask)[0]
    return {"features": feats, "groups": _by_action(joints, labels), "labels": labels}


def _generate(
    loaded: LoadedModel, actions: np.ndarray, n: int, strategy: str, rng: np.random.Generator
) -> tuple[np.ndarray, np.ndarray]:
    """Canonical windows (N, T, J, 3), labels (N,) and frame-0 root heights (N,) of ``n`` generated
    motions per action."""
    motions, labels = [], []
    for a in actions:
        motions.extend(s.motion for s in sample(loaded, int(a), n, rng, strategy=strategy))
        labels.extend([int(a)] * n)
    return canonical_windows(motions, loaded.window), np.array(labels), root_heights(motions)
