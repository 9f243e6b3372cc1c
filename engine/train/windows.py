"""Training windows: resampled clips, T-frame crops, origin shift and canonical facing."""

from __future__ import annotations

import hashlib
import logging
import re
from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from scipy.spatial.transform import Rotation

from engine.errors import DataError
from engine.motion.motion import Motion
from engine.motion.resample import resample_motion
from engine.motion.skeleton import Skeleton

log = logging.getLogger(__name__)

_SIDE_PATTERNS = (
    (re.compile(r"left", re.IGNORECASE), "L"),
    (re.compile(r"right", re.IGNORECASE), "R"),
    (re.compile(r"(?:(?<=^)|(?<=[_.:\- ]))[lL](?=$|[_.:\- ])"), "L"),
    (re.compile(r"(?:(?<=^)|(?<=[_.:\- ]))[rR](?=$|[_.:\- ])"), "R"),
    (re.compile(r"(?:(?<=^)|(?<=[_.:\- ]))L(?=[A-Z])"), "L"),
    (re.compile(r"(?:(?<=^)|(?<=[_.:\- ]))R(?=[A-Z])"), "R"),
)
_HIP_WORDS = ("hip", "upleg", "upperleg", "thigh", "leg")
_SHOULDER_WORDS = ("shoulder", "clavicle", "collar", "upperarm", "uparm", "arm")


def _side_and_stem(name: str) -> tuple[str, str] | None:
    """("L" or "R", the name without its side marker, lower-case) or None for a central joint."""
    for pattern, side in _SIDE_PATTERNS:
        stem, n = pattern.subn("", name, count=1)
        if n:
            return side, re.sub(r"[_.:\- ]", "", stem).lower()
    return None


def left_right_pairs(skeleton: Skeleton) -> list[tuple[int, int]]:
    """(left, right) joint index pairs used to measure facing: hips and shoulders when named so.

    Pairs are found by name (Left/Right, _L/_R, L_/R_, LHip/RHip …); hip-like and shoulder-like pairs
    are preferred, any mirrored pair is used otherwise. Without mirrored names the fallback is the rest
    pose: its most +x and most −x joints (BVH rest poses face +z, so +x is the left side).
    """
    sides: dict[str, dict[str, int]] = {}
    for j, name in enumerate(skeleton.names):
        found = _side_and_stem(name)
        if found is not None:
            sides.setdefault(found[1], {}).setdefault(found[0], j)
    pairs = {stem: (d["L"], d["R"]) for stem, d in sides.items() if "L" in d and "R" in d}
    preferred = []
    for words in (_HIP_WORDS, _SHOULDER_WORDS):
        match = next((s for w in words for s in sorted(pairs) if w in s), None)
        if match is not None:
            preferred.append(pairs[match])
    if preferred:
        return preferred
    if pairs:
        return list(pairs.values())
    rest = skeleton.rest_positions()
    log.info("no left/right joint names in the skeleton; measuring facing from the rest pose")
    return [(int(np.argmax(rest[:, 0])), int(np.argmin(rest[:, 0])))]


def _facing_yaw(frame0: np.ndarray, pairs: Sequence[tuple[int, int]]) -> np.ndarray:
    """Yaw (B,) of the facing direction (left-right vector × up) of frames (B, J, 3); 0 when undefined."""
    left = np.array([p[0] for p in pairs])
    right = np.array([p[1] for p in pairs])
    lr = (frame0[:, left] - frame0[:, right]).sum(axis=1)
    fwd_x, fwd_z = -lr[:, 2], lr[:, 0]
    yaw = np.arctan2(fwd_x, fwd_z)
    return np.where(np.hypot(fwd_x, fwd_z) > 1e-9, yaw, 0.0)


def _yaw_matrices(yaw: np.ndarray) -> np.ndarray:
    """(B, 3, 3) rotations by ``yaw`` (B,) about +y."""
    return Rotation.from_euler("y", np.asarray(yaw, dtype=np.float64)[:, None]).as_matrix()


def _canonical(windows: np.ndarray, root: int, pairs: Sequence[tuple[int, int]]) -> tuple[np.ndarray, ...]:
    """Canonical windows (B, T, J, 3), origins (B, 3) and yaws (B,) of windows (B, T, J, 3)."""
    origin = windows[:, 0, root].astype(np.float64)
    yaw = _facing_yaw(windows[:, 0], pairs)
    inverse = _yaw_matrices(-yaw)
    shifted = windows - origin[:, None, None, :]
    canon = np.einsum("bij,btkj->btki", inverse, shifted).astype(np.float32)
    return canon, origin, yaw


def canonicalize(joints: np.ndarray, skeleton: Skeleton) -> tuple[np.ndarray, float]:
    """Joints (T, J, 3) with the frame-0 root at the origin and the frame-0 body facing +z; and the yaw.

    The yaw (radians, about +y) is the original facing: rotating the result by it and adding the
    frame-0 root restores ``joints``.
    """
    canon, _, yaw = _canonical(np.asarray(joints)[None], skeleton.root, left_right_pairs(skeleton))
    return canon[0], float(yaw[0])


@dataclass
class PreparedClips:
    """Clips resampled to the model frame rate, ready for cropping.

    Parameters
    ----------
    joints : per clip, (T_i, J, 3) float32 positions at ``fps``.
    actions : (N,) int action index of each clip (into ``action_names``).
    action_names : the action vocabulary.
    sources : per clip, where it came from (``meta["source"]``, ``meta["path"]`` or ``clip{i}``).
    meta : per clip metadata (style …; never used in training).
    skeleton : the skeleton shared by every clip.
    fps : frame rate of ``joints``.
    window : window length T.
    pairs : (left, right) joint pairs that define the facing (see ``left_right_pairs``).
    """

    joints: list[np.ndarray]
    actions: np.ndarray
    action_names: list[str]
    sources: list[str]
    meta: list[dict[str, Any]]
    skeleton: Skeleton
    fps: float
    window: int
    pairs: list[tuple[int, int]] = field(default_factory=list)

    @property
    def n_clips(self) -> int:
        """Number of clips N."""
        return len(self.joints)

    @property
    def lengths(self) -> np.ndarray:
        """(N,) frame count of each clip."""
        return np.array([len(j) for j in self.joints], dtype=np.int64)

    def fingerprint(self) -> str:
        """SHA-256 of the prepared data (positions, actions, names, fps, window)."""
        h = hashlib.sha256()
        h.update(repr((self.action_names, self.skeleton.names, self.fps, self.window)).encode())
        h.update(self.actions.astype(np.int64).tobytes())
        for j in self.joints:
            h.update(np.ascontiguousarray(j).tobytes())
        return h.hexdigest()


@dataclass
class WindowBatch:
    """A batch of canonical T-frame windows.

    Parameters
    ----------
    joints : (B, T, J, 3) float32, frame-0 root at the origin, facing +z; padded with the last frame.
    mask : (B, T) bool, True for real frames.
    actions : (B,) int64 action indices.
    indices : (B,) clip indices; starts : (B,) first frame of each window in its clip.
    origin : (B, 3) frame-0 root position in the clip's coordinates; yaw : (B,) its facing (radians).
    root : index of the root joint.
    """

    joints: np.ndarray
    mask: np.ndarray
    actions: np.ndarray
    indices: np.ndarray
    starts: np.ndarray
    origin: np.ndarray
    yaw: np.ndarray
    root: int

    @property
    def trajectory(self) -> np.ndarray:
        """(B, T, 3) root path."""
        return self.joints[:, :, self.root]

    @property
    def lmp(self) -> np.ndarray:
        """(B, T, J·3) local movement profile: joints minus root."""
        local = self.joints - self.joints[:, :, self.root : self.root + 1]
        return local.reshape(local.shape[0], local.shape[1], -1)

    @property
    def ends(self) -> np.ndarray:
        """(B, 3) root position at each window's last real frame."""
        last = self.mask.sum(axis=1) - 1
        return self.trajectory[np.arange(len(last)), last]

    def restore(self, joints: np.ndarray) -> np.ndarray:
        """Canonical joints (B, T, J, 3) back in the clips' coordinates (undo rotation, then shift)."""
        rotated = np.einsum("bij,btkj->btki", _yaw_matrices(self.yaw), joints)
        return (rotated + self.origin[:, None, None, :]).astype(np.float32)


def prepare_clips(clips: Sequence[Motion], action_names: list[str], fps: float, window: int) -> PreparedClips:
    """Resample every clip to ``fps`` and check labels and skeletons."""
    if not clips:
        raise DataError("no clips to train on")
    skeleton = clips[0].skeleton
    names = list(action_names)
    actions, joints, sources, metas = [], [], [], []
    for i, clip in enumerate(clips):
        source = str(clip.meta.get("source", clip.meta.get("path", f"clip{i}")))
        if clip.action not in names:
            raise DataError(f"{source}: action {clip.action!r} is not one of {names}")
        if not clip.skeleton.same_topology(skeleton):
            raise DataError(f"{source}: skeleton differs from the first clip's")
        moved = clip if abs(clip.fps - fps) < 1e-6 else resample_motion(clip, fps)
        joints.append(np.ascontiguousarray(moved.joints, dtype=np.float32))
        actions.append(names.index(clip.action))
        sources.append(source)
        metas.append(dict(clip.meta))
    return PreparedClips(
        joints=joints,
        actions=np.array(actions, dtype=np.int64),
        action_names=names,
        sources=sources,
        meta=metas,
        skeleton=skeleton,
        fps=float(fps),
        window=int(window),
        pairs=left_right_pairs(skeleton),
    )


def crop_windows(
    prepared: PreparedClips, indices: Sequence[int] | np.ndarray, rng: np.random.Generator | None
) -> WindowBatch:
    """Canonical windows of clips ``indices``: a uniform random start (every start from 0 to T_i − T
    inclusive) drawn from ``rng``, or the centre crop when ``rng`` is None; short clips are padded."""
    indices = np.asarray(indices, dtype=np.int64)
    return windows_at(prepared, indices, crop_starts(prepared, indices, rng))


def crop_starts(
    prepared: PreparedClips, indices: Sequence[int] | np.ndarray, rng: np.random.Generator | None
) -> np.ndarray:
    """First frames of ``crop_windows``' windows of clips ``indices``: uniform from ``rng``, or centred."""
    last_start = np.maximum(prepared.lengths[np.asarray(indices, dtype=np.int64)] - prepared.window, 0)
    return last_start // 2 if rng is None else rng.integers(0, last_start + 1)


def every_window(prepared: PreparedClips, indices: Sequence[int] | np.ndarray, stride: int) -> np.ndarray:
    """(W, 2) (clip, start) of every window of clips ``indices``: starts 0, stride, … and the last one."""
    rows = []
    for i in np.asarray(indices, dtype=np.int64):
        last = max(int(prepared.lengths[i]) - prepared.window, 0)
        starts = np.unique(np.append(np.arange(0, last + 1, stride), last))
        rows.append(np.stack([np.full(len(starts), i), starts], axis=1))
    return np.concatenate(rows) if rows else np.zeros((0, 2), dtype=np.int64)


def windows_at(
    prepared: PreparedClips, indices: Sequence[int] | np.ndarray, starts: Sequence[int] | np.ndarray
) -> WindowBatch:
    """Canonical windows of clips ``indices`` starting at frames ``starts``; short clips are padded."""
    indices = np.asarray(indices, dtype=np.int64)
    starts = np.asarray(starts, dtype=np.int64)
    t = prepared.window
    lengths = prepared.lengths[indices]
    j = prepared.skeleton.n_joints
    raw = np.empty((len(indices), t, j, 3), dtype=np.float32)
    for b, (i, s) in enumerate(zip(indices, starts, strict=True)):
        clip = prepared.joints[i][s : s + t]
        raw[b, : len(clip)] = clip
        raw[b, len(clip) :] = clip[-1]
    mask = np.arange(t)[None, :] < np.minimum(lengths - starts, t)[:, None]
    root = prepared.skeleton.root
    canon, origin, yaw = _canonical(raw, root, prepared.pairs)
    return WindowBatch(canon, mask, prepared.actions[indices], indices, starts, origin, yaw, root)
