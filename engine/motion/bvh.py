"""BVH motion files: a tolerant, validating reader and a writer of the subset every importer reads.

Reading
-------
- Each joint may list any channels in any order; the listed rotation channels are intrinsic Euler
  angles in degrees (``Zrotation Xrotation Yrotation`` means R = Rz @ Rx @ Ry).
- Position channels on any joint replace that joint's OFFSET (axes without a channel keep it).
- ``joints`` always reproduce the file's forward kinematics exactly, using per-frame local
  translations. ``Skeleton.offsets`` are the frame-0 local translations (the OFFSET where a joint has
  no position channel). ``local_rotations`` and ``root_translation`` are kept only when they and the
  skeleton alone reproduce ``joints``: when a non-root joint's position channels vary over the clip
  by more than 1e-6 m (the Bandai-Namco ``Hips`` under a static ``joint_Root``), both are None and
  ``meta["varying_translation_joints"]`` names the joints; consumers then work from ``joints``.
- Units: ``units="auto"`` takes the median non-zero bone length L of frame 0 (raw file units):
  L < 1 is metres, L < 100 centimetres, otherwise millimetres. ``units`` or ``scale`` override it.
- Up axis: BVH is Y-up, but some tools write Z-up files: ``up_axis="z"`` turns one into Y-up
  ((x, y, z) → (x, z, −y), rotations conjugated; see ``engine.motion.axes``). Nothing is turned
  silently: ``odmo info`` and ``odmo convert`` only say when a body read as Y-up stands along z.

Writing
-------
One ROOT with ``Xposition Yposition Zposition`` + 3 rotations, 3 rotation channels in one fixed order
on every other joint, joints depth-first, names sanitised and de-duplicated, an End Site under every
leaf, values in metres by default (Blender's importer keeps the units as written, and its metre is
ours), ``Frame Time`` with 10 significant digits, written atomically.
"""

from __future__ import annotations

import json
import logging
import re
import warnings
from collections.abc import Sequence
from dataclasses import dataclass, field
from itertools import chain
from pathlib import Path
from typing import Any

import numpy as np

from engine.errors import ConfigError, MotionFormatError
from engine.fileio import atomic_write_text
from engine.limits import read_bytes
from engine.motion.axes import check_up_axis, to_y_up
from engine.motion.motion import Motion
from engine.motion.rotations import euler_to_quat, forward_kinematics, quat_continuity, quat_to_euler
from engine.motion.skeleton import Skeleton, sanitize_name

log = logging.getLogger(__name__)

UNITS_TO_M = {"m": 1.0, "cm": 0.01, "mm": 0.001, "in": 0.0254}
_POSITION = {"XPOSITION": 0, "YPOSITION": 1, "ZPOSITION": 2}
_ROTATION = {"XROTATION": "X", "YROTATION": "Y", "ZROTATION": "Z"}
_MIN_FRAME_TIME, _MAX_FRAME_TIME = 1e-4, 10.0
_CONSTANT_TRANSLATION_M = 1e-6
_STRETCH_TOLERANCE_M = 0.01  # a root bone changing length by more than this is not a bone
_FRAMES_RE = re.compile(r"^\s*frames\s*:\s*(\S+)\s*$", re.IGNORECASE)
_FRAME_TIME_RE = re.compile(r"^\s*frame\s+time\s*:\s*(\S+)\s*$", re.IGNORECASE)


@dataclass
class _Node:
    """A JOINT/ROOT (``name`` set) or an End Site (``name`` None) while the hierarchy is parsed."""

    name: str | None
    parent: int
    line: int
    offset: tuple[float, float, float] | None = None
    channels: list[str] = field(default_factory=list)
    has_channels: bool = False


class _Tokens:
    """Whitespace-separated hierarchy tokens with their 1-based line numbers."""

    def __init__(self, lines: Sequence[str], path: str, end_line: int):
        self.items = [(tok, no) for no, line in enumerate(lines, 1) for tok in line.split()]
        self.pos = 0
        self.path = path
        self.end_line = end_line

    def next(self, what: str) -> tuple[str, int]:
        """The next token, or an error naming ``what`` was expected when the hierarchy ends."""
        if self.pos >= len(self.items):
            raise MotionFormatError(f"hierarchy ends early: expected {what}", self.path, self.end_line)
        item = self.items[self.pos]
        self.pos += 1
        return item

    def name(self, what: str) -> tuple[str, int]:
        """A joint name: the rest of its line up to a '{' (3ds Max writes names such as "Bip01 L Thigh")."""
        tok, line = self.next(what)
        parts = [tok]
        while (
            self.pos < len(self.items) and self.items[self.pos][1] == line and self.items[self.pos][0] != "{"
        ):
            parts.append(self.items[self.pos][0])
            self.pos += 1
        return " ".join(parts), line

    def expect(self, keyword: str) -> int:
        """Consume ``keyword`` (case-insensitive) and return its line."""
        tok, line = self.next(repr(keyword))
        if tok.upper() != keyword.upper():
            raise MotionFormatError(f"expected {keyword!r}, found {tok!r}", self.path, line)
        return line

    def number(self, what: str) -> float:
        """The next token as a finite float."""
        tok, line = self.next(what)
        try:
            value = float(tok)
        except ValueError:
            raise MotionFormatError(f"expected a number for {what}, found {tok!r}", self.path, line) from None
        if not np.isfinite(value):
            raise MotionFormatError(f"{what} must be finite, found {tok!r}", self.path, line)
        return value


def read_bvh(path: str | Path, units: str = "auto", scale: float | None = None, up_axis: str = "y") -> Motion:
    """Read a BVH file into a Motion in metres, Y up (see the module docstring for the conventions)."""
    try:
        data = read_bytes(path, "BVH file")
    except OSError as exc:
        raise MotionFormatError(f"cannot read the file: {exc.strerror or exc}", path) from None
    return parse_bvh_text(_decode(data, str(path)), str(path), units=units, scale=scale, up_axis=up_axis)


def parse_bvh_text(
    text: str,
    path: str = "<string>",
    units: str = "auto",
    scale: float | None = None,
    up_axis: str = "y",
) -> Motion:
    """Parse the text of a BVH file into a Motion in metres, Y up; ``path`` only names it in errors."""
    if units not in UNITS_TO_M and units != "auto":
        raise ConfigError(f"units must be 'auto' or one of {', '.join(UNITS_TO_M)}, got {units!r}")
    check_up_axis(up_axis)
    if scale is not None and not (np.isfinite(scale) and scale > 0):
        raise ConfigError(f"scale must be a positive number, got {scale!r}")
    if "\x00" in text:
        line = text.count("\n", 0, text.index("\x00")) + 1
        raise MotionFormatError("binary data (NUL byte) in a text file", path, line)
    lines = text.replace("\r\n", "\n").replace("\r", "\n").split("\n")
    motion_at = next((i for i, line in enumerate(lines) if line.strip().upper() == "MOTION"), None)
    if motion_at is None:
        raise MotionFormatError("no MOTION section (empty or truncated file)", path, len(lines))
    nodes = _parse_hierarchy(lines[:motion_at], path, motion_at + 1)
    joints = [n for n in nodes if n.name is not None]
    n_channels = sum(len(n.channels) for n in joints)
    if n_channels == 0:
        raise MotionFormatError("the hierarchy declares no channels", path, motion_at + 1)
    frames, frame_time, data_start = _parse_motion_header(lines, motion_at, path)
    values = _parse_frames(lines, data_start, frames, n_channels, path)
    return to_y_up(_build_motion(nodes, values, frame_time, path, units, scale), up_axis)


def _decode(data: bytes, path: str) -> str:
    """UTF-8 text of ``data`` (a BOM is dropped); binary data raises MotionFormatError."""
    if b"\x00" in data:
        raise MotionFormatError(
            "binary data (NUL byte) in a text file", path, data.count(b"\n", 0, data.index(b"\x00")) + 1
        )
    try:
        return data.decode("utf-8-sig")
    except UnicodeDecodeError as exc:
        line = data.count(b"\n", 0, exc.start) + 1
        raise MotionFormatError("not UTF-8 text (binary or mis-encoded data)", path, line) from None


def _parse_hierarchy(lines: Sequence[str], path: str, motion_line: int) -> list[_Node]:
    """Nodes (joints and End Sites) in file order; parents precede children."""
    toks = _Tokens(lines, path, motion_line)
    toks.expect("HIERARCHY")
    toks.expect("ROOT")
    nodes: list[_Node] = []
    seen: set[str] = set()
    stack: list[int] = []

    def open_node(name: str | None, line: int) -> None:
        if name is not None:
            if name in seen:
                raise MotionFormatError(f"duplicate joint name {name!r}", path, line)
            seen.add(name)
        parent = stack[-1] if stack else -1
        nodes.append(_Node(name, parent, line))
        toks.expect("{")
        stack.append(len(nodes) - 1)

    name, line = toks.name("the root joint's name")
    open_node(name, line)
    while stack:
        node = nodes[stack[-1]]
        tok, line = toks.next("'}'")
        key = tok.upper()
        if key == "OFFSET":
            if node.offset is not None:
                raise MotionFormatError("second OFFSET in one block", path, line)
            node.offset = (toks.number("OFFSET"), toks.number("OFFSET"), toks.number("OFFSET"))
        elif key == "CHANNELS" and node.name is not None:
            _read_channels(toks, node, line)
        elif key == "JOINT" and node.name is not None:
            name, line = toks.name("a joint name")
            open_node(name, line)
        elif key == "END" and node.name is not None:
            toks.expect("Site")
            open_node(None, line)
        elif key == "}":
            _check_closed(node, path, line)
            stack.pop()
        else:
            raise MotionFormatError(f"unexpected {tok!r} in the hierarchy", path, line)
    if toks.pos < len(toks.items):
        tok, line = toks.items[toks.pos]
        what = "only one ROOT is supported" if tok.upper() == "ROOT" else f"stray {tok!r} after the hierarchy"
        raise MotionFormatError(what, path, line)
    return nodes


def _read_channels(toks: _Tokens, node: _Node, line: int) -> None:
    """Read ``CHANNELS n name...`` into ``node``."""
    if node.has_channels:
        raise MotionFormatError("second CHANNELS in one joint", toks.path, line)
    tok, line = toks.next("the channel count")
    if not tok.isdigit() or int(tok) > 6:
        raise MotionFormatError(f"channel count must be 0-6, found {tok!r}", toks.path, line)
    for _ in range(int(tok)):
        name, line = toks.next("a channel name")
        key = name.upper()
        if key not in _POSITION and key not in _ROTATION:
            raise MotionFormatError(f"unknown channel {name!r}", toks.path, line)
        if key in node.channels:
            raise MotionFormatError(f"channel {name!r} listed twice", toks.path, line)
        node.channels.append(key)
    node.has_channels = True


def _check_closed(node: _Node, path: str, line: int) -> None:
    """A block being closed must have had its OFFSET (and CHANNELS, for a joint)."""
    what = "End Site" if node.name is None else f"joint {node.name!r}"
    if node.offset is None:
        raise MotionFormatError(f"{what} has no OFFSET", path, line)
    if node.name is not None and not node.has_channels:
        raise MotionFormatError(f"{what} has no CHANNELS", path, line)


def _parse_motion_header(lines: Sequence[str], motion_at: int, path: str) -> tuple[int, float, int]:
    """(frames, frame time, index of the first data line) from the lines after MOTION."""
    i = motion_at + 1
    found = []
    for regex, what in ((_FRAMES_RE, "Frames:"), (_FRAME_TIME_RE, "Frame Time:")):
        while i < len(lines) and not lines[i].strip():
            i += 1
        match = regex.match(lines[i]) if i < len(lines) else None
        if match is None:
            raise MotionFormatError(f"expected a {what!r} line", path, min(i, len(lines) - 1) + 1)
        found.append((match.group(1), i + 1))
        i += 1
    (frames_tok, frames_line), (time_tok, time_line) = found
    if not frames_tok.isdigit():
        raise MotionFormatError(
            f"frame count must be a whole number, found {frames_tok!r}", path, frames_line
        )
    frames = int(frames_tok)
    if frames == 0:
        raise MotionFormatError("the file has zero frames", path, frames_line)
    try:
        frame_time = float(time_tok)
    except ValueError:
        raise MotionFormatError(f"frame time must be a number, found {time_tok!r}", path, time_line) from None
    if not _MIN_FRAME_TIME <= frame_time <= _MAX_FRAME_TIME:
        raise MotionFormatError(
            f"frame time must be in [{_MIN_FRAME_TIME}, {_MAX_FRAME_TIME}] s, found {time_tok!r}",
            path,
            time_line,
        )
    return frames, frame_time, i


def _parse_frames(lines: Sequence[str], start: int, frames: int, n_channels: int, path: str) -> np.ndarray:
    """(frames, n_channels) values of the data lines from ``lines[start]`` on."""
    end = len(lines)
    while end > start and not lines[end - 1].strip():
        end -= 1
    rows = lines[start:end]
    if len(rows) < frames:
        raise MotionFormatError(
            f"Frames: says {frames} but the file has {len(rows)} motion lines", path, end + 1
        )
    if len(rows) > frames:
        raise MotionFormatError(f"more motion lines than Frames: {frames}", path, start + frames + 1)
    split = [row.split() for row in rows]
    counts = np.fromiter(map(len, split), dtype=np.int64, count=len(split))
    bad = np.flatnonzero(counts != n_channels)
    if bad.size:
        k = int(bad[0])
        raise MotionFormatError(f"expected {n_channels} values, found {counts[k]}", path, start + k + 1)
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", DeprecationWarning)  # older numpy warns at a bad token
            values = np.fromstring("\n".join(rows), dtype=np.float64, sep=" ")
    except ValueError:  # newer numpy raises there
        values = np.zeros(0)
    if values.size != frames * n_channels:
        bad_token = _first_bad_number(split)
        if bad_token is not None:
            raise MotionFormatError(f"not a number: {bad_token[1]!r}", path, start + bad_token[0] + 1)
        # Forms Python reads but C's strtod does not (e.g. "1_000"): parse them the slow way.
        values = np.array([float(tok) for tok in chain.from_iterable(split)], dtype=np.float64)
    values = values.reshape(frames, n_channels)
    finite = np.isfinite(values)
    if not finite.all():
        k = int(np.flatnonzero(~finite.all(axis=1))[0])
        raise MotionFormatError("non-finite value (nan or inf) in the motion data", path, start + k + 1)
    return values


def _first_bad_number(split: Sequence[Sequence[str]]) -> tuple[int, str] | None:
    """(row index, token) of the first token that is not a number, or None."""
    for k, row in enumerate(split):
        for tok in row:
            try:
                float(tok)
            except ValueError:
                return k, tok
    return None


def _build_motion(
    nodes: list[_Node], values: np.ndarray, frame_time: float, path: str, units: str, scale: float | None
) -> Motion:
    """Forward kinematics of the parsed channels; the Motion in metres."""
    joint_of = {}
    joints: list[_Node] = []
    sites: list[tuple[int, tuple[float, float, float]]] = []
    for k, node in enumerate(nodes):
        if node.name is None:
            sites.append((joint_of[node.parent], node.offset))
        else:
            joint_of[k] = len(joints)
            joints.append(node)
    T, J = values.shape[0], len(joints)
    parents = np.array([-1 if n.parent < 0 else joint_of[n.parent] for n in joints])
    trans = np.empty((T, J, 3))
    trans[:] = np.array([n.offset for n in joints])
    quats = np.zeros((T, J, 4))
    quats[..., 0] = 1.0
    by_order: dict[str, tuple[list[int], list[list[int]]]] = {}
    col = 0
    for j, node in enumerate(joints):
        rot_cols = []
        order = ""
        for c, key in enumerate(node.channels, start=col):
            if key in _POSITION:
                trans[:, j, _POSITION[key]] = values[:, c]
            else:
                rot_cols.append(c)
                order += _ROTATION[key]
        col += len(node.channels)
        if order:
            members, cols = by_order.setdefault(order, ([], []))
            members.append(j)
            cols.append(rot_cols)
    for order, (members, cols) in by_order.items():
        quats[:, members] = euler_to_quat(values[:, np.array(cols)], order)

    factor, detected = _unit_factor(trans[0], parents, units, scale)
    trans *= factor
    skeleton = Skeleton(
        tuple(n.name for n in joints),
        parents,
        trans[0],
        tuple((p, tuple(v * factor for v in off)) for p, off in sites),
        "m",
    )
    root = skeleton.root
    root_translation = trans[:, root].copy()
    positions = forward_kinematics(skeleton, quats, root_translation, trans)
    if not np.all(np.isfinite(positions)) or np.abs(positions).max() > 1e9:
        raise MotionFormatError("values too large: joint positions overflow", path)
    spread = np.ptp(trans, axis=0).max(axis=1)
    spread[root] = 0.0
    varying = [skeleton.names[j] for j in np.flatnonzero(spread > _CONSTANT_TRANSLATION_M)]
    meta: dict[str, Any] = {"source": path, "units_detected": detected, "scale_to_m": factor}
    if varying:
        log.debug("%s: position channels vary on %s; keeping joints only", path, ", ".join(varying))
        meta["varying_translation_joints"] = varying
        quats, root_translation = None, None
    return Motion(positions, 1.0 / frame_time, skeleton, quats, root_translation, meta=meta)


def _unit_factor(
    translations: np.ndarray, parents: np.ndarray, units: str, scale: float | None
) -> tuple[float, str]:
    """(factor to metres, unit name) from the caller's choice or the median bone length."""
    if scale is not None:
        return float(scale), "scale"
    if units != "auto":
        return UNITS_TO_M[units], units
    lengths = np.linalg.norm(translations[parents >= 0], axis=1)
    lengths = lengths[lengths > 1e-9]
    median = float(np.median(lengths)) if lengths.size else 0.0
    detected = "m" if median < 1.0 else "cm" if median < 100.0 else "mm"
    return UNITS_TO_M[detected], detected


#: Metadata of a generated motion kept beside its BVH (BVH has no comment syntax importers agree on).
PROVENANCE_KEYS = ("model", "model_sha256", "code", "seed", "action", "mode", "end", "tool_version")
PROVENANCE_FORMAT = "odmo-provenance"


def provenance_path(path: str | Path) -> Path:
    """The provenance sidecar of a BVH file: ``walk.bvh`` → ``walk.bvh.json``."""
    return Path(f"{path}.json")


def write_bvh(
    path: str | Path, motion: Motion, rotation_order: str = "ZXY", *, units: str = "m"
) -> dict[str, Any]:
    """Write ``motion`` to a BVH file atomically; returns the report of :func:`format_bvh`.

    A generated motion (its ``meta`` names a model or a code) also gets ``provenance_path(path)``: JSON
    with the model, code, seed, action, mode and end location that made it, which ``odmo info`` shows.
    """
    text, report = format_bvh(motion, rotation_order, units=units)
    atomic_write_text(path, text)
    report["path"] = str(path)
    if "model" in motion.meta or "code" in motion.meta:
        from engine import __version__

        facts = {k: motion.meta[k] for k in PROVENANCE_KEYS if k in motion.meta}
        record = {"format": PROVENANCE_FORMAT, "file": Path(path).name, "tool_version": __version__} | facts
        atomic_write_text(provenance_path(path), json.dumps(record, indent=2) + "\n")
        report["provenance"] = str(provenance_path(path))
    return report


def format_bvh(
    motion: Motion, rotation_order: str = "ZXY", *, units: str = "m"
) -> tuple[str, dict[str, Any]]:
    """BVH text of ``motion`` and a report (``fk_error_m``: mean joint distance of the file's FK)."""
    order = rotation_order.upper()
    if sorted(order) != ["X", "Y", "Z"]:
        raise ConfigError(f"rotation order must be a permutation of XYZ, got {rotation_order!r}")
    if units not in UNITS_TO_M:
        raise ConfigError(f"units must be one of {', '.join(UNITS_TO_M)}, got {units!r}")
    dropped = None
    if motion.local_rotations is None:
        from engine.motion.ik import joints_to_rotations

        motion, dropped = _without_stretching_root(motion)
        skeleton, rotations, root_translation, _ = joints_to_rotations(motion)
        source = "ik"
    else:
        skeleton, rotations = motion.skeleton, motion.local_rotations
        root_translation = motion.root_translation
        if root_translation is None:
            root_translation = motion.joints[:, skeleton.root].astype(np.float64)
        source = "rotations"
    if not (np.all(np.isfinite(rotations)) and np.all(np.isfinite(root_translation))):
        raise ConfigError("cannot write non-finite rotations or translations to BVH")
    error = np.linalg.norm(forward_kinematics(skeleton, rotations, root_translation) - motion.joints, axis=-1)
    angles = quat_to_euler(quat_continuity(rotations), order)
    to_units = 1.0 / UNITS_TO_M[units]
    order_dfs = _depth_first(skeleton)
    columns = [root_translation * to_units] + [angles[:, j] for j in order_dfs]
    data = np.concatenate(columns, axis=1)
    if not np.all(np.isfinite(data)):
        raise ConfigError("cannot write non-finite values to BVH")
    names = _unique_names(skeleton.names)
    header = _format_hierarchy(skeleton, names, order, to_units)
    row_format = " ".join(["%.6f"] * data.shape[1])
    body = "\n".join(row_format % tuple(row) for row in data.tolist())
    text = f"{header}MOTION\nFrames: {motion.n_frames}\nFrame Time: {1.0 / motion.fps:.10g}\n{body}\n"
    report = {
        "fk_error_m": float(error.mean()),
        "fk_max_error_m": float(error.max()),
        "rotations_from": source,
        "rotation_order": order,
        "units": units,
        "frames": motion.n_frames,
        "joints": skeleton.n_joints,
        "renamed": {old: new for old, new in zip(skeleton.names, names, strict=True) if old != new},
        "dropped_root": dropped,
    }
    return text, report


def _without_stretching_root(motion: Motion) -> tuple[Motion, str | None]:
    """``motion`` without its root joint, and the root's name, when the root has one child and that bone
    changes length (a ground projection such as Bandai's ``joint_Root``): fixed-length bones cannot
    carry it, its child becomes the BVH ROOT instead. Otherwise ``motion`` unchanged and None."""
    skel = motion.skeleton
    root = skel.root
    children = skel.children(root)
    if len(children) != 1:
        return motion, None
    length = np.linalg.norm(motion.joints[:, children[0]] - motion.joints[:, root], axis=-1)
    if np.ptp(length) <= _STRETCH_TOLERANCE_M:
        return motion, None
    return motion.without_joints([skel.names[root]]), skel.names[root]


def _depth_first(skeleton: Skeleton) -> list[int]:
    """Joint indices in the order a BVH hierarchy lists them."""
    out: list[int] = []
    stack = [skeleton.root]
    while stack:
        j = stack.pop()
        out.append(j)
        stack.extend(reversed(skeleton.children(j)))
    return out


def _unique_names(names: Sequence[str]) -> list[str]:
    """Sanitised names, suffixed ``_2``, ``_3``... where sanitising makes two equal."""
    out: list[str] = []
    taken: set[str] = set()
    for name in names:
        base = candidate = sanitize_name(name)
        k = 2
        while candidate in taken:
            candidate = f"{base}_{k}"
            k += 1
        taken.add(candidate)
        out.append(candidate)
    return out


def _format_hierarchy(skeleton: Skeleton, names: Sequence[str], order: str, to_units: float) -> str:
    """The HIERARCHY section, braces on their own lines, tab-indented."""
    rotation_channels = " ".join(f"{axis}rotation" for axis in order)
    sites: dict[int, list[np.ndarray]] = {}
    for parent, offset in skeleton.end_sites:
        sites.setdefault(parent, []).append(np.asarray(offset, dtype=np.float64))
    out = ["HIERARCHY"]

    def vec(v: np.ndarray) -> str:
        return " ".join(f"{x * to_units:.6f}" for x in v)

    def emit(j: int, depth: int) -> None:
        pad = "\t" * depth
        if skeleton.parents[j] < 0:
            out.extend([f"ROOT {names[j]}", "{", f"\tOFFSET {vec(np.zeros(3))}"])
            out.append(f"\tCHANNELS 6 Xposition Yposition Zposition {rotation_channels}")
        else:
            out.extend([f"{pad}JOINT {names[j]}", f"{pad}{{", f"{pad}\tOFFSET {vec(skeleton.offsets[j])}"])
            out.append(f"{pad}\tCHANNELS 3 {rotation_channels}")
        kids = skeleton.children(j)
        for c in kids:
            emit(c, depth + 1)
        # Every leaf gets an End Site (half its own bone, so importers draw a visible leaf bone).
        leaf_sites = sites.get(j) or ([] if kids else [0.5 * skeleton.offsets[j]])
        for offset in leaf_sites:
            out.extend([f"{pad}\tEnd Site", f"{pad}\t{{", f"{pad}\t\tOFFSET {vec(offset)}", f"{pad}\t}}"])
        out.append(f"{pad}}}")

    emit(skeleton.root, 0)
    return "\n".join(out) + "\n"
