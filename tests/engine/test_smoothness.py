"""max_frame_jump on motions whose largest step is known."""

import numpy as np

from engine.metrics.smoothness import max_frame_jump


def test_largest_step_is_found() -> None:
    motions = np.zeros((2, 5, 3, 3))
    motions[1, 3:, 2] = [0.3, 0.4, 0.0]  # one joint jumps 0.5 m between frames 2 and 3
    assert np.isclose(max_frame_jump(motions), 0.5)


def test_masked_frames_do_not_count() -> None:
    motions = np.zeros((1, 4, 1, 3))
    motions[0, 3, 0, 0] = 9.0
    mask = np.array([[True, True, True, False]])
    assert max_frame_jump(motions, mask) == 0.0
    assert max_frame_jump(motions) == 9.0
