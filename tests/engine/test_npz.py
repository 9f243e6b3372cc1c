"""NPZ schema 1, plain .npy arrays and format dispatch by extension."""

from __future__ import annotations

import json
import zipfile
from pathlib import Path

import numpy as np
import pytest

from engine.errors import MotionFormatError
from engine.motion import Motion, Skeleton
from engine.motion.formats import read_motion, write_motion
from engine.motion.humanact12 import smpl24_skeleton
from engine.motion.npy import read_npy, write_npy
from engine.motion.npz import read_npz, write_npz


def sample_motion(with_rotations: bool = True) -> Motion:
    """A 5-frame 3-joint motion with rotations, an End Site, a label and metadata."""
    rng = np.random.default_rng(0)
    skel = Skeleton(
        ("root", "spine", "head"),
        np.array([-1, 0, 1]),
        [[0, 0, 0], [0, 0.3, 0], [0, 0.2, 0]],
        ((2, (0.0, 0.1, 0.0)),),
    )
    rot = rng.normal(size=(5, 3, 4))
    rot /= np.linalg.norm(rot, axis=-1, keepdims=True)
    return Motion(
        rng.normal(size=(5, 3, 3)),
        30.0,
        skel,
        rot if with_rotations else None,
        rng.normal(size=(5, 3)) if with_rotations else None,
        "jump",
        {"seed": 7, "code": [0.5, -1.0], "source": "unit test", "ik_fk_error_m": 0.001},
    )


def rewrite(path: Path, **changes: np.ndarray | None) -> None:
    """Rewrite the NPZ at ``path`` with some entries replaced (None deletes one)."""
    with np.load(path, allow_pickle=False) as archive:
        data = {k: archive[k] for k in archive.files}
    for key, value in changes.items():
        if value is None:
            del data[key]
        else:
            data[key] = value
    np.savez(path, **data)


def test_round_trip_keeps_everything(tmp_path: Path) -> None:
    motion = sample_motion()
    report = write_npz(tmp_path / "clip.npz", motion)
    back = read_npz(tmp_path / "clip.npz")
    assert report["frames"] == 5
    assert np.array_equal(back.joints, motion.joints) and back.joints.dtype == np.float32
    assert np.array_equal(back.local_rotations, motion.local_rotations)
    assert np.array_equal(back.root_translation, motion.root_translation)
    assert back.skeleton.same_topology(motion.skeleton)
    assert np.array_equal(back.skeleton.offsets, motion.skeleton.offsets)
    assert back.skeleton.end_sites == motion.skeleton.end_sites
    assert (back.fps, back.action, back.meta) == (30.0, "jump", motion.meta)


def test_file_has_no_object_arrays_and_records_versions(tmp_path: Path) -> None:
    write_npz(tmp_path / "clip.npz", sample_motion(with_rotations=False))
    with np.load(tmp_path / "clip.npz", allow_pickle=False) as archive:
        kinds = {k: archive[k].dtype.kind for k in archive.files}
        meta = json.loads(str(archive["meta"]))
    assert "O" not in kinds.values() and kinds["joint_names"] == "U"
    assert "local_rotations" not in kinds
    assert meta["format_version"] == 1 and meta["tool_version"] and meta["seed"] == 7


@pytest.mark.parametrize(
    ("changes", "message"),
    [
        ({"joints": None}, "missing key"),
        ({"joints": np.zeros((5, 3, 2), np.float32)}, "joints"),
        ({"parents": np.zeros(3)}, "parents"),
        ({"joint_names": np.array([1, 2, 3])}, "joint_names"),
        ({"offsets": np.full((3, 3), np.nan)}, "non-finite"),
        ({"meta": np.asarray(json.dumps({"format_version": 2}))}, "newer"),
        ({"meta": np.asarray("{not json")}, "JSON"),
        ({"root_translation": None}, "together"),
        ({"local_rotations": np.zeros((4, 3, 4))}, "local_rotations"),
        ({"parents": np.array([-1, 2, 0])}, "parent"),
    ],
)
def test_bad_files_raise_motion_format_error(tmp_path: Path, changes: dict, message: str) -> None:
    path = tmp_path / "bad.npz"
    write_npz(path, sample_motion())
    rewrite(path, **changes)
    with pytest.raises(MotionFormatError, match=message) as info:
        read_npz(path)
    assert info.value.path == str(path)


def test_object_arrays_and_garbage_are_refused(tmp_path: Path) -> None:
    path = tmp_path / "obj.npz"
    write_npz(path, sample_motion())
    rewrite(path, joint_names=np.array(["a", 1, None], dtype=object))
    with pytest.raises(MotionFormatError, match="readable"):
        read_npz(path)
    (tmp_path / "junk.npz").write_bytes(b"not a zip")
    with pytest.raises(MotionFormatError):
        read_npz(tmp_path / "junk.npz")


def test_failed_write_leaves_nothing(tmp_path: Path) -> None:
    motion = sample_motion()
    motion.meta["unserialisable"] = object()
    with pytest.raises(TypeError):
        write_npz(tmp_path / "clip.npz", motion)
    assert list(tmp_path.iterdir()) == []


def test_npy_round_trip_units_and_checks(tmp_path: Path) -> None:
    skel = smpl24_skeleton()
    joints = np.random.default_rng(1).normal(size=(8, 24, 3)).astype(np.float32)
    np.save(tmp_path / "cm.npy", joints * 100)
    motion = read_npy(tmp_path / "cm.npy", "smpl24", fps=25.0, units="cm")
    assert np.allclose(motion.joints, joints, atol=1e-5) and motion.fps == 25.0
    assert motion.skeleton.same_topology(skel)
    write_npy(tmp_path / "m.npy", motion)
    assert np.array_equal(np.load(tmp_path / "m.npy"), motion.joints)
    np.save(tmp_path / "wrong.npy", joints[:, :21])
    with pytest.raises(MotionFormatError, match="21 joints"):
        read_npy(tmp_path / "wrong.npy")
    np.save(tmp_path / "obj.npy", np.array([None], dtype=object), allow_pickle=True)
    with pytest.raises(MotionFormatError, match=r"obj\.npy"):
        read_npy(tmp_path / "obj.npy")


def test_dispatch_by_extension(tmp_path: Path) -> None:
    motion = sample_motion(with_rotations=False)
    write_motion(motion, tmp_path / "a.NPZ")
    assert np.array_equal(read_motion(tmp_path / "a.NPZ").joints, motion.joints)
    skel3 = motion.skeleton
    write_motion(motion, tmp_path / "a.npy")
    assert np.array_equal(read_motion(tmp_path / "a.npy", skeleton=skel3).joints, motion.joints)
    with pytest.raises(MotionFormatError, match="unknown motion file type"):
        write_motion(motion, tmp_path / "a.csv")
    with pytest.raises(MotionFormatError, match="unknown motion file type"):
        read_motion(tmp_path / "a.fbx")
    assert not (tmp_path / "a.csv").exists()


def test_npz_is_a_plain_zip_of_npy_members(tmp_path: Path) -> None:
    write_npz(tmp_path / "clip.npz", sample_motion())
    with zipfile.ZipFile(tmp_path / "clip.npz") as archive:
        names = set(archive.namelist())
    assert {"joints.npy", "fps.npy", "parents.npy", "joint_names.npy", "offsets.npy", "meta.npy"} <= names
