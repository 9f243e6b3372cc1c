"""Stated limits: over-sized files are refused before they are read, crafted headers before allocating."""

from __future__ import annotations

import io
import os
import subprocess
import sys
import zipfile
from pathlib import Path

import numpy as np
import pytest

from engine.errors import ConfigError, MotionFormatError, TooLargeError
from engine.limits import DEFAULT_MAX_FILE_BYTES, check_count, max_file_bytes
from engine.motion.formats import read_motion
from engine.npyio import load_npy, load_npz

#: Run a command with a 1.5 GB address space, as a small machine or a container limit would.
_LIMITED = (
    "import resource, sys; resource.setrlimit(resource.RLIMIT_AS, (1536 * 2**20, 1536 * 2**20));"
    "from engine.cli import main; sys.exit(main(sys.argv[1:]))"
)


def _odmo_limited(*args: str) -> subprocess.CompletedProcess:
    return subprocess.run(
        [sys.executable, "-c", _LIMITED, *args], capture_output=True, text=True, timeout=120
    )


def _sparse(path: Path, size: int) -> Path:
    with path.open("wb") as handle:
        handle.truncate(size)
    return path


def test_a_huge_sparse_bvh_is_refused_without_reading_it(tmp_path: Path) -> None:
    big = _sparse(tmp_path / "huge.bvh", 2 * 2**30)
    with pytest.raises(TooLargeError, match=r"huge\.bvh: BVH file of 2,048 MB is over the 512 MB limit"):
        read_motion(big)
    run = _odmo_limited("info", str(big))
    assert run.returncode == 1 and run.stderr.count("\n") == 1 and "huge.bvh" in run.stderr, run.stderr
    assert "Traceback" not in run.stderr


def test_the_limit_can_be_raised_or_lowered(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    assert max_file_bytes() == DEFAULT_MAX_FILE_BYTES
    small = _sparse(tmp_path / "small.bvh", 3 * 2**20)
    monkeypatch.setenv("ODMO_MAX_FILE_MB", "2")
    with pytest.raises(TooLargeError, match="over the 2 MB limit"):
        read_motion(small)
    monkeypatch.setenv("ODMO_MAX_FILE_MB", "lots")
    with pytest.raises(ConfigError, match="ODMO_MAX_FILE_MB"):
        max_file_bytes()


def test_a_huge_file_inside_a_dataset_folder_is_refused_by_name(tmp_path: Path) -> None:
    from engine.errors import DataError
    from engine.motion.datasets import load_folder

    _sparse(tmp_path / "walk_01.bvh", 2 * 2**30)
    with pytest.raises(DataError, match=r"walk_01\.bvh: .*over the 512 MB limit"):
        load_folder(tmp_path, pattern=r"(?P<action>[a-z]+)_", cache=False)


def _npy(shape: tuple[int, ...], dtype: str = "<f8", payload: bytes = b"") -> bytes:
    buffer = io.BytesIO()
    np.lib.format.write_array_header_1_0(buffer, {"descr": dtype, "fortran_order": False, "shape": shape})
    return buffer.getvalue() + payload


def test_npy_headers_cannot_ask_for_more_than_the_file_holds(tmp_path: Path) -> None:
    path = tmp_path / "bomb.npy"
    path.write_bytes(_npy((10**6, 10**6, 3)))
    with pytest.raises(ValueError, match="declares"):
        load_npy(path)
    with pytest.raises(MotionFormatError, match=r"bomb\.npy: not a readable \.npy array: its header"):
        read_motion(path)
    run = _odmo_limited("info", str(path))
    assert run.returncode == 1 and "Traceback" not in run.stderr and "bomb.npy" in run.stderr, run.stderr


def test_npz_members_cannot_ask_for_more_than_they_hold(tmp_path: Path) -> None:
    path = tmp_path / "bomb.npz"
    with zipfile.ZipFile(path, "w") as archive:
        archive.writestr("joints.npy", _npy((10**6, 10**6, 3)))
    with pytest.raises(MotionFormatError, match=r"bomb\.npz: not a readable NPZ archive: its header"):
        read_motion(path)


def test_object_arrays_are_refused_without_numpy_pickle_advice(tmp_path: Path) -> None:
    path = tmp_path / "objects.npy"
    np.save(path, np.array([{"a": 1}], dtype=object), allow_pickle=True)
    with pytest.raises(MotionFormatError) as info:
        read_motion(path)
    assert "Python objects" in str(info.value) and "allow_pickle" not in str(info.value)
    archive = tmp_path / "objects.npz"
    np.savez(archive, joints=np.array([None], dtype=object))
    with pytest.raises(MotionFormatError) as info:
        read_motion(archive)
    assert "Python objects" in str(info.value) and "allow_pickle" not in str(info.value)


def test_bounded_readers_match_numpy(tmp_path: Path) -> None:
    rng = np.random.default_rng(0)
    arrays = {
        "c": rng.normal(size=(4, 5, 3)).astype(np.float32),
        "f": np.asfortranarray(rng.normal(size=(6, 2))),
        "s": np.asarray("text"),
        "e": np.zeros((0, 3)),
        "u": np.asarray(["a", "bcd"]),
    }
    np.savez(tmp_path / "a.npz", **arrays)
    got = load_npz(tmp_path / "a.npz")
    assert set(got) == set(arrays)
    for key, value in arrays.items():
        assert got[key].dtype == value.dtype and np.array_equal(got[key], value)
    assert got["c"].flags.writeable
    np.save(tmp_path / "f.npy", arrays["f"])
    np.testing.assert_array_equal(load_npy(tmp_path / "f.npy"), arrays["f"])
    assert load_npz((tmp_path / "a.npz").read_bytes())["s"] == "text"


def test_memory_errors_become_one_line(tmp_path: Path) -> None:
    """A real allocation failure under the address-space limit: no traceback, one line, exit 1."""
    clip = tmp_path / "long.npy"
    np.save(clip, np.zeros((400_000, 24, 3), dtype=np.float32))  # 115 MB; FK and IK need far more
    env = os.environ | {"ODMO_MAX_FILE_MB": "1024"}
    script = (
        "import resource, sys; resource.setrlimit(resource.RLIMIT_AS, (900 * 2**20, 900 * 2**20));"
        "from engine.cli import main; sys.exit(main(sys.argv[1:]))"
    )
    run = subprocess.run(
        [sys.executable, "-c", script, "convert", str(clip), str(tmp_path / "out.bvh")],
        capture_output=True,
        text=True,
        env=env,
        timeout=300,
    )
    assert run.returncode == 1 and "Traceback" not in run.stderr, run.stderr
    assert run.stderr.count("\n") == 1 and "out of memory" in run.stderr
    assert not (tmp_path / "out.bvh").exists()
    assert not [p for p in tmp_path.iterdir() if p.name.endswith(".tmp")]


@pytest.mark.parametrize("n", [0, -1, 10**9, True, 2.5])
def test_request_counts_are_bounded(n: object) -> None:
    with pytest.raises(ConfigError, match="whole number from 1 to 10,000"):
        check_count("--n", n)  # type: ignore[arg-type]
