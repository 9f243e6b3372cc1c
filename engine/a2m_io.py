"""Action2Motion baseline folders (model.safetensors + model.json with ``"arch": "a2m"``) and generation."""

from __future__ import annotations

import json
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import torch
from safetensors import SafetensorError
from safetensors.torch import load as load_safetensors
from safetensors.torch import save as save_safetensors

from engine.errors import ConfigError, ModelFormatError
from engine.fileio import atomic_write_bytes, atomic_write_text
from engine.model.a2m import A2mConfig, A2mModel
from engine.modelio import FORMAT, FORMAT_VERSION, META_FILE, WEIGHTS_FILE, read_meta, resolve_device
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
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    tensors = {k: v.detach().to("cpu").contiguous() for k, v in model.state_dict().items()}
    atomic_write_bytes(
        out / WEIGHTS_FILE, save_safetensors(tensors, metadata={"format": FORMAT, "arch": ARCH})
    )
    meta = {
        "format": FORMAT,
        "format_version": FORMAT_VERSION,
        "arch": ARCH,
        "config": config.to_dict(),
        "skeleton": {
            "names": list(skeleton.names),
            "parents": [int(p) for p in skeleton.parents],
            "offsets": [[float(v) for v in row] for row in skeleton.offsets],
        },
        "fps": float(config.fps),
        "window": int(config.window),
        "action_names": list(action_names),
        "root_height": float(root_height),
        "provenance": provenance,
    }
    atomic_write_text(out / META_FILE, json.dumps(meta, indent=2) + "\n")


def _read_meta(path: Path) -> dict[str, Any]:
    """Parsed ``model.json`` of an A2M folder: ``modelio.read_meta``'s checks, then the architecture."""
    meta = read_meta(path)
    if meta.get("arch") != ARCH:
        raise ModelFormatError(f"{path}: architecture {meta.get('arch', 'odmo')!r} is not {ARCH!r}")
    return meta


def _read_weights(path: Path, model: A2mModel) -> dict[str, torch.Tensor]:
    """Tensors of ``path``, checked name by name, shape and dtype against ``model``."""
    try:
        tensors = load_safetensors(path.read_bytes())
    except FileNotFoundError:
        raise ModelFormatError(f"{path}: missing weights file") from None
    except (OSError, SafetensorError, ValueError, RuntimeError) as exc:
        raise ModelFormatError(f"{path}: corrupt weights: {exc}") from exc
    expected = model.state_dict()
    if set(tensors) != set(expected):
        missing, extra = sorted(set(expected) - set(tensors)), sorted(set(tensors) - set(expected))
        raise ModelFormatError(
            f"{path}: weights do not match the config (missing {missing}, unexpected {extra})"
        )
    for name, ref in expected.items():
        if tensors[name].shape != ref.shape or tensors[name].dtype != ref.dtype:
            raise ModelFormatError(
                f"{path}: tensor {name} is {tuple(tensors[name].shape)} {tensors[name].dtype}, "
                f"expected {tuple(ref.shape)} {ref.dtype}"
            )
    return tensors


def load_a2m(model_dir: str | Path, device: str = "cpu") -> LoadedA2m:
    """Read an A2M folder strictly: bad, newer or non-A2M files raise ModelFormatError."""
    folder = Path(model_dir)
    if not folder.is_dir():
        raise ModelFormatError(f"{folder}: not a model folder")
    meta_path = folder / META_FILE
    meta = _read_meta(meta_path)
    config = A2mConfig.from_dict(meta["config"])
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
    model.load_state_dict(_read_weights(folder / WEIGHTS_FILE, model))
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
