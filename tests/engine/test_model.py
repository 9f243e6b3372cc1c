"""The ODMO networks and losses: shapes, batch of one, decoding paths, masking, known loss values."""

from __future__ import annotations

import dataclasses
import math
from typing import Any

import pytest
import torch

from engine.errors import ConfigError, ModelFormatError
from engine.model import generator as generator_module
from engine.model import odmo as odmo_module
from engine.model.a2m import A2mConfig
from engine.model.config import OdmoConfig
from engine.model.dvgan import DvganConfig
from engine.model.losses import (
    COORDINATION_FLOOR,
    LOG_SPEED_FLOOR,
    SPECTRUM_FLOOR,
    LossJoints,
    amplitude_spectra,
    contrastive_loss,
    coordination_loss,
    floor_heights,
    floor_loss,
    foot_height_loss,
    heading_loss,
    masked_mse,
    mean_speeds,
    odmo_losses,
    own_contacts,
    prior_loss,
    shift_tolerant_mse,
    skate_loss,
    skim_loss,
    skim_speeds,
    span_mean_mse,
    spectrum_joints,
    spectrum_loss,
    speed_loss,
    stance_loss,
    stance_speeds,
    stand_heights,
    stand_loss,
    start_mse,
    twist_loss,
    velocity_gram,
)
from engine.model.odmo import OdmoModel
from engine.model.precision import bfloat16_autocast
from engine.motion.skeleton import Skeleton

pytestmark = pytest.mark.usefixtures("torch_single_thread")

J, T = 5, 12


def _model(**changes: object) -> OdmoModel:
    cfg = OdmoConfig(n_actions=3, n_joints=J, window=T, enc_fc=32, traj_hidden=16, motion_hidden=16)
    return OdmoModel(OdmoConfig(**(cfg.to_dict() | changes)), seed=1)


def test_shapes_and_batch_of_one_in_train_and_eval_mode() -> None:
    model = _model()
    for training in (True, False):
        model.train(training)
        mu, logvar = model.encode(torch.randn(1, T, J * 3), torch.ones(1, T, dtype=torch.bool))
        assert mu.shape == logvar.shape == (1, 20)
        joints, traj = model.decode(mu, torch.tensor([2]), torch.zeros(1, 3))
        assert joints.shape == (1, T, J, 3) and traj.shape == (1, T, 3)
        tf, _ = model.decode(
            mu, torch.tensor([2]), torch.zeros(1, 3), prev_truth=joints.detach(), tf_rate=0.5
        )
        assert tf.shape == (1, T, J, 3)
    torch.testing.assert_close(traj[:, 0], torch.zeros(1, 3))


_UPDATES: dict[str, dict[str, Any]] = {
    "absolute": {},
    "residual": {"pose_update": "residual"},
    "stepped": {"pose_update": "residual", "step_input": True},
}


def _reference_free_run(
    model: OdmoModel, z: torch.Tensor, action: torch.Tensor, end: torch.Tensor
) -> torch.Tensor:
    """Free-running decode written the plain way: one nn.LSTM call per frame on the concatenated input.

    A root-relative decoder reads back its output minus its root joint; the trajectory is the root. A
    decoder with ``velocity_input`` also reads the trajectory's step into each frame, in m/s. A residual
    decoder adds its output to the previous pose, which at frame 0 is its start pose; with ``step_input``
    it also reads the previous pose minus the one before (zero at frame 0).
    """
    gen = model.motion_gen
    n, t_len = z.shape[0], gen.window
    cond = model.condition(z, action)
    traj = model.traj_gen(cond, end)
    _, state = gen.traj_lstm(gen.traj_embed(traj))
    prev, poses = torch.zeros(n, gen.pose_dim), []
    if gen.residual:
        start = gen.start.view(-1, 3)
        prev = (start - start[:1] if gen.relative else start).flatten().expand(n, -1)
    before = prev
    for t in range(t_len):
        x = torch.cat([prev, cond, torch.full((n, 1), t / t_len)], dim=1)
        if gen.velocity_input:
            step = traj[:, t] - traj[:, t - 1] if t > 0 else torch.zeros(n, 3)
            x = torch.cat([x, step * model.config.fps], dim=1)
        if gen.step_input:
            x = torch.cat([x, prev - before], dim=1)
        before = prev
        out, state = gen.lstm(gen.embed_act(gen.embed(x))[:, None], state)
        pose = (gen.out(out[:, 0]) + (prev if gen.residual else 0.0)).view(n, -1, 3)
        if gen.relative:
            pose = pose - pose[:, :1]
        prev = pose.flatten(1)
        poses.append(prev)
    joints = torch.stack(poses, 1).view(n, t_len, -1, 3)
    return joints + traj.unsqueeze(2) if gen.relative else joints


@pytest.mark.parametrize(
    ("relative", "velocity", "update"),
    [
        (True, False, "absolute"),
        (False, False, "absolute"),
        (True, True, "absolute"),
        (True, False, "residual"),
        (True, True, "stepped"),
        (False, False, "stepped"),
    ],
)
def test_free_running_decode_matches_a_step_by_step_nn_lstm_loop(
    relative: bool, velocity: bool, update: str
) -> None:
    """``update`` "stepped": a residual decoder with ``step_input``."""
    model = _model(root_relative_poses=relative, root_velocity_input=velocity, fps=30.0, **_UPDATES[update])
    model.eval()
    if update != "absolute":
        with torch.no_grad():
            model.motion_gen.start.normal_(generator=torch.Generator().manual_seed(0))
    steps = J * 3 if update == "stepped" else 0
    assert model.motion_gen.embed.in_features == J * 3 + 3 * 20 + 1 + (3 if velocity else 0) + steps
    z, action, end = torch.randn(4, 20), torch.tensor([0, 1, 2, 1]), torch.randn(4, 3)
    with torch.no_grad():
        joints, _ = model.decode(z, action, end)
        expected = _reference_free_run(model, z, action, end)
    torch.testing.assert_close(joints, expected, atol=1e-5, rtol=1e-5)


@pytest.mark.parametrize(
    ("velocity", "update"), [(False, "absolute"), (True, "absolute"), (False, "residual"), (False, "stepped")]
)
def test_free_running_decode_trains_like_the_step_by_step_loop(velocity: bool, update: str) -> None:
    """The free-running loss terms backpropagate through the fused loop: same gradients as nn.LSTM steps."""
    model = _model(root_velocity_input=velocity, **_UPDATES[update]).train()
    z, action, end = torch.randn(3, 20), torch.tensor([0, 1, 2]), torch.randn(3, 3)
    target = torch.randn(3, T, J, 3)
    grads = []
    for decode in (
        lambda: model.decode(z, action, end)[0],
        lambda: _reference_free_run(model, z, action, end),
    ):
        model.zero_grad()
        (decode() - target).square().mean().backward()
        grads.append({n: p.grad.clone() for n, p in model.named_parameters() if p.grad is not None})
    assert grads[0].keys() == grads[1].keys() and any(n.startswith("motion_gen.lstm") for n in grads[0])
    assert ("motion_gen.start" in grads[0]) == (update != "absolute")
    for name, grad in grads[0].items():
        torch.testing.assert_close(grad, grads[1][name], atol=1e-5, rtol=1e-4, msg=name)


@pytest.mark.parametrize("batch", [1, 3])
def test_fast_decode_matches_the_reference_loop_at_default_sizes(batch: int) -> None:
    model = OdmoModel(OdmoConfig(n_actions=10, n_joints=21), seed=3).eval()
    z, action, end = torch.randn(batch, 20), torch.arange(batch) % 10, torch.randn(batch, 3)
    with torch.inference_mode():
        joints, _ = model.decode(z, action, end)
        expected = _reference_free_run(model, z, action, end)
    torch.testing.assert_close(joints, expected, atol=1e-5, rtol=1e-5)


@pytest.mark.parametrize(("residual", "stepped"), [(False, False), (True, False), (True, True)])
def test_compiled_and_eager_decoder_loops_agree(residual: bool, stepped: bool) -> None:
    model = _model(pose_update="residual", step_input=True).eval() if stepped else _model().eval()
    gen = model.motion_gen
    z, action, end = torch.randn(3, 20), torch.tensor([0, 1, 2]), torch.randn(3, 3)
    with torch.no_grad():
        cond = model.condition(z, action)
        state, const = gen._context(model.traj_gen(cond, end), cond)
        fused, bias_next, fused_step, bias_step, slope, w_ih, w_hh, bias = gen._step_weights()
        start = torch.randn(const.shape[-1])
        args = (const, bias_next, state[0], state[1], fused, slope, w_ih, w_hh, bias, start, residual)
        args += (fused_step, bias_step, stepped)
        eager = generator_module._free_run_loop(*args)
        compiled = generator_module._compiled(generator_module._free_run_loop)(*args)
    torch.testing.assert_close(compiled, eager, atol=1e-6, rtol=1e-6)


@pytest.mark.parametrize("use_end", [True, False])
def test_large_batches_decode_in_slices_like_single_rows(use_end: bool, monkeypatch) -> None:
    monkeypatch.setattr(odmo_module, "DECODE_SLICE", 3)
    model = _model(use_end_location=use_end).eval()
    z, action = torch.randn(7, 20), torch.tensor([0, 1, 2, 0, 1, 2, 0])
    end = torch.randn(7, 3) if use_end else None
    with torch.inference_mode():
        joints, traj = model.decode(z, action, end)
        rows = [
            model.decode(z[i : i + 1], action[i : i + 1], None if end is None else end[i : i + 1])
            for i in range(7)
        ]
    assert joints.shape == (7, T, J, 3) and traj.shape == (7, T, 3)
    torch.testing.assert_close(joints, torch.cat([r[0] for r in rows]), atol=1e-5, rtol=1e-5)
    torch.testing.assert_close(traj, torch.cat([r[1] for r in rows]), atol=1e-5, rtol=1e-5)


def test_cached_decoder_weights_follow_in_place_updates_and_reloads() -> None:
    model = _model().eval()
    z, action, end = torch.randn(2, 20), torch.tensor([0, 2]), torch.randn(2, 3)
    with torch.inference_mode():
        before, _ = model.decode(z, action, end)
    with torch.no_grad():
        model.motion_gen.lstm.weight_hh_l1.mul_(1.5)
        model.motion_gen.out.bias.add_(0.1)
    other = _model().eval()
    other.load_state_dict(model.state_dict())
    with torch.inference_mode():
        after, _ = model.decode(z, action, end)
        fresh, _ = other.decode(z, action, end)
        expected = _reference_free_run(model, z, action, end)
    assert not torch.allclose(before, after)
    torch.testing.assert_close(after, expected, atol=1e-5, rtol=1e-5)
    torch.testing.assert_close(fresh, expected, atol=1e-5, rtol=1e-5)


def test_free_running_decode_is_differentiable() -> None:
    model = _model().train()
    joints, _ = model.decode(torch.randn(2, 20), torch.tensor([0, 1]), torch.randn(2, 3))
    joints.square().sum().backward()
    gen = model.motion_gen
    for p in (
        gen.lstm.weight_hh_l0,
        gen.lstm.weight_ih_l1,
        gen.embed.weight,
        gen.out.bias,
        gen.embed_act.weight,
    ):
        assert p.grad is not None and p.grad.abs().sum() > 0


def test_teacher_forcing_is_causal_and_full_forcing_ignores_the_generator() -> None:
    model = _model().eval()
    z, action, end = torch.randn(2, 20), torch.tensor([0, 1]), torch.randn(2, 3)
    truth = torch.randn(2, T, J, 3)
    changed = truth.clone()
    changed[:, 6, 1] += 1.0  # one joint: a whole-body shift leaves a root-centred pose unchanged
    with torch.no_grad():
        a, _ = model.decode(z, action, end, prev_truth=truth, tf_rate=1.0)
        b, _ = model.decode(z, action, end, prev_truth=changed, tf_rate=1.0)
    torch.testing.assert_close(a[:, :7], b[:, :7])
    assert (a[:, 7] - b[:, 7]).abs().max() > 1e-4


def test_scheduled_sampling_mixes_truth_and_predictions() -> None:
    model = _model().eval()
    z, action, end = torch.randn(2, 20), torch.tensor([0, 1]), torch.randn(2, 3)
    truth = torch.randn(2, T, J, 3)
    with torch.no_grad():
        forced, _ = model.decode(z, action, end, prev_truth=truth, tf_rate=1.0)
        mixed, _ = model.decode(
            z, action, end, prev_truth=truth, tf_rate=0.5, generator=torch.Generator().manual_seed(0)
        )
        none, _ = model.decode(z, action, end, prev_truth=truth, tf_rate=0.0)
    torch.testing.assert_close(forced[:, 0], mixed[:, 0])
    assert (forced - mixed).abs().max() > 1e-4 and (none - mixed).abs().max() > 1e-4


def test_construction_is_seeded_and_leaves_global_rng_alone() -> None:
    before = torch.random.get_rng_state()
    a, b, c = _model(), _model(), OdmoModel(_model().config, seed=2)
    assert torch.equal(torch.random.get_rng_state(), before)
    sa, sb, sc = a.state_dict(), b.state_dict(), c.state_dict()
    assert all(torch.equal(sa[k], sb[k]) for k in sa)
    assert any(not torch.equal(sa[k], sc[k]) for k in sa)


def test_end_location_switch() -> None:
    with pytest.raises(ValueError, match="end locations"):
        _model().trajectory(torch.randn(2, 20), torch.tensor([0, 1]))
    off = _model(use_end_location=False)
    assert off.trajectory(torch.randn(2, 20), torch.tensor([0, 1])).shape == (2, T, 3)
    assert off.traj_gen.embed[0].in_features == 3 * 20


@pytest.mark.parametrize("exact", [True, False])
def test_exact_end_shears_the_path_onto_the_end_location(exact: bool) -> None:
    model = _model(exact_end=exact)
    z, action, end = torch.randn(4, 20), torch.tensor([0, 1, 2, 0]), 3.0 * torch.randn(4, 3)
    with torch.no_grad():
        path = model.trajectory(z, action, end)
        free = model.traj_gen._path(torch.cat([model.condition(z, action), end], dim=1))
    torch.testing.assert_close(path[:, 0], torch.zeros(4, 3))
    miss = (path[:, -1] - end).abs().max()
    assert (miss < 1e-5) if exact else torch.equal(path, free)
    if exact:
        shear = (path - free) / (end - free[:, -1]).unsqueeze(1)
        torch.testing.assert_close(shear, torch.linspace(0, 1, T).view(1, T, 1).expand(4, T, 3))


def test_root_relative_poses_put_the_root_on_the_trajectory() -> None:
    model = _model().eval()
    z, action, end = torch.randn(3, 20), torch.tensor([0, 1, 2]), torch.randn(3, 3)
    with torch.no_grad():
        free, traj = model.decode(z, action, end)
        forced, traj_f = model.decode(z, action, end, prev_truth=torch.randn(3, T, J, 3), tf_rate=0.5)
    torch.testing.assert_close(free[:, :, 0], traj, atol=1e-6, rtol=0)
    torch.testing.assert_close(forced[:, :, 0], traj_f, atol=1e-6, rtol=0)
    assert (free[:, :, 1:] - traj.unsqueeze(2)).abs().max() > 1e-3


def test_configs_saved_before_the_switches_load_as_the_paper_model() -> None:
    old = OdmoConfig(n_actions=2, n_joints=5).to_dict()
    del old["exact_end"], old["root_relative_poses"], old["train_precision"]
    cfg = OdmoConfig.from_dict(old)
    assert not cfg.exact_end and not cfg.root_relative_poses and cfg.train_precision == "float32"
    assert not OdmoModel(cfg).motion_gen.relative


def test_masked_loss_ignores_padded_frames() -> None:
    pred, target = torch.randn(3, T, J, 3), torch.randn(3, T, J, 3)
    mask = torch.ones(3, T, dtype=torch.bool)
    mask[1, 8:] = False
    base = masked_mse(pred, target, mask)
    pred2, target2 = pred.clone(), target.clone()
    pred2[1, 8:] += 100.0
    target2[1, 8:] -= 50.0
    torch.testing.assert_close(masked_mse(pred2, target2, mask), base)
    expected = torch.cat([(pred - target)[0], (pred - target)[1, :8], (pred - target)[2]]).square().mean()
    torch.testing.assert_close(base, expected)


def test_every_frame_loss_term_ignores_padding() -> None:
    model = _model()
    cfg = model.config
    joints, mask = torch.randn(4, T, J, 3), torch.ones(4, T, dtype=torch.bool)
    mask[0, 5:] = False
    kw = {
        "mu": torch.randn(4, 20),
        "logvar": torch.randn(4, 20),
        "same": torch.tensor([True, False]),
        "root": 0,
    }
    pred, free = torch.randn(4, T, J, 3), torch.randn(4, T, J, 3)
    a = odmo_losses(cfg, joints=joints, trajectory=joints[:, :, 0], mask=mask, pred_joints=pred,
                    pred_trajectory=pred[:, :, 1], free_joints=free, **kw)  # fmt: skip
    joints2, pred2, free2 = joints.clone(), pred.clone(), free.clone()
    joints2[0, 5:] = 7.0
    pred2[0, 5:] = -3.0
    free2[0, 5:] = 4.0
    b = odmo_losses(cfg, joints=joints2, trajectory=joints2[:, :, 0], mask=mask, pred_joints=pred2,
                    pred_trajectory=pred2[:, :, 1], free_joints=free2, **kw)  # fmt: skip
    assert a["free"] > 0 and a["speed"] > 0
    for k in a:
        torch.testing.assert_close(a[k], b[k])


def _circling(phase: float, radius: float = 0.2, fps: float = 20.0) -> torch.Tensor:
    """(1, 40, 2, 3): a root walking along x at 1 m/s and a hand circling it at 1 turn/s (radius m)."""
    t = torch.arange(40, dtype=torch.float64) / fps
    root = torch.stack([t, torch.zeros_like(t), torch.zeros_like(t)], dim=1)
    angle = 2 * math.pi * t + phase
    hand = root + radius * torch.stack([torch.cos(angle), torch.sin(angle), torch.zeros_like(t)], dim=1)
    return torch.stack([root, hand], dim=1)[None]


def test_mean_speeds_are_root_relative_and_phase_free() -> None:
    mask = torch.ones(1, 40, dtype=torch.bool)
    speeds = mean_speeds(_circling(0.0), mask, 20.0, root=0)
    # chord of 1/20 turn at 20 fps: 2·r·sin(π/20)·20 m/s (≈ 2π·r), the root's own walk left out
    torch.testing.assert_close(
        speeds[0, 0, 1], torch.tensor(2 * 0.2 * math.sin(math.pi / 20) * 20, dtype=torch.float64)
    )
    assert speeds[0, 0, 0] < 1e-4  # the root itself: only the sqrt guard (1e-6 m a frame)
    # the same motion half a turn later: no speed error; a hand held still: the whole speed
    assert speed_loss(_circling(math.pi), _circling(0.0), mask, 20.0, root=0) < 1e-12
    still = _circling(0.0)
    still[:, :, 1] = still[:, :, 0] + torch.tensor([0.2, 0.0, 0.0], dtype=torch.float64)
    expected = speeds[0, 0, 1] ** 2 / 2
    torch.testing.assert_close(
        speed_loss(still, _circling(0.0), mask, 20.0, root=0), expected, rtol=1e-4, atol=0
    )
    # padded frames do not count
    padded = mask.clone()
    padded[0, 20:] = False
    moved = _circling(0.0)
    moved[:, 20:] += 5.0 * torch.rand(1, 20, 2, 3, dtype=torch.float64)
    torch.testing.assert_close(
        mean_speeds(moved, padded, 20.0, 0), mean_speeds(_circling(0.0), padded, 20.0, 0)
    )


def _hand_along_y(speeds: list[float]) -> torch.Tensor:
    """(1, len + 1, 2, 3): a still root and a hand moving along y at each step's speed (m/s, 20 fps)."""
    y = torch.cat([torch.zeros(1), torch.cumsum(torch.tensor(speeds, dtype=torch.float64) / 20.0, 0)])
    joints = torch.zeros(1, len(y), 2, 3, dtype=torch.float64)
    joints[0, :, 1, 1] = y
    return joints


def test_speed_spans_see_a_burst_that_the_window_mean_does_not() -> None:
    real = _hand_along_y([0.5] * 39)  # 0.5 m/s throughout
    burst = _hand_along_y([1.5] * 13 + [0.0] * 26)  # the same window mean, all of it in the first third
    mask = torch.ones(1, 40, dtype=torch.bool)
    torch.testing.assert_close(
        mean_speeds(burst, mask, 20.0, 0, span=13)[0, :, 1].double(),
        torch.tensor([1.5, 0.0, 0.0], dtype=torch.float64),
        atol=1e-4,
        rtol=0,
    )
    assert speed_loss(burst, real, mask, 20.0, root=0) < 1e-8
    # per span (1.0², 0.5², 0.5²), over two joints of which the root has no error
    torch.testing.assert_close(
        speed_loss(burst, real, mask, 20.0, root=0, span=13),
        torch.tensor((1.0 + 0.25 + 0.25) / 2 / 3, dtype=torch.float64),
        atol=1e-4,
        rtol=0,
    )
    # spans with no real frame are left out, not counted as still
    padded = mask.clone()
    padded[0, 20:] = False
    short = torch.ones(1, 20, dtype=torch.bool)
    torch.testing.assert_close(
        speed_loss(burst, real, padded, 20.0, root=0, span=10),
        speed_loss(burst[:, :20], real[:, :20], short, 20.0, root=0, span=10),
    )


def test_log_speed_loss_weighs_relative_errors() -> None:
    """A hand at a third of its speed costs the same whether it circles slowly or fast; the absolute
    loss grows with the square of the speed instead."""
    mask = torch.ones(1, 40, dtype=torch.bool)
    floor = LOG_SPEED_FLOOR

    def loss(radius: float, log: bool) -> torch.Tensor:
        real = _circling(0.0, radius)
        slow = real.clone()
        slow[:, :, 1] = real[:, :, 0] + (real[:, :, 1] - real[:, :, 0]) / 3  # a third of the radius
        return speed_loss(slow, real, mask, 20.0, root=0, log=log)

    speed = mean_speeds(_circling(0.0, 0.5), mask, 20.0, root=0)[0, 0, 1]
    expected = (math.log(speed / 3 + floor) - math.log(speed + floor)) ** 2 / 2  # the root: no error
    torch.testing.assert_close(loss(0.5, log=True), torch.tensor(expected, dtype=torch.float64))
    assert 0.75 < float(loss(0.1, log=True) / loss(0.5, log=True)) < 1.0
    ratio = loss(0.1, log=False) / loss(0.5, log=False)
    torch.testing.assert_close(ratio, torch.tensor(0.04, dtype=torch.float64))  # (0.1 / 0.5)²


def test_the_upper_speed_term_compares_spans_of_the_chosen_joints() -> None:
    """A swing that stops halfway has the window's mean speed of a steady swing at half its speed but
    not its spans'; over its 20-frame spans the error is that of each span's log speeds, on the joints
    it is told to compare only; through ``odmo_losses`` it is weighted by ``w_upper_speed``."""
    mask = torch.ones(1, 60, dtype=torch.bool)
    steady = _swinging(1.0, 0.1)
    burst = _swinging(1.0, 0.2)
    burst[0, 30:, 1] = burst[0, 30:, 0] + (burst[0, 29, 1] - burst[0, 29, 0])
    spans_real = mean_speeds(steady, mask, 20.0, root=0, span=20)[0, :, 1]
    spans_burst = mean_speeds(burst, mask, 20.0, root=0, span=20)[0, :, 1]
    floor = LOG_SPEED_FLOOR
    expected = float(((torch.log(spans_burst + floor) - torch.log(spans_real + floor)) ** 2).mean())
    got = speed_loss(burst, steady, mask, 20.0, root=0, log=True, span=20, on=[1])
    assert float(got) == pytest.approx(expected, rel=1e-9)
    assert float(got) > 10 * float(speed_loss(burst, steady, mask, 20.0, root=0, log=True, on=[1]))
    assert float(speed_loss(burst, steady, mask, 20.0, root=0, log=True, span=20, on=[0])) == 0.0
    kw = {"mu": torch.zeros(2, 20), "logvar": torch.zeros(2, 20), "same": torch.tensor([True]), "root": 0}
    kw |= {"joints": steady.float().repeat(2, 1, 1, 1), "trajectory": steady[:, :, 0].float().repeat(2, 1, 1)}
    kw |= {"mask": mask.repeat(2, 1), "pred_joints": steady.float().repeat(2, 1, 1, 1)}
    kw |= {
        "pred_trajectory": steady[:, :, 0].float().repeat(2, 1, 1),
        "free_joints": burst.float().repeat(2, 1, 1, 1),
    }
    cfg = OdmoConfig(n_actions=2, n_joints=2, w_upper_speed=2.0, speed_error="log", upper_speed_span=20)
    terms = odmo_losses(cfg, **kw, upper_on=(1,))
    assert float(terms["upper_speed"]) == pytest.approx(expected, rel=1e-4)
    without = odmo_losses(dataclasses.replace(cfg, w_upper_speed=0.0), **kw, upper_on=(1,))
    off = odmo_losses(
        dataclasses.replace(cfg, w_upper_speed=0.0), **kw, upper_on=()
    )  # as LossJoints leaves it
    assert float(off["upper_speed"]) == 0.0
    assert float(terms["total"] - without["total"]) == pytest.approx(2 * expected, rel=1e-3)
    assert (
        OdmoConfig.from_dict({k: v for k, v in cfg.to_dict().items() if k != "w_upper_speed"}).w_upper_speed
        == 0
    )


def _swinging(hz: float, amplitude: float, frames: int = 60, fps: float = 20.0) -> torch.Tensor:
    """(1, frames, 2, 3): a root walking along x at 1 m/s and a hand swinging sideways about it."""
    t = torch.arange(frames, dtype=torch.float64) / fps
    root = torch.stack([t, torch.zeros_like(t), torch.zeros_like(t)], dim=1)
    swing = amplitude * torch.sin(2 * math.pi * hz * t)
    hand = root + torch.stack([torch.zeros_like(t), torch.ones_like(t), swing], dim=1)
    return torch.stack([root, hand], dim=1)[None]


def test_amplitude_spectra_put_a_swing_in_its_bin() -> None:
    """A 0.1 m swing on a whole number of cycles (60 frames at 20 fps: bins of 1/3 Hz) has A/2 in its
    bin and nothing elsewhere, whatever its phase or the root's walk; padded frames do not count."""
    mask = torch.ones(1, 60, dtype=torch.bool)
    quick, slow = _swinging(2.0, 0.1), _swinging(1 / 3, 0.1)
    spectrum = amplitude_spectra(quick, mask, root=0)[0, 1]
    assert int(spectrum.argmax()) == 6 and abs(float(spectrum[6]) - 0.05) < 1e-9
    assert float(spectrum.sum() - spectrum[6]) < 1e-4
    assert int(amplitude_spectra(slow, mask, root=0)[0, 1].argmax()) == 1
    assert float(amplitude_spectra(quick, mask, root=0)[0, 0].max()) < 1e-5  # the root itself
    # the same swing half a cycle later costs nothing; the slow one of the same amplitude does
    shifted = _swinging(2.0, 0.1, frames=65)[:, 5:]
    assert float(spectrum_loss(shifted, quick, mask, root=0)) < 1e-12
    # bins 1 and 6 of the hand swap A/2 for nothing, of 2 joints × 31 bins
    expected = 2 * math.log((0.05 + SPECTRUM_FLOOR) / SPECTRUM_FLOOR) ** 2 / 62
    assert abs(float(spectrum_loss(slow, quick, mask, root=0)) - expected) < 1e-3 * expected
    padded = mask.clone()
    padded[0, 30:] = False
    moved = quick.clone()
    moved[:, 30:] += 3.0
    torch.testing.assert_close(amplitude_spectra(moved, padded, 0), amplitude_spectra(quick, padded, 0))


def test_spectrum_spans_see_a_wave_that_stops() -> None:
    """A 0.3 m swing for one second then still, against a steady 0.1 m swing: per 20-frame span
    (bins of 1 Hz) the first span's bin 2 holds 3A/2 against A/2 and the two still spans nothing
    against A/2, of 3 spans × 2 joints × 11 bins; runs of fewer than two real frames are left out."""
    mask = torch.ones(1, 60, dtype=torch.bool)
    steady = _swinging(2.0, 0.1)
    stops = _swinging(2.0, 0.3)
    stops[:, 20:, 1] = stops[:, 20:, 0] + torch.tensor([0.0, 1.0, 0.0], dtype=torch.float64)
    a, floor = 0.1, SPECTRUM_FLOOR
    first = math.log((1.5 * a + floor) / (0.5 * a + floor)) ** 2
    errors = first + 2 * math.log((0.5 * a + floor) / floor) ** 2
    loss = spectrum_loss(stops, steady, mask, root=0, span=20)
    assert float(loss) == pytest.approx(errors / 66, rel=1e-4)
    assert float(spectrum_loss(steady, stops, mask, root=0, span=20)) == pytest.approx(float(loss))
    assert float(spectrum_loss(_swinging(2.0, 0.1, frames=70)[:, 10:], steady, mask, 0, span=20)) < 1e-12
    one_more = torch.ones(1, 61, dtype=torch.bool)
    longer = _swinging(2.0, 0.1, frames=61), _swinging(2.0, 0.3, frames=61)
    longer[1][:, 20:, 1] = longer[1][:, 20:, 0] + torch.tensor([0.0, 1.0, 0.0], dtype=torch.float64)
    torch.testing.assert_close(spectrum_loss(longer[1], longer[0], one_more, 0, span=20), loss)


def test_free_spans_compare_mean_poses_and_leave_the_swing_to_the_phase_free_terms() -> None:
    """Per 10-frame run (one cycle of a 2 Hz swing at 20 fps) a swing and the still pose at its mean cost
    nothing, the same swing 0.2 m higher costs 0.2² on one of 2 joints × 3 axes; span 1 is the per-frame
    error; padded frames are left out of both the means and the weights."""
    mask = torch.ones(1, 60, dtype=torch.bool)
    swing = _swinging(2.0, 0.1)
    still = _swinging(2.0, 0.0)
    assert float(span_mean_mse(still, swing, mask, 10)) < 1e-20
    assert float(span_mean_mse(still, swing, mask, 1)) == pytest.approx(float(masked_mse(still, swing, mask)))
    assert float(masked_mse(still, swing, mask)) == pytest.approx(0.1**2 / 2 / 6, rel=1e-9)
    higher = swing.clone()
    higher[:, :, 1, 1] += 0.2
    assert float(span_mean_mse(higher, swing, mask, 10)) == pytest.approx(0.04 / 6, rel=1e-9)
    padded = mask.clone()
    padded[0, 45:] = False
    moved = higher.clone()
    moved[:, 45:] += 5.0
    assert float(span_mean_mse(moved, swing, padded, 10)) == pytest.approx(0.04 / 6, rel=1e-9)
    cfg = OdmoConfig(n_actions=2, n_joints=2, free_span=10)
    assert cfg.to_dict()["free_span"] == 10
    with pytest.raises(ConfigError, match="free_span"):
        OdmoConfig(n_actions=2, n_joints=2, free_span=0)


def _swing_at(phase: float, amplitude: float = 0.1) -> torch.Tensor:
    """``_swinging`` at 1 Hz (20 frames a cycle at 20 fps), its swing started ``phase`` cycles later."""
    joints = _swinging(1.0, 0.0)
    t = torch.arange(60, dtype=torch.float64) / 20.0
    joints[0, :, 1, 2] = amplitude * torch.sin(2 * math.pi * (t - phase))
    return joints


def test_a_shift_tolerant_free_term_keeps_a_swing_out_of_phase_above_a_still_pose() -> None:
    """Per frame (about the root), a swing a quarter cycle (5 frames) out of phase costs more than the
    still pose at its mean, which is what pulls a free decode of uncertain phase to a standstill;
    allowed a shift of 5 frames it costs nothing and the still pose keeps its cost; shift 0 is the
    per-frame error, padded frames count for neither, and every window takes its own shift."""
    mask = torch.ones(1, 60, dtype=torch.bool)
    truth, late, still = (x - x[:, :, :1] for x in (_swing_at(0.0), _swing_at(0.25), _swing_at(0.0, 0.0)))
    assert float(masked_mse(late, truth, mask)) > float(masked_mse(still, truth, mask))
    assert float(shift_tolerant_mse(late, truth, mask, 1, 5)) < 1e-20
    assert float(shift_tolerant_mse(still, truth, mask, 1, 5)) == pytest.approx(0.1**2 / 2 / 6, rel=0.05)
    one_frame_off = (2 * 0.1 * math.sin(math.pi / 20)) ** 2 / 2 / 6  # 5 frames late, 4 allowed
    assert float(shift_tolerant_mse(late, truth, mask, 1, 4)) == pytest.approx(one_frame_off, rel=0.05)
    torch.testing.assert_close(shift_tolerant_mse(late, truth, mask, 1, 0), masked_mse(late, truth, mask))
    padded = mask.clone()
    padded[0, 50:] = False
    spoiled = late.clone()
    spoiled[:, 50:] += 5.0
    assert float(shift_tolerant_mse(spoiled, truth, padded, 1, 5)) < 1e-20
    early = _swing_at(-0.25) - _swing_at(-0.25)[:, :, :1]
    both = shift_tolerant_mse(torch.cat([late, early]), torch.cat([truth, truth]), mask.repeat(2, 1), 1, 5)
    assert float(both) < 1e-20


def test_the_free_term_shifts_root_relative_poses_when_asked() -> None:
    """A free decode whose hand swings a quarter cycle late along a root that walks on time: the per-frame
    free term sees the lag, ``free_shift`` 5 does not (it compares poses about the root, whose path is
    the trajectory loss's); the field is saved and checked."""
    truth, late = _swing_at(0.0).float(), _swing_at(0.25).float()
    mask = torch.ones(1, 60, dtype=torch.bool)
    kw = {"mu": torch.zeros(1, 20), "logvar": torch.zeros(1, 20), "same": torch.tensor([True]), "root": 0}
    kw |= {"joints": truth, "trajectory": truth[:, :, 0], "mask": mask, "pred_joints": truth}
    kw |= {"pred_trajectory": truth[:, :, 0], "free_joints": late}
    plain = OdmoConfig(n_actions=2, n_joints=2, w_free=1.0)
    shifted = OdmoConfig(n_actions=2, n_joints=2, w_free=1.0, free_shift=5)
    assert float(odmo_losses(plain, **kw)["free"]) > 1e-4
    assert float(odmo_losses(shifted, **kw)["free"]) < 1e-12
    assert shifted.to_dict()["free_shift"] == 5
    assert OdmoConfig.from_dict(plain.to_dict() | {"free_shift": 5}).free_shift == 5
    with pytest.raises(ConfigError, match="free_shift"):
        OdmoConfig(n_actions=2, n_joints=2, free_shift=-1)


def test_a_reversed_encoder_reads_each_clip_from_its_last_real_frame_to_its_first() -> None:
    """Its code of a clip is the forward encoder's code (same weights) of the clip played backwards;
    padded frames change neither; a clip and its reverse get different codes; the switch is saved."""
    forward, backward = _model().eval(), _model(encoder_reverse=True).eval()
    backward.load_state_dict(forward.state_dict())
    generator = torch.Generator().manual_seed(0)
    lmp = torch.randn(2, T, J * 3, generator=generator)
    mask = torch.ones(2, T, dtype=torch.bool)
    mask[1, 8:] = False
    played_back = lmp.clone()
    played_back[0] = lmp[0].flip(0)
    played_back[1, :8] = lmp[1, :8].flip(0)
    padded = lmp.clone()
    padded[1, 8:] = 99.0
    with torch.no_grad():
        mu, logvar = backward.encode(lmp, mask)
        expected = forward.encode(played_back, mask)
        torch.testing.assert_close((mu, logvar), expected)
        torch.testing.assert_close(backward.encode(padded, mask)[0], mu)
        torch.testing.assert_close(backward.encode(lmp)[0][0], mu[0])
        assert float((forward.encode(lmp, mask)[0] - mu).abs().max()) > 1e-3
    assert OdmoConfig.from_dict(backward.config.to_dict()).encoder_reverse
    assert not OdmoConfig.from_dict(
        {k: v for k, v in forward.config.to_dict().items() if k != "encoder_reverse"}
    ).encoder_reverse


def test_a_clocked_decoder_reads_sin_and_cos_of_time_at_each_frequency() -> None:
    """Its pose-free input is the unclocked decoder's (same other weights) plus W_c·[sin 2πft, cos 2πft]
    at each frequency, t in seconds (20 fps: at 1.25 Hz frame 4 is a quarter turn, sin 1, cos 0); the
    frequencies are saved, checked, and a model without them keeps its input width."""
    plain = _model().eval()
    clocked = _model(clock_hz=(1.25, 2.5)).eval()
    state = plain.state_dict()
    w = clocked.motion_gen.embed.weight.detach()
    clock_w = w[:, -4:]
    clocked.load_state_dict(
        state | {"motion_gen.embed.weight": torch.cat([state["motion_gen.embed.weight"], clock_w], 1)}
    )
    torch.testing.assert_close(
        clocked.motion_gen.clock[0, 4], torch.tensor([1.0, 0.0, 0.0, -1.0]), atol=1e-6, rtol=0
    )
    z, action, end = torch.randn(2, 20), torch.tensor([0, 2]), torch.randn(2, 3)
    with torch.no_grad():
        consts = []
        for model in (plain, clocked):
            cond = model.condition(z, action)
            consts.append(model.motion_gen._context(model.traj_gen(cond, end), cond)[1])
        seconds = torch.arange(T, dtype=torch.float32)[:, None] / 20.0
        angles = 2 * math.pi * seconds * torch.tensor([1.25, 2.5])
        expected = consts[0] + torch.cat([angles.sin(), angles.cos()], 1) @ clock_w.t()
        torch.testing.assert_close(consts[1], expected, atol=1e-5, rtol=1e-5)
        assert not torch.allclose(clocked.decode(z, action, end)[0], plain.decode(z, action, end)[0])
    assert plain.motion_gen.embed.in_features == clocked.motion_gen.embed.in_features - 4
    assert OdmoConfig.from_dict(clocked.config.to_dict()).clock_hz == (1.25, 2.5)
    assert (
        OdmoConfig.from_dict({k: v for k, v in plain.config.to_dict().items() if k != "clock_hz"}).clock_hz
        == ()
    )
    for bad in ((0.0,), (-1.0,), (10.5,), (float("nan"),), ("fast",), (1.0,) * 33):
        with pytest.raises(ConfigError, match="clock_hz"):
            OdmoConfig(n_actions=2, n_joints=J, clock_hz=bad)


def test_a_residual_decoder_that_emits_nothing_holds_the_previous_pose() -> None:
    """Output layer at zero: teacher-forced, each frame is the real previous frame about the generated root
    (frame 0 the start pose); free-running, every frame is the start pose. An absolute decoder with the
    same weights puts every joint on the root. Rotations cannot step; the switch is saved and checked."""
    model = _model(pose_update="residual").eval()
    gen = model.motion_gen
    with torch.no_grad():
        gen.out.weight.zero_()
        gen.out.bias.zero_()
        gen.start.copy_(torch.arange(J * 3, dtype=torch.float32) / 10)
    z, action, end = torch.randn(2, 20), torch.tensor([0, 2]), torch.randn(2, 3)
    truth = torch.randn(2, T, J, 3)
    with torch.no_grad():
        forced, traj = model.decode(z, action, end, prev_truth=truth, tf_rate=1.0)
        free, _ = model.decode(z, action, end)
    about_root = forced - traj.unsqueeze(2)
    start = gen.start.view(J, 3) - gen.start.view(J, 3)[:1]
    torch.testing.assert_close(about_root[:, 1:], (truth - truth[:, :, :1])[:, :-1])
    torch.testing.assert_close(about_root[:, 0], start.expand(2, J, 3))
    torch.testing.assert_close(free - traj.unsqueeze(2), start.expand(2, T, J, 3))
    absolute = _model().eval()
    absolute.load_state_dict({k: v for k, v in model.state_dict().items() if k != "motion_gen.start"})
    with torch.no_grad():
        flat, flat_traj = absolute.decode(z, action, end)
    torch.testing.assert_close(flat, flat_traj.unsqueeze(2).expand(2, T, J, 3))
    assert OdmoConfig.from_dict(model.config.to_dict()).pose_update == "residual"
    with pytest.raises(ConfigError, match="pose_update"):
        OdmoConfig(n_actions=2, n_joints=J, pose_update="residual", pose_output="rotations")
    with pytest.raises(ConfigError, match="pose_update"):
        OdmoConfig(n_actions=2, n_joints=J, pose_update="sideways")
    with pytest.raises(ConfigError, match="step_input"):
        OdmoConfig(n_actions=2, n_joints=J, step_input=True)
    saved = _model(pose_update="residual", step_input=True).config.to_dict()
    assert OdmoConfig.from_dict(saved).step_input
    assert not OdmoConfig.from_dict({k: v for k, v in saved.items() if k != "step_input"}).step_input


def test_the_start_term_compares_the_first_frames_about_the_root() -> None:
    """A hand swinging a quarter cycle late costs its error over the first 3 frames only (from 0.1 m at
    frame 0: sin −90°, −72°, −54° against sin 0°, 18°, 36°); a root moved away costs nothing; padded first
    frames count for nothing; through ``odmo_losses`` it is weighted by ``w_start`` on the free decode."""
    truth, late = _swing_at(0.0), _swing_at(0.25)
    mask = torch.ones(1, 60, dtype=torch.bool)
    expected = (
        sum(
            (0.1 * (math.sin(2 * math.pi * (t - 5) / 20) - math.sin(2 * math.pi * t / 20))) ** 2
            for t in range(3)
        )
        / 3
        / 6
    )
    assert float(start_mse(late, truth, mask, 0, 3)) == pytest.approx(expected, rel=1e-9)
    away = late.clone()
    away[:, :, :] += torch.tensor([3.0, 0.0, -2.0], dtype=torch.float64)
    assert float(start_mse(away, truth, mask, 0, 3)) == pytest.approx(expected, rel=1e-9)
    assert float(start_mse(late, truth, mask, 0, 60)) == pytest.approx(
        float(masked_mse(late - late[:, :, :1], truth - truth[:, :, :1], mask))
    )
    padded = mask.clone()
    padded[0, :3] = False
    assert float(start_mse(late, truth, padded, 0, 3)) == 0.0
    kw = {"mu": torch.zeros(2, 20), "logvar": torch.zeros(2, 20), "same": torch.tensor([True]), "root": 0}
    kw |= {
        "joints": truth.float().repeat(2, 1, 1, 1),
        "trajectory": truth[:, :, 0].float().repeat(2, 1, 1),
        "mask": mask.repeat(2, 1),
    }
    kw |= {
        "pred_joints": truth.float().repeat(2, 1, 1, 1),
        "pred_trajectory": truth[:, :, 0].float().repeat(2, 1, 1),
        "free_joints": late.float().repeat(2, 1, 1, 1),
    }
    cfg = OdmoConfig(n_actions=2, n_joints=2, w_start=10.0, start_frames=3)
    losses = odmo_losses(cfg, **kw)
    assert float(losses["start"]) == pytest.approx(expected, rel=1e-5)
    assert float(losses["total"]) == pytest.approx(10 * expected + float(losses["prior"]), rel=1e-4)
    assert OdmoConfig.from_dict({k: v for k, v in cfg.to_dict().items() if k != "w_start"}).w_start == 0.0
    with pytest.raises(ConfigError, match="start_frames"):
        OdmoConfig(n_actions=2, n_joints=2, start_frames=0)


def test_skate_loss_is_the_squared_speed_of_planted_feet() -> None:
    t = torch.arange(10, dtype=torch.float32)
    feet = torch.zeros(1, 10, 2, 3)
    feet[0, :, 0, 0] = t * 0.05  # foot 0 slides at 1 m/s (20 fps)
    feet[0, :, 1, 2] = t * 0.10  # foot 1 swings at 2 m/s
    labels = torch.zeros(1, 10, 2)
    labels[0, :, 0] = 1.0  # only foot 0 is planted in the data
    mask = torch.ones(1, 10, dtype=torch.bool)
    torch.testing.assert_close(skate_loss(feet, labels, mask, 20.0), torch.tensor(1.0))
    labels[0, :, 1] = 1.0
    torch.testing.assert_close(skate_loss(feet, labels, mask, 20.0), torch.tensor(2.5))


def test_spectrum_leaves_the_legs_out_when_asked() -> None:
    # root 0; spine 1 -> hand 2; leg 3 -> foot 4 -> toe 5; a second leg 6 -> foot 7
    parents = [-1, 0, 1, 0, 3, 4, 0, 6]
    cfg = OdmoConfig(n_actions=3, n_joints=8, foot_joints=(4, 5, 7), foot_heights=(0.1, 0.05, 0.1))
    assert spectrum_joints(cfg, parents, 0) == list(range(8))
    no_legs = OdmoConfig(**(cfg.to_dict() | {"spectrum_legs": False}))
    assert spectrum_joints(no_legs, parents, 0) == [0, 1, 2]
    t = torch.arange(40, dtype=torch.float32) / 20.0
    pred, target = torch.zeros(1, 40, 8, 3), torch.zeros(1, 40, 8, 3)
    target[0, :, 5, 1] = 0.1 * torch.sin(2 * math.pi * t)  # only a toe moves
    mask = torch.ones(1, 40, dtype=torch.bool)
    assert spectrum_loss(pred, target, mask, 0) > 0
    assert spectrum_loss(pred, target, mask, 0, [0, 1, 2]) == 0


def test_free_skate_is_taken_on_the_free_running_decode() -> None:
    cfg = _model(
        w_skate=0.0, w_free_skate=2.0, foot_contact=True, foot_joints=(1,), foot_heights=(0.0,)
    ).config
    joints, mask = torch.zeros(2, T, J, 3), torch.ones(2, T, dtype=torch.bool)
    free = joints.clone()
    free[:, :, 1, 0] = torch.arange(T, dtype=torch.float32) * 0.05  # the free decode's foot slides at 1 m/s
    kw = {"mu": torch.zeros(2, 20), "logvar": torch.zeros(2, 20), "same": torch.tensor([True]), "root": 0}
    terms = odmo_losses(cfg, joints=joints, trajectory=joints[:, :, 0], mask=mask, pred_joints=joints,
                        pred_trajectory=joints[:, :, 0], contact_logits=torch.zeros(2, T, 1),
                        contacts=torch.ones(2, T, 1), free_joints=free, **kw)  # fmt: skip
    torch.testing.assert_close(terms["skate"], torch.tensor(0.0))
    torch.testing.assert_close(terms["free_skate"], torch.tensor(1.0))
    expected = terms["contrastive"] + terms["prior"] + terms["contact"] + 2.0 * terms["free_skate"]
    torch.testing.assert_close(terms["total"], expected)


@pytest.mark.parametrize(
    ("config", "field", "message"),
    [
        (OdmoConfig, "scheduled_sampling", "one_step, free_run"),
        (A2mConfig, "pose_rep", "lie, joints"),
        (DvganConfig, "generator", "rnn, cnn"),
    ],
)
def test_every_kind_names_the_choices_of_a_field_it_does_not_know(config, field, message) -> None:
    with pytest.raises(ConfigError, match=f"{field} must be one of {message}, got 'bogus'"):
        config(n_actions=3, n_joints=5, **{field: "bogus"})


def test_own_contacts_follow_the_decode_lowered_to_its_floor() -> None:
    # two feet resting at 10 cm (ankle) and 4 cm (toe); the whole window floats 50 cm up
    feet = torch.zeros(1, 4, 2, 3)
    feet[..., 0, 1], feet[..., 1, 1] = 0.6, 0.54
    feet[0, 1, 0, 1] = 0.62  # 2 cm up: still planted
    feet[0, 2, 0, 1] = 0.65  # 5 cm up: lifted
    feet[0, 3, 1, 1] = 0.40  # the toe 14 cm lower in a padded frame: not the floor
    mask = torch.tensor([[True, True, True, False]])
    labels = own_contacts(feet, (0.1, 0.04), mask)
    assert labels[0, :3].tolist() == [[1.0, 1.0], [1.0, 1.0], [0.0, 1.0]]


def test_free_skate_on_own_contacts_holds_the_feet_the_decode_plants() -> None:
    cfg = _model(
        w_skate=0.0, w_free_skate=1.0, foot_contact=True, foot_joints=(1, 2), foot_heights=(0.0, 0.0),
        free_skate_contacts="own",
    ).config  # fmt: skip
    joints, mask = torch.zeros(2, T, J, 3), torch.ones(2, T, dtype=torch.bool)
    free = joints.clone()
    free[:, :, 1, 0] = torch.arange(T, dtype=torch.float32) * 0.05  # foot 1 slides on the floor at 1 m/s
    free[:, :, 2, 0] = torch.arange(T, dtype=torch.float32) * 0.10  # foot 2 swings 20 cm up at 2 m/s
    free[:, :, 2, 1] = 0.2
    kw = {"mu": torch.zeros(2, 20), "logvar": torch.zeros(2, 20), "same": torch.tensor([True]), "root": 0}
    terms = odmo_losses(cfg, joints=joints, trajectory=joints[:, :, 0], mask=mask, pred_joints=joints,
                        pred_trajectory=joints[:, :, 0], contact_logits=torch.zeros(2, T, 2),
                        contacts=torch.zeros(2, T, 2), free_joints=free, **kw)  # fmt: skip
    torch.testing.assert_close(terms["free_skate"], torch.tensor(1.0))  # the data's feet are never planted
    data_rule = OdmoConfig(**(cfg.to_dict() | {"free_skate_contacts": "data"}))
    terms = odmo_losses(data_rule, joints=joints, trajectory=joints[:, :, 0], mask=mask, pred_joints=joints,
                        pred_trajectory=joints[:, :, 0], contact_logits=torch.zeros(2, T, 2),
                        contacts=torch.zeros(2, T, 2), free_joints=free, **kw)  # fmt: skip
    torch.testing.assert_close(terms["free_skate"], torch.tensor(0.0))


def test_foot_height_loss_compares_time_at_each_height_whatever_the_phase() -> None:
    t = torch.arange(20, dtype=torch.float32)
    target = torch.zeros(1, 20, 2, 3)
    target[0, :, 0, 1] = 0.1 + 0.1 * torch.sin(t)  # a foot resting at 10 cm that lifts and drops
    target[0, :, 1, 1] = 0.04 + 0.05 * (t % 4 == 0)  # a toe at 4 cm, lifted 5 cm every fourth frame
    mask = torch.ones(1, 20, dtype=torch.bool)
    rest = (0.1, 0.04)
    out_of_step = target.roll(7, dims=1)
    out_of_step[..., 1] += 0.5  # later and half a metre up: the floor is the window's own
    torch.testing.assert_close(foot_height_loss(out_of_step, target, rest, mask), torch.tensor(0.0))
    floating = target.clone()
    floating[0, :, 1, 1] = 0.09  # the toe never comes down: 5 cm too high in 15 of 20 frames, per foot
    expected = torch.tensor(15 * 0.05**2 / 40)
    torch.testing.assert_close(foot_height_loss(floating, target, rest, mask), expected)
    floating[0, 15:] = 5.0  # padded frames cost nothing
    mask[0, 15:] = False
    assert foot_height_loss(floating, target, rest, mask) < expected


def _two_feet(low_speed: float, high_speed: float, gap: float, t: int = 20) -> torch.Tensor:
    """(1, t, 2, 3): foot 0 on the floor sliding along x at ``low_speed`` m/s (20 fps), foot 1 ``gap`` m
    up moving along z at ``high_speed``."""
    feet = torch.zeros(1, t, 2, 3, dtype=torch.float64)
    steps = torch.arange(t, dtype=torch.float64) / 20.0
    feet[0, :, 0, 0] = low_speed * steps
    feet[0, :, 1, 2] = high_speed * steps
    feet[0, :, 1, 1] = gap
    return feet


def test_the_stance_term_is_the_speed_of_the_lowest_foot() -> None:
    """The foot put lowest gives the speed (the other's weight is e^-10 at 10 cm); feet level share it;
    resting heights are subtracted first; padded steps cost nothing; the loss is the squared difference
    of the two windows' speeds, weighted by ``w_stance`` through ``odmo_losses`` on the free decode. A
    still foot reads 2 mm/s, the guard that keeps the square root's gradient finite."""
    mask = torch.ones(1, 20, dtype=torch.bool)
    rest = (0.0, 0.0)
    walk = _two_feet(0.0, 2.0, 0.1)  # the standing foot still, the swinging one up
    skim = _two_feet(1.0, 0.0, 0.1)  # the lowest foot slides, the raised one stands
    still = 0.002 + 2.0 * math.exp(-10)
    assert float(stance_speeds(walk, rest, mask, 20.0)) == pytest.approx(still, abs=1e-4)
    assert float(stance_speeds(skim, rest, mask, 20.0)) == pytest.approx(1.0, abs=1e-4)
    assert float(stance_speeds(_two_feet(1.0, 3.0, 0.0), rest, mask, 20.0)) == pytest.approx(2.0, abs=1e-4)
    assert float(stance_speeds(skim, (0.0, 0.2), mask, 20.0)) == pytest.approx(0.002, abs=1e-3)
    padded = mask.clone()
    padded[0, 10:] = False
    sped = skim.clone()
    sped[0, 10:, 0, 0] = 10.0 * torch.arange(10, dtype=torch.float64)
    assert float(stance_speeds(sped, rest, padded, 20.0)) == pytest.approx(1.0, abs=1e-4)
    assert float(stance_loss(skim, walk, rest, mask, 20.0)) == pytest.approx(0.996, abs=1e-3)
    assert float(stance_loss(walk.roll(5, dims=1), walk, rest, mask, 20.0)) == pytest.approx(0.0, abs=1e-6)
    # through odmo_losses: feet 0 and 1 of a 2-joint body, the free decode skimming where the data walks
    kw = {"mu": torch.zeros(2, 20), "logvar": torch.zeros(2, 20), "same": torch.tensor([True]), "root": 0}
    kw |= {"joints": walk.float().repeat(2, 1, 1, 1), "trajectory": walk[:, :, 0].float().repeat(2, 1, 1)}
    kw |= {"mask": mask.repeat(2, 1), "pred_joints": walk.float().repeat(2, 1, 1, 1)}
    kw |= {
        "pred_trajectory": walk[:, :, 0].float().repeat(2, 1, 1),
        "free_joints": skim.float().repeat(2, 1, 1, 1),
    }
    kw |= {"contact_logits": torch.zeros(2, 20, 2), "contacts": torch.zeros(2, 20, 2)}
    cfg = OdmoConfig(n_actions=2, n_joints=2, foot_joints=(0, 1), foot_heights=rest, w_stance=3.0)
    losses = odmo_losses(cfg, **kw)
    assert float(losses["stance"]) == pytest.approx(0.996, abs=1e-3)
    without = odmo_losses(dataclasses.replace(cfg, w_stance=0.0), **kw)
    assert float(losses["total"] - without["total"]) == pytest.approx(3 * 0.996, abs=3e-3)
    assert OdmoConfig.from_dict({k: v for k, v in cfg.to_dict().items() if k != "w_stance"}).w_stance == 0.0


def test_the_skim_term_is_the_skate_rules_planted_speed_made_soft() -> None:
    """Per window: the squared horizontal speed of feet within 3 cm of the window's lowest foot point,
    weighed by a sigmoid of the height (0.5 at the rule's 3 cm edge), over steps and joints; the loss is
    how far the decode's exceeds the data's, and its gradient lifts a sliding foot as well as slowing it."""
    mask = torch.ones(1, 20, dtype=torch.bool)
    near = torch.sigmoid(torch.tensor(3.0, dtype=torch.float64))  # a foot on the floor: 3 cm inside
    skim = _two_feet(1.0, 2.0, 0.1)  # slides on the floor at 1 m/s while the other swings 10 cm up
    assert float(skim_speeds(skim, mask, 20.0)) == pytest.approx(float(near**2) / 2, abs=1e-3)
    edge = _two_feet(0.0, 2.0, 0.03)  # the swinging foot exactly at the edge counts half in each frame
    assert float(skim_speeds(edge, mask, 20.0)) == pytest.approx(4.0 / 4 / 2, rel=1e-3)
    lifted = _two_feet(0.0, 2.0, 0.2)
    assert float(skim_speeds(lifted, mask, 20.0)) < 1e-6
    assert float(skim_loss(lifted, skim, mask, 20.0)) == 0.0  # no gain for keeping feet higher than real
    pred = skim.clone().requires_grad_()
    loss = skim_loss(pred, lifted, mask, 20.0)
    assert float(loss.detach()) == pytest.approx(float(near**2) / 2, abs=1e-3)
    loss.backward()
    assert (pred.grad[0, 1:-1, 0, 1] < 0).all()  # descending the loss raises the sliding foot
    padded = mask.clone()
    padded[0, 10:] = False
    sped = skim.clone()
    sped[0, 10:, 0, 0] = 10.0 * torch.arange(10, dtype=torch.float64)
    assert float(skim_speeds(sped, padded, 20.0)) == pytest.approx(float(near**2) / 2, abs=1e-3)


def test_the_stand_term_sees_legs_drawn_up_wherever_the_floor_is() -> None:
    """The mean over real frames of the root's height over the lowest foot joint; lifting the whole body
    changes nothing, drawing the feet up under it does, and the loss is the squared difference (m²)."""
    mask = torch.ones(1, 20, dtype=torch.bool)
    body = torch.zeros(1, 20, 3, 3)  # root, left foot, right foot
    body[0, :, 0, 1] = 0.9
    body[0, ::2, 1, 1] = 0.1  # the left foot lifts 10 cm every other frame, the right stays down
    assert float(stand_heights(body, 0, (1, 2), mask)) == pytest.approx(0.9)
    floating = body + torch.tensor([0.0, 0.5, 0.0])
    assert float(stand_loss(floating, body, 0, (1, 2), mask)) == pytest.approx(0.0, abs=1e-10)
    tucked = body.clone()
    tucked[0, :, 1:, 1] += 0.4  # both feet drawn 40 cm up under the body
    assert float(stand_heights(tucked, 0, (1, 2), mask)) == pytest.approx(0.5)
    assert float(stand_loss(tucked, body, 0, (1, 2), mask)) == pytest.approx(0.16)
    padded = mask.clone()
    padded[0, 10:] = False
    tucked[0, 10:, 0, 1] = 9.0  # padded frames cost nothing
    assert float(stand_heights(tucked, 0, (1, 2), padded)) == pytest.approx(0.5)


def test_the_floor_term_sees_feet_lifted_together_and_a_floor_of_their_own() -> None:
    """The sorted per-frame height of the lowest foot over its resting height, against the data's in the
    same frame: alternating feet out of phase cost nothing, both lifted together or the whole body raised
    cost the squared lift (m²); the loss reaches the total through ``w_floor``."""
    mask = torch.ones(1, 20, dtype=torch.bool)
    rest = (0.05, 0.05)
    walk = torch.zeros(1, 20, 2, 3)
    walk[..., 1] = 0.05
    walk[0, ::2, 0, 1] += 0.1  # each foot lifts 10 cm in turn: one is always down
    walk[0, 1::2, 1, 1] += 0.1
    assert floor_heights(walk, rest).abs().max() < 1e-7
    late = walk.roll(1, dims=1)  # the same steps a frame later
    assert float(floor_loss(late, walk, rest, mask)) == pytest.approx(0.0, abs=1e-12)
    hop = walk.clone()
    hop[0, :10, :, 1] += 0.2  # both feet 20 cm up together for half the window
    assert float(floor_loss(hop, walk, rest, mask)) == pytest.approx(0.5 * 0.04, rel=1e-5)
    raised = walk + torch.tensor([0.0, 0.3, 0.0])
    assert float(floor_loss(raised, walk, rest, mask)) == pytest.approx(0.09, rel=1e-5)
    padded = mask.clone()
    padded[0, 10:] = False
    assert float(floor_loss(hop, walk, rest, padded)) == pytest.approx(0.04, rel=1e-5)
    joints = torch.zeros(1, 20, 3, 3)
    joints[:, :, 1:] = walk
    joints[:, :, 0, 1] = 0.9
    lifted = joints.clone()
    lifted[:, :, 1:] = hop
    joints, lifted = joints.repeat(2, 1, 1, 1), lifted.repeat(2, 1, 1, 1)  # an anchor and its partner
    kw = {"joints": joints, "trajectory": joints[:, :, 0], "mask": mask.repeat(2, 1), "pred_joints": joints}
    kw |= {"pred_trajectory": joints[:, :, 0], "mu": torch.zeros(2, 4), "logvar": torch.zeros(2, 4)}
    kw |= {"same": torch.tensor([True]), "root": 0, "free_joints": lifted}
    kw |= {"contact_logits": torch.zeros(2, 20, 2), "contacts": torch.zeros(2, 20, 2)}
    cfg = OdmoConfig(n_actions=2, n_joints=3, foot_joints=(1, 2), foot_heights=rest, w_floor=2.0)
    losses = odmo_losses(cfg, **kw)
    assert float(losses["floor"]) == pytest.approx(0.02, rel=1e-5)
    without = odmo_losses(dataclasses.replace(cfg, w_floor=0.0), **kw)
    assert float(losses["total"] - without["total"]) == pytest.approx(0.04, rel=1e-4)


@pytest.mark.parametrize("update", ["absolute", "residual", "stepped"])
def test_a_rollout_is_the_decode_fed_real_poses_up_to_its_start_then_its_own(update: str) -> None:
    """Frames 4…8 of a rollout from frame 4 are those of a teacher-forced decode whose previous poses
    after frame 3 are its own, fed back one at a time (independent of the rollout's code); its first
    frame is the teacher-forced one; a rollout cannot start at frame 0 or run past the window."""
    model = _model(**_UPDATES[update]).eval()
    z, action, end = torch.randn(2, 20), torch.tensor([0, 2]), torch.randn(2, 3)
    truth = torch.randn(2, T, J, 3)
    with torch.no_grad():
        rolled = model.rollout(z, action, end, truth, 4, 5)
        forced = model.decode_full(z, action, end, prev_truth=truth, tf_rate=1.0).joints
        previous = truth.clone()
        for t in range(4, 8):
            previous[:, t] = model.decode_full(z, action, end, prev_truth=previous, tf_rate=1.0).raw[:, t]
        fed = model.decode_full(z, action, end, prev_truth=previous, tf_rate=1.0).joints
    assert rolled.shape == (2, 5, J, 3)
    torch.testing.assert_close(rolled, fed[:, 4:9], atol=1e-5, rtol=0)
    torch.testing.assert_close(rolled[:, 0], forced[:, 4], atol=1e-5, rtol=0)
    assert (rolled[:, 1:] - forced[:, 5:9]).abs().max() > 1e-3  # its own poses, not the real ones
    for start in (0, T - 4):
        with pytest.raises(ValueError, match="rollout"):
            model.rollout(z, action, end, truth, start, 5)


def test_the_rollout_term_compares_the_rolled_frames_about_the_root() -> None:
    """A rollout of frames 10…24 that is the swing a quarter cycle late costs the per-frame error over
    those frames only, wherever its root is; padded frames count for nothing; through ``odmo_losses``
    it is weighted by ``w_rollout``; the frame count must stay below the window."""
    truth, late = _swing_at(0.0), _swing_at(0.25)
    mask = torch.ones(1, 60, dtype=torch.bool)
    span = slice(10, 25)
    expected = float(
        masked_mse(late[:, span] - late[:, span, :1], truth[:, span] - truth[:, span, :1], mask[:, span])
    )
    assert expected > 1e-3
    rolled = late[:, span] + torch.tensor([3.0, 0.0, -2.0], dtype=torch.float64)
    kw = {"mu": torch.zeros(2, 20), "logvar": torch.zeros(2, 20), "same": torch.tensor([True]), "root": 0}
    kw |= {"joints": truth.float().repeat(2, 1, 1, 1), "trajectory": truth[:, :, 0].float().repeat(2, 1, 1)}
    kw |= {"mask": mask.repeat(2, 1), "pred_joints": truth.float().repeat(2, 1, 1, 1)}
    kw |= {"pred_trajectory": truth[:, :, 0].float().repeat(2, 1, 1)}
    cfg = OdmoConfig(n_actions=2, n_joints=2, w_rollout=4.0)
    losses = odmo_losses(cfg, **kw, rollout=(10, rolled.float().repeat(2, 1, 1, 1)))
    assert float(losses["rollout"]) == pytest.approx(expected, rel=1e-5)
    assert float(losses["total"]) == pytest.approx(4 * expected + float(losses["prior"]), rel=1e-4)
    padded = mask.repeat(2, 1)
    padded[:, 10:25] = False
    gone = odmo_losses(cfg, **(kw | {"mask": padded}), rollout=(10, rolled.float().repeat(2, 1, 1, 1)))
    assert float(gone["rollout"]) == 0.0
    assert float(odmo_losses(cfg, **kw)["rollout"]) == 0.0
    assert OdmoConfig.from_dict({k: v for k, v in cfg.to_dict().items() if k != "w_rollout"}).w_rollout == 0.0
    with pytest.raises(ConfigError, match="rollout_frames"):
        OdmoConfig(n_actions=2, n_joints=2, window=20, w_rollout=1.0, rollout_frames=20)


def _crab(deg: float, t: int = 20) -> torch.Tensor:
    """(1, t, 3, 3): a root and two hips walking along +x at 1.2 m/s, the hip axis turned ``deg`` from +z."""
    clip = torch.zeros(1, t, 3, 3)
    clip[0, :, :, 0] = 1.2 * torch.arange(t, dtype=torch.float32)[:, None] / 20.0
    half = 0.1 * torch.tensor([math.sin(math.radians(deg)), 0.0, math.cos(math.radians(deg))])
    clip[0, :, 1] += half
    clip[0, :, 2] -= half
    return clip


def test_heading_loss_is_the_squared_cosine_error_of_a_turned_body() -> None:
    mask = torch.ones(1, 20, dtype=torch.bool)
    assert float(heading_loss(_crab(0.0), _crab(0.0), mask, (1, 2), 20.0)) < 1e-12
    expected = math.sin(math.radians(30.0)) ** 2  # cos(hips axis, travel) = sin 30° against 0
    torch.testing.assert_close(
        heading_loss(_crab(30.0), _crab(0.0), mask, (1, 2), 20.0), torch.tensor(expected)
    )
    still = _crab(0.0)
    still[..., 0] = still[:, :1, :, 0]  # the data stands still: no travel, no heading to compare
    assert float(heading_loss(_crab(30.0), still, mask, (1, 2), 20.0)) == 0.0
    crab = _crab(30.0).requires_grad_()
    heading_loss(crab, _crab(0.0), mask, (1, 2), 20.0).backward()
    assert crab.grad is not None and float(crab.grad.abs().sum()) > 0


def _pair_kwargs(real: torch.Tensor, free: torch.Tensor) -> dict[str, Any]:
    """``odmo_losses`` arguments for a window (1, T, J, 3) and its partner, both ``real``, decoded exactly
    when teacher-forced and as ``free`` free-running, their codes at 0."""
    real, free, t = real.repeat(2, 1, 1, 1), free.repeat(2, 1, 1, 1), real.shape[1]
    kw = {"mu": torch.zeros(2, t), "logvar": torch.zeros(2, t), "same": torch.tensor([True]), "root": 0}
    kw |= {"joints": real, "trajectory": real[:, :, 0], "mask": torch.ones(2, t, dtype=torch.bool)}
    return kw | {"pred_joints": real, "pred_trajectory": real[:, :, 0], "free_joints": free}


def test_the_heading_term_enters_the_total_with_its_weight_and_needs_hips() -> None:
    cfg = OdmoConfig(n_actions=2, n_joints=3, w_heading=3.0, w_contrastive=0.0, w_prior=0.0, w_free=0.0)
    kw = _pair_kwargs(_crab(0.0), _crab(30.0))
    terms = odmo_losses(cfg, hips=(1, 2), **kw)
    torch.testing.assert_close(terms["heading"], torch.tensor(0.25))
    torch.testing.assert_close(terms["total"], terms["velocity"] * cfg.w_velocity + 3.0 * terms["heading"])
    assert float(odmo_losses(cfg, **kw)["heading"]) == 0.0  # no hips: no heading term


def test_loss_joints_find_the_hips_above_the_feet_and_the_shoulders() -> None:
    # root 0; spine 1 -> arm 2 -> hand 3, arm 4 -> hand 5; legs 6 -> 7 -> foot 8 -> toe 9, 10 -> 11 -> 12
    names = ("Hips", "Spine", "Arm_L", "Hand_L", "Arm_R", "Hand_R", "UpperLeg_L", "Knee_L", "Foot_L")
    names += ("Toes_L", "UpperLeg_R", "Knee_R", "Foot_R")
    parents = [-1, 0, 1, 2, 1, 4, 0, 6, 7, 8, 0, 10, 11]
    offsets = [[0, 0.9, 0], [0, 0.4, 0], [0.2, 0, 0], [0.5, 0, 0], [-0.2, 0, 0], [-0.5, 0, 0], [0.1, 0, 0]]
    offsets += [[0, -0.4, 0]] * 3 + [[-0.1, 0, 0]] + [[0, -0.4, 0]] * 2
    skel = Skeleton(names, parents, offsets)
    cfg = OdmoConfig(n_actions=3, n_joints=13, foot_joints=(8, 9, 12), foot_heights=(0.1, 0.05, 0.1))
    every = tuple(range(13))
    feet = ((9, 8),)  # the toe below the left ankle; the right foot has none
    assert LossJoints.of(cfg, skel) == LossJoints(0, every, (6, 10), (2, 4), every, (), feet)
    upper = OdmoConfig(**(cfg.to_dict() | {"w_upper_speed": 1.0}))
    assert LossJoints.of(upper, skel).upper_on == (1, 2, 3, 4, 5)  # neither the root nor a leg
    one_leg = Skeleton(names[:10], parents[:10], offsets[:10])
    ten = tuple(range(10))
    assert LossJoints.of(cfg, one_leg) == LossJoints(0, ten, None, None, ten, (), feet)
    legs = OdmoConfig(**(cfg.to_dict() | {"coordination_on": "legs"}))
    assert LossJoints.of(legs, skel).coordination_on == (6, 7, 8, 9, 10, 11, 12)


def _twisted(deg: float, t: int = 6) -> torch.Tensor:
    """(1, t, 5, 3): a pelvis, hips (1, 2) on the z axis and shoulders (3, 4) turned ``deg`` about +y."""
    clip = torch.zeros(1, t, 5, 3)
    clip[..., 1] = torch.tensor([0.9, 0.9, 0.9, 1.4, 1.4])
    clip[..., 1, 2], clip[..., 2, 2] = 0.1, -0.1
    rad = math.radians(deg)
    clip[..., 3, 0], clip[..., 3, 2] = 0.2 * math.sin(rad), 0.2 * math.cos(rad)
    clip[..., 4, 0], clip[..., 4, 2] = -0.2 * math.sin(rad), -0.2 * math.cos(rad)
    return clip


def test_twist_loss_is_the_chord_between_the_twists() -> None:
    mask = torch.ones(1, 6, dtype=torch.bool)
    assert float(twist_loss(_twisted(12.0), _twisted(12.0), mask, (1, 2), (3, 4))) < 1e-12
    expected = torch.tensor(2 - 2 * math.cos(math.radians(30.0)))
    torch.testing.assert_close(twist_loss(_twisted(40.0), _twisted(10.0), mask, (1, 2), (3, 4)), expected)
    torch.testing.assert_close(twist_loss(_twisted(-20.0), _twisted(10.0), mask, (1, 2), (3, 4)), expected)
    late = _twisted(40.0)
    late[:, 3:] = _twisted(10.0)[:, 3:]
    half = mask.clone()
    half[:, 3:] = False  # padded frames cost nothing: the twisted half alone
    torch.testing.assert_close(twist_loss(late, _twisted(10.0), half, (1, 2), (3, 4)), expected)
    pred = _twisted(40.0).requires_grad_()
    twist_loss(pred, _twisted(10.0), mask, (1, 2), (3, 4)).backward()
    assert pred.grad is not None and float(pred.grad[..., 3:, :].abs().sum()) > 0


def test_the_twist_term_enters_the_total_with_its_weight_and_needs_shoulders() -> None:
    cfg = OdmoConfig(n_actions=2, n_joints=5, w_twist=2.0, w_contrastive=0.0, w_prior=0.0, w_free=0.0)
    kw = _pair_kwargs(_twisted(0.0), _twisted(60.0))
    terms = odmo_losses(cfg, hips=(1, 2), shoulders=(3, 4), **kw)
    torch.testing.assert_close(terms["twist"], torch.tensor(1.0))  # 2 − 2 cos 60°
    torch.testing.assert_close(terms["total"], terms["velocity"] * cfg.w_velocity + 2.0 * terms["twist"])
    assert float(odmo_losses(cfg, hips=(1, 2), **kw)["twist"]) == 0.0  # no shoulders: no twist term


def test_the_foot_twist_term_averages_each_foots_twist_against_the_hips() -> None:
    """A pair turned heel-first (180°) against the data costs 2 − 2 cos 180° = 4 per frame; the hips'
    own pair never turns against itself (0): their mean is 2, weighted into the total only when on."""
    cfg = OdmoConfig(n_actions=2, n_joints=5, w_foot_twist=0.5, w_contrastive=0.0, w_prior=0.0, w_free=0.0)
    kw = _pair_kwargs(_twisted(10.0), _twisted(190.0))
    terms = odmo_losses(cfg, hips=(1, 2), feet=((3, 4), (1, 2)), **kw)
    torch.testing.assert_close(terms["foot_twist"], torch.tensor(2.0))
    torch.testing.assert_close(terms["total"], terms["velocity"] * cfg.w_velocity + 0.5 * terms["foot_twist"])
    assert float(odmo_losses(cfg, feet=((3, 4),), **kw)["foot_twist"]) == 0.0  # no hips: no term
    off = odmo_losses(dataclasses.replace(cfg, w_foot_twist=0.0), hips=(1, 2), feet=((3, 4),), **kw)
    assert float(off["foot_twist"]) == 0.0
    assert float(off["total"]) == pytest.approx(float(off["velocity"]) * cfg.w_velocity)


def _stepping(alternate: bool, frames: int = 61, skip: int = 0) -> torch.Tensor:
    """(1, frames, 3, 3): a root walking along x at 1 m/s and two feet either side of it swinging 0.2 m
    fore and aft at 1 Hz (20 fps), in turn or together; ``skip`` frames cut from the start."""
    t = torch.arange(frames + skip, dtype=torch.float64)[skip:] / 20.0
    root = torch.stack([t, torch.zeros_like(t), torch.zeros_like(t)], dim=1)
    swing = 0.2 * torch.sin(2 * math.pi * t)
    zero = torch.zeros_like(t)
    left, right = (root + torch.stack([swing, zero, torch.full_like(t, z)], dim=1) for z in (0.1, -0.1))
    if alternate:
        right = right - torch.stack([2 * swing, zero, zero], dim=1)
    return torch.stack([root, left, right], dim=1)[None]


def test_coordination_loss_sees_feet_that_step_together_and_not_the_phase() -> None:
    """Alternating feet against feet moving together: in the root's frame each foot's fore-aft velocity
    has mean square a = (2·0.2·sin(π/20)·20)²/2 over the 60 steps (whole cycles), the two feet's cross
    terms are −a and +a, so the error is 2·(2a)² against norms 2a² each; a shift in time costs nothing."""
    mask = torch.ones(1, 61, dtype=torch.bool)
    walk, hop = _stepping(True), _stepping(False)
    a = (2 * 0.2 * math.sin(math.pi / 20) * 20) ** 2 / 2
    gram = velocity_gram(walk, mask, root=0, fps=20.0)[0]
    assert float(gram[3, 3]) == pytest.approx(a, rel=1e-9)  # left foot's x with itself
    assert float(gram[3, 6]) == pytest.approx(-a, rel=1e-9)  # left x with right x: opposite
    assert float(gram[3:, 3:].abs().sum() - 4 * a) < 1e-9  # no sideways or vertical movement
    expected = 8 * a**2 / (4 * a**2 + 4 * a**2 + COORDINATION_FLOOR)
    assert float(coordination_loss(hop, walk, mask, 0, 20.0)) == pytest.approx(expected, rel=1e-9)
    assert float(coordination_loss(_stepping(True, skip=7), walk, mask, 0, 20.0)) < 1e-12
    assert float(coordination_loss(walk, walk, mask, 0, 20.0)) == 0.0
    # Only the feet (1, 2): the same Gram without the root's rows, which are zero relative to itself.
    assert float(coordination_loss(hop, walk, mask, 0, 20.0, on=(1, 2))) == pytest.approx(expected, rel=1e-9)
    assert float(coordination_loss(hop, walk, mask, 0, 20.0, on=(1,))) == 0.0  # one foot alone: no phase
    cfg = OdmoConfig(n_actions=2, n_joints=3, w_coordination=2.0, w_contrastive=0.0, w_prior=0.0, w_free=0.0)
    terms = odmo_losses(cfg, **_pair_kwargs(walk, hop))
    torch.testing.assert_close(terms["coordination"], torch.tensor(expected, dtype=torch.float64))
    torch.testing.assert_close(
        terms["total"], terms["velocity"] * cfg.w_velocity + 2.0 * terms["coordination"], check_dtype=False
    )
    assert float(odmo_losses(cfg, **_pair_kwargs(walk, hop), coordination_on=(1,))["coordination"]) == 0.0


def test_contrastive_known_values() -> None:
    mu_a = torch.zeros(4, 2)
    mu_b = torch.tensor([[0.3, 0.0], [1.0, 0.0], [3.0, 4.0], [6.0, 0.0]])
    same = torch.tensor([True, True, False, False])
    # same: 0.5·relu(0.09 − 0.25) = 0, 0.5·relu(1 − 0.25) = 0.375
    # different: 0.5·(5 − 5)² = 0, 0.5·relu(5 − 6)² = 0
    torch.testing.assert_close(contrastive_loss(mu_a, mu_b, same, 5.0), torch.tensor(0.375 / 4))
    # The pull weight scales only the same-action term; 0 keeps just the push between actions.
    torch.testing.assert_close(contrastive_loss(mu_a, mu_b, same, 5.0, 0.5), torch.tensor(0.1875 / 4))
    torch.testing.assert_close(contrastive_loss(mu_a, mu_b, same, 5.0, 0.0), torch.tensor(0.0))
    near = torch.tensor([[1.0, 0.0]])
    torch.testing.assert_close(
        contrastive_loss(torch.zeros(1, 2), near, torch.tensor([False]), 5.0), torch.tensor(8.0)
    )


def test_prior_is_minimal_at_variance_sigma2() -> None:
    logvars = torch.linspace(-6, 1, 701).view(-1, 1)
    values = torch.stack([prior_loss(lv.view(1, 1), 0.05) for lv in logvars])
    best = logvars[values.argmin()].item()
    assert math.isclose(math.exp(best), 0.05, rel_tol=0.01)
    assert abs(prior_loss(torch.full((2, 3), math.log(0.05)), 0.05).item()) < 1e-6


def test_zero_weight_switches_a_term_off() -> None:
    cfg = _model(w_recon=0.0, w_prior=2.0).config
    joints = torch.randn(2, T, J, 3)
    terms = odmo_losses(
        cfg,
        joints=joints,
        trajectory=joints[:, :, 0],
        mask=torch.ones(2, T, dtype=torch.bool),
        pred_joints=joints + 1,
        pred_trajectory=joints[:, :, 0],
        mu=torch.zeros(2, 20),
        logvar=torch.zeros(2, 20),
        same=torch.tensor([True]),
        root=0,
    )
    expected = terms["traj"] + terms["consistency"] + terms["contrastive"] + 2 * terms["prior"]
    torch.testing.assert_close(terms["total"], expected)
    assert terms["recon"] > 0


def test_config_round_trip_and_validation() -> None:
    cfg = OdmoConfig(n_actions=10, n_joints=21, alpha=4.0)
    assert OdmoConfig.from_dict(cfg.to_dict()) == cfg
    with pytest.raises(ModelFormatError, match="unknown model config keys: bogus"):
        OdmoConfig.from_dict(cfg.to_dict() | {"bogus": 1})
    with pytest.raises(ModelFormatError, match="invalid"):
        OdmoConfig.from_dict({"n_actions": 2})
    with pytest.raises(ConfigError):
        OdmoConfig(n_actions=0, n_joints=21)
    with pytest.raises(ConfigError, match="train_precision must be one of float32, bfloat16, got 'fp8'"):
        OdmoConfig(n_actions=10, n_joints=21, train_precision="fp8")
    with pytest.raises(ConfigError, match="speed_error must be one of absolute, log, got 'relative'"):
        OdmoConfig(n_actions=10, n_joints=21, speed_error="relative")
    old = {k: v for k, v in cfg.to_dict().items() if k != "speed_error"}  # a model.json from before it
    assert OdmoConfig.from_dict(old).speed_error == "absolute"
    with pytest.raises(ConfigError, match="free_skate_contacts must be one of data, own, got 'both'"):
        OdmoConfig(n_actions=10, n_joints=21, free_skate_contacts="both")
    assert cfg.teacher_forcing(0) == 1.0 and math.isclose(cfg.teacher_forcing(10_000), 0.3)
    assert math.isclose(cfg.teacher_forcing(cfg.tf_decay_epochs // 2), 0.65)


def test_outputs_stay_float32_under_autocast_and_the_free_run_leaves_no_trace() -> None:
    model = _model().eval()
    z, action, end = torch.randn(2, 20), torch.tensor([0, 2]), torch.randn(2, 3)
    lmp, truth = torch.randn(2, T, J * 3), torch.randn(2, T, J, 3)
    with torch.no_grad():
        plain, _ = model.decode(z, action, end)
        with bfloat16_autocast("cpu"):
            mu, logvar = model.encode(lmp)
            free, traj = model.decode(z, action, end)
            forced, _ = model.decode(z, action, end, prev_truth=truth, tf_rate=0.5)
        after, _ = model.decode(z, action, end)
    assert {t.dtype for t in (mu, logvar, free, traj, forced)} == {torch.float32}
    # At most the trajectory LSTMs ran in bfloat16; the cached float32 loop weights are untouched.
    assert (free - plain).abs().max() < 0.1
    assert torch.equal(after, plain)


def test_free_running_scheduled_sampling_feeds_back_the_free_running_decode() -> None:
    model = _model(scheduled_sampling="free_run").eval()
    with torch.no_grad():
        model.motion_gen.embed.weight[:, : model.motion_gen.pose_dim] *= 30.0  # the previous pose matters
    one_step = _model(scheduled_sampling="one_step").eval()
    one_step.load_state_dict(model.state_dict())
    z, action, end = torch.randn(2, 20), torch.tensor([0, 1]), torch.randn(2, 3)
    truth = 10 * torch.randn(2, T, J, 3)  # far from anything the decoder makes
    gen = model.motion_gen
    with torch.no_grad():
        trained, _ = model.decode(z, action, end, prev_truth=truth, tf_rate=0.0)
        free, traj = model.decode(z, action, end)
        # tf_rate 0: every previous pose is the free-running decode's own (root-relative) pose
        poses = (free - traj.unsqueeze(2)).flatten(2)
        prev = torch.cat([poses.new_zeros(2, 1, gen.pose_dim), poses[:, :-1]], dim=1)
        cond = model.condition(z, action)
        state, const = gen._context(traj, cond)
        expected = gen._absolute(gen._run(prev, const, state)[0], traj)
        other, _ = one_step.decode(z, action, end, prev_truth=truth, tf_rate=0.0)
    torch.testing.assert_close(trained, expected, atol=1e-4, rtol=1e-4)
    torch.testing.assert_close(trained, free, atol=1e-4, rtol=1e-4)  # its own input: the free run again
    assert not torch.allclose(other, trained, atol=1e-3)  # one-step samples read the truth's predictions


def test_the_papers_model_is_one_setting_away() -> None:
    from engine.model.config import PAPER
    from tests.fixtures.procedural import procedural_skeleton

    paper = OdmoModel(OdmoConfig(n_actions=3, n_joints=11, **PAPER))
    paper.attach_skeleton(procedural_skeleton())
    assert paper.projection is None and paper.contact is None and not paper.motion_gen.relative
    assert not paper.motion_gen.free_running_samples and paper.config.w_velocity == 0.0
    assert paper.config.w_free == paper.config.w_speed == 0.0
    ours = OdmoModel(OdmoConfig(n_actions=3, n_joints=11, foot_joints=(8, 10), foot_heights=(0.05, 0.05)))
    ours.attach_skeleton(procedural_skeleton())
    assert ours.projection is not None and ours.contact is not None
    # a model.json written before the switches existed loads as the paper's decoder
    old = {k: v for k, v in ours.config.to_dict().items() if k not in PAPER or k == "contrastive_pull"}
    assert OdmoConfig.from_dict(old).to_dict() | {"foot_joints": (8, 10), "foot_heights": (0.05, 0.05)} == (
        OdmoConfig(n_actions=3, n_joints=11, **PAPER).to_dict()
        | {"foot_joints": (8, 10), "foot_heights": (0.05, 0.05)}
    )


def test_code_rhythms_are_the_clock_weighted_by_the_code() -> None:
    """With ``code_rhythms`` M the pose-free input gains W_r·r, r(t) = Σ_f clock_f(t)·A(cond)_f: a rhythm
    whose phase the code sets (two codes give rhythms a quarter turn apart when their weights say so);
    the clocked decoder without it is the same model with its rhythm inputs' weights at zero."""
    clocked = _model(clock_hz=(1.25,)).eval()
    rhythmic = _model(clock_hz=(1.25,), code_rhythms=1).eval()
    state = rhythmic.state_dict()
    width = clocked.motion_gen.embed.in_features
    assert rhythmic.motion_gen.embed.in_features == width + 1
    w_r = torch.zeros(16, 1)
    w_r[0, 0] = 1.0  # the rhythm drives hidden input 0 alone
    rhythm = torch.zeros_like(state["motion_gen.rhythm.weight"])  # (2F·M, C·D) = (2, 60)
    rhythm[0, 0], rhythm[1, 1] = 1.0, 1.0  # sin weighted by code[0], cos by code[1] (action 0's block)
    weight = torch.cat([clocked.state_dict()["motion_gen.embed.weight"], w_r], 1)
    rhythmic.load_state_dict(
        clocked.state_dict()
        | {
            "motion_gen.embed.weight": weight,
            "motion_gen.rhythm.weight": rhythm,
            "motion_gen.rhythm.bias": torch.zeros(2),
        }
    )
    z = torch.zeros(2, 20)
    z[0, 0], z[1, 1] = 0.5, 0.5  # a sine and a cosine of the same size
    action, end = torch.tensor([0, 0]), torch.randn(2, 3)
    with torch.no_grad():
        consts = []
        for model in (clocked, rhythmic):
            cond = model.condition(z, action)
            consts.append(model.motion_gen._context(model.traj_gen(cond, end), cond)[1])
    added = consts[1] - consts[0]
    angles = 2 * math.pi * 1.25 * torch.arange(T, dtype=torch.float32) / 20.0
    torch.testing.assert_close(added[0, :, 0], 0.5 * angles.sin(), atol=1e-5, rtol=0)
    torch.testing.assert_close(added[1, :, 0], 0.5 * angles.cos(), atol=1e-5, rtol=0)
    assert float(added[:, :, 1:].abs().max()) < 1e-6
    assert OdmoConfig.from_dict(rhythmic.config.to_dict()).code_rhythms == 1
    with pytest.raises(ConfigError, match="clock_hz"):
        OdmoConfig(n_actions=3, n_joints=J, window=T, code_rhythms=4)
