"""Training of DVGAN through the shared epoch loop, and its model folder: the generator on the data's
typical skeleton, its foot heights and a latent bank of its top-level noise codes."""

from __future__ import annotations

import dataclasses
from collections.abc import Callable, Sequence
from pathlib import Path

import numpy as np
import torch

from engine.latent.bank import LatentBank, build_bank
from engine.model.dvgan import DvganConfig, DvganNetwork, phrase_words
from engine.model.dvgan_features import n_features
from engine.modelio import save_bank, write_model_folder
from engine.motion.motion import Motion
from engine.train.dvgan_steps import ClipFeatures, DvganSteps, clip_features
from engine.train.epochs import (
    TrainProgress,
    TrainResult,
    root_height,
)
from engine.train.kind_run import KindRun, RunOptions, WarmStart

ARCH = "dvgan"
#: Top-level codes per action in a bank.
BANK_PER_ACTION = 200


def data_config(config: DvganConfig, action_names: Sequence[str], features: ClipFeatures) -> DvganConfig:
    """``config`` with what the data decides: feature count, vocabulary and resting foot heights."""
    words = tuple(sorted({w for a in action_names for w in phrase_words(a)}))
    return dataclasses.replace(
        config,
        n_features=n_features(features.skeleton),
        words=words,
        foot_heights=tuple(float(h) for h in features.foot_heights),
    )


def dvgan_bank(
    generator: DvganNetwork,
    action_names: Sequence[str],
    *,
    per_action: int = BANK_PER_ACTION,
    projections: Sequence[str] = ("pca", "tsne", "umap"),
    k_range: tuple[int, int] = (3, 11),
    seed: int = 0,
) -> LatentBank:
    """A bank of ``per_action`` top-level codes z_0 ~ N(0, I) per action (drawn from ``seed``), with the
    modes and maps of ``build_bank``: a sample's finer noise is fixed by its seed, so a code is a motion."""
    rng = np.random.default_rng(seed)
    dim = generator.config.noise_dim
    codes = rng.standard_normal((per_action * len(action_names), dim)).astype(np.float32)
    actions = np.repeat(np.arange(len(action_names)), per_action)
    metas = [{"origin": "sample", "seed": seed, "index": i} for i in range(len(codes))]
    return build_bank(
        codes,
        actions,
        np.zeros((len(codes), 3), np.float32),
        [f"sample {seed}:{i}" for i in range(len(codes))],
        metas,
        list(action_names),
        k_range=k_range,
        projections=tuple(projections),
        seed=seed,
    )


def train_dvgan(
    clips: Sequence[Motion],
    action_names: list[str],
    out_dir: Path,
    config: DvganConfig,
    *,
    seed: int = 0,
    device: str = "auto",
    resume: bool = False,
    val_fraction: float = 0.1,
    progress: Callable[[TrainProgress], None] | None = None,
    cancel: Callable[[], bool] | None = None,
    checkpoint_every: int = 1,
    bank_per_action: int = BANK_PER_ACTION,
    bank_projections: Sequence[str] = ("pca", "tsne", "umap"),
    bank_k_range: tuple[int, int] = (3, 11),
    warm_start: WarmStart | None = None,
) -> TrainResult:
    """Train DVGAN on ``clips`` and write its model folder ``out_dir`` (weights, model.json on the data's
    typical skeleton, train_log.csv, checkpoints/last.pt, latent_bank.npz); the split, budget, ``resume``
    and ``cancel`` as in ``engine.train.loop.train``. With ``warm_start`` the generator starts from those
    weights (a checkpoint to resume from still wins) and the provenance names them."""
    out = Path(out_dir)
    options = RunOptions(seed, device, resume, val_fraction, progress, cancel, checkpoint_every)
    data = KindRun.prepare(clips, action_names, config, options)
    prepared = data.prepared
    features = clip_features(prepared)
    config = data_config(config, prepared.action_names, features)
    train_idx, val_idx = data.split
    steps = DvganSteps(
        config, prepared, train_idx, val_idx, features, seed=seed, device=data.device, warm_start=warm_start
    )
    run = data.train(steps, out, config)
    made = data.provenance(run, config, warm_start, steps=int(steps.counter.steps))
    generator = steps.g.eval()
    write_model_folder(
        out, generator, config.to_dict(), features.skeleton, prepared.action_names, made,
        root_height(prepared), ARCH,
    )  # fmt: skip
    with torch.random.fork_rng(devices=[]):
        bank = dvgan_bank(
            generator, prepared.action_names, per_action=bank_per_action, projections=bank_projections,
            k_range=bank_k_range, seed=seed,
        )  # fmt: skip
    save_bank(out, bank)
    return data.result(out, config, run, bank)
