"""Dataset folders: labelled clips from a folder, with a content-hash cache of parsed clips.

Layouts
-------
- Bandai-Namco (detected by ``cfg/content_label.txt`` and ``data/*.bvh``): the action is the
  content name of each clip's JSON sidecar ``{"content": id, "style": id}`` (names from
  ``cfg/content_label.txt`` without the ``dataset-2_`` prefix, in id order); the style goes to
  ``meta["style"]`` only. ``drop_joints`` defaults to ``("joint_Root",)``, the ground-projected
  root, so clips have 21 body joints with ``Hips`` as root.
- HumanAct12 (``.npy`` files named like ``P01G01R01F0069T0143A0102.npy``): coarse class from the
  name (see :mod:`engine.motion.humanact12`), SMPL-24 skeleton, 20 fps.
- Any other folder of ``.bvh`` / ``.npz`` / ``.npy`` files: labels from ``pattern`` (a regex
  searched in the file name, with a named group ``action``; other named groups go to meta) or
  from a ``labels`` sidecar: CSV with a header ``file,action[,style,...]`` or JSON mapping a file
  name to an action or to ``{"action": ..., "style": ...}``. Clips without a label are skipped
  (logged); a folder with no labelled clip raises DataError.

Clips carry joint positions only (no local rotations). An unreadable clip raises DataError
naming the file (``on_error="raise"``, the default) or is skipped with a logged warning
(``on_error="skip"``). Parsed clips are cached in one file per folder under ``$ODMO_CACHE_DIR``
(default ``~/.cache/odmo-explorer``), keyed by each file's content hash. Each entry carries a CRC-32 of
its parsed content; an unreadable cache, or an entry that fails its check, is rebuilt from the source
files with a logged warning, never trusted.
"""

from __future__ import annotations

import csv
import hashlib
import json
import logging
import os
import re
import zipfile
import zlib
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from engine.errors import CancelledError, ConfigError, DataError, OdmoError
from engine.fileio import atomic_write
from engine.limits import check_file_size, read_bytes
from engine.motion.axes import check_up_axis
from engine.motion.motion import Motion
from engine.motion.skeleton import Skeleton
from engine.npyio import load_npz

log = logging.getLogger(__name__)

CACHE_VERSION = 2  # 2: a CRC-32 of each entry's content, verified on read
BANDAI_DROP_JOINTS = ("joint_Root",)
_MOTION_SUFFIXES = (".bvh", ".npz", ".npy")
_BANDAI_PREFIX = re.compile(r"^dataset-\d+_")
#: Bandai-Namco clip names, e.g. ``dataset-2_walk-turn-left_feminine_021.bvh``: clips copied out of the
#: dataset (without its cfg/ folder) keep their labels.
_BANDAI_NAME = re.compile(r"^dataset-\d+_(?P<action>[a-z]+(?:-[a-z]+)*)_(?P<style>[a-z]+)_\d+\.bvh$")


@dataclass(eq=False)
class Dataset:
    """Labelled clips of one folder, all on one skeleton topology.

    Parameters
    ----------
    clips : the clips, each with ``action`` and ``meta["source"]`` (path relative to ``root``),
        ``meta["style"]`` where known.
    action_names : the actions, in the folder's id order (Bandai) or sorted.
    root : the folder.
    fingerprint : hash of the clip contents and labels, for model provenance.
    skeleton : the first clip's skeleton (every clip has the same joint names and parents).
    """

    clips: list[Motion]
    action_names: list[str]
    root: Path
    fingerprint: str
    skeleton: Skeleton
    layout: str = "generic"
    skipped: list[str] = field(default_factory=list)

    def __len__(self) -> int:
        """Number of clips."""
        return len(self.clips)


@dataclass(frozen=True)
class _Entry:
    """One clip file to load: its path, label and metadata."""

    path: Path
    action: str
    meta: dict[str, Any]


def load_folder(
    path: str | Path,
    pattern: str | None = None,
    labels: str | Path | None = None,
    cache: bool = True,
    progress: Callable[[int, int], None] | None = None,
    cancel: Callable[[], bool] | None = None,
    limit: int | None = None,
    drop_joints: Sequence[str] | None = None,
    on_error: str = "raise",
    up_axis: str = "y",
) -> Dataset:
    """Load the labelled clips of a dataset folder (Bandai-Namco, HumanAct12 or pattern/sidecar labels);
    ``up_axis`` is the files' up axis (they are turned Y-up)."""
    if on_error not in ("raise", "skip"):
        raise ConfigError(f"on_error must be 'raise' or 'skip', got {on_error!r}")
    root, layout, entries, action_names, drop = _scan(path, pattern, labels, limit, drop_joints, up_axis)
    store = _Cache(root, drop, up_axis) if cache else None
    clips: list[Motion] = []
    skipped: list[str] = []
    digests: list[str] = []
    for i, entry in enumerate(entries):
        if cancel is not None and cancel():
            raise CancelledError(f"loading {root} cancelled after {i} of {len(entries)} clips")
        try:
            digest, motion = _read_entry(entry, root, store, drop, up_axis)
        except DataError as exc:
            if on_error == "raise":
                raise
            log.warning("skipping %s", exc)
            skipped.append(str(entry.path))
            continue
        source = motion.meta["source"]
        if clips and not motion.skeleton.same_topology(clips[0].skeleton):
            raise DataError(f"{entry.path}: skeleton differs from {clips[0].meta['source']}")
        clips.append(motion)
        digests.append(f"{source}\t{digest}\t{entry.action}\t{json.dumps(entry.meta, sort_keys=True)}")
        if progress is not None:
            progress(i + 1, len(entries))
    if store is not None:
        store.save(prune=limit is None)
    if not clips:
        raise DataError(f"{root}: no readable labelled clips")
    used = sorted({c.action for c in clips if c.action is not None})
    if layout == "generic":
        action_names = used
    fingerprint = hashlib.sha256("\n".join([layout, *drop, *digests]).encode()).hexdigest()[:32]
    log.info("loaded %d clips (%d actions) from %s", len(clips), len(action_names), root)
    return Dataset(clips, action_names, root, fingerprint, clips[0].skeleton, layout, skipped)


@dataclass(frozen=True, eq=False)
class FolderClips(Sequence[Motion]):
    """The labelled clips of a dataset folder read one at a time: ``clips[k]`` is file k, from the
    folder's parse cache when it has one (read-only: at most ``ODMO_MAX_FILE_MB``, the cache file's size
    limit) or parsed when asked for and not kept; a DataError naming the file if it cannot be read.

    Parameters
    ----------
    root : the folder; entries : its labelled clip files in order.
    action_names : the actions, in the folder's id order (Bandai) or sorted.
    drop : joints left out of every clip; up_axis : the files' up axis.
    store : the folder's parse cache, read-only (None: parse every file).
    """

    root: Path
    entries: list[_Entry]
    action_names: list[str]
    drop: tuple[str, ...]
    up_axis: str
    store: _Cache | None = None

    def __len__(self) -> int:
        """Number of clips."""
        return len(self.entries)

    def __getitem__(self, k: int) -> Motion:  # type: ignore[override]
        """Clip ``k``, read from its file, with ``meta["source"]``."""
        return _read_entry(self.entries[k], self.root, self.store, self.drop, self.up_axis)[1]

    def label(self, k: int) -> tuple[str, dict[str, Any]]:
        """The action and metadata (labels and ``source``) clip ``k`` has, known without reading it."""
        entry = self.entries[k]
        return entry.action, dict(entry.meta) | {"source": entry.path.relative_to(self.root).as_posix()}


def open_folder(
    path: str | Path,
    pattern: str | None = None,
    labels: str | Path | None = None,
    up_axis: str = "y",
    cache: bool = True,
) -> FolderClips:
    """The labelled clips of a dataset folder (as :func:`load_folder` finds them), read when asked for,
    through the folder's parse cache when ``cache`` and it has one."""
    root, layout, entries, action_names, drop = _scan(path, pattern, labels, None, None, up_axis)
    if layout == "generic":
        action_names = sorted({entry.action for entry in entries})
    store = _Cache(root, drop, up_axis, read_only=True) if cache else None
    return FolderClips(root, entries, action_names, drop, up_axis, store if store and store.entries else None)


def _scan(
    path: str | Path,
    pattern: str | None,
    labels: str | Path | None,
    limit: int | None,
    drop_joints: Sequence[str] | None,
    up_axis: str,
) -> tuple[Path, str, list[_Entry], list[str], tuple[str, ...]]:
    """The folder, its layout, its labelled clip files (at most ``limit``), action names and the joints
    to drop; DataError for a folder that is missing or has no labelled clip."""
    root = Path(path).expanduser().resolve()
    if not root.is_dir():
        raise DataError(f"{root}: not a folder")
    if limit is not None:
        limit = max(0, int(limit))
    if _is_bandai(root) and pattern is None and labels is None:
        layout, (entries, action_names) = "bandai", _bandai_entries(root, limit)
        drop = BANDAI_DROP_JOINTS if drop_joints is None else tuple(drop_joints)
    else:
        layout, (entries, action_names) = "generic", _generic_entries(root, pattern, labels)
        drop = () if drop_joints is None else tuple(drop_joints)
    entries = entries[:limit]
    if not entries:
        hint = (
            "" if pattern or labels else " (name the label with --pattern '(?P<action>...)' or --labels FILE)"
        )
        raise DataError(f"{root}: no labelled clips{hint}")
    check_up_axis(up_axis)
    return root, layout, entries, action_names, drop


def _read_entry(
    entry: _Entry, root: Path, store: _Cache | None, drop: Sequence[str], up_axis: str
) -> tuple[str, Motion]:
    """(content hash, clip with ``meta["source"]``) of one file; DataError naming it when unreadable."""
    try:
        digest, motion = _load_clip(entry, store, drop, up_axis)
    except OdmoError as exc:
        named = str(exc) if str(exc).startswith(str(entry.path)) else f"{entry.path}: {exc}"
        raise DataError(named) from None
    motion.meta["source"] = entry.path.relative_to(root).as_posix()
    return digest, motion


def cache_dir() -> Path:
    """The cache folder: ``$ODMO_CACHE_DIR`` or ``~/.cache/odmo-explorer``."""
    return Path(os.environ.get("ODMO_CACHE_DIR") or Path.home() / ".cache" / "odmo-explorer")


def _is_bandai(root: Path) -> bool:
    """True for the Bandai-Namco layout (cfg/content_label.txt and data/*.bvh)."""
    return (root / "cfg" / "content_label.txt").is_file() and any((root / "data").glob("*.bvh"))


def _label_names(path: Path) -> list[str]:
    """Names listed one per line in a Bandai label file, without the ``dataset-N_`` prefix."""
    lines = path.read_text(encoding="utf-8").splitlines()
    return [_BANDAI_PREFIX.sub("", line.strip()) for line in lines if line.strip()]


def _bandai_entries(root: Path, limit: int | None) -> tuple[list[_Entry], list[str]]:
    """The first ``limit`` clips of a Bandai-Namco folder labelled by their JSON sidecars, and the actions."""
    actions = _label_names(root / "cfg" / "content_label.txt")
    style_file = root / "cfg" / "style_label.txt"
    styles = _label_names(style_file) if style_file.is_file() else []
    entries = []
    for bvh in sorted((root / "data").glob("*.bvh"), key=lambda p: p.name)[:limit]:
        sidecar = bvh.with_suffix(".json")
        try:
            label = json.loads(sidecar.read_text(encoding="utf-8"))
            content = int(label["content"])
            meta = {"action_id": content}
            if "style" in label:
                style = int(label["style"])
                meta["style"] = styles[style] if 0 <= style < len(styles) else str(style)
            entries.append(_Entry(bvh, actions[content], meta))
        except (OSError, ValueError, KeyError, TypeError, IndexError) as exc:
            raise DataError(f"{sidecar}: unusable label sidecar ({type(exc).__name__}: {exc})") from None
    return entries, actions


def _generic_entries(
    root: Path, pattern: str | None, labels: str | Path | None
) -> tuple[list[_Entry], list[str]]:
    """Motion files of a folder labelled by a sidecar, a file-name regex or the HumanAct12 naming."""
    from engine.motion.humanact12 import label_from_filename

    files = sorted(p for p in root.iterdir() if p.suffix.lower() in _MOTION_SUFFIXES and p.is_file())
    if labels is not None:
        labels = Path(labels).expanduser()
        table = _read_sidecar(labels if labels.is_absolute() or labels.exists() else root / labels)
        found = [(p, table.get(p.name) or table.get(p.stem)) for p in files]
    elif pattern is not None:
        try:
            regex = re.compile(pattern)
        except re.error as exc:
            raise ConfigError(f"bad label pattern {pattern!r}: {exc}") from None
        if "action" not in regex.groupindex:
            raise ConfigError(f"label pattern {pattern!r} needs a named group (?P<action>...)")
        found = [(p, _match_label(regex, p.name)) for p in files]
    else:
        found = []
        for p in files:
            label = label_from_filename(p.name) if p.suffix.lower() == ".npy" else None
            if label is not None:
                found.append((p, {"action": label[0], **label[1]}))
            else:
                found.append((p, _match_label(_BANDAI_NAME, p.name)))
    entries = []
    for p, label in found:
        if label is None:
            log.info("no label for %s, skipped", p.name)
            continue
        meta = {k: v for k, v in label.items() if k != "action"}
        entries.append(_Entry(p, str(label["action"]), meta))
    return entries, sorted({e.action for e in entries})


def _match_label(regex: re.Pattern[str], name: str) -> dict[str, str] | None:
    """Named groups of ``regex`` found in ``name`` (None when it does not match)."""
    match = regex.search(name)
    if match is None or match["action"] is None:
        return None
    return {k: v for k, v in match.groupdict().items() if v is not None}


def _read_sidecar(path: Path) -> dict[str, dict[str, Any]]:
    """File name -> label fields from a CSV (header ``file,action,...``) or JSON sidecar."""
    try:
        check_file_size(path, "label file")
        text = path.read_text(encoding="utf-8-sig")
    except OSError as exc:
        raise DataError(f"{path}: cannot read labels ({exc.strerror or exc})") from None
    except UnicodeDecodeError as exc:
        line = exc.object.count(b"\n", 0, exc.start) + 1
        raise DataError(f"{path}:{line}: labels are not UTF-8 text") from None
    if path.suffix.lower() == ".json":
        try:
            raw = json.loads(text)
        except json.JSONDecodeError as exc:
            raise DataError(f"{path}:{exc.lineno}: invalid JSON ({exc.msg})") from None
        if not isinstance(raw, dict):
            raise DataError(f"{path}: expected a JSON object mapping file names to labels")
        table = {}
        for name, value in raw.items():
            fields = value if isinstance(value, dict) else {"action": value}
            if not isinstance(fields.get("action"), str):
                raise DataError(f"{path}: entry {name!r} has no string 'action'")
            table[name] = fields
        return table
    if "\x00" in text:
        line = text.count("\n", 0, text.index("\x00")) + 1
        raise DataError(f"{path}:{line}: binary data in a label file")
    try:
        rows = list(csv.reader(text.splitlines()))
    except csv.Error as exc:
        raise DataError(f"{path}: not a CSV label file ({exc})") from None
    if not rows or rows[0][:2] != ["file", "action"]:
        raise DataError(f"{path}:1: the CSV header must start with 'file,action'")
    header = rows[0]
    table = {}
    for line, row in enumerate(rows[1:], start=2):
        if not row:
            continue
        if len(row) != len(header):
            raise DataError(f"{path}:{line}: expected {len(header)} columns, got {len(row)}")
        table[row[0]] = dict(zip(header[1:], row[1:], strict=True))
    return table


def _load_clip(entry: _Entry, store: _Cache | None, drop: Sequence[str], up_axis: str) -> tuple[str, Motion]:
    """(content hash, parsed clip without the ``drop`` joints, turned Y-up) of one file, from the cache if
    it has it."""
    from engine.motion.formats import read_motion

    try:
        data = read_bytes(entry.path, "motion file")
    except OSError as exc:
        raise DataError(f"cannot read ({exc})") from None
    digest = hashlib.blake2b(data, digest_size=16).hexdigest()
    cached = store.get(digest) if store is not None else None
    if cached is not None:
        try:
            return digest, Motion(*cached, action=entry.action, meta=dict(entry.meta))
        except OdmoError as exc:
            log.warning("the cached copy of %s is unusable (%s); re-reading the file", entry.path, exc)
    motion = read_motion(entry.path, up_axis=up_axis).without_joints(drop)
    parsed = (motion.joints, motion.fps, motion.skeleton)
    if store is not None:
        store.put(digest, parsed)
    return digest, Motion(*parsed, action=entry.action, meta=dict(entry.meta))


def drop_extra_joints(motion: Motion, names: Sequence[str]) -> Motion:
    """``motion`` without its joints beyond ``names`` (e.g. Bandai's ground-projected ``joint_Root``),
    dropped by name, when it has every joint of ``names``; unchanged otherwise, for the caller's skeleton
    check to name the mismatch."""
    have = motion.skeleton.names
    if tuple(have) == tuple(names) or not set(names) <= set(have):
        return motion
    return motion.without_joints([n for n in have if n not in names])


def conform_to(skeleton: Skeleton, motion: Motion) -> Motion:
    """``motion`` on ``skeleton``'s joints: extra joints (e.g. Bandai's ground-projected ``joint_Root``) are
    dropped by name when every joint of ``skeleton`` is present; ConfigError naming the file and both joint
    lists otherwise."""
    if not skeleton.same_topology(motion.skeleton):
        motion = drop_extra_joints(motion, skeleton.names)
    if not skeleton.same_topology(motion.skeleton):
        theirs = motion.skeleton
        source = motion.meta.get("source", motion.meta.get("path", "the motion"))
        raise ConfigError(
            f"{source}: skeleton does not match the model's ({theirs.n_joints} joints "
            f"[{', '.join(theirs.names)}] vs {skeleton.n_joints} joints [{', '.join(skeleton.names)}])"
        )
    return motion


_Parsed = tuple[np.ndarray, float, Skeleton]


class _Cache:
    """Parsed clips (joints, fps, skeleton) of one folder by content hash, in one NPZ file (no pickles);
    ``read_only``: clips parsed afresh are not kept."""

    def __init__(self, root: Path, drop: Sequence[str], up_axis: str, read_only: bool = False) -> None:
        self.read_only = read_only
        turned = [f"up_axis={up_axis}"] if up_axis != "y" else []  # Y-up keys predate the option
        key = "\n".join([str(root), str(CACHE_VERSION), *drop, *turned])
        key = hashlib.sha1(key.encode()).hexdigest()[:16]
        self.path = cache_dir() / "datasets" / f"{root.name}-{key}.npz"
        self.entries: dict[str, _Parsed] = {}
        self.used: set[str] = set()
        self.dirty = False
        if self.path.is_file():
            try:
                self.entries, damaged = _read_cache(self.path)
            except (OSError, ValueError, KeyError, IndexError, TypeError, EOFError, zipfile.BadZipFile,
                    zlib.error, OdmoError) as exc:  # fmt: skip
                log.warning("rebuilding the unreadable cache %s (%s: %s)", self.path, type(exc).__name__, exc)
                damaged = 0
                self.dirty = True
            if damaged:
                log.warning(
                    "%s: %d cached clips failed their checksum; re-reading them from the source files",
                    self.path,
                    damaged,
                )
                self.dirty = True

    def get(self, digest: str) -> _Parsed | None:
        """The cached clip with this content hash, or None."""
        self.used.add(digest)
        return self.entries.get(digest)

    def put(self, digest: str, parsed: _Parsed) -> None:
        """Remember a freshly parsed clip (unless read-only)."""
        if self.read_only:
            return
        self.entries[digest] = parsed
        self.dirty = True

    def save(self, prune: bool) -> None:
        """Write the cache if it changed (dropping clips no longer in the folder when ``prune``)."""
        if prune and set(self.entries) != self.used:
            self.entries = {k: v for k, v in self.entries.items() if k in self.used}
            self.dirty = True
        if not self.dirty or not self.entries:
            return
        topologies = {(skel.names, tuple(skel.parents)) for _, _, skel in self.entries.values()}
        if len(topologies) != 1:
            log.warning("clips have different skeletons; not caching %s", self.path)
            return
        try:
            _write_cache(self.path, self.entries)
        except OSError as exc:
            log.warning("could not write cache %s: %s", self.path, exc)


def _write_cache(path: Path, entries: dict[str, _Parsed]) -> None:
    """Write ``entries`` (one skeleton topology) to one NPZ file atomically."""
    parsed = list(entries.values())
    skeletons = [skel for _, _, skel in parsed]
    first = skeletons[0]
    arrays = {
        "version": np.asarray(CACHE_VERSION),
        "digests": np.asarray(list(entries), dtype=np.str_),
        "frames": np.array([len(joints) for joints, _, _ in parsed], dtype=np.int64),
        "fps": np.array([fps for _, fps, _ in parsed]),
        "joints": np.concatenate([joints for joints, _, _ in parsed]),
        "offsets": np.stack([skel.offsets for skel in skeletons]),
        "names": np.asarray(first.names, dtype=np.str_),
        "parents": np.asarray(first.parents),
        "site_parents": np.array([p for p, _ in first.end_sites], dtype=np.int64),
        "site_offsets": np.array([[o for _, o in skel.end_sites] for skel in skeletons]).reshape(
            len(skeletons), len(first.end_sites), 3
        ),
        "units": np.asarray([skel.units for skel in skeletons], dtype=np.str_),
    }
    bounds, topology = np.concatenate([[0], np.cumsum(arrays["frames"])]), _topology(arrays)
    arrays["checks"] = np.array(
        [
            _entry_check(
                arrays["joints"][bounds[i] : bounds[i + 1]],
                _entry_key(arrays["offsets"][i], arrays["site_offsets"][i], str(arrays["units"][i])),
                float(arrays["fps"][i]),
                topology,
            )
            for i in range(len(parsed))
        ],
        dtype=np.uint32,
    )
    arrays["whole_check"] = np.asarray(_whole_check(arrays), dtype=np.uint32)
    with atomic_write(path, "wb") as handle:
        np.savez(handle, **arrays)


def _entry_key(offsets: np.ndarray, site_offsets: np.ndarray, units: str) -> bytes:
    """The bytes that identify one entry's skeleton (its rest offsets, End Sites and units)."""
    return offsets.tobytes() + site_offsets.tobytes() + units.encode()


def _topology(arrays: dict[str, np.ndarray]) -> bytes:
    """The bytes of the joint tree every entry shares: names, parents and End Site parents."""
    return (
        "\n".join(arrays["names"].tolist()).encode()
        + arrays["parents"].tobytes()
        + arrays["site_parents"].tobytes()
    )


def _whole_check(arrays: dict[str, np.ndarray]) -> int:
    """CRC-32 of everything the entries are built from, in one pass (the check of an intact cache)."""
    crc = zlib.crc32(np.ascontiguousarray(arrays["joints"]))
    for key in ("frames", "fps", "offsets", "site_offsets", "units", "digests", "checks"):
        crc = zlib.crc32(np.ascontiguousarray(arrays[key]), crc)
    return zlib.crc32(_topology(arrays), crc)


def _entry_check(joints: np.ndarray, key: bytes, fps: float, topology: bytes) -> int:
    """CRC-32 of one cache entry's content: joints, skeleton key, fps and the shared joint tree."""
    crc = zlib.crc32(np.ascontiguousarray(joints))
    return zlib.crc32(topology + key + np.float64(fps).tobytes(), crc)


def _read_cache(path: Path) -> tuple[dict[str, _Parsed], int]:
    """Clips of a cache file written by :func:`_write_cache` keyed by content hash, and how many entries
    failed their check (left out)."""
    data = load_npz(path)
    if int(data["version"]) != CACHE_VERSION:
        return {}, 0
    names = tuple(data["names"].tolist())
    site_parents = data["site_parents"].tolist()
    bounds = np.concatenate([[0], np.cumsum(data["frames"])])
    checks, topology = data["checks"], _topology(data)
    intact = _whole_check(data) == int(data["whole_check"])  # else find the damaged entries one by one
    skeletons: dict[bytes, Skeleton] = {}  # clips of one performer share one Skeleton object
    entries, damaged = {}, 0
    for i, digest in enumerate(data["digests"].tolist()):
        offsets, site_offsets, units = data["offsets"][i], data["site_offsets"][i], str(data["units"][i])
        key = _entry_key(offsets, site_offsets, units)
        joints, fps = data["joints"][bounds[i] : bounds[i + 1]], float(data["fps"][i])
        if not intact and _entry_check(joints, key, fps, topology) != int(checks[i]):
            damaged += 1
            continue
        try:
            if key not in skeletons:
                sites = tuple(
                    (p, (float(o[0]), float(o[1]), float(o[2])))
                    for p, o in zip(site_parents, site_offsets, strict=True)
                )
                skeletons[key] = Skeleton(names, data["parents"], offsets, sites, units)
        except OdmoError:
            damaged += 1
            continue
        entries[digest] = (joints, fps, skeletons[key])
    return entries, damaged
