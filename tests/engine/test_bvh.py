"""BVH reading, writing and resampling on hand-written files with hand-computed answers."""

from __future__ import annotations

from pathlib import Path

import bvhio
import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from engine.errors import ConfigError, MotionFormatError
from engine.motion.axes import looks_z_up
from engine.motion.bvh import format_bvh, parse_bvh_text, read_bvh, write_bvh
from engine.motion.motion import Motion
from engine.motion.resample import resample_motion
from engine.motion.rotations import euler_to_quat, forward_kinematics
from engine.motion.skeleton import Skeleton

DATA = Path(__file__).resolve().parents[1] / "data"
ORDERS = ["XYZ", "XZY", "YXZ", "YZX", "ZXY", "ZYX"]

CMU_EXPECTED = {
    "Hips": [[0, 0.9, 0], [0.05, 0.9, 0]],
    "LHipJoint": [[0, 0.9, 0], [0.05, 0.9, 0]],
    "LeftUpLeg": [[0.1, 0.9, 0], [0.05, 1.0, 0]],
    "LeftLeg": [[0.1, 0.5, 0], [0.05, 1.0, 0.4]],
    "Spine": [[0, 1.1, 0], [-0.15, 0.9, 0]],
}


def _expected(motion: Motion, table: dict[str, list[list[float]]]) -> None:
    for name, frames in table.items():
        got = motion.joints[:, motion.skeleton.index(name)]
        assert np.allclose(got, frames, atol=1e-6), name


@pytest.mark.parametrize("name", ["cmu_style.bvh", "cmu_style_crlf.bvh"])
def test_cmu_style_file_by_hand(name: str) -> None:
    motion = read_bvh(DATA / name)
    assert motion.skeleton.names == ("Hips", "LHipJoint", "LeftUpLeg", "LeftLeg", "Spine")
    assert list(motion.skeleton.parents) == [-1, 0, 1, 2, 0]
    assert motion.fps == pytest.approx(1 / 0.0083333)
    assert motion.meta["units_detected"] == "cm"
    assert motion.meta["source"] == str(DATA / name)
    _expected(motion, CMU_EXPECTED)
    assert motion.joints.dtype == np.float32
    assert np.allclose(motion.skeleton.offsets[3], [0, -0.4, 0])
    sites = dict(motion.skeleton.end_sites)
    assert np.allclose(sites[3], [0, -0.05, 0]) and np.allclose(sites[4], [0, 0.3, 0])
    # Rotations are kept: intrinsic ZYX on the root, X -90 on LHipJoint in frame 1.
    assert np.allclose(motion.local_rotations[1, 1], euler_to_quat(np.array([-90.0]), "X"))
    assert np.allclose(motion.root_translation, [[0, 0.9, 0], [0.05, 0.9, 0]])


def test_bandai_style_file_by_hand() -> None:
    motion = read_bvh(DATA / "bandai_style.bvh")
    assert motion.skeleton.names == ("joint_Root", "Hips", "Spine", "UpperLeg_L")
    assert motion.meta["units_detected"] == "cm"
    _expected(
        motion,
        {
            "joint_Root": [[0, 0, 0], [0, 0, 0]],
            "Hips": [[0.1, 0.9, -0.05], [0.2, 0.9, -0.05]],
            "Spine": [[0.1, 1.05, -0.05], [0.2, 0.9, -0.2]],
            "UpperLeg_L": [[0.1, 0.8, -0.05], [0.2, 0.9, 0.05]],
        },
    )
    # Position channels replace OFFSET; the varying Hips translation cannot live in a rotation-only rig.
    assert np.allclose(motion.skeleton.offsets[3], [-0.1, 0, 0])
    assert motion.meta["varying_translation_joints"] == ["Hips"]
    assert motion.local_rotations is None and motion.root_translation is None


def _one_bone(channels: str, values: list[float], child_offset: str = "1 2 3") -> str:
    n = len(channels.split())
    return (
        "HIERARCHY\nROOT a\n{\n OFFSET 0 0 0\n"
        f" CHANNELS {n} {channels}\n JOINT b\n {{\n  OFFSET {child_offset}\n  CHANNELS 0\n"
        "  End Site\n  {\n   OFFSET 0 1 0\n  }\n }\n}\n"
        f"MOTION\nFrames: 1\nFrame Time: 0.04\n{' '.join(map(str, values))}\n"
    )


@pytest.mark.parametrize("order", ORDERS)
def test_every_rotation_order_matches_scipy_intrinsic(order: str) -> None:
    angles = [37.0, -61.0, 112.0]
    channels = "Xposition Yposition Zposition " + " ".join(f"{a}rotation" for a in order)
    motion = parse_bvh_text(_one_bone(channels, [0.5, 0.25, -1.0, *angles]), units="m")
    expected = np.array([0.5, 0.25, -1.0]) + Rotation.from_euler(order, angles, degrees=True).apply([1, 2, 3])
    assert np.allclose(motion.joints[0, 1], expected, atol=1e-6)
    assert not np.allclose(
        motion.joints[0, 1],
        np.array([0.5, 0.25, -1.0])
        + Rotation.from_euler(order.lower(), angles, degrees=True).apply([1, 2, 3]),
        atol=1e-3,
    )


def test_channels_interleaved_and_partial_positions() -> None:
    text = _one_bone("Zrotation Yposition Xrotation Yrotation", [90.0, 5.0, 0.0, 0.0])
    motion = parse_bvh_text(text, units="m")
    # Only Y is a channel: X and Z of the root keep its OFFSET (0, _, 0).
    assert np.allclose(motion.joints[0], [[0, 5, 0], [-2, 6, 3]], atol=1e-6)


def test_units_override_and_detection() -> None:
    text = (DATA / "cmu_style.bvh").read_text()
    assert parse_bvh_text(text, units="m").joints[0, 0, 1] == pytest.approx(90.0)
    scaled = parse_bvh_text(text, scale=0.5)
    assert scaled.joints[0, 0, 1] == pytest.approx(45.0) and scaled.meta["units_detected"] == "scale"
    assert parse_bvh_text(text.replace("90.0 0.0", "900.0 0.0"), units="mm").joints[0, 0, 1] == pytest.approx(
        0.9
    )
    with pytest.raises(ConfigError):
        parse_bvh_text(text, units="furlong")
    with pytest.raises(ConfigError):
        parse_bvh_text(text, scale=-1.0)


def test_zero_length_bones_are_kept() -> None:
    motion = parse_bvh_text(_one_bone("Zrotation", [45.0], child_offset="0 0 0"), units="m")
    assert np.allclose(motion.joints[0], 0.0)
    assert motion.skeleton.bone_lengths()[1] == 0.0


def test_names_with_spaces_and_upper_case_end_site(tmp_path: Path) -> None:
    text = (
        "HIERARCHY\nROOT Bip01 Pelvis\n{\n OFFSET 0 90 0\n CHANNELS 6 Xposition Yposition Zposition"
        " Zrotation Xrotation Yrotation\n JOINT Bip01 L Thigh {\n  OFFSET 10 0 0\n"
        "  CHANNELS 3 Zrotation Xrotation Yrotation\n  END Site\n  {\n   OFFSET 0 -40 0\n  }\n }\n}\n"
        "MOTION\nFrames: 1\nFrame Time: 0.0333333\n0 90 0 0 0 0 90 0 0\n"
    )
    motion = parse_bvh_text(text, units="cm")
    assert motion.skeleton.names == ("Bip01 Pelvis", "Bip01 L Thigh")
    np.testing.assert_allclose(motion.joints[0], [[0, 0.9, 0], [0.1, 0.9, 0]], atol=1e-6)
    write_bvh(tmp_path / "max.bvh", motion)
    assert read_bvh(tmp_path / "max.bvh").skeleton.names == ("Bip01_Pelvis", "Bip01_L_Thigh")


def test_a_ground_projected_root_is_dropped_from_joints_only_export(tmp_path: Path) -> None:
    motion = _chain_motion(np.random.default_rng(4))
    skel = motion.skeleton
    ground = motion.joints[:, :1] * np.array([1.0, 0.0, 1.0])
    parents = np.concatenate([[-1], np.where(skel.parents < 0, 0, skel.parents + 1)])
    offsets = np.concatenate([np.zeros((1, 3)), skel.offsets])
    projected = Motion(
        np.concatenate([ground, motion.joints], axis=1),
        30.0,
        Skeleton(("Ground", *skel.names), parents, offsets),
    )
    report = write_bvh(tmp_path / "ground.bvh", projected)
    assert report["dropped_root"] == "Ground" and report["joints"] == skel.n_joints
    back = read_bvh(tmp_path / "ground.bvh")
    assert back.skeleton.names == skel.names
    np.testing.assert_allclose(back.joints, motion.joints, atol=1e-4)
    assert write_bvh(tmp_path / "plain.bvh", Motion(motion.joints, 30.0, skel))["dropped_root"] is None


def _chain_motion(rng: np.random.Generator, order: str = "ZXY") -> Motion:
    skel = Skeleton(
        ("root", "spine", "head", "arm", "hand"),
        np.array([-1, 0, 1, 1, 3]),
        np.array([[0, 0.9, 0], [0, 0.2, 0], [0, 0.3, 0], [0.15, 0.1, 0], [0.3, 0, 0]]),
        ((2, (0.0, 0.1, 0.0)),),
    )
    T = 13
    rots = euler_to_quat(np.cumsum(rng.uniform(-20, 20, (T, 5, 3)), axis=0), order)
    root = np.cumsum(rng.uniform(-0.05, 0.05, (T, 3)), axis=0) + np.array([0, 0.9, 0])
    joints = forward_kinematics(skel, rots, root)
    return Motion(joints, 30.0, skel, rots, root, action="wave", meta={"style": "x"})


@pytest.mark.parametrize("order", ["ZXY", "XYZ", "YZX"])
def test_write_read_round_trip(tmp_path: Path, order: str) -> None:
    motion = _chain_motion(np.random.default_rng(3), order)
    report = write_bvh(tmp_path / "out.bvh", motion, rotation_order=order)
    assert report["fk_error_m"] < 1e-6 and report["rotations_from"] == "rotations"
    back = read_bvh(tmp_path / "out.bvh")
    assert back.meta["units_detected"] == "m"
    assert back.skeleton.names == motion.skeleton.names
    assert np.max(np.abs(back.joints - motion.joints)) < 1e-5
    assert back.fps == pytest.approx(30.0, rel=1e-8)
    # Read -> write -> read of a file gives the same positions again.
    again = parse_bvh_text(format_bvh(back, order)[0])
    assert np.max(np.abs(again.joints - back.joints)) < 1e-5


def test_golden_file_round_trip(tmp_path: Path) -> None:
    motion = read_bvh(DATA / "cmu_style.bvh")
    write_bvh(tmp_path / "cmu.bvh", motion, units="cm")
    back = read_bvh(tmp_path / "cmu.bvh")
    assert back.meta["units_detected"] == "cm"
    assert np.max(np.abs(back.joints - motion.joints)) < 1e-5


def test_writer_output_read_by_bvhio(tmp_path: Path) -> None:
    motion = _chain_motion(np.random.default_rng(4))
    write_bvh(tmp_path / "out.bvh", motion)
    root = bvhio.readAsHierarchy(str(tmp_path / "out.bvh"))
    layout = root.layout()
    assert [joint.Name for joint, _, _ in layout] == list(motion.skeleton.names)
    for frame in range(motion.n_frames):
        root.loadPose(frame)
        pos = np.array([list(joint.PositionWorld) for joint, _, _ in layout])
        assert np.allclose(pos, motion.joints[frame], atol=1e-5)


def test_writer_format_details(tmp_path: Path) -> None:
    motion = _chain_motion(np.random.default_rng(5))
    skel = motion.skeleton
    renamed = Skeleton(("root joint", "spine", "3head", "arm-1", "arm_1"), skel.parents, skel.offsets)
    motion = Motion(motion.joints, 1 / 0.0083333, renamed, motion.local_rotations, motion.root_translation)
    text, report = format_bvh(motion)
    assert text.endswith("\n") and "\r" not in text
    assert "ROOT root_joint" in text and "JOINT _3head" in text and "JOINT arm_1_2" in text
    assert report["renamed"] == {
        "root joint": "root_joint",
        "3head": "_3head",
        "arm-1": "arm_1",
        "arm_1": "arm_1_2",
    }
    lines = text.split("\n")
    assert lines[lines.index("MOTION") + 2] == "Frame Time: 0.0083333"
    assert all(line.strip() in {"{", "}"} for line in lines if "{" in line or "}" in line)
    assert text.count("CHANNELS 6 Xposition Yposition Zposition Zrotation Xrotation Yrotation") == 1
    assert text.count("CHANNELS 3 Zrotation Xrotation Yrotation") == 4
    assert text.count("End Site") == 2  # the head's own site and one added under the leaf "hand"
    assert parse_bvh_text(text).skeleton.names == ("root_joint", "spine", "_3head", "arm_1", "arm_1_2")


def test_writer_eulers_are_continuous(tmp_path: Path) -> None:
    skel = Skeleton(("a", "b"), np.array([-1, 0]), np.array([[0, 0, 0], [0, 1.0, 0]]))
    z = np.linspace(0, 1000, 101)
    rots = np.zeros((101, 2, 4))
    rots[..., 0] = 1
    rots[:, 0] = (
        euler_to_quat(np.stack([z, 0 * z, 0 * z], 1), "ZXY") * np.where(np.arange(101) % 2, -1, 1)[:, None]
    )
    joints = forward_kinematics(skel, rots, np.zeros((101, 3)))
    text, _ = format_bvh(Motion(joints, 30, skel, rots, np.zeros((101, 3))))
    data = np.array(text.split("Frame Time: ")[1].split()[1:], float).reshape(101, 9)
    assert np.allclose(data[:, 3], z, atol=1e-5)


def test_writer_rejects_bad_input_and_leaves_no_file(tmp_path: Path) -> None:
    motion = _chain_motion(np.random.default_rng(6))
    with pytest.raises(ConfigError):
        write_bvh(tmp_path / "bad.bvh", motion, rotation_order="ZZY")
    rots = motion.local_rotations.copy()
    rots[3, 2] = np.nan
    broken = Motion(motion.joints, 30, motion.skeleton, rots, motion.root_translation)
    with pytest.raises(ConfigError):
        write_bvh(tmp_path / "bad.bvh", broken)
    assert list(tmp_path.iterdir()) == []


def test_writer_uses_ik_without_rotations(tmp_path: Path) -> None:
    motion = _chain_motion(np.random.default_rng(7)).with_joints(
        _chain_motion(np.random.default_rng(7)).joints
    )
    report = write_bvh(tmp_path / "ik.bvh", motion)
    assert report["rotations_from"] == "ik"
    back = read_bvh(tmp_path / "ik.bvh")
    assert np.mean(np.linalg.norm(back.joints - motion.joints, axis=-1)) == pytest.approx(
        report["fk_error_m"], abs=1e-5
    )


BAD_CASES = {
    "empty": ("", None),
    "fewer lines than frames": ("Frames: 2|Frames: 3", 40),
    "extra line": ("Frame Time: .0083333\n|Frame Time: .0083333\n" + "0 " * 18 + "\n", 40),
    "wrong value count": ("0.0 90.0 0.0 0.0 0.0 0.0 0.0|0.0 90.0 0.0 0.0 0.0", 38),
    "nan": ("5.0 90.0|5.0 nan", 39),
    "inf": ("5.0 90.0|5.0 -inf", 39),
    "not a number": ("5.0 90.0|5.0 9O.0", 39),
    "zero frame time": (".0083333|0", 37),
    "absurd frame time": (".0083333|1e6", 37),
    "negative frame time": (".0083333|-0.01", 37),
    "unknown channel": ("Xrotation\n        End Site|Wrotation\n        End Site", 17),
    "duplicate joint": ("JOINT Spine|JOINT LeftUpLeg", 25),
    "zero frames": ("Frames: 2|Frames: 0", 36),
    "missing brace": ("    }\n  }\n  JOINT Spine|    }\n  JOINT Spine", 34),
    "extra brace": ("}\nMOTION|}\n}\nMOTION", 35),
    "stray token": ("OFFSET 10.00 0.00 0.00|OFFSET 10.00 0.00 0.00 7", 12),
    "truncated hierarchy": ("  JOINT Spine|MOTION\n  JOINT Spine", 25),
    "second root": ("}\nMOTION|}\nROOT X\n{\n}\nMOTION", 35),
}


@pytest.mark.parametrize("case", sorted(BAD_CASES))
def test_bad_files_raise_motion_format_error_with_line(case: str) -> None:
    good = (DATA / "cmu_style.bvh").read_text()
    change, line = BAD_CASES[case]
    if case == "empty":
        text = ""
    else:
        old, new = change.split("|")
        assert old in good
        text = good.replace(old, new, 1)
    with pytest.raises(MotionFormatError) as info:
        parse_bvh_text(text, path="bad.bvh")
    assert info.value.path == "bad.bvh"
    if line is not None:
        assert info.value.line == line, str(info.value)


def test_binary_and_non_utf8_files(tmp_path: Path) -> None:
    (tmp_path / "bin.bvh").write_bytes(b"HIERARCHY\n\x00\x01\x02garbage")
    (tmp_path / "latin.bvh").write_bytes((DATA / "cmu_style.bvh").read_bytes().replace(b"Spine", b"Sp\xefne"))
    with pytest.raises(MotionFormatError) as info:
        read_bvh(tmp_path / "bin.bvh")
    assert info.value.line == 2
    with pytest.raises(MotionFormatError) as info:
        read_bvh(tmp_path / "latin.bvh")
    assert info.value.line == 25
    with pytest.raises(MotionFormatError):
        read_bvh(tmp_path / "missing.bvh")


def test_resample_interpolates_and_keeps_duration() -> None:
    motion = _chain_motion(np.random.default_rng(8))
    half = resample_motion(motion, 15.0)
    assert half.n_frames == 7 and half.fps == 15.0
    assert np.allclose(half.joints, motion.joints[::2])
    assert np.allclose(half.local_rotations, motion.local_rotations[::2])
    assert half.action == "wave" and half.meta == {"style": "x", "resampled_from_fps": 30.0}
    double = resample_motion(motion, 60.0)
    assert double.n_frames == 25 and double.duration == pytest.approx(motion.duration)
    assert np.allclose(double.joints[1], (motion.joints[0] + motion.joints[1]) / 2, atol=1e-6)
    assert np.allclose(
        double.root_translation[3], (motion.root_translation[1] + motion.root_translation[2]) / 2
    )


def test_resample_slerps_rotations() -> None:
    skel = Skeleton(("a", "b"), np.array([-1, 0]), np.array([[0, 0, 0], [1.0, 0, 0]]))
    rots = np.zeros((2, 2, 4))
    rots[..., 0] = 1
    rots[1, 0] = euler_to_quat(np.array([90.0]), "Z")
    motion = Motion(np.zeros((2, 2, 3)), 10, skel, rots, np.zeros((2, 3)))
    up = resample_motion(motion, 30)
    assert up.n_frames == 4
    for k in range(4):
        assert np.allclose(
            np.abs(np.sum(up.local_rotations[k, 0] * euler_to_quat(np.array([30.0 * k]), "Z"))), 1
        )
    with pytest.raises(ConfigError):
        resample_motion(motion, 0)
    with pytest.raises(ConfigError):
        resample_motion(motion, float("nan"))


def _chain_bvh(offsets: dict[str, str], root_channels: str, joint_channels: str, rows: list[str]) -> str:
    """A hips → spine → head chain with one leg, in the given offsets, channel orders and frame rows."""
    return (
        "HIERARCHY\nROOT Hips\n{\n  OFFSET 0 0 0\n"
        f"  CHANNELS 6 {root_channels}\n"
        f"  JOINT Spine\n  {{\n    OFFSET {offsets['Spine']}\n    CHANNELS 3 {joint_channels}\n"
        f"    JOINT Head\n    {{\n      OFFSET {offsets['Head']}\n      CHANNELS 3 {joint_channels}\n"
        f"      End Site\n      {{\n        OFFSET {offsets['Head']}\n      }}\n    }}\n  }}\n"
        f"  JOINT LeftLeg\n  {{\n    OFFSET {offsets['LeftLeg']}\n    CHANNELS 3 {joint_channels}\n"
        f"    End Site\n    {{\n      OFFSET {offsets['LeftLeg']}\n    }}\n  }}\n}}\n"
        f"MOTION\nFrames: {len(rows)}\nFrame Time: 0.05\n" + "\n".join(rows) + "\n"
    )


def test_z_up_files_are_turned_y_up_with_consistent_rotations(tmp_path: Path) -> None:
    rng = np.random.default_rng(4)
    y_rows, z_rows = [], []
    for _ in range(5):
        px, py, pz = rng.uniform(-50, 50, 3)
        angles = rng.uniform(-60, 60, (4, 3))  # (Z, X, Y) degrees of the root and each joint
        y_rows.append(" ".join(f"{v:.4f}" for v in (px, py, pz, *angles.ravel())))
        # Written by hand for Z-up: (x, y, z) → (x, −z, y); a turn about y becomes one about z and a turn
        # about z one about −y, so Z X Y angles (a, b, c) become Y X Z angles (−a, b, c).
        z_angles = np.column_stack([-angles[:, 0], angles[:, 1], angles[:, 2]])
        z_rows.append(" ".join(f"{v:.4f}" for v in (px, -pz, py, *z_angles.ravel())))
    positions = "Xposition Yposition Zposition"
    y_text = _chain_bvh(
        {"Spine": "0 10 0", "Head": "0 10 0", "LeftLeg": "5 -15 0"},
        f"{positions} Zrotation Xrotation Yrotation", "Zrotation Xrotation Yrotation", y_rows
    )  # fmt: skip
    z_text = _chain_bvh(
        {"Spine": "0 0 10", "Head": "0 0 10", "LeftLeg": "5 0 -15"},
        f"{positions} Yrotation Xrotation Zrotation", "Yrotation Xrotation Zrotation", z_rows
    )  # fmt: skip
    y_file, z_file = tmp_path / "y_up.bvh", tmp_path / "z_up.bvh"
    y_file.write_text(y_text)
    z_file.write_text(z_text)
    truth = read_bvh(y_file, units="cm")
    assert not looks_z_up(truth) and "turned_from_up_axis" not in truth.meta
    assert looks_z_up(read_bvh(z_file, units="cm"))  # read as Y-up, it lies on its back
    turned = read_bvh(z_file, units="cm", up_axis="z")
    assert turned.meta["turned_from_up_axis"] == "z" and not looks_z_up(turned)
    np.testing.assert_allclose(turned.joints, truth.joints, atol=1e-5)
    np.testing.assert_allclose(turned.skeleton.offsets, truth.skeleton.offsets, atol=1e-9)
    fk = forward_kinematics(turned.skeleton, turned.local_rotations, turned.root_translation)
    np.testing.assert_allclose(fk, truth.joints, atol=1e-5)
    write_bvh(tmp_path / "out.bvh", turned)
    np.testing.assert_allclose(read_bvh(tmp_path / "out.bvh").joints, truth.joints, atol=1e-4)
    with pytest.raises(ConfigError, match="up axis must be one of y, z, got 'x'"):
        read_bvh(y_file, up_axis="x")
