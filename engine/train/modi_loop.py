"""Training of MoDi through the shared epoch loop, and its model folder: the EMA generator, its foot
heights and a latent bank of sampled and inverted W codes."""

from __future__ import annotations

import dataclasses
import logging
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from engine.generators.modi import save_modi
from engine.generators.modi_latent import INVERT_STEPS, decode_codes, invert, sample_w
from engine.latent.bank import LatentBank, build_bank
from engine.model.modi import ModiConfig, ModiNetwork
from engine.modelio import save_bank
from engine.motion.contact import foot_joints, resting_heights
from engine.motion.motion import Motion
from engine.motion.skeleton import Skeleton
from engine.train.epochs import (
    TrainProgress,
    TrainResult,
    root_height,
    split_metas,
)
from engine.train.kind_run import KindRun, RunOptions
from engine.train.modi_steps import ClipFeatures, ModiSteps
from engine.train.windows import PreparedClips, crop_windows

if TYPE_CHECKING:
    from engine.metrics.classifier import Classifier

log = logging.getLogger(__name__)

#: Sampled codes in a bank, beside one inverted code per clip.
BANK_SAMPLES = 2000
#: Clips inverted at once while building a bank.
INVERT_BATCH = 128


def label_samples(
    network: ModiNetwork,
    skeleton: Skeleton,
    codes: np.ndarray,
    classifier: Classifier | None,
    inverted: np.ndarray,
    inverted_labels: np.ndarray,
) -> np.ndarray:
    """(N,) action label of sampled W codes: the classifier's prediction on their motions' centre windows,
    or without a classifier the majority label of their 5 nearest inverted clips in W."""
    if classifier is None:
        from sklearn.neighbors import KNeighborsClassifier

        knn = KNeighborsClassifier(n_neighbors=min(5, len(inverted))).fit(inverted, inverted_labels)
        return knn.predict(codes).astype(np.int64)
    from engine.metrics.unconditional import classify_joints

    joints, _ = decode_codes(network, codes)
    _, predicted = classify_joints(classifier, joints, skeleton)
    return predicted.astype(np.int64)


def inverted_clips(labels: np.ndarray, per_label: int | None, seed: int) -> np.ndarray:
    """Indices of the clips a bank inverts: all, or up to ``per_label`` of each label drawn with ``seed``."""
    if per_label is None:
        return np.arange(len(labels))
    rng = np.random.default_rng(seed)
    picks = [rng.permutation(np.flatnonzero(labels == a))[:per_label] for a in np.unique(labels)]
    return np.sort(np.concatenate(picks))


def invert_clips(
    network: ModiNetwork,
    prepared: PreparedClips,
    indices: np.ndarray,
    steps: int = INVERT_STEPS,
    space: str = "W",
    cancel: Callable[[], bool] | None = None,
) -> tuple[np.ndarray, np.ndarray]:
    """Codes and mean joint errors (m) of the canonical centre windows of clips ``indices``."""
    codes, errors = [], []
    for lo in range(0, len(indices), INVERT_BATCH):
        batch = crop_windows(prepared, indices[lo : lo + INVERT_BATCH], None)
        found = invert(network, batch.joints, batch.mask, space, steps, cancel=cancel)
        codes.append(found.codes)
        errors.append(found.errors)
    return np.concatenate(codes), np.concatenate(errors)


def modi_bank(
    network: ModiNetwork,
    prepared: PreparedClips,
    val_idx: np.ndarray,
    *,
    classifier: Classifier | None = None,
    n_samples: int = BANK_SAMPLES,
    per_label: int | None = None,
    steps: int = INVERT_STEPS,
    projections: Sequence[str] = ("pca", "tsne", "umap"),
    k_range: tuple[int, int] = (3, 11),
    seed: int = 0,
    cancel: Callable[[], bool] | None = None,
) -> LatentBank:
    """A bank of clips' W inversions (their own label and metadata, their inversion error; every clip,
    or ``per_label`` clips of each label drawn with ``seed``) and ``n_samples`` codes of the prior
    (labelled by ``label_samples``), with modes per label (diagonal Gaussians: a full covariance of W
    would be 0.5 MB a mode) and maps."""
    chosen = inverted_clips(prepared.actions, per_label, seed)
    inverted, errors = invert_clips(network, prepared, chosen, steps, cancel=cancel)
    real_labels = prepared.actions[chosen]
    sampled = sample_w(network, n_samples, seed) if n_samples else np.zeros((0, inverted.shape[1]))
    labels = (
        label_samples(network, prepared.skeleton, sampled, classifier, inverted, real_labels)
        if n_samples
        else []
    )
    clip_metas = split_metas(prepared, val_idx)
    metas = [
        clip_metas[i] | {"origin": "inverted", "inversion_error_m": round(float(e), 4)}
        for i, e in zip(chosen, errors, strict=True)
    ]
    metas += [{"origin": "sample", "seed": seed, "index": i} for i in range(n_samples)]
    return build_bank(
        np.concatenate([inverted, sampled]).astype(np.float32),
        np.concatenate([real_labels, np.asarray(labels, np.int64)]),
        np.zeros((len(chosen) + n_samples, 3), np.float32),
        [*(prepared.sources[i] for i in chosen), *(f"sample {seed}:{i}" for i in range(n_samples))],
        metas,
        prepared.action_names,
        k_range=k_range,
        projections=tuple(projections),
        seed=seed,
        covariance="diag",
    )


def shipped_network(steps: ModiSteps, prepared: PreparedClips) -> ModiNetwork:
    """The EMA generator with the training data's resting foot heights in its config (foot clean-up)."""
    network = steps.g_ema
    heights = resting_heights(prepared.joints, foot_joints(prepared.skeleton))
    network.config = dataclasses.replace(network.config, foot_heights=tuple(float(h) for h in heights))
    return network


def train_modi(
    clips: Sequence[Motion],
    action_names: list[str],
    out_dir: Path,
    config: ModiConfig,
    *,
    seed: int = 0,
    device: str = "auto",
    resume: bool = False,
    val_fraction: float = 0.1,
    progress: Callable[[TrainProgress], None] | None = None,
    cancel: Callable[[], bool] | None = None,
    checkpoint_every: int = 1,
    clip_features: ClipFeatures | None = None,
    classifier: Classifier | None = None,
    bank_samples: int = BANK_SAMPLES,
    bank_per_label: int | None = None,
    bank_steps: int = INVERT_STEPS,
    bank_projections: Sequence[str] = ("pca", "tsne", "umap"),
    bank_k_range: tuple[int, int] = (3, 11),
) -> TrainResult:
    """Train MoDi on ``clips`` and write its model folder ``out_dir`` (weights, model.json, train_log.csv,
    checkpoints/last.pt, latent_bank.npz); the split, budget, ``resume`` and ``cancel`` as in
    ``engine.train.loop.train``. ``clip_features`` skips the inverse kinematics when already computed;
    the bank holds ``bank_samples`` prior codes and the clips (all, or ``bank_per_label`` per label)
    inverted in W by ``bank_steps`` steps."""
    out = Path(out_dir)
    options = RunOptions(seed, device, resume, val_fraction, progress, cancel, checkpoint_every)
    data = KindRun.prepare(clips, action_names, config, options)
    prepared, (train_idx, val_idx) = data.prepared, data.split
    steps = ModiSteps(
        config, prepared, train_idx, val_idx, seed=seed, device=data.device, clips=clip_features
    )
    run = data.train(steps, out, config)
    network = shipped_network(steps, prepared)
    made = data.provenance(run, config, steps=int(steps.counter.steps))
    save_modi(out, network, prepared.skeleton, prepared.action_names, made, root_height(prepared))
    bank = modi_bank(
        network,
        prepared,
        val_idx,
        classifier=classifier,
        n_samples=bank_samples,
        per_label=bank_per_label,
        steps=bank_steps,
        projections=bank_projections,
        k_range=bank_k_range,
        seed=seed,
        cancel=cancel,
    )
    save_bank(out, bank)
    return data.result(out, config, run, bank)
