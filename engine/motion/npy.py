"""Plain ``.npy`` joint arrays (T, J, 3), as in HumanML3D / HumanAct12, on a given skeleton."""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np

from engine.errors import ConfigError, MotionFormatError, OdmoError
from engine.fileio import atomic_write
from engine.motion.motion import Motion
from engine.motion.skeleton import Skeleton
from engine.npyio import load_npy

UNIT_SCALE = {"m": 1.0, "cm": 0.01, "mm": 0.001}


def _builders() -> dict[str, Callable[[], Skeleton]]:
    from engine.motion.humanact12 import smpl22_skeleton, smpl24_skeleton

    return {"smpl24": smpl24_skeleton, "smpl22": smpl22_skeleton}


def named_skeleton(name: str) -> Skeleton:
    """A built-in skeleton by name (``"smpl24"`` for HumanAct12, ``"smpl22"`` for HumanML3D)."""
    builders = _builders()
    if name not in builders:
        raise ConfigError(f"unknown skeleton {name!r}; built in: auto, {', '.join(builders)}")
    return builders[name]()


def _skeleton_for(path: Path, skeleton: Skeleton | str, n_joints: int) -> Skeleton:
    """``skeleton``, a built-in one by name, or (``"auto"``) the built-in one with ``n_joints`` joints."""
    if not isinstance(skeleton, str):
        return skeleton
    if skeleton != "auto":
        return named_skeleton(skeleton)
    for build in _builders().values():
        if (found := build()).n_joints == n_joints:
            return found
    sizes = ", ".join(f"{name} ({build().n_joints})" for name, build in _builders().items())
    raise MotionFormatError(
        f"array has {n_joints} joints and no built-in skeleton has as many ({sizes}); "
        "pass a Skeleton to read_npy, or store the clip as NPZ with its joint tree",
        path,
    )


def read_npy(
    path: str | Path, skeleton: Skeleton | str = "auto", fps: float = 20.0, units: str = "m"
) -> Motion:
    """Read a (T, J, 3) joint-position array in ``units`` as a Motion on ``skeleton`` (metres).

    ``skeleton`` is a Skeleton, a built-in name, or ``"auto"``: the built-in skeleton with as many joints
    as the array (SMPL-24 for HumanAct12, SMPL-22 for HumanML3D).
    """
    from engine.motion.humanact12 import label_from_filename

    path = Path(path)
    if units not in UNIT_SCALE:
        raise ConfigError(f"unknown units {units!r}; choose one of {', '.join(UNIT_SCALE)}")
    try:
        joints = load_npy(path)
    except (ValueError, OSError, EOFError) as exc:
        raise MotionFormatError(f"not a readable .npy array: {exc}", path) from None
    if joints.dtype.kind not in "fiu" or joints.ndim != 3 or joints.shape[2] != 3:
        raise MotionFormatError(
            f"expected a numeric (T, J, 3) array, got {joints.dtype} {joints.shape}", path
        )
    skel = _skeleton_for(path, skeleton, joints.shape[1])
    if joints.shape[1] != skel.n_joints:
        raise MotionFormatError(
            f"array has {joints.shape[1]} joints but the skeleton has {skel.n_joints}", path
        )
    if not np.all(np.isfinite(joints)):
        raise MotionFormatError("array holds non-finite values", path)
    label = label_from_filename(path.name)
    action, meta = (None, {}) if label is None else label
    try:
        motion = Motion(joints * UNIT_SCALE[units], fps, skel, action=action, meta=meta)
    except OdmoError as exc:
        raise MotionFormatError(str(exc), path) from None
    motion.meta["source"] = path.name
    return motion


def write_npy(path: str | Path, motion: Motion) -> dict[str, Any]:
    """Write the joint positions (T, J, 3) float32 metres to ``path`` atomically; returns a report."""
    with atomic_write(path, "wb") as handle:
        np.save(handle, np.asarray(motion.joints, dtype=np.float32), allow_pickle=False)
    return {"path": str(path), "frames": motion.n_frames, "joints": motion.n_joints, "format": "npy"}
