"""Up axis: motions stored Z-up (some exporters, raw AMASS joints) turned into the engine's Y-up frame."""

from __future__ import annotations

import dataclasses

import numpy as np
from scipy.spatial.transform import Rotation

from engine.errors import ConfigError
from engine.motion.motion import Motion
from engine.motion.skeleton import Skeleton

UP_AXES = ("y", "z")
#: Z-up, right-handed → Y-up, right-handed: (x, y, z) → (x, z, −y), a −90° turn about x.
Z_UP_TO_Y_UP = Rotation.from_euler("x", -90.0, degrees=True)
#: A body looks Z-up when it is this many times taller along z than along y.
_Z_UP_RATIO = 1.5


def check_up_axis(up_axis: str) -> None:
    """ConfigError unless ``up_axis`` is one of UP_AXES."""
    if up_axis not in UP_AXES:
        raise ConfigError(f"up axis must be one of {', '.join(UP_AXES)}, got {up_axis!r}")


def looks_z_up(motion: Motion) -> bool:
    """Whether the body stands along z: the median per-frame z extent of its joints is 1.5× the y extent.

    The root is left out (it may be a ground projection left behind, like Bandai's ``joint_Root``). A hint
    only, since a long creature (a snake, a horse) lies along z in a Y-up file too.
    """
    joints = np.delete(motion.joints, motion.skeleton.root, axis=1)
    if joints.shape[1] == 0:
        return False
    spans = np.median(np.ptp(joints, axis=1), axis=0)
    return bool(spans[2] > _Z_UP_RATIO * spans[1])


def rotated(motion: Motion, rotation: Rotation) -> Motion:
    """``motion`` turned by ``rotation`` about the origin: positions, offsets, End Sites and root path
    rotate; each local rotation q becomes r·q·r⁻¹, so forward kinematics gives the turned joints."""
    matrix = rotation.as_matrix()
    skel = motion.skeleton
    sites = tuple((p, tuple(float(v) for v in matrix @ np.asarray(o))) for p, o in skel.end_sites)
    skeleton = Skeleton(skel.names, skel.parents, skel.offsets @ matrix.T, sites, skel.units)
    rotations = motion.local_rotations
    if rotations is not None:
        flat = Rotation.from_quat(rotations.reshape(-1, 4), scalar_first=True)
        turned = rotation * flat * rotation.inv()
        rotations = turned.as_quat(scalar_first=True).reshape(rotations.shape)
    translation = None if motion.root_translation is None else motion.root_translation @ matrix.T
    return dataclasses.replace(
        motion,
        joints=motion.joints @ matrix.T.astype(np.float32),
        skeleton=skeleton,
        local_rotations=rotations,
        root_translation=translation,
        meta=dict(motion.meta),
    )


def to_y_up(motion: Motion, up_axis: str = "y") -> Motion:
    """``motion``, whose source is ``up_axis``-up, in the Y-up frame (itself when it already is); a turned
    motion records ``meta["turned_from_up_axis"] = "z"``."""
    check_up_axis(up_axis)
    if up_axis == "y":
        return motion
    turned = rotated(motion, Z_UP_TO_Y_UP)
    turned.meta["turned_from_up_axis"] = up_axis
    return turned
