"""The ODMO Explorer NPZ motion format, schema version 1.

An uncompressed ``numpy.savez`` archive with no object arrays, read with ``allow_pickle=False``:

=================== ============== =============================================================
key                 dtype / shape  meaning
=================== ============== =============================================================
joints              float32 (T,J,3) joint positions in metres, y up, right-handed
fps                 float64 ()      frames per second
parents             int64 (J,)      parent index of each joint, -1 for the root
joint_names         <U (J,)         joint names (fixed-width unicode)
offsets             float64 (J,3)   rest offsets from the parent, metres
units               <U ()           unit of ``joints`` and ``offsets``: always "m"
up_axis             <U ()           always "y"
action              <U ()           action label, "" when none
meta                <U ()           JSON object: ``format_version`` (1), ``tool_version``, then the
                                    clip's metadata (source, seed, code, IK error, style, ...)
local_rotations     float64 (T,J,4) optional quaternions (w, x, y, z) relative to the parent
root_translation    float64 (T,3)   optional, present exactly when ``local_rotations`` is
end_site_parents    int64 (E,)      optional BVH End Site parents
end_site_offsets    float64 (E,3)   optional BVH End Site offsets, metres
=================== ============== =============================================================

A reader refuses missing keys, wrong shapes or dtypes, non-finite values and a ``format_version``
newer than it knows. ``docs/NPZ_FORMAT.md`` describes the same schema for other tools.
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import numpy as np

from engine import __version__
from engine.errors import MotionFormatError, OdmoError
from engine.fileio import atomic_write
from engine.motion.motion import Motion
from engine.motion.skeleton import Skeleton
from engine.npyio import load_npz

FORMAT_VERSION = 1
_REQUIRED = ("joints", "fps", "parents", "joint_names", "offsets", "units", "up_axis", "action", "meta")
_BOOKKEEPING = ("format_version", "tool_version")


def write_npz(path: str | Path, motion: Motion) -> dict[str, Any]:
    """Write ``motion`` to ``path`` in schema version 1, atomically; returns a small report."""
    skel = motion.skeleton
    meta = {"format_version": FORMAT_VERSION, "tool_version": __version__, **motion.meta}
    arrays: dict[str, np.ndarray] = {
        "joints": np.asarray(motion.joints, dtype=np.float32),
        "fps": np.asarray(motion.fps, dtype=np.float64),
        "parents": np.asarray(skel.parents, dtype=np.int64),
        "joint_names": np.asarray(skel.names, dtype=np.str_),
        "offsets": np.asarray(skel.offsets, dtype=np.float64),
        "units": np.asarray("m"),
        "up_axis": np.asarray("y"),
        "action": np.asarray(motion.action or ""),
        "meta": np.asarray(json.dumps(meta, sort_keys=True)),
    }
    if motion.local_rotations is not None and motion.root_translation is not None:
        arrays["local_rotations"] = np.asarray(motion.local_rotations, dtype=np.float64)
        arrays["root_translation"] = np.asarray(motion.root_translation, dtype=np.float64)
    if skel.end_sites:
        arrays["end_site_parents"] = np.array([p for p, _ in skel.end_sites], dtype=np.int64)
        arrays["end_site_offsets"] = np.array([o for _, o in skel.end_sites], dtype=np.float64)
    with atomic_write(path, "wb") as handle:
        np.savez(handle, **arrays)
    return {"path": str(path), "frames": motion.n_frames, "joints": motion.n_joints, "format": "npz"}


def read_npz(path: str | Path) -> Motion:
    """Read a schema-1 NPZ file into a :class:`Motion`; raises MotionFormatError naming the file."""
    path = Path(path)
    try:
        data = load_npz(path)
    except (ValueError, OSError) as exc:
        raise MotionFormatError(f"not a readable NPZ archive: {exc}", path) from None
    missing = [key for key in _REQUIRED if key not in data]
    if missing:
        raise MotionFormatError(f"missing key(s): {', '.join(missing)}", path)
    meta = _read_meta(data["meta"], path)
    joints = _check(data, "joints", "f", 3, path)
    T, J = joints.shape[:2]
    if joints.shape[2] != 3:
        raise MotionFormatError(f"'joints' must be (T, J, 3), got {joints.shape}", path)
    fps = float(_check(data, "fps", "fi", 0, path))
    parents = _check(data, "parents", "iu", 1, path, (J,))
    names = _check(data, "joint_names", "U", 1, path, (J,))
    offsets = _check(data, "offsets", "f", 2, path, (J, 3))
    units, up_axis = str(_check(data, "units", "U", 0, path)), str(_check(data, "up_axis", "U", 0, path))
    if units != "m" or up_axis != "y":
        raise MotionFormatError(f"expected units 'm' and up_axis 'y', got {units!r} and {up_axis!r}", path)
    has_rot = "local_rotations" in data
    if has_rot != ("root_translation" in data):
        raise MotionFormatError("'local_rotations' and 'root_translation' must come together", path)
    rotations = _check(data, "local_rotations", "f", 3, path, (T, J, 4)) if has_rot else None
    translation = _check(data, "root_translation", "f", 2, path, (T, 3)) if has_rot else None
    sites: tuple[tuple[int, tuple[float, float, float]], ...] = ()
    if "end_site_parents" in data:
        site_parents = _check(data, "end_site_parents", "iu", 1, path)
        site_offsets = _check(data, "end_site_offsets", "f", 2, path, (len(site_parents), 3))
        sites = tuple(
            (int(p), tuple(float(v) for v in o)) for p, o in zip(site_parents, site_offsets, strict=True)
        )
    action = str(_check(data, "action", "U", 0, path)) or None
    try:
        skeleton = Skeleton(tuple(names.tolist()), parents, offsets, sites, "m")
        return Motion(joints, fps, skeleton, rotations, translation, action, meta)
    except OdmoError as exc:
        raise MotionFormatError(str(exc), path) from None


def _read_meta(raw: np.ndarray, path: Path) -> dict[str, Any]:
    """The clip metadata from the JSON ``meta`` entry, after checking the format version."""
    if raw.dtype.kind != "U" or raw.shape != ():
        raise MotionFormatError("'meta' must be a unicode scalar holding JSON", path)
    try:
        meta = json.loads(str(raw))
    except json.JSONDecodeError as exc:
        raise MotionFormatError(f"'meta' is not valid JSON ({exc})", path) from None
    if not isinstance(meta, dict):
        raise MotionFormatError("'meta' must be a JSON object", path)
    version = meta.get("format_version")
    if not isinstance(version, int):
        raise MotionFormatError("'meta' has no integer format_version", path)
    if version > FORMAT_VERSION:
        raise MotionFormatError(
            f"format version {version} is newer than this tool reads ({FORMAT_VERSION}); upgrade", path
        )
    return {k: v for k, v in meta.items() if k not in _BOOKKEEPING}


def _check(
    data: dict[str, np.ndarray],
    key: str,
    kinds: str,
    ndim: int,
    path: Path,
    shape: tuple[int, ...] | None = None,
) -> np.ndarray:
    """``data[key]`` after checking its dtype kind, rank, shape and (for numbers) finiteness."""
    value = data[key]
    if value.dtype.kind not in kinds:
        raise MotionFormatError(f"'{key}' has dtype {value.dtype}, expected kind {kinds!r}", path)
    if value.ndim != ndim or (shape is not None and value.shape != shape):
        want = shape if shape is not None else f"{ndim} dimensions"
        raise MotionFormatError(f"'{key}' has shape {value.shape}, expected {want}", path)
    if value.dtype.kind == "f" and not np.all(np.isfinite(value)):
        raise MotionFormatError(f"'{key}' holds non-finite values", path)
    return value
