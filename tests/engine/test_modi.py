"""MoDi: pooled-skeleton hierarchy, skeletal convolutions, generator and critic, losses, training step."""

from __future__ import annotations

import itertools
import math
from pathlib import Path

import numpy as np
import pytest
import torch
import torch.nn.functional as F  # noqa: N812

from engine.errors import ConfigError, ModelFormatError
from engine.model.modi import ModiConfig, ModiDiscriminator, ModiNetwork
from engine.model.modi_losses import contact_losses, r1_penalty
from engine.model.modi_motion import MotionCoder
from engine.model.skeleton_conv import (
    SkeletalConv,
    neighbourhood,
    plan_blocks,
    pool_skeleton,
    pooling_mask,
    skeleton_hierarchy,
)
from engine.motion.datasets import load_folder
from engine.motion.motion import Motion
from engine.train.epochs import run_epochs, run_identity, steps_per_epoch
from engine.train.modi_steps import ModiSteps, clip_features, window_features
from engine.train.windows import crop_windows, prepare_clips
from tests.fixtures.procedural import procedural_skeleton

#: A small model: 3 levels, 16 frames, tiny channels.
SMALL = {"levels": 3, "window": 16, "channels": 16, "min_channels": 8, "w_dim": 32, "batch_size": 4}


def small_config(n_joints: int, **changes: object) -> ModiConfig:
    return ModiConfig(n_joints=n_joints, **(SMALL | changes))


@pytest.fixture(scope="module")
def bandai_clips(bandai_dir: Path) -> list[Motion]:
    """24 Bandai clips (Hips-rooted, 21 joints), one every ~120 files."""
    clips = load_folder(bandai_dir).clips
    return clips[:: len(clips) // 24][:24]


# --- topology ---------------------------------------------------------------------------------------------


def test_toy_tree_pools_as_worked_out_by_hand() -> None:
    # root 0 with three chains of three edges (0-1-2-3, 0-4-5-6, 0-7-8-9); feet at 3 and 6
    levels = skeleton_hierarchy([-1, 0, 1, 2, 0, 4, 5, 0, 7, 8], [3, 6], 4)
    # a chain of three edges merges into one (a pair, then the odd edge joins it)
    assert levels[1].parents == (-1, 0, 0, 0)
    assert levels[1].groups == ((0,), (1, 2, 3), (4, 5, 6), (7, 8, 9))
    assert levels[1].feet == (1, 2)
    # no chain left with two edges: the leaf edges of the root joint merge
    assert levels[2].parents == (-1, 0)
    assert levels[2].groups == ((0,), (1, 2, 3))
    assert levels[2].feet == (1, 1)
    # nothing left to merge: the level repeats
    assert levels[3].parents == (-1, 0) and levels[3].groups == ((0,), (1,))
    assert [lv.n_entities for lv in levels] == [13, 7, 5, 5]


def test_chains_pair_from_the_top_and_stop_at_forks() -> None:
    # 0-1-2-3-4 chain of four edges below the root's, then joint 4 forks into 5 and 6-7
    parents, groups = pool_skeleton([-1, 0, 1, 2, 3, 4, 4, 6])
    assert groups == ((0,), (1, 2), (3, 4), (5,), (6, 7))
    assert parents == (-1, 0, 1, 2, 2)


def test_neighbourhood_of_a_small_tree() -> None:
    # edges 0 (root), 1 and 2 (children of joint 0), 3 (child of 2); foot at joint 3
    (level,) = skeleton_hierarchy([-1, 0, 0, 2], [3], 1)
    near = neighbourhood(level, 1)
    expected = np.array(
        [
            # 0  1  2  3  d  c
            [1, 1, 1, 0, 1, 0],
            [1, 1, 1, 0, 1, 0],  # siblings 1 and 2 share joint 0
            [1, 1, 1, 1, 1, 0],
            [0, 0, 1, 1, 0, 1],
            [1, 1, 1, 0, 1, 0],  # the displacement: the root's edge and its neighbours
            [0, 0, 0, 1, 0, 1],  # the contact: its foot's edge
        ],
        dtype=bool,
    )
    np.testing.assert_array_equal(near, expected)
    assert neighbourhood(level, 2)[5, 2] and not neighbourhood(level, 2)[5, 0]
    np.testing.assert_array_equal(neighbourhood(level, 0), np.eye(6, dtype=bool))


def test_bandai_hierarchy(bandai_clips: list[Motion]) -> None:
    skeleton = bandai_clips[0].skeleton
    names = skeleton.names
    feet = [names.index(n) for n in ("Foot_L", "Toes_L", "Foot_R", "Toes_R")]
    levels = skeleton_hierarchy(skeleton.parents, feet, 5)
    assert [lv.n_edges for lv in levels] == [21, 11, 7, 4, 3]
    assert [lv.n_entities for lv in levels] == [26, 16, 12, 9, 8]

    def joints_of(level: int, edge: int) -> set[str]:
        found = {edge}
        for lv in levels[level:0:-1]:
            found = {e for g in found for e in lv.groups[g]}
        return {names[e] for e in found}

    one, two = levels[1], levels[2]
    assert {"UpperLeg_L", "LowerLeg_L"} in [joints_of(1, e) for e in range(one.n_edges)]
    arm = {"Shoulder_R", "UpperArm_R", "LowerArm_R", "Hand_R"}
    assert arm in [joints_of(2, e) for e in range(two.n_edges)]
    # the coarsest: the root's edge, spine with head and arms, both legs
    assert sorted(len(joints_of(4, e)) for e in range(3)) == [1, 8, 12]
    for fine, coarse in itertools.pairwise(levels):
        mask = pooling_mask(fine, coarse)
        np.testing.assert_array_equal(mask.sum(axis=0), np.ones(fine.n_entities))  # a partition


# --- skeletal convolution ---------------------------------------------------------------------------------


def test_skeletal_conv_sees_only_its_mask() -> None:
    mask = np.array([[1, 0, 0], [1, 1, 0]], dtype=bool)
    conv = SkeletalConv(mask, 4, 5, 3)
    conv.reset_parameters(torch.Generator().manual_seed(0))
    x = torch.randn(2, 12, 8)
    y = x.clone()
    y[:, 8:] += 1.0  # entity 2: outside every output's mask
    y[:, 4:8] += 1.0  # entity 1: seen by output 1 only
    a, b = conv(x), conv(y)
    torch.testing.assert_close(a[:, :5], b[:, :5])
    assert not torch.allclose(a[:, 5:], b[:, 5:])
    assert conv.weight.shape == (3, 5, 4, 3)  # weights only for the three allowed pairs


@pytest.mark.parametrize("density", [0.25, 0.6, 1.0])
def test_blocked_products_equal_the_dense_convolution(density: float) -> None:
    rng = np.random.default_rng(0)
    mask = rng.random((14, 11)) < density
    mask[np.arange(14), rng.integers(0, 11, 14)] = True  # every output sees something
    conv = SkeletalConv(mask, 3, 2, 3)
    conv.reset_parameters(torch.Generator().manual_seed(2))
    with torch.no_grad():
        conv.bias.normal_()
    assert 1 <= len(conv.blocks) < 14
    x = torch.randn(4, 33, 9)
    torch.testing.assert_close(conv(x), F.conv1d(x, conv.dense_weight(), conv.bias, padding=1))


def test_blocks_grow_while_one_product_is_cheaper() -> None:
    diagonal = np.eye(8, dtype=bool)
    # 2 x 2 (4) beats 1 + 1 + overhead 4; 3 x 3 (9) ties 4 + 1 + 4; 4 x 4 (16) loses to 9 + 1 + 4
    assert [(a, b) for a, b, _ in plan_blocks(diagonal)] == [(0, 3), (3, 6), (6, 8)]
    full = np.ones((5, 7), dtype=bool)
    ((start, stop, inputs),) = plan_blocks(full)
    assert (start, stop) == (0, 5) and list(inputs) == list(range(7))


@pytest.mark.parametrize("resample", ["none", "up", "down"])
def test_modulated_conv_matches_per_sample_weights(resample: str) -> None:
    mask = np.array([[1, 1], [0, 1], [1, 0]], dtype=bool)
    conv = SkeletalConv(mask, 3, 4, 3, demodulate=True, resample=resample)
    conv.reset_parameters(torch.Generator().manual_seed(1))
    x, style = torch.randn(2, 6, 8), torch.rand(2, 3) + 0.5
    out = conv(x, style)
    for b in range(2):  # StyleGAN2 eqs. 10-11 on each sample's own weights
        w = conv.dense_weight() * style[b].repeat(2)[None, :, None]
        w = w / w.square().sum((1, 2), keepdim=True).sqrt()
        xb = x[b : b + 1]
        if resample == "up":
            xb = F.interpolate(xb, scale_factor=2.0, mode="linear", align_corners=False)
        ref = F.conv1d(xb, w, padding=1)
        if resample == "down":
            ref = F.avg_pool1d(ref, 2)
        torch.testing.assert_close(out[b : b + 1], ref + conv.bias[:, None], rtol=1e-4, atol=1e-5)


# --- generator and critic ---------------------------------------------------------------------------------


@pytest.fixture(scope="module")
def small_models() -> tuple[ModiNetwork, ModiDiscriminator]:
    skeleton = procedural_skeleton()
    config = small_config(skeleton.n_joints)
    return ModiNetwork(config, skeleton, seed=3), ModiDiscriminator(config, skeleton, seed=4)


def test_shapes_and_styles(small_models: tuple[ModiNetwork, ModiDiscriminator]) -> None:
    g, d = small_models
    x = g(torch.randn(5, 32))
    assert x.shape == (5, 11 + 1 + 2, 6, 16)  # joints, displacement, two feet; K = 6; 16 frames
    assert d(x).shape == (5,)
    assert g.n_styles == 2 + 3 * 2 and g.style_levels == [0, 0, 1, 1, 1, 2, 2, 2]
    assert g.coder.joints(x).shape == (5, 16, 11, 3)


def test_decoded_bones_keep_their_lengths(small_models: tuple[ModiNetwork, ModiDiscriminator]) -> None:
    g, _ = small_models
    with torch.no_grad():
        g.coder.std.mul_(3.0)  # wild rotations: every bone still rigid
        joints = g.coder.joints(g(torch.randn(8, 32))).double()
        g.coder.std.div_(3.0)
    parents = list(procedural_skeleton().parents)
    bones = (joints[:, :, 1:] - joints[:, :, parents[1:]]).norm(dim=-1)
    cv = bones.std(dim=(0, 1)) / bones.mean(dim=(0, 1))
    assert cv.max() < 1e-5
    rest = np.linalg.norm(procedural_skeleton().offsets[1:], axis=1)
    np.testing.assert_allclose(bones.mean(dim=(0, 1)).numpy(), rest, rtol=1e-5)


def test_same_seed_same_model_and_motions() -> None:
    skeleton = procedural_skeleton()
    config = small_config(skeleton.n_joints)
    a, b = ModiNetwork(config, skeleton, seed=7), ModiNetwork(config, skeleton, seed=7)
    for (name, p), q in zip(a.state_dict().items(), b.state_dict().values(), strict=True):
        assert torch.equal(p, q), name
    other = ModiNetwork(config, skeleton, seed=8)
    assert not torch.equal(a.const, other.const)
    with torch.no_grad():  # noise strengths start at 0; give the noise a say
        for conv in [*a.convs, *b.convs]:
            conv.noise_strength.fill_(0.5)
    z = torch.randn(3, 32)
    torch.testing.assert_close(a(z), b(z), rtol=0, atol=0)
    draw = [g.synthesize(g.map(z), "random", torch.Generator().manual_seed(5)) for g in (a, b)]
    torch.testing.assert_close(draw[0], draw[1], rtol=0, atol=0)
    assert not torch.allclose(draw[0], a(z))  # random noise is not the fixed noise


def test_truncation_zero_decodes_the_mean_w(small_models: tuple[ModiNetwork, ModiDiscriminator]) -> None:
    g, _ = small_models
    with torch.no_grad():
        g.w_avg.copy_(torch.randn(32))
        x = g(torch.randn(4, 32), psi=0.0)
        ref = g.synthesize(g.w_avg[None].expand(4, -1))
        half = g(torch.randn(4, 32), psi=0.5)
    torch.testing.assert_close(x, ref)
    assert not torch.allclose(half, ref)


def test_style_mixing_ends_are_the_single_codes(
    small_models: tuple[ModiNetwork, ModiDiscriminator],
) -> None:
    g, _ = small_models
    with torch.no_grad():
        w1, w2 = g.map(torch.randn(2, 32)), g.map(torch.randn(2, 32))
        one, two = g.synthesize(w1), g.synthesize(w2)
        torch.testing.assert_close(g.synthesize(g.mix(w1, w2, g.n_levels)), one)
        torch.testing.assert_close(g.synthesize(g.mix(w1, w2, 0)), two)
        mixed = g.synthesize(g.mix(w1, w2, 1))
        per_code = g.synthesize(g.mix(w1, w2, torch.tensor([0, 3])))
    assert not torch.allclose(mixed, one) and not torch.allclose(mixed, two)
    torch.testing.assert_close(per_code[0], two[0])
    torch.testing.assert_close(per_code[1], one[1])
    with pytest.raises(ConfigError):
        g.mix(w1, w2, 4)


# --- losses -----------------------------------------------------------------------------------------------


def test_r1_penalty_matches_finite_differences() -> None:
    torch.manual_seed(0)
    weight = torch.randn(2, 3, 4, dtype=torch.float64)

    def critic(x: torch.Tensor) -> torch.Tensor:
        return torch.tanh((x * weight).sum((1, 2, 3))) + (x**3).sum((1, 2, 3)) * 0.1

    x = torch.randn(5, 2, 3, 4, dtype=torch.float64)
    eps = 1e-6
    grads = torch.zeros_like(x)
    for i in range(x[0].numel()):
        step = torch.zeros(x[0].numel(), dtype=torch.float64)
        step[i] = eps
        step = step.view(2, 3, 4)
        grads.view(5, -1)[:, i] = (critic(x + step) - critic(x - step)) / (2 * eps)
    expected = grads.square().flatten(1).sum(1).mean()
    assert float(r1_penalty(critic, x).detach()) == pytest.approx(float(expected), rel=1e-7)
    weight.requires_grad_(True)
    r1_penalty(critic, x).backward()  # differentiable for the critic's update
    assert weight.grad is not None and torch.isfinite(weight.grad).all()


def test_contact_losses(small_models: tuple[ModiNetwork, ModiDiscriminator]) -> None:
    g, _ = small_models
    x = torch.zeros(2, g.coder.n_entities, 6, 16)
    first_contact = g.coder.n_joints + 1
    with torch.no_grad():
        touch0, fcon0 = contact_losses(g.coder, x, 20.0)
        # contact label 1 everywhere (raw), and the root sliding at 1 m/s: fcon = speed² · s(1)
        raw = g.coder.denormalise(x)
        raw[:, first_contact:, 0] = 1.0
        raw[:, g.coder.n_joints, 2] = 1.0 / 20.0  # a step of 5 cm a frame (the root travels as velocity)
        saved = g.coder.feature_mask.clone()
        g.coder.feature_mask.copy_(g.coder.padding_mask)
        touch, fcon = contact_losses(g.coder, g.coder.normalise(raw), 20.0)
        g.coder.feature_mask.copy_(saved)
    assert float(touch) == pytest.approx(math.log1p(math.exp(-6.0)), rel=1e-5)
    assert float(fcon) == pytest.approx(1.0 / (1.0 + math.exp(-6.0)), rel=1e-4)
    assert float(touch0) >= 0 and float(fcon0) == pytest.approx(0.0, abs=1e-10)


# --- config -----------------------------------------------------------------------------------------------


def test_config_round_trip_and_strictness() -> None:
    config = ModiConfig(n_joints=21, n_actions=10)
    assert ModiConfig.from_dict(config.to_dict()) == config
    with pytest.raises(ModelFormatError, match="unknown model config keys: bogus"):
        ModiConfig.from_dict(config.to_dict() | {"bogus": 1})
    with pytest.raises(ModelFormatError):
        ModiConfig.from_dict({k: v for k, v in config.to_dict().items() if k != "n_joints"})
    with pytest.raises(ModelFormatError, match="architecture"):
        ModiConfig.from_dict(config.to_dict() | {"arch": "a2m"})
    with pytest.raises(ConfigError, match="halve"):
        ModiConfig(n_joints=21, window=60)
    with pytest.raises(ConfigError, match="odd"):
        ModiConfig(n_joints=21, kernel=4)
    with pytest.raises(ConfigError, match="mixing"):
        ModiConfig(n_joints=21, mixing=1.5)
    assert config.level_channels() == [128, 64, 32, 16, 16]
    assert config.level_frames() == [4, 8, 16, 32, 64]
    with pytest.raises(ConfigError, match="joints"):
        ModiNetwork(config, procedural_skeleton())


# --- data and training ------------------------------------------------------------------------------------


def test_real_windows_rebuild_their_joints(bandai_clips: list[Motion]) -> None:
    config = ModiConfig(n_joints=21)
    prepared = prepare_clips(bandai_clips, sorted({c.action for c in bandai_clips}), 20.0, 64)
    g = ModiNetwork(config, prepared.skeleton)
    clips = clip_features(prepared)
    batch = crop_windows(prepared, np.arange(prepared.n_clips), np.random.default_rng(0))
    raw = g.coder.raw_features(*window_features(g, clips, batch))
    g.coder.set_statistics(raw)
    joints = g.coder.joints(g.coder.normalise(raw)).numpy()
    # the features and FK on the model's fixed skeleton give back the canonical windows (centimetres:
    # the clips' own bone lengths differ a little from the first clip's)
    err = np.linalg.norm(joints - batch.joints, axis=-1)
    assert np.median(err) < 0.01 and err.mean() < 0.02
    contacts = raw[:, g.coder.n_joints + 1 :, 0]
    assert 0.2 < float(contacts.mean()) < 0.9  # feet are planted some of the time
    assert set(np.unique(contacts.numpy())) <= {0.0, 1.0}
    # leaf joints keep the identity: their features are constant and masked out
    head = prepared.skeleton.index("Head")
    assert float(g.coder.feature_mask[head].sum()) == 0.0


def test_training_steps_stay_finite_and_resume_the_r1_schedule(procedural_clips: list[Motion]) -> None:
    skeleton = procedural_clips[0].skeleton
    config = small_config(skeleton.n_joints, r1_every=2)
    prepared = prepare_clips(procedural_clips, ["walk", "wave", "jump"], config.fps, config.window)
    steps = ModiSteps(config, prepared, np.arange(0, 60), np.arange(60, 72), seed=0)
    before = {k: v.clone() for k, v in steps.modules.state_dict().items()}
    rng, gen = np.random.default_rng(0), torch.Generator().manual_seed(0)
    logs = [steps.step(0, rng, gen) for _ in range(5)]
    assert all(set(log) == set(steps.terms) for log in logs) and steps.terms[-1] == "total"
    assert all(math.isfinite(v) for log in logs for v in log.values())
    assert logs[0]["r1"] > 0
    val = steps.validate()
    assert val is not None and all(math.isfinite(v) for v in val.values())
    after = steps.modules.state_dict()
    assert int(after["counter.steps"]) == 5
    for part in ("g.const", "d.logit.weight"):
        assert not torch.equal(before[part], after[part])
    ema = after["g_ema.const"]
    assert not torch.equal(ema, before["g_ema.const"]) and not torch.equal(ema, after["g.const"])
    assert steps.epoch_columns(0)["steps"] == 5.0

    again = ModiSteps(config, prepared, np.arange(0, 60), np.arange(60, 72), seed=0)
    rng2, gen2 = np.random.default_rng(0), torch.Generator().manual_seed(0)
    logs2 = [again.step(0, rng2, gen2) for _ in range(5)]
    assert logs2 == logs  # seeded: the same run


def test_feet_by_their_chains_are_the_full_forward_kinematics(
    small_models: tuple[ModiNetwork, ModiDiscriminator],
) -> None:
    g, _ = small_models
    with torch.no_grad():
        x = g(torch.randn(3, 32))
        feet, _ = g.coder.feet_and_contacts(x)
        full = g.coder.joints(x)
    assert g.coder.foot_chain == [0, 7, 8, 9, 10]  # hips, both legs: not the spine or the arms
    torch.testing.assert_close(feet, full[:, :, g.coder.feet])


def test_epoch_loop_resumes_exactly(procedural_clips: list[Motion], tmp_path: Path) -> None:
    skeleton = procedural_clips[0].skeleton
    config = small_config(skeleton.n_joints, r1_every=3, epoch_size=8, epochs=2)
    prepared = prepare_clips(procedural_clips, ["walk", "wave", "jump"], config.fps, config.window)
    identity = run_identity(config, prepared.fingerprint(), 0, 0.1)

    def run(out: Path, epochs: int) -> ModiSteps:
        steps = ModiSteps(config, prepared, np.arange(60), np.arange(60, 72), seed=0)
        run_epochs(
            steps,
            out,
            config,
            identity,
            epochs=epochs,
            steps_per_epoch=steps_per_epoch(config),
            rng=np.random.default_rng(0),
            generator=torch.Generator().manual_seed(0),
            resume=True,
        )
        return steps

    straight = run(tmp_path / "straight", 2)
    run(tmp_path / "split", 1)
    resumed = run(tmp_path / "split", 2)
    for (name, a), b in zip(
        straight.modules.state_dict().items(), resumed.modules.state_dict().values(), strict=True
    ):
        assert torch.equal(a, b), name
    assert int(resumed.counter.steps) == 4


def test_the_root_travels_as_velocity_and_older_models_read_positions() -> None:
    skeleton = procedural_skeleton()
    rotations = torch.eye(3).expand(2, 6, skeleton.n_joints, 3, 3).clone()
    root = torch.cumsum(torch.full((2, 6, 3), 0.25), dim=1)  # walking steadily forwards and rising
    root[:, :, 1] = torch.linspace(0.0, 0.1, 6)
    velocity, position = MotionCoder(skeleton, True), MotionCoder(skeleton, False)
    contacts = torch.zeros(2, 6, len(velocity.feet))
    raw = velocity.raw_features(rotations, root, contacts)
    step = raw[:, skeleton.n_joints, :3].permute(0, 2, 1)
    torch.testing.assert_close(step[:, 1:, 0], torch.full((2, 5), 0.25))  # x per frame, not position
    torch.testing.assert_close(step[..., 1], root[..., 1])  # the height stays a height
    torch.testing.assert_close(velocity.split(velocity.normalise(raw))[1], root)
    raw_old = position.raw_features(rotations, root, contacts)
    torch.testing.assert_close(position.split(position.normalise(raw_old))[1], root)
    config = ModiConfig(n_joints=skeleton.n_joints).to_dict()
    del config["root_velocity"]
    assert ModiConfig.from_dict(config).root_velocity is False and ModiConfig(n_joints=3).root_velocity
