"""``odmo info`` and ``odmo convert`` through engine.cli.main and the installed console script."""

from __future__ import annotations

import pickle
import shutil
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from engine.cli import main
from engine.motion.axes import Z_UP_TO_Y_UP, rotated
from engine.motion.bvh import read_bvh, write_bvh
from engine.motion.npz import read_npz


def test_info_of_a_bandai_bvh(bandai_dir: Path, capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["info", str(bandai_dir / "data" / "dataset-2_walk_normal_001.bvh")]) == 0
    out = capsys.readouterr().out
    assert (
        "frames:    273" in out
        and "fps:       30" in out
        and "joints:    22" in out
        and "units:     m" in out
    )


def test_convert_bvh_npz_bvh_with_resampling(bandai_dir: Path, tmp_path: Path, capsys) -> None:
    source = bandai_dir / "data" / "dataset-2_walk_normal_001.bvh"
    npz, bvh = tmp_path / "walk.npz", tmp_path / "walk.bvh"
    assert main(["convert", str(source), str(npz), "--fps", "20", "--drop-joints", "joint_Root"]) == 0
    clip = read_npz(npz)
    assert clip.fps == 20.0 and clip.n_joints == 21 and clip.n_frames == 182
    assert main(["convert", str(npz), str(bvh)]) == 0
    out = capsys.readouterr().out
    error_mm = float(out.split("joints converted to rotations by IK: mean FK error")[1].split()[0])
    assert 0 <= error_mm < 10
    back = read_bvh(bvh)
    assert np.mean(np.linalg.norm(back.joints - clip.joints, axis=-1)) < 0.01
    assert main(["info", str(bvh)]) == 0
    assert "rotations: yes" in capsys.readouterr().out


def test_npy_and_pickle_inputs(tmp_path: Path, capsys) -> None:
    joints = np.random.default_rng(0).normal(scale=0.1, size=(8, 24, 3)).astype(np.float32)
    np.save(tmp_path / "P01G01R01F0001T0008A0401.npy", joints)
    assert main(["info", str(tmp_path / "P01G01R01F0001T0008A0401.npy"), "--input-fps", "10"]) == 0
    out = capsys.readouterr().out
    assert "label:     jump" in out and "fps:       10" in out
    pkl = tmp_path / "humanact12poses.pkl"
    pkl.write_bytes(pickle.dumps({"joints3D": [joints, joints[:5]], "y": [3, 5]}))
    assert main(["convert", str(pkl), str(tmp_path / "out")]) == 1
    assert "--allow-pickle" in capsys.readouterr().err
    assert main(["convert", str(pkl), str(tmp_path / "out"), "--allow-pickle"]) == 0
    assert sorted(p.name for p in (tmp_path / "out").iterdir()) == ["0000_jump.npz", "0001_lift_dumbbell.npz"]


@pytest.mark.parametrize(
    "argv",
    [
        ["info", "/no/such/file.bvh"],
        ["convert", "/no/such/file.bvh", "out.npz"],
        ["info", "__FILE__.txt"],
        ["convert", "__FILE__.npz", "out.fbx"],
        ["convert", "__FILE__.npz", "out.npz", "--drop-joints", "nope"],
    ],
)
def test_errors_are_one_line_with_exit_1(tmp_path: Path, capsys, argv: list[str]) -> None:
    good = tmp_path / "clip.npz"
    np.save(tmp_path / "clip.npy", np.zeros((3, 24, 3), np.float32))
    main(["convert", str(tmp_path / "clip.npy"), str(good)])
    (tmp_path / "clip.txt").write_text("hello")
    capsys.readouterr()
    argv = [a.replace("__FILE__", str(tmp_path / "clip")).replace("out.", f"{tmp_path}/out.") for a in argv]
    assert main(argv) == 1
    err = capsys.readouterr().err
    assert err.startswith(f"odmo {argv[0]}: error: ") and err.count("\n") == 1 and "Traceback" not in err


def test_console_script(tmp_path: Path) -> None:
    odmo = shutil.which("odmo") or str(Path(sys.executable).with_name("odmo"))
    bad = tmp_path / "bad.npz"
    bad.write_bytes(b"junk")
    result = subprocess.run([odmo, "info", str(bad)], capture_output=True, text=True, timeout=120)
    assert result.returncode == 1
    assert result.stderr.strip().startswith("odmo info: error:") and str(bad) in result.stderr
    assert "Traceback" not in result.stderr and result.stdout == ""


def test_info_of_a_dataset_folder(tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capsys) -> None:
    monkeypatch.setenv("ODMO_CACHE_DIR", str(tmp_path / "cache"))
    folder = tmp_path / "humanact12"
    folder.mkdir()
    for name in ["P01G01R01F0001T0010A0101", "P02G01R01F0001T0010A0201", "P02G01R01F0001T0010A0203"]:
        np.save(folder / f"{name}.npy", np.zeros((5, 24, 3), np.float32))
    assert main(["info", str(folder)]) == 0
    out = capsys.readouterr().out
    assert "clips:       3 (15 frames)" in out and "  walk: 2" in out and "  warm_up: 1" in out


def test_a_z_up_bvh_gets_a_hint_and_reads_upright_with_up_axis_z(
    bandai_dir: Path, tmp_path: Path, capsys
) -> None:
    upright = read_bvh(bandai_dir / "data" / "dataset-2_walk_normal_001.bvh")
    lying = tmp_path / "z_up.bvh"
    write_bvh(lying, rotated(upright, Z_UP_TO_Y_UP.inv()))  # joints only: through IK, joint_Root left out
    hint = "the body stands along z: if the file is Z-up, add --up-axis z"
    assert main(["info", str(lying)]) == 0
    assert f"up axis:   y; {hint}\n" in capsys.readouterr().out
    assert main(["convert", str(lying), str(tmp_path / "lying.npz")]) == 0
    assert f"  note: {hint}\n" in capsys.readouterr().out
    out = tmp_path / "upright.npz"
    assert main(["convert", str(lying), str(out), "--up-axis", "z"]) == 0
    assert "note:" not in capsys.readouterr().out
    error = np.linalg.norm(read_npz(out).joints - upright.joints[:, 1:], axis=2)
    assert error.mean() < 0.01  # metres: the IK fit of the joints-only export
    assert main(["info", str(out)]) == 0
    assert "up axis:   y (turned from z-up)\n" in capsys.readouterr().out
    upright_bvh = tmp_path / "upright.bvh"
    write_bvh(upright_bvh, upright)
    assert main(["info", str(upright_bvh)]) == 0
    assert "up axis:   y\n" in capsys.readouterr().out
    assert main(["info", str(upright_bvh), "--up-axis", "z"]) == 0  # a Y-up file turned by mistake
    assert "after turning: if the file is Y-up, leave out --up-axis z\n" in capsys.readouterr().out
    # Every input format takes the option: the lying NPZ turns upright like the BVH it came from.
    assert main(["convert", str(tmp_path / "lying.npz"), str(tmp_path / "again.npz"), "--up-axis", "z"]) == 0
    np.testing.assert_allclose(read_npz(tmp_path / "again.npz").joints, read_npz(out).joints, atol=1e-5)
