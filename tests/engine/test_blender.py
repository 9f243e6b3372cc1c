"""A real client: Blender's own BVH importer reads our files and poses the same joints."""

from __future__ import annotations

import json
import shutil
import subprocess
from pathlib import Path

import numpy as np
import pytest

from engine.motion.bvh import read_bvh, write_bvh
from engine.motion.motion import Motion
from engine.motion.rotations import euler_to_quat, forward_kinematics

SCRIPT = Path(__file__).resolve().parents[1] / "data" / "blender_fk.py"
DATA = Path(__file__).resolve().parents[1] / "data"

pytestmark = [
    pytest.mark.blender,
    pytest.mark.slow,
    pytest.mark.skipif(shutil.which("blender") is None, reason="no blender binary on PATH"),
]


def _blender_positions(bvh: Path, out: Path) -> tuple[list[str], np.ndarray]:
    """Joint names and (T, J, 3) world positions converted from Blender's z-up to our y-up."""
    subprocess.run(
        ["blender", "-b", "--factory-startup", "--python", str(SCRIPT), "--", str(bvh), str(out)],
        check=True,
        capture_output=True,
        timeout=120,
    )
    result = json.loads(out.read_text())
    z_up = np.array(result["frames"])
    return result["names"], np.stack([z_up[..., 0], z_up[..., 2], -z_up[..., 1]], axis=-1)


def test_blender_imports_our_file_with_the_same_joint_positions(tmp_path: Path) -> None:
    rest = read_bvh(DATA / "cmu_style.bvh").skeleton
    rng = np.random.default_rng(11)
    T = 20
    rots = euler_to_quat(np.cumsum(rng.uniform(-15, 15, (T, rest.n_joints, 3)), axis=0), "ZXY")
    root = np.cumsum(rng.uniform(-0.03, 0.03, (T, 3)), axis=0) + np.array([0, 0.9, 0])
    motion = Motion(forward_kinematics(rest, rots, root), 30.0, rest, rots, root)
    write_bvh(tmp_path / "ours.bvh", motion, rotation_order="YXZ")
    names, positions = _blender_positions(tmp_path / "ours.bvh", tmp_path / "blender.json")
    assert names == list(rest.names)
    assert positions.shape == motion.joints.shape
    assert np.abs(positions - motion.joints).max() < 0.01
