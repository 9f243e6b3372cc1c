"""Feet and hands of a skeleton found by name, and foot-contact labels of joint positions.

Contact rule (labels for training and for the decode-time clean-up): a foot joint is planted in a frame
when its height lies within ``height_tol`` (3 cm) of its resting height (the lowest height that joint
reaches in the data, floor at y = 0) and its speed is under ``speed_tol`` (0.5 m/s).

Floating rule (``floats``; the physical metric and the clean-up's ground rule share it): a clip floats
when every foot joint stays over ``FLOAT_HEIGHT`` (10 cm) for ``FLOAT_SECONDS`` (0.5 s) in a row.
"""

from __future__ import annotations

import re
from collections.abc import Sequence

import numpy as np

from engine.motion.skeleton import Skeleton

_FOOT = re.compile(r"foot|toe|ankle", re.IGNORECASE)
_HAND = re.compile(r"hand|wrist", re.IGNORECASE)
HEIGHT_TOL = 0.03
SPEED_TOL = 0.5
FLOAT_HEIGHT = 0.10
FLOAT_SECONDS = 0.5


def foot_joints(skeleton: Skeleton) -> list[int]:
    """Indices of the joints whose name says foot, toe or ankle (in skeleton order)."""
    return [j for j, name in enumerate(skeleton.names) if _FOOT.search(name)]


def hand_joints(skeleton: Skeleton) -> list[int]:
    """Indices of the hand joints: named hand or wrist, the top-most of each chain (not the fingers)."""
    named = [j for j, name in enumerate(skeleton.names) if _HAND.search(name)]
    return [j for j in named if int(skeleton.parents[j]) not in named]


def leg_chains(skeleton: Skeleton) -> list[tuple[int, int, int, list[int]]]:
    """Per leg: (hip, knee, ankle, foot joints below the ankle) for two-bone IK.

    The ankle is the top-most foot joint of a chain; knee and hip are its parent and grandparent. Only
    chains whose hip and knee each have one child are returned (moving the knee then bends no other bone).
    """
    feet = foot_joints(skeleton)
    parents = skeleton.parents
    chains = []
    for j in feet:
        if int(parents[j]) in feet:
            continue
        knee = int(parents[j])
        hip = int(parents[knee]) if knee >= 0 else -1
        if hip < 0 or len(skeleton.children(hip)) != 1 or len(skeleton.children(knee)) != 1:
            continue
        below = [k for k in feet if k != j and _descends(parents, k, j)]
        chains.append((hip, knee, j, below))
    return chains


def hip_pair(skeleton: Skeleton) -> tuple[int, int] | None:
    """The two hips, the tops of the two ``leg_chains`` (None unless the rig has exactly two legs)."""
    legs = leg_chains(skeleton)
    return (legs[0][0], legs[1][0]) if len(legs) == 2 else None


def pelvis_joint(skeleton: Skeleton) -> int:
    """The pelvis: the hips' parent (a rig's root may stay at the origin), or the root without two legs."""
    hips = hip_pair(skeleton)
    return skeleton.root if hips is None else int(skeleton.parents[hips[0]])


def ankle_pair(skeleton: Skeleton) -> tuple[int, int] | None:
    """The two ankles, the top foot joints of the two ``leg_chains`` (None unless the rig has two legs)."""
    legs = leg_chains(skeleton)
    return (legs[0][2], legs[1][2]) if len(legs) == 2 else None


def foot_lines(skeleton: Skeleton) -> list[tuple[int, int]]:
    """Per leg with a joint below its ankle, (ankle, the first foot joint below it): the line a foot
    points along."""
    return [(ankle, below[0]) for _, _, ankle, below in leg_chains(skeleton) if below]


def shoulder_pair(skeleton: Skeleton) -> tuple[int, int] | None:
    """The tops of the two arms (from each hand up to the joint below the first that branches, the
    chest), the first on the side of ``hip_pair``'s first in the rest pose; None without two hands and
    two legs."""
    hips, hands = hip_pair(skeleton), hand_joints(skeleton)
    if hips is None or len(hands) != 2:
        return None
    tops = []
    for j in hands:
        while int(skeleton.parents[j]) >= 0 and len(skeleton.children(int(skeleton.parents[j]))) == 1:
            j = int(skeleton.parents[j])
        tops.append(j)
    if tops[0] == tops[1] or int(skeleton.parents[tops[0]]) < 0:
        return None
    rest = skeleton.rest_positions()
    same_side = np.dot(rest[tops[0]] - rest[tops[1]], rest[hips[0]] - rest[hips[1]]) >= 0
    return (tops[0], tops[1]) if same_side else (tops[1], tops[0])


def _descends(parents: np.ndarray, k: int, ancestor: int) -> bool:
    """Whether joint ``k`` lies below ``ancestor`` in the tree."""
    p = int(parents[k])
    while p >= 0:
        if p == ancestor:
            return True
        p = int(parents[p])
    return False


def resting_heights(clips: list[np.ndarray], joints: list[int]) -> np.ndarray:
    """(F,) lowest height each of ``joints`` reaches over ``clips`` of (T, J, 3) positions (floor y = 0)."""
    lows = np.stack([np.asarray(c)[:, joints, 1].min(axis=0) for c in clips])
    return np.median(lows, axis=0).astype(np.float32)


def contact_labels(
    joints: np.ndarray,
    fps: float,
    feet: list[int],
    rest: np.ndarray,
    height_tol: float = HEIGHT_TOL,
    speed_tol: float = SPEED_TOL,
) -> np.ndarray:
    """(..., T, F) bool: foot joint f planted in frame t (height within ``height_tol`` of ``rest``, and
    speed under ``speed_tol``) for joints (..., T, J, 3) with the floor at y = 0."""
    pos = np.asarray(joints, dtype=np.float64)[..., feet, :]
    low = pos[..., 1] - np.asarray(rest, dtype=np.float64) <= height_tol
    step = np.linalg.norm(np.diff(pos, axis=-3), axis=-1) * fps
    speed = np.concatenate([step[..., :1, :], step], axis=-2)
    speed = np.minimum(speed, np.concatenate([step, step[..., -1:, :]], axis=-2))
    return low & (speed < speed_tol)


def floats(joints: np.ndarray, feet: Sequence[int], fps: float) -> np.ndarray:
    """Whether every foot joint stays more than 10 cm above the floor for 0.5 s or more in a row, per
    clip of joints (..., T, J, 3): a bool array of the leading shape (0-d for one clip)."""
    up = np.asarray(joints)[..., list(feet), 1].min(axis=-1) > FLOAT_HEIGHT  # (..., T)
    need = max(1, int(np.ceil(FLOAT_SECONDS * fps - 1e-9)))
    count = np.cumsum(up, axis=-1)
    run = count - np.maximum.accumulate(np.where(up, 0, count), axis=-1)
    return (run >= need).any(axis=-1)
