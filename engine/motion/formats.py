"""Read and write motion files, choosing the format by extension (.bvh, .npz, .npy)."""

from __future__ import annotations

from pathlib import Path
from typing import Any

from engine.errors import MotionFormatError
from engine.motion.motion import Motion

SUPPORTED = (".bvh", ".npz", ".npy")


def read_motion(path: str | Path, up_axis: str = "y", **kwargs: Any) -> Motion:
    """Read a motion file whose up axis is ``up_axis`` into the Y-up frame; ``kwargs`` go to the format's
    reader (e.g. ``skeleton=`` for .npy)."""
    from engine.motion.axes import to_y_up

    path = Path(path)
    suffix = _suffix(path)
    if suffix == ".bvh":
        from engine.motion.bvh import read_bvh

        return read_bvh(path, up_axis=up_axis, **kwargs)
    if suffix == ".npz":
        from engine.motion.npz import read_npz

        return to_y_up(read_npz(path, **kwargs), up_axis)
    from engine.motion.npy import read_npy

    return to_y_up(read_npy(path, **kwargs), up_axis)


def write_motion(motion: Motion, path: str | Path, **kwargs: Any) -> dict[str, Any]:
    """Write ``motion`` atomically in the format of ``path``'s extension; returns the writer's report."""
    path = Path(path)
    suffix = _suffix(path)
    if suffix == ".bvh":
        from engine.motion.bvh import write_bvh

        return write_bvh(path, motion, **kwargs)
    if suffix == ".npz":
        from engine.motion.npz import write_npz

        return write_npz(path, motion, **kwargs)
    from engine.motion.npy import write_npy

    return write_npy(path, motion, **kwargs)


def _suffix(path: Path) -> str:
    """The lower-case extension of ``path`` if it is a supported one."""
    suffix = path.suffix.lower()
    if suffix not in SUPPORTED:
        raise MotionFormatError(
            f"{f'unknown motion file type {suffix!r}' if suffix else 'no file extension'}; "
            f"supported: {', '.join(SUPPORTED)}",
            path,
        )
    return suffix
