"""HumanAct12: labels from file names, the SMPL-24 skeleton and the opt-in allow-list pickle reader."""

from __future__ import annotations

import os
import pickle
from pathlib import Path

import numpy as np
import pytest

from engine.errors import ConfigError, MotionFormatError
from engine.motion.humanact12 import (
    ACTIONS,
    label_from_filename,
    read_actor_pickle,
    smpl22_skeleton,
    smpl24_skeleton,
)
from engine.motion.npy import read_npy
from engine.motion.safe_pickle import load_data_pickle


class _RunsCode:
    """A pickle payload that would create a marker file when unpickled."""

    def __init__(self, marker: Path) -> None:
        self.marker = marker

    def __reduce__(self):
        return os.system, (f"touch {self.marker}",)


class _EvalsCode:
    """A pickle payload that would call eval."""

    def __reduce__(self):
        return eval, ("1 + 1",)


@pytest.mark.parametrize(
    ("name", "action", "fine"),
    [
        ("P01G01R01F0069T0143A0102.npy", "warm_up", "0102"),
        ("P12G02R03F0001T0100A0504.npy", "drink", "0504"),
        ("P03G01R02F0010T0050A0901.npy", "turn steering wheel", "0901"),
        ("P03G01R02F0010T0050A1203.npy", "throw", "1203"),
    ],
)
def test_label_from_filename(name: str, action: str, fine: str) -> None:
    assert label_from_filename(name) == (action, {"fine_class": fine})


@pytest.mark.parametrize(
    "name", ["walk_01.npy", "P01G01R01F0069T0143A1301.npy", "P01G01R01F0069T0143A0001.npy"]
)
def test_names_without_a_valid_class_have_no_label(name: str) -> None:
    assert label_from_filename(name) is None


def test_twelve_classes_in_order() -> None:
    assert len(ACTIONS) == 12 and ACTIONS[0] == "warm_up" and ACTIONS[-1] == "throw"


def test_smpl24_skeleton_is_a_plausible_body() -> None:
    skel = smpl24_skeleton()
    assert skel.n_joints == 24 and skel.names[skel.root] == "pelvis"
    lengths = dict(zip(skel.names, skel.bone_lengths(), strict=True))
    for left, right in [
        ("left_knee", "right_knee"),
        ("left_elbow", "right_elbow"),
        ("left_hip", "right_hip"),
    ]:
        assert lengths[left] == pytest.approx(lengths[right], rel=0.05)
    assert 0.3 < lengths["left_knee"] < 0.45 and 0.2 < lengths["left_elbow"] < 0.3
    assert skel.offsets[skel.index("head")][1] > 0 and skel.offsets[skel.index("left_ankle")][1] < 0
    assert skel.offsets[skel.index("left_hip")][0] > 0 > skel.offsets[skel.index("right_hip")][0]


def test_read_npy_labels_from_the_name(tmp_path: Path) -> None:
    path = tmp_path / "P01G01R01F0069T0143A0301.npy"
    np.save(path, np.zeros((10, 24, 3), np.float32))
    motion = read_npy(path)
    assert (motion.action, motion.meta["fine_class"], motion.fps) == ("run", "0301", 20.0)


def test_read_npy_picks_the_built_in_skeleton_by_joint_count(tmp_path: Path) -> None:
    rng = np.random.default_rng(1)
    for n_joints, name in ((24, "right_hand"), (22, "right_wrist")):
        path = tmp_path / f"clip{n_joints}.npy"
        joints = rng.normal(size=(9, n_joints, 3)).astype(np.float32)
        np.save(path, joints)
        motion = read_npy(path)
        assert motion.skeleton.n_joints == n_joints and motion.skeleton.names[-1] == name
        np.testing.assert_array_equal(motion.joints, joints)
    body = smpl22_skeleton()  # HumanML3D's 22 joints: SMPL-24 without the hands
    full = smpl24_skeleton()
    assert body.names == full.names[:22]
    np.testing.assert_array_equal(body.parents, full.parents[:22])
    np.save(tmp_path / "seven.npy", np.zeros((4, 7, 3)))
    with pytest.raises(MotionFormatError, match=r"seven.npy: array has 7 joints .*smpl24 \(24\), smpl22"):
        read_npy(tmp_path / "seven.npy")
    with pytest.raises(MotionFormatError, match=r"clip22\.npy: array has 22 joints but the skeleton has 24"):
        read_npy(tmp_path / "clip22.npy", skeleton="smpl24")
    with pytest.raises(ConfigError, match="unknown skeleton 'smplx'; built in: auto, smpl24, smpl22"):
        read_npy(tmp_path / "clip22.npy", skeleton="smplx")


@pytest.mark.parametrize("protocol", [2, 4, 5])
def test_actor_pickle_is_read_only_with_opt_in(tmp_path: Path, protocol: int) -> None:
    rng = np.random.default_rng(0)
    clips = [rng.normal(size=(12, 24, 3)).astype(np.float32), rng.normal(size=(7, 24, 3))]
    path = tmp_path / "humanact12poses.pkl"
    with path.open("wb") as handle:
        pickle.dump(
            {"joints3D": clips, "y": [np.int64(0), 11], "poses": [np.zeros((12, 72))]}, handle, protocol
        )
    with pytest.raises(MotionFormatError, match="opt-in"):
        read_actor_pickle(path)
    motions = read_actor_pickle(path, allow_pickle=True)
    assert [m.action for m in motions] == ["warm_up", "throw"]
    assert [m.n_frames for m in motions] == [12, 7]
    assert np.allclose(motions[1].joints, clips[1].astype(np.float32))


def test_pickle_that_runs_code_is_refused(tmp_path: Path) -> None:
    marker = tmp_path / "pwned"
    path = tmp_path / "evil.pkl"
    path.write_bytes(pickle.dumps({"joints3D": [_RunsCode(marker)], "y": [0]}))
    with pytest.raises(MotionFormatError, match=r"unsafe.*system") as info:
        read_actor_pickle(path, allow_pickle=True)
    assert info.value.path == str(path)
    assert not marker.exists()
    path.write_bytes(pickle.dumps(_EvalsCode()))
    with pytest.raises(MotionFormatError, match="eval"):
        load_data_pickle(path)


def test_wrong_pickle_contents_are_reported(tmp_path: Path) -> None:
    path = tmp_path / "other.pkl"
    path.write_bytes(pickle.dumps({"joints3D": [np.zeros((5, 24, 3))], "y": [12]}))
    with pytest.raises(MotionFormatError, match="label"):
        read_actor_pickle(path, allow_pickle=True)
    path.write_bytes(pickle.dumps([1, 2, 3]))
    with pytest.raises(MotionFormatError, match="joints3D"):
        read_actor_pickle(path, allow_pickle=True)
    path.write_bytes(b"\x80\x04junk")
    with pytest.raises(MotionFormatError, match="pickle"):
        load_data_pickle(path)


def _memory_bombs() -> dict[str, bytes]:
    """Pickles of a few dozen bytes that use only allowed globals yet ask for terabytes."""
    reconstruct = (
        b"\x80\x02cnumpy.core.multiarray\n_reconstruct\ncnumpy\nndarray\n"
        b"\x8a\x06\x00\xa0\x72\x4e\x18\x09\x85C\x01b\x87R."  # _reconstruct(ndarray, (10**13,), b'b')
    )
    ndarray = b"\x80\x02cnumpy\nndarray\n\x8a\x06\x00\xa0\x72\x4e\x18\x09\x85U\x02f8\x86R."
    binbytes8 = b"\x80\x04\x8e" + (2**40).to_bytes(8, "little") + b"abc."
    unicode8 = b"\x80\x04\x8d" + (2**40).to_bytes(8, "little") + b"abc."
    frame = b"\x80\x04\x95" + (2**40).to_bytes(8, "little") + b"N."
    return {"reconstruct": reconstruct, "ndarray": ndarray, "binbytes8": binbytes8, "unicode8": unicode8,
            "frame": frame}  # fmt: skip


@pytest.mark.parametrize("name", sorted(_memory_bombs()))
def test_allowed_globals_cannot_exhaust_memory(tmp_path: Path, name: str) -> None:
    """Refused with one error naming the file, before allocating, even under a 1.5 GB address space."""
    import subprocess
    import sys

    path = tmp_path / f"{name}.pkl"
    path.write_bytes(_memory_bombs()[name])
    with pytest.raises(MotionFormatError, match=rf"{name}\.pkl: .*(refused|claims|memory)"):
        load_data_pickle(path)
    script = (
        "import resource, sys; resource.setrlimit(resource.RLIMIT_AS, (1536 * 2**20, 1536 * 2**20));"
        "from engine.cli import main; sys.exit(main(['info', '--allow-pickle', sys.argv[1]]))"
    )
    run = subprocess.run([sys.executable, "-c", script, str(path)], capture_output=True, text=True)
    assert run.returncode == 1 and "Traceback" not in run.stderr, run.stderr
    assert run.stderr.count("\n") == 1 and path.name in run.stderr


def test_pickle_labels_must_be_integers(tmp_path: Path) -> None:
    path = tmp_path / "bools.pkl"
    path.write_bytes(pickle.dumps({"joints3D": [np.zeros((5, 24, 3))], "y": [True]}))
    with pytest.raises(MotionFormatError, match=r"label True is not a coarse class id"):
        read_actor_pickle(path, allow_pickle=True)
