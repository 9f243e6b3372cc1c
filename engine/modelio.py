"""Model folder I/O: model.safetensors + model.json (versioned, strict) and the latent bank."""

from __future__ import annotations

import json
import logging
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np
import torch
from safetensors import SafetensorError
from safetensors.torch import load as load_safetensors
from safetensors.torch import save as save_safetensors

from engine.errors import ConfigError, ModelFormatError
from engine.fileio import atomic_write_bytes, atomic_write_text
from engine.model.config import OdmoConfig
from engine.model.odmo import OdmoModel
from engine.motion.skeleton import Skeleton

if TYPE_CHECKING:
    from engine.latent.bank import LatentBank

log = logging.getLogger(__name__)

FORMAT = "odmo-explorer-model"
FORMAT_VERSION = 1
WEIGHTS_FILE = "model.safetensors"
META_FILE = "model.json"
BANK_FILE = "latent_bank.npz"


@dataclass
class LoadedModel:
    """A model folder in memory: the network (eval mode) and everything needed to use it."""

    model: OdmoModel
    config: OdmoConfig
    skeleton: Skeleton
    action_names: list[str]
    fps: float
    window: int
    root_height: float
    provenance: dict[str, Any]
    bank: LatentBank | None
    path: Path


def resolve_device(device: str) -> torch.device:
    """``"auto"`` → CUDA when available, else CPU; any other torch device string as given."""
    if device == "auto":
        return torch.device("cuda" if torch.cuda.is_available() else "cpu")
    try:
        dev = torch.device(device)
    except (RuntimeError, TypeError) as exc:
        raise ConfigError(f"unknown device {device!r}") from exc
    if dev.type == "cuda" and not torch.cuda.is_available():
        raise ConfigError("device 'cuda' requested but CUDA is not available")
    return dev


def save_model(
    out_dir: str | Path,
    model: OdmoModel,
    config: OdmoConfig,
    skeleton: Skeleton,
    action_names: list[str],
    provenance: dict[str, Any],
    root_height: float,
) -> None:
    """Write ``model.safetensors`` and ``model.json`` into ``out_dir`` (each atomically)."""
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    if len(action_names) != config.n_actions or skeleton.n_joints != config.n_joints:
        raise ConfigError("action names / skeleton do not match the model config")
    tensors = {k: v.detach().to("cpu").contiguous() for k, v in model.state_dict().items()}
    atomic_write_bytes(out / WEIGHTS_FILE, save_safetensors(tensors, metadata={"format": FORMAT}))
    meta = {
        "format": FORMAT,
        "format_version": FORMAT_VERSION,
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


def read_meta(path: Path) -> dict[str, Any]:
    """Parsed ``model.json``, checked for format, version (none newer than this program) and keys."""
    try:
        meta = json.loads(path.read_text(encoding="utf-8"))
    except FileNotFoundError:
        raise ModelFormatError(f"{path}: missing (not a model folder?)") from None
    except (OSError, UnicodeDecodeError, json.JSONDecodeError) as exc:
        raise ModelFormatError(f"{path}: unreadable model description: {exc}") from exc
    if not isinstance(meta, dict) or meta.get("format") != FORMAT:
        raise ModelFormatError(f"{path}: not an ODMO Explorer model description")
    version = meta.get("format_version")
    if not isinstance(version, int) or version < 1:
        raise ModelFormatError(f"{path}: bad format_version {version!r}")
    if version > FORMAT_VERSION:
        raise ModelFormatError(
            f"{path}: format version {version} is newer than this program reads ({FORMAT_VERSION}); upgrade"
        )
    missing = [
        k for k in ("config", "skeleton", "action_names", "root_height", "provenance") if k not in meta
    ]
    if missing:
        raise ModelFormatError(f"{path}: missing keys: {', '.join(missing)}")
    return meta


def _read_weights(path: Path, model: OdmoModel) -> dict[str, torch.Tensor]:
    """Tensors of ``path``, checked name by name and shape by shape against ``model``."""
    try:
        tensors = load_safetensors(path.read_bytes())
    except FileNotFoundError:
        raise ModelFormatError(f"{path}: missing weights file") from None
    except (OSError, SafetensorError, ValueError, RuntimeError) as exc:
        raise ModelFormatError(f"{path}: corrupt weights: {exc}") from exc
    expected = model.state_dict()
    missing = sorted(set(expected) - set(tensors))
    extra = sorted(set(tensors) - set(expected))
    if missing or extra:
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


def load_model(model_dir: str | Path, device: str = "cpu", with_bank: bool = True) -> LoadedModel:
    """Read a model folder strictly: missing, corrupt, mis-shaped or newer files raise ModelFormatError."""
    folder = Path(model_dir)
    if not folder.is_dir():
        raise ModelFormatError(f"{folder}: not a model folder")
    meta_path = folder / META_FILE
    meta = read_meta(meta_path)
    config = OdmoConfig.from_dict(meta["config"])
    try:
        sk = meta["skeleton"]
        skeleton = Skeleton(tuple(sk["names"]), np.array(sk["parents"]), np.array(sk["offsets"], dtype=float))
    except (KeyError, TypeError, ValueError, ConfigError) as exc:
        raise ModelFormatError(f"{meta_path}: bad skeleton: {exc}") from exc
    names = [str(a) for a in meta["action_names"]]
    if len(names) != config.n_actions or skeleton.n_joints != config.n_joints:
        raise ModelFormatError(f"{meta_path}: action names or skeleton disagree with the config")
    model = OdmoModel(config)
    model.load_state_dict(_read_weights(folder / WEIGHTS_FILE, model))
    model.to(resolve_device(device)).eval()
    bank = None
    if with_bank:
        from engine.latent.bank import LatentBank

        bank_path = folder / BANK_FILE
        if bank_path.exists():
            bank = LatentBank.load(bank_path)
        else:
            log.warning("%s: no latent bank; sampling from modes is unavailable", bank_path)
    return LoadedModel(
        model=model,
        config=config,
        skeleton=skeleton,
        action_names=names,
        fps=float(config.fps),
        window=int(config.window),
        root_height=float(meta["root_height"]),
        provenance=dict(meta["provenance"]),
        bank=bank,
        path=folder,
    )
