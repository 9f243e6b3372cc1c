"""The reader on 50 real Bandai-Namco-2 clips: rigid bones, feet on the floor, human height, speed."""

from __future__ import annotations

import time
from pathlib import Path

import numpy as np
import pytest

from engine.motion.bvh import read_bvh, write_bvh


@pytest.fixture(scope="module")
def clips(bandai_dir: Path) -> list[Path]:
    """50 clips spread over the sorted file list (all actions and styles)."""
    files = sorted((bandai_dir / "data").glob("*.bvh"))
    return files[:: max(1, len(files) // 50)][:50]


def test_real_clips_are_rigid_grounded_and_human_sized(clips: list[Path]) -> None:
    assert len(clips) == 50
    for path in clips:
        motion = read_bvh(path)
        skel = motion.skeleton
        assert skel.n_joints == 22 and skel.names[0] == "joint_Root", path
        assert motion.meta["units_detected"] == "cm" and motion.fps == pytest.approx(30.0, rel=1e-5)
        # joint_Root is static; the body's translation rides on Hips' position channels.
        assert motion.meta["varying_translation_joints"] == ["Hips"]
        hips = skel.index("Hips")
        bones = [j for j in range(skel.n_joints) if skel.parents[j] >= 0 and j != hips]
        lengths = np.linalg.norm(motion.joints[:, bones] - motion.joints[:, skel.parents[bones]], axis=-1)
        assert np.ptp(lengths, axis=0).max() < 1e-4, path
        feet = [skel.index(n) for n in ("Foot_L", "Foot_R", "Toes_L", "Toes_R")]
        assert -0.05 <= motion.joints[:, feet, 1].min() <= 0.15, path
        # Bandai's Head joint is the base of the skull (its End Site has zero length): ~1.3-1.4 m.
        head = motion.joints[:, skel.index("Head"), 1].max() - motion.joints[:, feet, 1].min()
        assert 1.2 <= head <= 1.8, path
        assert 0.75 <= np.median(motion.joints[:, hips, 1]) <= 1.15, path


def test_real_clip_write_and_read_back(clips: list[Path], tmp_path: Path) -> None:
    motion = read_bvh(clips[0])
    # Drop the static joint_Root so the writer's IK sees rigid bones only.
    body = motion.skeleton.subset(range(1, motion.n_joints))
    trimmed = type(motion)(motion.joints[:, 1:], motion.fps, body)
    report = write_bvh(tmp_path / "clip.bvh", trimmed)
    back = read_bvh(tmp_path / "clip.bvh")
    assert back.meta["units_detected"] == "m" and back.skeleton.names == body.names
    err = np.linalg.norm(back.joints - trimmed.joints, axis=-1).mean()
    assert err == pytest.approx(report["fk_error_m"], abs=1e-5)
    assert err < 0.02


def test_parse_speed_of_a_200_frame_clip(clips: list[Path]) -> None:
    path = min(clips, key=lambda p: abs(read_bvh(p).n_frames - 200))
    times = []
    for _ in range(5):
        start = time.perf_counter()
        read_bvh(path)
        times.append(time.perf_counter() - start)
    # Target is 20 ms (about 11 ms measured); the bound leaves room for a busy shared machine.
    assert min(times) < 0.1
