"""Where a generator's pose output starts: the mean pose of the training clips' canonical centre windows."""

from __future__ import annotations

import numpy as np
from scipy.spatial.transform import Rotation

from engine.motion.ik import joints_to_rotations
from engine.motion.motion import Motion
from engine.train.windows import PreparedClips, crop_windows


def centre_frames(prepared: PreparedClips, indices: np.ndarray) -> np.ndarray:
    """The real frames (N, J, 3) of the canonical centre windows of clips ``indices``."""
    batch = crop_windows(prepared, np.asarray(indices), None)
    return batch.joints[np.asarray(batch.mask, bool)]


def mean_local_rotations(prepared: PreparedClips, indices: np.ndarray) -> Rotation:
    """Each joint's mean local rotation (J rotations; inverse kinematics, ``engine.motion.ik``) over the
    canonical centre windows of clips ``indices``."""
    frames = centre_frames(prepared, indices)
    _, local, _, _ = joints_to_rotations(Motion(frames, prepared.fps, prepared.skeleton))
    means = [Rotation.from_quat(local[:, j], scalar_first=True).mean() for j in range(local.shape[1])]
    return Rotation.concatenate(means)
