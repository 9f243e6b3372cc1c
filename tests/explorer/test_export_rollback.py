"""A multi-file motion export that fails part-way leaves nothing of itself: no BVH, no provenance sidecar."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from engine.errors import OutputError
from engine.motion.bvh import provenance_path
from explorer.export import export_motions
from explorer.state import Decoded
from tests.fixtures.procedural import make_procedural_clips


def _items(n: int) -> list[Decoded]:
    clips = make_procedural_clips(n_per_style=1)[:n]
    return [Decoded(c, f"clip {i}", code=np.zeros(4, np.float32), seed=i) for i, c in enumerate(clips)]


def test_a_failed_bvh_export_removes_its_files_and_their_sidecars(tmp_path: Path) -> None:
    items = _items(3)
    (tmp_path / "walk_002.bvh").mkdir()  # the third file cannot be written
    with pytest.raises(OutputError):
        export_motions(items, tmp_path / "walk.bvh", "some/model")
    assert sorted(p.name for p in tmp_path.iterdir()) == ["walk_002.bvh"]


def test_a_bvh_export_writes_each_file_with_its_sidecar(tmp_path: Path) -> None:
    written = export_motions(_items(2), tmp_path / "walk.bvh", "some/model")
    assert [p.name for p in written] == ["walk_000.bvh", "walk_001.bvh"]
    assert all(provenance_path(p).is_file() for p in written)
