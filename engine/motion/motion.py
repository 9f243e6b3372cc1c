"""Motion: joint positions over time on a skeleton, with optional local rotations; a data class without I/O.

Files are read and written by ``engine.motion.formats`` (``read_motion``, ``write_motion``), rates changed by
``engine.motion.resample.resample_motion``, shared operations live in ``engine.motion.ops``.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field, replace
from typing import Any

import numpy as np

from engine.errors import ConfigError
from engine.motion.skeleton import Skeleton

#: Largest joint coordinate accepted, in metres: beyond it float32 arithmetic (IK, FK) loses all meaning.
MAX_COORDINATE_M = 1e5


@dataclass(eq=False)
class Motion:
    """A clip of motion.

    Parameters
    ----------
    joints : (T, J, 3) float32 joint positions in metres, y up, right-handed.
    fps : frames per second.
    skeleton : the skeleton the joints belong to.
    local_rotations : optional (T, J, 4) float quaternions (w, x, y, z), each joint relative to its parent.
    root_translation : optional (T, 3) float root position in metres (with ``local_rotations`` it
        reproduces ``joints`` by forward kinematics).
    action : optional action label.
    meta : free metadata (style, source file, seed, code, ...); JSON-serialisable values.
    """

    joints: np.ndarray
    fps: float
    skeleton: Skeleton
    local_rotations: np.ndarray | None = None
    root_translation: np.ndarray | None = None
    action: str | None = None
    meta: dict[str, Any] = field(default_factory=dict)

    def __post_init__(self) -> None:
        self.joints = np.asarray(self.joints, dtype=np.float32)
        t = self.joints.shape[0] if self.joints.ndim == 3 else -1
        if self.joints.ndim != 3 or self.joints.shape[2] != 3:
            raise ConfigError(f"joints must be (T, J, 3), got {self.joints.shape}")
        if t == 0:
            raise ConfigError("a motion needs at least one frame")
        if self.joints.shape[1] != self.skeleton.n_joints:
            raise ConfigError(
                f"joints have {self.joints.shape[1]} joints, skeleton has {self.skeleton.n_joints}"
            )
        reach = float(np.max(np.abs(self.joints)))  # NaN when any value is NaN
        if not reach <= MAX_COORDINATE_M:
            if not np.all(np.isfinite(self.joints)):
                raise ConfigError("joint positions must be finite")
            raise ConfigError(
                f"joint positions reach {reach:.3g} m, beyond {MAX_COORDINATE_M:g} m: not motion in metres "
                "(wrong units or a damaged file?)"
            )
        self.fps = float(self.fps)
        if not (0 < self.fps <= 10000):
            raise ConfigError(f"fps must be in (0, 10000], got {self.fps}")
        if self.local_rotations is not None:
            self.local_rotations = np.asarray(self.local_rotations, dtype=np.float64)
            if self.local_rotations.shape != (t, self.skeleton.n_joints, 4):
                raise ConfigError(f"local_rotations must be (T, J, 4), got {self.local_rotations.shape}")
        if self.root_translation is not None:
            self.root_translation = np.asarray(self.root_translation, dtype=np.float64)
            if self.root_translation.shape != (t, 3):
                raise ConfigError(f"root_translation must be (T, 3), got {self.root_translation.shape}")

    @property
    def n_frames(self) -> int:
        """Number of frames T."""
        return int(self.joints.shape[0])

    @property
    def n_joints(self) -> int:
        """Number of joints J."""
        return int(self.joints.shape[1])

    @property
    def duration(self) -> float:
        """Length in seconds, (T - 1) / fps."""
        return (self.n_frames - 1) / self.fps

    def with_joints(self, joints: np.ndarray, **changes: Any) -> Motion:
        """A copy with new joint positions and no rotations (they would no longer match)."""
        return replace(self, joints=joints, local_rotations=None, root_translation=None, **changes)

    def without_joints(self, names: Sequence[str]) -> Motion:
        """This motion (positions, label, meta) without the joints called ``names``; absent names are
        ignored. A dropped parent's offset folds into its child (``Skeleton.subset``)."""
        skel = self.skeleton
        keep = [j for j, n in enumerate(skel.names) if n not in names]
        if len(keep) == skel.n_joints:
            return self
        return Motion(self.joints[:, keep], self.fps, skel.subset(keep), action=self.action, meta=self.meta)
