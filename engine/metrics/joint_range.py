"""Joint rotations against the range real motion uses.

Fixed bone lengths do not make a body: a position decoder can keep every length and still turn the
pelvis half round between the legs (the two hips on the wrong sides) or fold a collarbone onto the chest,
moving a few short-bone joints by 10 cm, which joint-position errors barely register. Here each clip is
solved into local joint rotations (``engine.motion.ik.joints_to_rotations``); per joint, the real clips
give a mean rotation and the angle from it that ``RANGE_QUANTILE`` of their frames stay within, and a
set of clips is scored by the share of its (frame, joint) rotations beyond that angle: about
1 − ``RANGE_QUANTILE`` for the real clips themselves, by construction. Leaf joints (no rotation to solve)
are left out.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from scipy.spatial.transform import Rotation

from engine.errors import ConfigError
from engine.motion.ik import joints_to_rotations
from engine.motion.motion import Motion
from engine.motion.skeleton import Skeleton

RANGE_QUANTILE = 0.99


def local_rotations(clip: np.ndarray, skeleton: Skeleton) -> np.ndarray:
    """(T, J, 4) local joint rotations (w, x, y, z) solved from one clip's (T, J, 3) positions."""
    _, local, _, _ = joints_to_rotations(Motion(np.asarray(clip, np.float32), 1.0, skeleton))
    return local


@dataclass(frozen=True)
class JointRange:
    """Per rotating joint, the real clips' mean local rotation and the angle (degrees) from it within
    which ``RANGE_QUANTILE`` of their frames lie."""

    joints: np.ndarray  # (K,) indices of the joints with children
    mean: np.ndarray  # (K, 4) quaternions (w, x, y, z)
    limit_deg: np.ndarray  # (K,)

    @classmethod
    def fit(
        cls, clips: Sequence[np.ndarray], skeleton: Skeleton, quantile: float = RANGE_QUANTILE
    ) -> JointRange:
        """The range of real ``clips`` (each (T, J, 3) metres); ConfigError without clips or joints."""
        joints = np.array([j for j in range(skeleton.n_joints) if skeleton.children(j)], dtype=int)
        if not clips or not len(joints):
            raise ConfigError("a joint range needs real clips of a skeleton with at least one bone")
        rotations = np.concatenate([local_rotations(c, skeleton)[:, joints] for c in clips])
        means = np.stack(
            [_as_rotation(rotations[:, k]).mean().as_quat(scalar_first=True) for k in range(len(joints))]
        )
        angles = _angles(rotations, means)
        return cls(joints, means, np.quantile(angles, quantile, axis=0))

    def deviations(self, clip: np.ndarray, skeleton: Skeleton) -> np.ndarray:
        """(T, K) angle (degrees) of each frame's local rotation of each rotating joint from the mean."""
        return _angles(local_rotations(clip, skeleton)[:, self.joints], self.mean)

    def outside(self, clips: Sequence[np.ndarray], skeleton: Skeleton) -> np.ndarray:
        """(N,) per clip, the share of its (frame, joint) rotations beyond the real range."""
        return np.array([float(np.mean(self.deviations(c, skeleton) > self.limit_deg)) for c in clips])


def _as_rotation(quats: np.ndarray) -> Rotation:
    """scipy rotations of (..., 4) (w, x, y, z) quaternions."""
    return Rotation.from_quat(quats.reshape(-1, 4), scalar_first=True)


def _angles(quats: np.ndarray, means: np.ndarray) -> np.ndarray:
    """(N, K) geodesic angles (degrees) between (N, K, 4) rotations and the (K, 4) means."""
    n, k = quats.shape[:2]
    relative = _as_rotation(np.broadcast_to(means, (n, k, 4))).inv() * _as_rotation(quats)
    return np.degrees(relative.magnitude()).reshape(n, k)
