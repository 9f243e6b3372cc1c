"""Decode latent codes into motions with a loaded ODMO model."""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import numpy as np
import torch

from engine.errors import ConfigError
from engine.model.odmo import OdmoModel
from engine.modelio import LoadedModel
from engine.motion.ik import plant_feet
from engine.motion.motion import Motion


def action_index(loaded: LoadedModel, action: int | str) -> int:
    """Index of ``action`` (a name or an index) among the model's actions; ConfigError if unknown."""
    names = loaded.action_names
    if isinstance(action, str):
        if action in names:
            return names.index(action)
        raise ConfigError(f"unknown action {action!r}; the model knows: {', '.join(names)}")
    index = int(action)
    if not 0 <= index < len(names):
        raise ConfigError(f"action index {index} out of range 0..{len(names) - 1}")
    return index


def as_codes(loaded: LoadedModel, code: np.ndarray | Sequence[float]) -> np.ndarray:
    """(B, D) float32 codes from a (D,) or (B, D) array; ConfigError on a wrong size."""
    codes = np.asarray(code, dtype=np.float32)
    if codes.ndim == 1:
        codes = codes[None]
    dim = loaded.config.latent_dim
    if codes.ndim != 2 or codes.shape[1] != dim:
        raise ConfigError(f"a code must have {dim} values, got shape {np.shape(code)}")
    if not np.all(np.isfinite(codes)):
        raise ConfigError("codes must be finite")
    return codes


def resolve_ends(
    loaded: LoadedModel, codes: np.ndarray, action: int, end: np.ndarray | Sequence[float] | None
) -> np.ndarray | None:
    """(B, 3) end locations for ``codes``: the given ones, or predicted from the bank (None if unused).

    ``end`` may be (3,) or (B, 3) root end positions in metres, or (2,) / (B, 2) floor positions (x, z)
    whose height is taken from the bank's prediction for each code. A model trained without end
    locations ignores them and gets None.
    """
    if not loaded.config.use_end_location:
        return None
    n = codes.shape[0]
    if end is not None:
        given = np.asarray(end, dtype=np.float32)
        if given.ndim == 1:
            given = np.repeat(given[None], n, axis=0)
        if given.shape not in ((n, 2), (n, 3)) or not np.all(np.isfinite(given)):
            raise ConfigError(f"end must be (3,), (2,) x/z or one row per code, got shape {np.shape(end)}")
        if given.shape[1] == 3:
            return np.ascontiguousarray(given)
    if loaded.bank is None:
        if end is None:
            raise ConfigError(f"{loaded.path}: the model has no latent bank; give an end location")
        heights = np.zeros(n, dtype=np.float32)
    else:
        predicted = np.asarray(loaded.bank.end_location(codes, action), dtype=np.float32).reshape(n, 3)
        if end is None:
            return predicted
        heights = predicted[:, 1]
    return np.stack([given[:, 0], heights, given[:, 1]], axis=1).astype(np.float32)


def display_lift(loaded: LoadedModel) -> np.ndarray:
    """(3,) offset added to decoded positions: the model works with the frame-0 root at the origin."""
    return np.array([0.0, loaded.root_height, 0.0], dtype=np.float32)


def _writable(array: np.ndarray, dtype: type) -> np.ndarray:
    """``array`` as a writable C-contiguous array of ``dtype`` (copied only when needed)."""
    return np.require(array, dtype=dtype, requirements=("C", "W"))


def ready_model(loaded: LoadedModel) -> OdmoModel:
    """The loaded ODMO network, decoding onto the model's skeleton (attached once)."""
    model = loaded.model
    if model.skeleton is None:
        model.attach_skeleton(loaded.skeleton)
    return model


def plant(loaded: LoadedModel, joints: np.ndarray, contact: np.ndarray | None) -> np.ndarray:
    """Display-height joints (B, T, J, 3) with the foot clean-up applied where the model predicts contact
    (unchanged for models without a contact head)."""
    config = loaded.config
    if contact is None or not (config.foot_contact and config.foot_joints and config.foot_heights):
        return joints
    feet, heights = config.foot_joints, config.foot_heights
    return plant_feet(joints, contact > 0.0, loaded.skeleton, feet, heights, fps=loaded.fps)


def decode_tensors(
    loaded: LoadedModel, z: torch.Tensor, actions: torch.Tensor, ends: torch.Tensor | None
) -> tuple[np.ndarray, np.ndarray]:
    """Joints (B, T, J, 3) and root trajectory (B, T, 3) at display height of codes ``z`` (B, D) on the
    model's device: on the skeleton's bone lengths (``bone_projection``) with planted feet pinned
    (``foot_contact``), which is what the app shows and every export writes; the trajectory moves with
    the joints' root when the clean-up lowers a clip onto the floor."""
    with torch.inference_mode():
        out = ready_model(loaded).decode_full(z, actions, ends)
    lift = display_lift(loaded)
    contact = None if out.contact is None else out.contact.cpu().numpy()
    raw = out.joints.cpu().numpy() + lift
    joints = plant(loaded, raw, contact)
    root = loaded.skeleton.root
    moved = joints[:, :, root] - raw[:, :, root]  # the clean-up lowers a floating clip rigidly, root too
    return joints, out.trajectory.cpu().numpy() + lift + moved


def decode_array(
    loaded: LoadedModel, codes: np.ndarray, actions: np.ndarray, ends: np.ndarray | None
) -> tuple[np.ndarray, np.ndarray]:
    """Decode a batch (``decode_tensors``); ``codes`` (B, D) float32, ``actions`` (B,) int, ``ends``
    (B, 3) float32 or None."""
    device = next(loaded.model.parameters()).device
    z = torch.as_tensor(_writable(codes, np.float32), device=device)
    a = torch.as_tensor(_writable(actions, np.int64), device=device)
    e = None if ends is None else torch.as_tensor(_writable(ends, np.float32), device=device)
    return decode_tensors(loaded, z, a, e)


def generated_motion(
    loaded: LoadedModel,
    joints: np.ndarray,
    code: np.ndarray,
    action: int,
    end: np.ndarray | None,
    mode: int | None = None,
    seed: int | None = None,
    **extra: Any,
) -> Motion:
    """Wrap decoded (T, J, 3) positions as a Motion carrying its provenance in ``meta``."""
    meta = {
        "code": [float(v) for v in code],
        "action": loaded.action_names[action],
        "mode": None if mode is None else int(mode),
        "end": None if end is None else [float(v) for v in end],
        "seed": seed,
        "model": str(loaded.path),
        "model_sha256": getattr(loaded.bank, "weights_sha256", None) or None,
        **extra,
    }
    return Motion(joints, loaded.fps, loaded.skeleton, action=loaded.action_names[action], meta=meta)


def decode_batch(
    loaded: LoadedModel,
    codes: np.ndarray,
    action: int | str,
    end: np.ndarray | Sequence[float] | None = None,
    *,
    modes: Sequence[int] | None = None,
    seed: int | None = None,
) -> list[Motion]:
    """Decode (B, D) codes of one action into B motions (end predicted from the bank when None)."""
    index = action_index(loaded, action)
    z = as_codes(loaded, codes)
    ends = resolve_ends(loaded, z, index, end)
    joints, _ = decode_array(loaded, z, np.full(len(z), index), ends)
    return [
        generated_motion(
            loaded,
            joints[i],
            z[i],
            index,
            None if ends is None else ends[i],
            None if modes is None else modes[i],
            seed,
        )
        for i in range(len(z))
    ]


def decode(
    loaded: LoadedModel,
    code: np.ndarray | Sequence[float],
    action: int | str,
    end: np.ndarray | Sequence[float] | None = None,
    *,
    mode: int | None = None,
    seed: int | None = None,
) -> Motion:
    """Decode one (D,) code of ``action`` into a Motion (end predicted from the bank when None)."""
    z = as_codes(loaded, code)
    if len(z) != 1:
        raise ConfigError(f"decode takes one code, got {len(z)}; use decode_batch")
    return decode_batch(loaded, z, action, end, modes=None if mode is None else [mode], seed=seed)[0]
