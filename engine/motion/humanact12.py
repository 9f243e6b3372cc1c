"""HumanAct12: the SMPL-24 skeleton, action labels from file names, and the opt-in ACTOR pickle."""

from __future__ import annotations

import re
from pathlib import Path

import numpy as np

from engine.errors import MotionFormatError, OdmoError
from engine.motion.motion import Motion
from engine.motion.skeleton import Skeleton

FPS = 20.0

# The 12 coarse classes, in HumanAct12's order (class 1 is warm_up).
ACTIONS = (
    "warm_up",
    "walk",
    "run",
    "jump",
    "drink",
    "lift_dumbbell",
    "sit",
    "eat",
    "turn steering wheel",
    "phone",
    "boxing",
    "throw",
)

# ``P01G01R01F0069T0143A0102.npy``: A + two digits of coarse class + two digits of fine sub-class.
FILE_PATTERN = r"P\d+G\d+R\d+F\d+T\d+A(?P<coarse>\d\d)(?P<fine>\d\d)"
_FILE_RE = re.compile(FILE_PATTERN)

SMPL24_NAMES = (
    "pelvis",
    "left_hip",
    "right_hip",
    "spine1",
    "left_knee",
    "right_knee",
    "spine2",
    "left_ankle",
    "right_ankle",
    "spine3",
    "left_foot",
    "right_foot",
    "neck",
    "left_collar",
    "right_collar",
    "head",
    "left_shoulder",
    "right_shoulder",
    "left_elbow",
    "right_elbow",
    "left_wrist",
    "right_wrist",
    "left_hand",
    "right_hand",
)
SMPL24_PARENTS = (-1, 0, 0, 0, 1, 2, 3, 4, 5, 6, 7, 8, 9, 9, 9, 12, 13, 14, 16, 17, 18, 19, 20, 21)
# Approximate rest offsets of the neutral SMPL body (metres, y up, +x to the body's left, +z forward).
SMPL24_OFFSETS = (
    (0.0, 0.0, 0.0),
    (0.0695, -0.0914, -0.0068),
    (-0.0677, -0.0905, -0.0043),
    (-0.0025, 0.1089, -0.0267),
    (0.0343, -0.3752, -0.0045),
    (-0.0383, -0.3826, -0.0089),
    (0.0055, 0.1352, 0.0011),
    (-0.0136, -0.3980, -0.0437),
    (0.0158, -0.3984, -0.0423),
    (0.0015, 0.0529, 0.0254),
    (0.0264, -0.0558, 0.1193),
    (-0.0254, -0.0481, 0.1233),
    (-0.0028, 0.2139, -0.0429),
    (0.0788, 0.1217, -0.0341),
    (-0.0818, 0.1188, -0.0386),
    (0.0052, 0.0650, 0.0513),
    (0.0910, 0.0305, -0.0089),
    (-0.0960, 0.0326, -0.0091),
    (0.2596, -0.0128, -0.0275),
    (-0.2537, -0.0133, -0.0215),
    (0.2492, 0.0090, -0.0012),
    (-0.2553, 0.0078, -0.0056),
    (0.0840, -0.0082, -0.0149),
    (-0.0847, -0.0061, -0.0103),
)


def smpl24_skeleton() -> Skeleton:
    """The SMPL-24 joint tree with approximate rest offsets in metres."""
    return Skeleton(SMPL24_NAMES, np.array(SMPL24_PARENTS), np.array(SMPL24_OFFSETS), (), "m")


def smpl22_skeleton() -> Skeleton:
    """SMPL-24 without the two hand joints: the 22-joint body of HumanML3D's joint arrays."""
    return Skeleton(SMPL24_NAMES[:22], np.array(SMPL24_PARENTS[:22]), np.array(SMPL24_OFFSETS[:22]), (), "m")


def label_from_filename(name: str) -> tuple[str, dict[str, str]] | None:
    """(coarse action, meta with the fine code) parsed from a HumanAct12 file name, or None if it has none."""
    match = _FILE_RE.search(Path(name).name)
    if match is None:
        return None
    coarse = int(match["coarse"])
    if not 1 <= coarse <= len(ACTIONS):
        return None
    return ACTIONS[coarse - 1], {"fine_class": f"{match['coarse']}{match['fine']}"}


def read_actor_pickle(path: str | Path, allow_pickle: bool = False, fps: float = FPS) -> list[Motion]:
    """Clips of ACTOR's ``humanact12poses.pkl`` (``joints3D`` (T, 24, 3), ``y`` coarse ids from 0).

    Pickles can run code, so this needs ``allow_pickle=True`` and then accepts only plain data.
    """
    from engine.motion.safe_pickle import load_data_pickle

    path = Path(path)
    if not allow_pickle:
        raise MotionFormatError(
            "reading a pickle needs an explicit opt-in (allow_pickle / --allow-pickle)", path
        )
    data = load_data_pickle(path)
    if not isinstance(data, dict) or "joints3D" not in data or "y" not in data:
        raise MotionFormatError("expected a dict with 'joints3D' and 'y' (ACTOR humanact12poses.pkl)", path)
    clips, labels = data["joints3D"], data["y"]
    if not isinstance(clips, list | tuple) or not isinstance(labels, list | tuple | np.ndarray):
        raise MotionFormatError("'joints3D' and 'y' must be lists (ACTOR humanact12poses.pkl)", path)
    if len(clips) != len(labels):
        raise MotionFormatError(f"{len(clips)} clips but {len(labels)} labels", path)
    skeleton = smpl24_skeleton()
    motions = []
    for i, (joints, label) in enumerate(zip(clips, labels, strict=True)):
        if isinstance(label, bool | np.bool_) or not isinstance(label, int | np.integer):
            raise MotionFormatError(f"clip {i}: label {label!r} is not a coarse class id 0..11", path)
        if not 0 <= int(label) < len(ACTIONS):
            raise MotionFormatError(f"clip {i}: label {label!r} is not a coarse class id 0..11", path)
        try:
            motion = Motion(np.asarray(joints), fps, skeleton, action=ACTIONS[int(label)])
        except (OdmoError, ValueError, TypeError) as exc:
            raise MotionFormatError(f"clip {i}: {exc}", path) from None
        motion.meta.update(source=f"{path.name}#{i}")
        motions.append(motion)
    return motions
