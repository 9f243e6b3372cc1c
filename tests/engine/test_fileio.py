"""Atomic writes: nothing half-written on failure, usual permissions on success."""

import os
from pathlib import Path

import pytest

from engine.fileio import atomic_write, atomic_write_text


def test_failed_write_leaves_nothing(tmp_path: Path) -> None:
    target = tmp_path / "out.txt"
    with pytest.raises(RuntimeError), atomic_write(target) as handle:
        handle.write("partial")
        raise RuntimeError("boom")
    assert list(tmp_path.iterdir()) == []


def test_success_replaces_with_umask_permissions(tmp_path: Path) -> None:
    target = tmp_path / "out.txt"
    target.write_text("old")
    atomic_write_text(target, "new")
    assert target.read_text() == "new"
    mask = os.umask(0)
    os.umask(mask)
    assert target.stat().st_mode & 0o777 == 0o666 & ~mask


def test_an_unwritable_target_names_it_and_leaves_nothing(tmp_path: Path) -> None:
    from engine.errors import OutputError

    (tmp_path / "file").write_text("in the way")
    with pytest.raises(OutputError, match=r"file/out\.txt: cannot write there \(a file is in the way"):
        atomic_write_text(tmp_path / "file" / "out.txt", "x")


def test_a_failed_write_names_the_target_and_leaves_nothing(tmp_path: Path) -> None:
    from engine.errors import OutputError

    target = tmp_path / "out.bin"
    failed = pytest.raises(OutputError, match=r"out\.bin: writing failed, nothing was written \(No space")
    with failed, atomic_write(target, "wb"):
        raise OSError(28, "No space left on device")
    assert list(tmp_path.iterdir()) == []
