"""DVGAN's motion representation (paper §5: exponential maps) on a fixed skeleton, frame by frame.

Per frame, in this order: the root's heading change (yaw rate about y, radians per frame), the root's
horizontal step in its own heading frame (x, z), the root height, the root's tilt (its rotation without
the heading) and every other joint's local rotation as exponential maps (axis × angle), then one contact
label per foot joint (0 or 1). Nothing in a frame depends on where the motion is or which way it faces,
so a sequence can run for thousands of frames without its features leaving the training range; positions
come back by summing the steps and by forward kinematics of the data's skeleton (root offset zeroed).
"""

from __future__ import annotations

import numpy as np
from scipy.spatial.transform import Rotation

from engine.motion.contact import contact_labels, foot_joints
from engine.motion.ik import joints_to_rotations
from engine.motion.motion import Motion
from engine.motion.rotations import forward_kinematics
from engine.motion.skeleton import Skeleton

#: Features before the rotations: yaw rate, step x, step z, height.
ROOT_FEATURES = 4


def n_features(skeleton: Skeleton) -> int:
    """Features per frame of motions on ``skeleton``."""
    return ROOT_FEATURES + 3 * skeleton.n_joints + len(foot_joints(skeleton))


def _heading(root: Rotation) -> tuple[np.ndarray, Rotation]:
    """Heading angles (T,) about y and the tilts (root = heading · tilt) of root rotations (swing–twist)."""
    q = root.as_quat(scalar_first=True)
    yaw = np.unwrap(2.0 * np.arctan2(q[:, 2], q[:, 0]))
    return yaw, Rotation.from_euler("y", -yaw[:, None]) * root


def solve_pose(
    joints: np.ndarray, fps: float, skeleton: Skeleton
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Local rotations (T, J, 4) of joint positions (T, J, 3) by inverse kinematics, the root's without its
    heading; the headings (T,) and the root positions (T, 3)."""
    _, local, root_pos, _ = joints_to_rotations(Motion(np.asarray(joints, np.float32), fps, skeleton))
    yaw, tilt = _heading(Rotation.from_quat(local[:, skeleton.root], scalar_first=True))
    local[:, skeleton.root] = tilt.as_quat(scalar_first=True)
    return local, yaw, root_pos


def typical_skeleton(skeleton: Skeleton, frames: np.ndarray, fps: float) -> Skeleton:
    """``skeleton`` with its bone lengths and rest directions turned to where ``frames`` (N, J, 3) hold
    the bones on average, one depth at a time, so that inverse kinematics solves small rotations: a rest
    pose whose bone points against the data's (a leg rest along +x, seen along −x) leaves shortest-arc
    rotations near π, whose axis, and with it the exponential map, flips from frame to frame."""
    offsets = np.array(skeleton.offsets, dtype=np.float64)
    parents = np.asarray(skeleton.parents)
    depth = np.zeros(len(parents), dtype=int)
    for j, p in enumerate(parents):
        depth[j] = 0 if p < 0 else depth[p] + 1
    for level in range(1, int(depth.max())):
        rest = Skeleton(skeleton.names, skeleton.parents, offsets)
        _, local, _, _ = joints_to_rotations(Motion(np.asarray(frames, np.float32), fps, rest))
        for j in np.flatnonzero(depth == level):
            kids = [c for c in skeleton.children(j) if np.linalg.norm(offsets[c]) > 0]
            turn = Rotation.from_quat(local[:, j], scalar_first=True)
            if len(kids) == 1:
                seen = turn.apply(offsets[kids[0]]).mean(axis=0)
                offsets[kids[0]] = seen / np.linalg.norm(seen) * np.linalg.norm(offsets[kids[0]])
            elif kids:
                offsets[kids] = turn.mean().apply(offsets[kids])
    return Skeleton(skeleton.names, skeleton.parents, offsets)


def pose_features(
    local: np.ndarray, yaw: np.ndarray, root_pos: np.ndarray, contacts: np.ndarray
) -> np.ndarray:
    """(T, F) float32 features of ``solve_pose``'s output and the contact labels (T, F_feet)."""
    t = len(local)
    rotvecs = Rotation.from_quat(local.reshape(-1, 4), scalar_first=True).as_rotvec()
    step = np.diff(root_pos, axis=0, prepend=root_pos[:1])
    local_step = Rotation.from_euler("y", -yaw[:, None]).apply(step)
    root = np.stack([np.diff(yaw, prepend=yaw[:1]), local_step[:, 0], local_step[:, 2], root_pos[:, 1]], 1)
    return np.concatenate([root, rotvecs.reshape(t, -1), contacts], axis=1).astype(np.float32)


def motion_features(
    joints: np.ndarray, fps: float, skeleton: Skeleton, rest: np.ndarray
) -> tuple[np.ndarray, float, np.ndarray]:
    """(T, F) float32 features of joint positions (T, J, 3) (floor y = 0) on ``skeleton``, with the
    heading (radians) and floor position (x, z) of its first frame, which ``feature_joints`` takes back;
    ``rest`` (F,) are the foot joints' resting heights for the contact labels."""
    local, yaw, root_pos = solve_pose(joints, fps, skeleton)
    contacts = contact_labels(joints, fps, foot_joints(skeleton), rest)
    features = pose_features(local, yaw, root_pos, contacts)
    return features, float(yaw[0]), root_pos[0, [0, 2]].astype(np.float64)


def feature_joints(
    features: np.ndarray,
    skeleton: Skeleton,
    heading: float = 0.0,
    start: np.ndarray | None = None,
) -> tuple[np.ndarray, np.ndarray]:
    """Joint positions (T, J, 3) float32 and contact values (T, F) of features (T, F) on ``skeleton``.

    The root starts at ``start`` (x, z; default the origin) facing ``heading`` (radians about y) before
    the first frame's step and turn are applied.
    """
    x = np.asarray(features, dtype=np.float64)
    t, j = len(x), skeleton.n_joints
    yaw = heading + np.cumsum(x[:, 0])
    steps = Rotation.from_euler("y", yaw[:, None]).apply(np.stack([x[:, 1], np.zeros(t), x[:, 2]], axis=1))
    root = np.cumsum(steps, axis=0)
    if start is not None:  # the first frame's step is zero in real data: frame 0 sits at ``start``
        root[:, [0, 2]] += np.asarray(start, dtype=np.float64)[None]
    root[:, 1] = x[:, 3]
    rotvecs = x[:, ROOT_FEATURES : ROOT_FEATURES + 3 * j].reshape(t, j, 3)
    rotations = Rotation.from_rotvec(rotvecs.reshape(-1, 3))
    root_rot = Rotation.from_euler("y", yaw[:, None]) * rotations[np.arange(t) * j + skeleton.root]
    quats = rotations.as_quat(scalar_first=True).reshape(t, j, 4)
    quats[:, skeleton.root] = root_rot.as_quat(scalar_first=True)
    offsets = np.array(skeleton.offsets, dtype=np.float64)
    offsets[skeleton.root] = 0.0
    fixed = Skeleton(skeleton.names, skeleton.parents, offsets)
    joints = forward_kinematics(fixed, quats, root).astype(np.float32)
    return joints, x[:, ROOT_FEATURES + 3 * j :].astype(np.float32)
