"""Action2Motion baseline folders (model.safetensors + model.json with ``"arch": "a2m"``) and generation."""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import torch

from engine.errors import ConfigError, ModelFormatError
from engine.model.a2m import A2mConfig, A2mModel
from engine.modelio import (
    META_FILE,
    WEIGHTS_FILE,
    read_meta,
    read_weights,
    resolve_device,
    write_model_folder,
)
from engine.motion.skeleton import Skeleton

ARCH = "a2m"


@dataclass
class LoadedA2m:
    """An A2M model folder in memory: the network (eval mode) and what is needed to use it."""

    model: A2mModel
    config: A2mConfig
    skeleton: Skeleton
    action_names: list[str]
    fps: float
    window: int
    root_height: float
    provenance: dict[str, Any]
    path: Path


def save_a2m(
    out_dir: str | Path,
    model: A2mModel,
    skeleton: Skeleton,
    action_names: list[str],
    provenance: dict[str, Any],
    root_height: float,
) -> None:
    """Write ``model.safetensors`` and ``model.json`` (``"arch": "a2m"``) into ``out_dir`` atomically."""
    config = model.config
    if len(action_names) != config.n_actions or skeleton.n_joints != config.n_joints:
        raise ConfigError("action names / skeleton do not match the model config")
    write_model_folder(
        out_dir, model, config.to_dict(), skeleton, action_names, provenance, root_height, ARCH
    )


def _read_meta(path: Path) -> dict[str, Any]:
    """Parsed ``model.json`` of an A2M folder: ``modelio.read_meta``'s checks, then the architecture."""
    meta = read_meta(path)
    if meta.get("arch") != ARCH:
        raise ModelFormatError(f"{path}: architecture {meta.get('arch', 'odmo')!r} is not {ARCH!r}")
    return meta


def load_a2m(model_dir: str | Path, device: str = "cpu") -> LoadedA2m:
    """Read an A2M folder strictly: bad, newer or non-A2M files raise ModelFormatError."""
    folder = Path(model_dir)
    if not folder.is_dir():
        raise ModelFormatError(f"{folder}: not a model folder")
    meta_path = folder / META_FILE
    meta = _read_meta(meta_path)
    try:
        config = A2mConfig.from_dict(meta["config"])
    except ModelFormatError as exc:
        raise ModelFormatError(f"{meta_path}: {exc}") from None
    try:
        sk = meta["skeleton"]
        skeleton = Skeleton(tuple(sk["names"]), np.array(sk["parents"]), np.array(sk["offsets"], dtype=float))
        names = [str(a) for a in meta["action_names"]]
        root_height = float(meta["root_height"])
    except (KeyError, TypeError, ValueError, ConfigError) as exc:
        raise ModelFormatError(f"{meta_path}: bad skeleton or action names: {exc}") from exc
    if len(names) != config.n_actions or skeleton.n_joints != config.n_joints:
        raise ModelFormatError(f"{meta_path}: action names or skeleton disagree with the config")
    model = A2mModel(config)
    model.load_state_dict(read_weights(folder / WEIGHTS_FILE, model, meta))
    model.to(resolve_device(device)).eval()
    return LoadedA2m(
        model=model,
        config=config,
        skeleton=skeleton,
        action_names=names,
        fps=float(config.fps),
        window=int(config.window),
        root_height=root_height,
        provenance=dict(meta["provenance"]),
        path=folder,
    )


def generate_a2m(
    loaded: LoadedA2m, action: int | str, n: int, generator: torch.Generator | int
) -> np.ndarray:
    """(n, T, J, 3) float32 motions of ``action`` (index or name) sampled from the learned prior.

    ``generator`` is a torch.Generator on the model's device or a seed; the same seed gives the same motions.
    """
    if n < 1:
        raise ConfigError(f"n must be at least 1, got {n}")
    if isinstance(action, str):
        if action not in loaded.action_names:
            raise ConfigError(f"unknown action {action!r}; the model knows {', '.join(loaded.action_names)}")
        action = loaded.action_names.index(action)
    if not 0 <= int(action) < loaded.config.n_actions:
        raise ConfigError(f"action index {action} out of range 0..{loaded.config.n_actions - 1}")
    device = next(loaded.model.parameters()).device
    if isinstance(generator, int):
        generator = torch.Generator(device).manual_seed(generator)
    with torch.inference_mode():
        joints = loaded.model.sample(
            torch.full((n,), int(action), dtype=torch.long, device=device), generator
        )
    return joints.cpu().numpy().astype(np.float32)
