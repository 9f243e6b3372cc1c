"""Skeleton: joint names, parent indices and rest offsets."""

from __future__ import annotations

import re
from collections.abc import Sequence
from dataclasses import dataclass, field

import numpy as np

from engine.errors import ConfigError

_NAME_RE = re.compile(r"[^A-Za-z0-9_]")


def sanitize_name(name: str) -> str:
    """Return ``name`` reduced to ``[A-Za-z_][A-Za-z0-9_]*`` (what every BVH importer accepts)."""
    clean = _NAME_RE.sub("_", name.strip()) or "joint"
    return clean if not clean[0].isdigit() else f"_{clean}"


@dataclass(frozen=True, eq=False)
class Skeleton:
    """A kinematic tree.

    Parameters
    ----------
    names : joint names, length J, unique.
    parents : (J,) int, parent index of each joint, -1 for the root; parents precede children.
    offsets : (J, 3) float, rest offset of each joint from its parent (root: from the origin), metres.
    end_sites : (E, 2) pairs ``(parent index, (3,) offset)`` of BVH End Sites, kept for writing.
    units : unit of ``offsets`` ("m" once loaded).
    """

    names: tuple[str, ...]
    parents: np.ndarray
    offsets: np.ndarray
    end_sites: tuple[tuple[int, tuple[float, float, float]], ...] = field(default=())
    units: str = "m"

    def __post_init__(self) -> None:
        names = tuple(str(n) for n in self.names)
        parents = np.asarray(self.parents, dtype=np.int64).reshape(-1)
        offsets = np.asarray(self.offsets, dtype=np.float64).reshape(-1, 3)
        n = len(names)
        if n == 0:
            raise ConfigError("a skeleton needs at least one joint")
        if parents.shape != (n,) or offsets.shape != (n, 3):
            raise ConfigError(
                f"skeleton sizes disagree: {n} names, {parents.shape[0]} parents, {offsets.shape[0]} offsets"
            )
        if len(set(names)) != n:
            dup = sorted({x for x in names if names.count(x) > 1})
            raise ConfigError(f"duplicate joint names: {', '.join(dup)}")
        roots = np.flatnonzero(parents < 0)
        if len(roots) != 1:
            raise ConfigError(f"a skeleton needs exactly one root, found {len(roots)}")
        if np.any(parents >= np.arange(n)):
            raise ConfigError("every parent must come before its children")
        if not np.all(np.isfinite(offsets)):
            raise ConfigError("skeleton offsets must be finite")
        parents.setflags(write=False)
        offsets.setflags(write=False)
        object.__setattr__(self, "names", names)
        object.__setattr__(self, "parents", parents)
        object.__setattr__(self, "offsets", offsets)

    @property
    def n_joints(self) -> int:
        """Number of joints J."""
        return len(self.names)

    @property
    def root(self) -> int:
        """Index of the root joint."""
        return int(np.flatnonzero(self.parents < 0)[0])

    def index(self, name: str) -> int:
        """Index of the joint called ``name``."""
        try:
            return self.names.index(name)
        except ValueError:
            raise ConfigError(f"no joint named {name!r}") from None

    def children(self, j: int) -> list[int]:
        """Indices of the children of joint ``j``."""
        return [int(c) for c in np.flatnonzero(self.parents == j)]

    def bone_lengths(self) -> np.ndarray:
        """(J,) rest length of the bone from each joint's parent (0 for the root)."""
        lengths = np.linalg.norm(self.offsets, axis=1)
        lengths[self.root] = 0.0
        return lengths

    def rest_positions(self) -> np.ndarray:
        """(J, 3) joint positions of the rest pose (offsets summed down the tree)."""
        pos = np.zeros((self.n_joints, 3))
        for j, p in enumerate(self.parents):
            pos[j] = self.offsets[j] + (pos[p] if p >= 0 else 0.0)
        return pos

    def scaled(self, factor: float, units: str = "m") -> Skeleton:
        """The same skeleton with offsets multiplied by ``factor``."""
        sites = tuple((p, tuple(float(v) * factor for v in o)) for p, o in self.end_sites)
        return Skeleton(self.names, self.parents, self.offsets * factor, sites, units)

    def subset(self, keep: Sequence[int]) -> Skeleton:
        """Skeleton of the joints ``keep`` (in order); a dropped parent's offset folds into its child."""
        keep = [int(k) for k in keep]
        pos = {k: i for i, k in enumerate(keep)}
        parents, offsets = [], []
        for k in keep:
            off = self.offsets[k].copy()
            p = int(self.parents[k])
            while p >= 0 and p not in pos:
                off += self.offsets[p]
                p = int(self.parents[p])
            parents.append(pos[p] if p >= 0 else -1)
            offsets.append(off)
        sites = tuple((pos[p], o) for p, o in self.end_sites if p in pos)
        return Skeleton(
            tuple(self.names[k] for k in keep),
            np.array(parents),
            np.array(offsets),
            sites,
            self.units,
        )

    def same_topology(self, other: Skeleton) -> bool:
        """True when ``other`` has the same joint names and parents."""
        return self.names == other.names and np.array_equal(self.parents, other.parents)
