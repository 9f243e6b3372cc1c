"""The start-up profile of bench/odmo_start.py on motion whose heights and speeds are known."""

from __future__ import annotations

import numpy as np
import pytest

from bench.odmo_start import profile


def test_profile_reads_root_height_lowest_foot_and_foot_speed() -> None:
    fps, frames = 4.0, 8
    t = np.arange(frames)
    joints = np.zeros((2, frames, 5, 3))
    joints[:, :, 0, 1] = 0.9 + 0.01 * t  # root rising 1 cm a frame
    joints[:, :, 1, 1] = 0.10  # one foot held at 10 cm
    joints[:, :, 2, 1] = 0.05 + 0.01 * t  # the other climbing from 5 cm
    joints[:, :, 1:3, 0] = (t / fps)[:, None]  # both feet travelling at 1 m/s
    joints[:, :, 3, 1] = 1.2  # one hand held low
    joints[:, :, 4, 1] = 1.0 + 0.1 * t  # the other raised past it from frame 3
    out = profile(joints, [1, 2], [3, 4], frames=5, fps=fps)
    assert out["root_m"] == pytest.approx([0.90, 0.91, 0.92, 0.93, 0.94])
    assert out["lowest_foot_m"] == pytest.approx([0.05, 0.06, 0.07, 0.08, 0.09])
    assert out["highest_hand_m"] == pytest.approx([1.2, 1.2, 1.2, 1.3, 1.4])
    climbing = np.hypot(0.25, 0.01) * fps
    assert out["foot_speed_per_quarter_s"] == pytest.approx([round((1.0 + climbing) / 2, 2)] * (frames - 1))
