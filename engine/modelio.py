"""Model folder I/O: model.safetensors + model.json (versioned, strict) and the latent bank."""

from __future__ import annotations

import hashlib
import json
import logging
from collections.abc import Callable
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
from engine.limits import read_bytes
from engine.model.config import OdmoConfig
from engine.model.config_base import ModelConfig
from engine.model.odmo import OdmoModel
from engine.motion.skeleton import Skeleton

if TYPE_CHECKING:
    from engine.latent.bank import LatentBank

log = logging.getLogger(__name__)

FORMAT = "odmo-explorer-model"
#: 2 added the content checksums ``weights_sha256`` and ``bank_sha256``; version-1 folders load unverified.
FORMAT_VERSION = 2
WEIGHTS_FILE = "model.safetensors"
META_FILE = "model.json"
BANK_FILE = "latent_bank.npz"
_REQUIRED_KEYS = ("config", "skeleton", "action_names", "root_height", "provenance")
_KNOWN_KEYS = {
    "format", "format_version", "arch", "fps", "window", "weights_sha256", "bank_sha256", *_REQUIRED_KEYS
}  # fmt: skip


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


@dataclass
class LoadedFolder:
    """A model folder of any kind in memory: its network (eval mode), config, skeleton, actions, frame
    rate, window, display height, provenance, path and latent bank; each kind narrows the types."""

    model: torch.nn.Module
    config: Any
    skeleton: Skeleton
    action_names: list[str]
    fps: float
    window: int
    root_height: float
    provenance: dict[str, Any]
    path: Path
    bank: LatentBank | None = None


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
    """Write ``model.safetensors`` and ``model.json`` into ``out_dir`` (see :func:`write_model_folder`)."""
    write_model_folder(out_dir, model, config.to_dict(), skeleton, action_names, provenance, root_height)


def write_model_folder(
    out_dir: str | Path,
    model: torch.nn.Module,
    config: dict[str, Any],
    skeleton: Skeleton,
    action_names: list[str],
    provenance: dict[str, Any],
    root_height: float,
    arch: str | None = None,
) -> None:
    """Write the weights, then ``model.json`` holding their checksum, each atomically.

    A latent bank of earlier weights is removed: it no longer describes the model. A writer killed
    between the two files leaves a folder whose weights fail the checksum, never a silently mixed one.
    """
    if len(action_names) != config["n_actions"] or skeleton.n_joints != config["n_joints"]:
        raise ConfigError("action names / skeleton do not match the model config")
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    tensors = {k: v.detach().to("cpu").contiguous() for k, v in model.state_dict().items()}
    extra = {} if arch is None else {"arch": arch}
    weights = save_safetensors(tensors, metadata={"format": FORMAT, **extra})
    atomic_write_bytes(out / WEIGHTS_FILE, weights)
    meta = {
        "format": FORMAT,
        "format_version": FORMAT_VERSION,
        **extra,
        "config": config,
        "skeleton": {
            "names": list(skeleton.names),
            "parents": [int(p) for p in skeleton.parents],
            "offsets": [[float(v) for v in row] for row in skeleton.offsets],
        },
        "fps": float(config["fps"]),
        "window": int(config["window"]),
        "action_names": list(action_names),
        "root_height": float(root_height),
        "provenance": provenance,
        "weights_sha256": _sha256(weights),
    }
    atomic_write_text(out / META_FILE, json.dumps(meta, indent=2) + "\n")
    (out / BANK_FILE).unlink(missing_ok=True)


def save_bank(model_dir: str | Path, bank: LatentBank) -> Path:
    """Write ``bank`` into a model folder, tied to its weights; ``model.json`` records its checksum."""
    folder = Path(model_dir)
    meta_path = folder / META_FILE
    meta = read_meta(meta_path)
    weights_sha = meta.get("weights_sha256")
    if weights_sha is None:  # a version-1 folder: record the weights' checksum now
        weights_sha = _sha256(_read_bytes(folder / WEIGHTS_FILE, "weights"))
    data = bank.to_bytes(weights_sha256=weights_sha)
    atomic_write_bytes(folder / BANK_FILE, data)
    meta |= {"format_version": FORMAT_VERSION, "weights_sha256": weights_sha, "bank_sha256": _sha256(data)}
    atomic_write_text(meta_path, json.dumps(meta, indent=2) + "\n")
    return folder / BANK_FILE


def _sha256(data: bytes) -> str:
    return hashlib.sha256(data).hexdigest()


def _read_bytes(path: Path, what: str) -> bytes:
    """The bytes of a model-folder file, refused over the file-size limit."""
    try:
        return read_bytes(path, what)
    except FileNotFoundError:
        raise ModelFormatError(f"{path}: missing {what} file") from None
    except OSError as exc:
        raise ModelFormatError(f"{path}: unreadable {what}: {exc}") from exc


def check_checksum(path: Path, data: bytes, meta: dict[str, Any], key: str) -> None:
    """ModelFormatError unless ``data`` has the checksum ``meta[key]`` (version-1 folders have none)."""
    expected = meta.get(key)
    if expected is None and meta["format_version"] < 2:
        log.warning("%s: a version-1 model folder has no checksums; its files are not verified", path)
        return
    if not isinstance(expected, str) or _sha256(data) != expected:
        raise ModelFormatError(
            f"{path}: content does not match the checksum in {META_FILE} (damaged, or a write was "
            "interrupted); restore the folder or train it again"
        )


def read_meta(path: Path) -> dict[str, Any]:
    """Parsed ``model.json``, checked for format, version (none newer than this program) and keys."""
    try:
        meta = json.loads(read_bytes(path, "model description").decode("utf-8"))
    except FileNotFoundError:
        raise ModelFormatError(f"{path}: missing (not a model folder?)") from None
    except (OSError, UnicodeDecodeError, json.JSONDecodeError) as exc:
        raise ModelFormatError(f"{path}: unreadable model description: {exc}") from exc
    if not isinstance(meta, dict) or meta.get("format") != FORMAT:
        raise ModelFormatError(f"{path}: not an ODMO Explorer model description")
    version = meta.get("format_version")
    if isinstance(version, bool) or not isinstance(version, int) or version < 1:
        raise ModelFormatError(f"{path}: bad format_version {version!r}")
    if version > FORMAT_VERSION:
        raise ModelFormatError(
            f"{path}: format version {version} is newer than this program reads ({FORMAT_VERSION}); upgrade"
        )
    missing = [k for k in _REQUIRED_KEYS if k not in meta]
    if missing:
        raise ModelFormatError(f"{path}: missing keys: {', '.join(missing)}")
    unknown = sorted(set(meta) - _KNOWN_KEYS)
    if unknown:
        raise ModelFormatError(f"{path}: unknown keys: {', '.join(unknown)}")
    return meta


def read_weights(path: Path, model: torch.nn.Module, meta: dict[str, Any]) -> dict[str, torch.Tensor]:
    """Tensors of ``path``, checked name by name and shape by shape against ``model``, then checksummed."""
    data = _read_bytes(path, "weights")
    try:
        tensors = load_safetensors(data)
    except (SafetensorError, ValueError, RuntimeError) as exc:
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
    check_checksum(path, data, meta, "weights_sha256")
    return tensors


def read_bank(folder: Path, meta: dict[str, Any]) -> LatentBank | None:
    """The folder's latent bank, verified against model.json, or None when the folder has none."""
    from engine.latent.bank import LatentBank

    path = folder / BANK_FILE
    if not path.exists():
        log.warning("%s: no latent bank; sampling from modes is unavailable", path)
        return None
    data = _read_bytes(path, "latent bank")
    if meta["format_version"] >= 2 and "bank_sha256" not in meta:
        raise ModelFormatError(
            f"{path}: not recorded in {META_FILE} (a training run or bank build was interrupted?); "
            "rebuild it with `odmo bank`"
        )
    check_checksum(path, data, meta, "bank_sha256")
    bank = LatentBank.from_bytes(data, path)
    if bank.weights_sha256 and bank.weights_sha256 != meta.get("weights_sha256", bank.weights_sha256):
        raise ModelFormatError(
            f"{path}: built from other weights than {WEIGHTS_FILE}; rebuild it with `odmo bank`"
        )
    return bank


@dataclass
class FolderContents:
    """A model folder read and checked: its description, config, skeleton, actions and network."""

    meta: dict[str, Any]
    config: Any
    skeleton: Skeleton
    action_names: list[str]
    model: torch.nn.Module
    path: Path

    def loaded_fields(self) -> dict[str, Any]:
        """The fields every kind's loaded-model record has, by name."""
        return {
            "model": self.model,
            "config": self.config,
            "skeleton": self.skeleton,
            "action_names": self.action_names,
            "fps": float(self.config.fps),
            "window": int(self.config.window),
            "root_height": float(self.meta["root_height"]),
            "provenance": dict(self.meta["provenance"]),
            "path": self.path,
        }


def read_model_folder(
    model_dir: str | Path,
    arch: str,
    config_type: type[ModelConfig],
    build: Callable[[Any, Skeleton], torch.nn.Module],
    device: str = "cpu",
) -> FolderContents:
    """Read a folder of kind ``arch`` strictly (ModelFormatError for anything missing, corrupt, mis-shaped,
    newer or of another kind); ``build(config, skeleton)`` makes the network its weights load into (eval
    mode)."""
    folder = Path(model_dir)
    if not folder.is_dir():
        raise ModelFormatError(f"{folder}: not a model folder")
    meta_path = folder / META_FILE
    meta = read_meta(meta_path)
    if meta.get("arch", "odmo") != arch:
        raise ModelFormatError(f"{meta_path}: architecture {meta.get('arch', 'odmo')!r} is not {arch!r}")
    try:
        config = config_type.from_dict(meta["config"])
    except ModelFormatError as exc:
        raise ModelFormatError(f"{meta_path}: {exc}") from None
    try:
        sk = meta["skeleton"]
        skeleton = Skeleton(tuple(sk["names"]), np.array(sk["parents"]), np.array(sk["offsets"], dtype=float))
        names = [str(a) for a in meta["action_names"]]
        float(meta["root_height"])
    except (KeyError, TypeError, ValueError, ConfigError) as exc:
        raise ModelFormatError(f"{meta_path}: bad skeleton, action names or root height: {exc}") from exc
    if len(names) != config.n_actions or skeleton.n_joints != config.n_joints:
        raise ModelFormatError(f"{meta_path}: action names or skeleton disagree with the config")
    model = build(config, skeleton)
    model.load_state_dict(read_weights(folder / WEIGHTS_FILE, model, meta))
    model.to(resolve_device(device)).eval()
    return FolderContents(meta, config, skeleton, names, model, folder)


def read_kind_folder(
    model_dir: str | Path,
    arch: str,
    config_type: type[ModelConfig],
    build: Callable[[Any, Skeleton], torch.nn.Module],
    device: str = "cpu",
    with_bank: bool = True,
) -> dict[str, Any]:
    """The fields of a kind's loaded-folder record (``LoadedFolder``): the folder read strictly by
    :func:`read_model_folder` and its latent bank, when ``with_bank`` and the folder has one."""
    found = read_model_folder(model_dir, arch, config_type, build, device)
    with_bank = with_bank and (found.path / BANK_FILE).is_file()
    bank = read_bank(found.path, found.meta) if with_bank else None
    return found.loaded_fields() | {"bank": bank}


def load_model(model_dir: str | Path, device: str = "cpu", with_bank: bool = True) -> LoadedModel:
    """Read an ODMO model folder strictly (see :func:`read_model_folder`), with its latent bank."""
    found = read_model_folder(model_dir, "odmo", OdmoConfig, lambda config, _: OdmoModel(config), device)
    bank = read_bank(found.path, found.meta) if with_bank else None
    return LoadedModel(**found.loaded_fields(), bank=bank)
