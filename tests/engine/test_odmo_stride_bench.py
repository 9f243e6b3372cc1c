"""The stride figures of bench/odmo_stride.py on motion whose stride, phase and hand speed are known."""

from __future__ import annotations

import numpy as np
import pytest
import torch

from bench.odmo_stride import (
    fitted_codes,
    primed_decode,
    probe_r2,
    stance_figures,
    stride_figures,
    strides,
)
from engine.model.config import OdmoConfig
from engine.model.odmo import OdmoModel


def _gait(amplitude: float, phase: float, direction: tuple[float, float], frames: int = 40) -> np.ndarray:
    """(1, frames, 4, 3): a root walking at 1 m/s along ``direction`` (x, z), two ankles leading each
    other by ``amplitude``·sin about it at 1 Hz, and a hand circling the root at 0.5 m/s (20 fps)."""
    t = np.arange(frames) / 20.0
    d = np.array([direction[0], 0.0, direction[1]])
    root = t[:, None] * d + np.array([0.0, 0.9, 0.0])
    lead = amplitude / 2 * np.sin(2 * np.pi * (t - phase))
    joints = np.zeros((1, frames, 4, 3))
    joints[0, :, 0] = root
    joints[0, :, 1] = root + lead[:, None] * d
    joints[0, :, 2] = root - lead[:, None] * d
    angle = 0.5 * t / 0.1  # a 0.1 m circle at 0.5 m/s
    joints[0, :, 3] = root + np.stack([0.1 * np.cos(angle), np.full_like(t, 0.5), 0.1 * np.sin(angle)], 1)
    return joints


def test_the_stride_is_the_ankles_lead_along_the_travel_whichever_way_it_goes() -> None:
    sideways = _gait(0.6, 0.0, (1.0, 0.0))
    expected = 0.6 * np.sin(2 * np.pi * np.arange(40) / 20)
    np.testing.assert_allclose(strides(sideways, (1, 2), 0)[0], expected, atol=1e-12)
    standing = sideways.copy()
    standing[..., 0, :] = standing[:, :1, 0]  # the root stays: the lead is read along +z, here 0
    np.testing.assert_allclose(strides(standing, (1, 2), 0), 0.0, atol=1e-12)


def test_stride_figures_see_a_damped_stride_its_phase_and_the_hand() -> None:
    real = _gait(0.6, 0.0, (0.6, 0.8))
    same = stride_figures(real, real, (1, 2), [3], 0, 20.0)
    assert same["stride_m"] == pytest.approx(0.6 / np.sqrt(2), abs=1e-3)  # a sine's std: amplitude / √2
    assert same["phase_r"] == pytest.approx(1.0)
    assert same["hand_speed_m_s"] == pytest.approx(0.5, abs=0.01)
    damped = stride_figures(_gait(0.15, 0.5, (0.6, 0.8)), real, (1, 2), [3], 0, 20.0)
    assert damped["stride_m"] == pytest.approx(0.15 / np.sqrt(2), abs=1e-3)
    assert damped["phase_r"] == pytest.approx(-1.0)  # half a cycle out of phase


def test_a_decode_primed_with_no_frame_runs_free_and_with_every_frame_is_teacher_forced() -> None:
    """An untrained model's primed decode: 0 real frames is its free decode, the whole window its
    teacher-forced one, 5 frames the teacher-forced one up to frame 5 and its own after."""
    model = OdmoModel(OdmoConfig(n_actions=2, n_joints=4, window=12), seed=3).eval()
    generator = torch.Generator().manual_seed(0)
    z = torch.randn(3, 20, generator=generator)
    actions, ends = torch.tensor([0, 1, 1]), torch.randn(3, 3, generator=generator)
    truth = torch.randn(3, 12, 4, 3, generator=generator)
    with torch.no_grad():
        free = model.decode_full(z, actions, ends).joints
        forced = model.decode_full(z, actions, ends, prev_truth=truth, tf_rate=1.0).joints
        torch.testing.assert_close(primed_decode(model, z, actions, ends, truth, 0), free, atol=1e-5, rtol=0)
        torch.testing.assert_close(primed_decode(model, z, actions, ends, truth, 12), forced)
        five = primed_decode(model, z, actions, ends, truth, 5)
    torch.testing.assert_close(five[:, :6], forced[:, :6])
    assert float((five[:, 6:] - forced[:, 6:]).abs().max()) > 1e-3


def test_the_code_probe_reads_what_the_codes_say_and_only_that() -> None:
    """Poses a linear function of the codes (plus 1 % noise) score about 1; poses independent of them
    at most about 0."""
    rng = np.random.default_rng(0)
    codes = rng.normal(size=(200, 20))
    said = codes @ rng.normal(size=(20, 9)) + 0.01 * rng.normal(size=(200, 9))
    assert probe_r2(codes, said) > 0.99
    assert probe_r2(codes, rng.normal(size=(200, 9))) < 0.05


def test_stance_figures_read_the_lower_foot_and_the_gap_between_the_feet() -> None:
    """One foot on the floor standing still, the other 10 cm up moving at 1 m/s: the lowest foot stands
    (2 mm/s, the square root's guard) and the gap is 10 cm; swap the heights and the lowest foot moves."""
    joints = np.zeros((1, 40, 3, 3))
    joints[0, :, 2, 1] = 0.1
    joints[0, :, 2, 0] = np.arange(40) / 20.0
    walking = stance_figures(joints, [1, 2], (0.0, 0.0), (1, 2), 20.0)
    assert walking == {"stance_m_s": pytest.approx(0.002, abs=1e-3), "foot_gap_m": pytest.approx(0.1)}
    skimming = joints.copy()
    skimming[0, :, 1, 1], skimming[0, :, 2, 1] = 0.1, 0.0
    assert stance_figures(skimming, [1, 2], (0.0, 0.0), (1, 2), 20.0)["stance_m_s"] == pytest.approx(
        1.0, abs=1e-3
    )


def test_hand_figures_read_the_rhythm_and_whether_the_hands_follow() -> None:
    """The hand circles at 5 rad/s (0.80 Hz); a decode whose hand circles the other way round follows
    on one axis and opposes on the other (r 0), one mirrored through the root opposes (r −1)."""
    real = _gait(0.6, 0.0, (0.6, 0.8), frames=81)
    same = stride_figures(real, real, (1, 2), [3], 0, 20.0)
    assert same["hand_r"] == pytest.approx(1.0)
    assert same["hand_rhythm_hz"] == pytest.approx(5 / (2 * np.pi), abs=0.05)
    mirrored = real.copy()
    mirrored[..., 3, :] = 2 * real[..., 0, :] - real[..., 3, :]
    assert stride_figures(mirrored, real, (1, 2), [3], 0, 20.0)["hand_r"] == pytest.approx(-1.0)
    backwards = real.copy()
    backwards[..., 3, 2] = 2 * real[..., 0, 2] - real[..., 3, 2]  # z mirrored: the circle turns back
    assert abs(stride_figures(backwards, real, (1, 2), [3], 0, 20.0)["hand_r"]) < 0.05


def test_fitted_codes_bring_the_free_decode_closer_and_leave_the_model_as_it_was() -> None:
    """Fitting codes to decodes of other codes (so a fit exists) cuts the error; the weights stay."""
    model = OdmoModel(OdmoConfig(n_actions=2, n_joints=4, window=12), seed=3).eval()
    generator = torch.Generator().manual_seed(0)
    z, target = torch.randn(3, 20, generator=generator), torch.randn(3, 20, generator=generator)
    actions, ends = torch.tensor([0, 1, 1]), torch.randn(3, 3, generator=generator)
    with torch.no_grad():
        truth = model.decode_full(target, actions, ends).joints
    before = {k: v.clone() for k, v in model.state_dict().items()}

    def error(codes: torch.Tensor) -> float:
        with torch.no_grad():
            joints = model.decode_full(codes, actions, ends).joints
        about = lambda j: j - j[:, :, :1]  # noqa: E731
        return float((about(joints) - about(truth)).square().mean())

    fitted = fitted_codes(model, z, actions, ends, truth, steps=50)
    assert error(fitted) < 0.5 * error(z)
    assert all(torch.equal(v, model.state_dict()[k]) for k, v in before.items())
    assert all(p.requires_grad for p in model.parameters())
