"""MoDi as a generator kind: its folder, prior sampling with truncation, W / W+ decoding, style mixing,
crowds, inversion, its bank and the unconditional metrics."""

from __future__ import annotations

import shutil
from pathlib import Path

import numpy as np
import pytest

from engine.cli import main
from engine.errors import CancelledError, ConfigError, ModelFormatError
from engine.generators import SampleRequest, open_generator
from engine.generators.modi import ModiGenerator
from engine.generators.modi_latent import as_wplus, crowd_codes, decode_codes, invert, mix_codes
from engine.metrics.physics import bone_length_cv
from engine.metrics.unconditional import action_kl, action_shares, kid, precision_recall
from engine.motion.npz import read_npz

pytestmark = pytest.mark.usefixtures("torch_single_thread")


@pytest.fixture(scope="module")
def modi(tiny_modi_dir: Path) -> ModiGenerator:
    generator = open_generator(tiny_modi_dir)
    assert isinstance(generator, ModiGenerator)
    return generator


def test_it_opens_as_an_unconditional_kind_with_its_capabilities(modi: ModiGenerator) -> None:
    assert modi.kind == "modi" and modi.action_names is None
    assert modi.code_space.name == "W" and modi.code_space.size == 32
    assert {"sample", "decode", "truncate", "mix", "invert", "bank", "modes"} <= modi.capabilities
    assert "end" not in modi.capabilities and "follow_path" not in modi.capabilities
    assert modi.label_names == modi.bank.action_names


def test_prior_samples_are_motions_on_the_skeleton_repeatable_by_seed(modi: ModiGenerator) -> None:
    a = modi.sample(SampleRequest(None, 3, 7))
    b = modi.sample(SampleRequest(None, 3, 7))
    c = modi.sample(SampleRequest(None, 3, 8))
    for x, y in zip(a, b, strict=True):
        np.testing.assert_array_equal(x.motion.joints, y.motion.joints)
    assert not np.allclose(a[0].motion.joints, c[0].motion.joints)
    parents = modi.skeleton.parents
    for s in a:
        assert s.motion.joints.shape == (16, 11, 3) and s.motion.fps == modi.fps
        assert bone_length_cv(s.motion.joints, parents) < 1e-4  # rotations through forward kinematics
        assert s.motion.action in modi.label_names  # labelled by its nearest bank codes
    # the code a sample carries decodes to its motion
    again = modi.decode(np.stack([s.code for s in a]))
    for s, m in zip(a, again, strict=True):
        np.testing.assert_allclose(m.joints, s.motion.joints, atol=1e-5)


def test_truncation_pulls_codes_to_the_mean_w(modi: ModiGenerator) -> None:
    w_avg = modi.loaded.model.w_avg.numpy()
    free = np.stack([s.code for s in modi.sample(SampleRequest(None, 4, 1))])
    half = np.stack([s.code for s in modi.sample(SampleRequest(None, 4, 1, truncation=0.5))])
    np.testing.assert_allclose(half - w_avg, 0.5 * (free - w_avg), atol=1e-5)
    mean = modi.sample(SampleRequest(None, 2, 1, truncation=0.0))
    np.testing.assert_allclose(mean[0].motion.joints, mean[1].motion.joints, atol=1e-6)
    with pytest.raises(ConfigError, match="psi must lie in"):
        modi.sample(SampleRequest(None, 1, 0, truncation=3.0))


def test_w_and_its_w_plus_broadcast_decode_alike(modi: ModiGenerator) -> None:
    net = modi.loaded.model
    w = modi.sample(SampleRequest(None, 2, 3))[0].code
    plus = np.tile(w, net.n_styles)
    a, b = decode_codes(net, w[None])[0], decode_codes(net, plus[None])[0]
    np.testing.assert_allclose(a, b, atol=1e-6)
    with pytest.raises(ConfigError, match=r"W \(N, 32\) or W\+"):
        as_wplus(net, np.zeros((1, 33)))


def test_style_mixing_takes_the_coarse_levels_from_one_code_and_the_fine_from_the_other(
    modi: ModiGenerator,
) -> None:
    net = modi.loaded.model
    a, b = (s.code for s in modi.sample(SampleRequest(None, 2, 4)))
    mixed = mix_codes(net, a, b, 1).reshape(net.n_styles, -1)
    for layer, level in enumerate(net.style_levels):
        np.testing.assert_array_equal(mixed[layer], a if level < 1 else b)
    np.testing.assert_array_equal(mix_codes(net, a, b, 0).reshape(net.n_styles, -1)[0], b)
    whole_a = modi.mix(a, b, net.n_levels).motion.joints
    np.testing.assert_allclose(whole_a, modi.decode(a[None])[0].joints, atol=1e-5)
    with pytest.raises(ConfigError, match=r"split must lie in 0\.\.3"):
        mix_codes(net, a, b, 4)


def test_a_crowd_spreads_around_its_code_by_sigma() -> None:
    centre = np.arange(4, dtype=np.float32)
    crowd = crowd_codes(centre, 2000, 0.5, seed=0)
    np.testing.assert_allclose(crowd.mean(axis=0), centre, atol=0.05)
    np.testing.assert_allclose(crowd.std(axis=0), 0.5, atol=0.03)
    np.testing.assert_array_equal(crowd_codes(centre, 3, 0.0, 1), np.tile(centre, (3, 1)))


def test_inversion_recovers_a_generated_motion_and_wplus_fits_at_least_as_well(
    modi: ModiGenerator,
) -> None:
    net = modi.loaded.model
    flags = [p.requires_grad for p in net.parameters()]
    codes = np.stack([s.code for s in modi.sample(SampleRequest(None, 3, 9))])
    targets, _ = decode_codes(net, codes)
    start = decode_codes(net, net.w_avg.numpy()[None])[0]
    before = np.linalg.norm(start - targets, axis=-1).mean()
    w = invert(net, targets, space="W", steps=150, lr=0.05)
    plus = invert(net, targets, space="W+", steps=150, lr=0.05)
    assert w.codes.shape == (3, 32) and plus.codes.shape == (3, 32 * net.n_styles)
    assert w.errors.mean() < 0.3 * before
    assert plus.errors.mean() <= w.errors.mean() * 1.1
    # the reported error is the error of the returned codes' motions
    found = decode_codes(net, w.codes)[0]
    np.testing.assert_allclose(
        np.linalg.norm(found - targets, axis=-1).mean(axis=(1, 2)), w.errors, atol=1e-5
    )
    assert [p.requires_grad for p in net.parameters()] == flags  # the network is left as it was


def test_inversion_reports_progress_and_cancels(modi: ModiGenerator) -> None:
    net = modi.loaded.model
    targets, _ = decode_codes(net, np.zeros((1, 32), np.float32))
    seen: list[int] = []
    invert(net, targets, steps=5, progress=lambda step, steps, err: seen.append(step))
    assert seen == [1, 2, 3, 4, 5]
    with pytest.raises(CancelledError):
        invert(net, targets, steps=5, cancel=lambda: True)
    with pytest.raises(ConfigError, match="targets must be finite"):
        invert(net, np.zeros((1, 15, 11, 3)))
    with pytest.raises(ConfigError, match="unknown inversion space"):
        invert(net, targets, space="Z")


def test_the_bank_holds_inverted_clips_and_labelled_samples(modi: ModiGenerator, procedural_clips) -> None:
    bank = modi.bank
    origins = [m["origin"] for m in bank.meta]
    assert origins.count("inverted") == len(procedural_clips) and origins.count("sample") == 40
    inverted = [m for m in bank.meta if m["origin"] == "inverted"]
    assert all("style" in m and m["inversion_error_m"] >= 0 for m in inverted)
    assert bank.codes.shape == (len(procedural_clips) + 40, 32)
    # inverted clips keep their own label
    labels = {c.meta["source"]: c.action for c in procedural_clips}
    for i in np.flatnonzero(np.array(origins) == "inverted"):
        assert bank.action_names[bank.actions[i]] == labels[str(bank.sources[i])]


def test_sampling_a_label_draws_from_its_modes(modi: ModiGenerator) -> None:
    label = modi.label_names[0]
    samples = modi.sample(SampleRequest(label, 4, 0))
    assert all(s.action == 0 and s.mode >= 0 for s in samples)
    with pytest.raises(ConfigError, match="needs an action label"):
        modi.sample(SampleRequest("dance", 1, 0, strategy="mode_preserving"))
    with pytest.raises(ConfigError, match="prior is unconditional"):
        modi.sample(SampleRequest(label, 1, 0, strategy="prior"))


def test_a_copied_folder_decodes_bit_identically_and_damage_is_refused(
    tiny_modi_dir: Path, tmp_path: Path
) -> None:
    copy = Path(shutil.copytree(tiny_modi_dir, tmp_path / "copy"))
    a = open_generator(tiny_modi_dir).sample(SampleRequest(None, 2, 5))
    b = open_generator(copy).sample(SampleRequest(None, 2, 5))
    for x, y in zip(a, b, strict=True):
        np.testing.assert_array_equal(x.motion.joints, y.motion.joints)
    data = bytearray((copy / "model.safetensors").read_bytes())
    data[-3] ^= 0xFF
    (copy / "model.safetensors").write_bytes(bytes(data))
    with pytest.raises(ModelFormatError, match="checksum"):
        open_generator(copy)


def test_cli_samples_without_an_action_and_with_truncation(tiny_modi_dir: Path, tmp_path: Path) -> None:
    out = tmp_path / "s.npz"
    argv = ["sample", "--model", str(tiny_modi_dir), "--n", "1", "--seed", "2", "--truncation", "0.7"]
    assert main([*argv, "--out", str(out)]) == 0
    expected = open_generator(tiny_modi_dir).sample(SampleRequest(None, 1, 2, truncation=0.7))[0]
    np.testing.assert_allclose(read_npz(out).joints, expected.motion.joints, atol=1e-6)


# --- the unconditional metrics, on sets whose answer is known -------------------------------------------


def test_kid_is_near_zero_for_one_distribution_and_grows_with_a_shift() -> None:
    rng = np.random.default_rng(0)
    a, b = rng.standard_normal((400, 8)), rng.standard_normal((400, 8))
    assert abs(kid(a, b)) < 0.01 * kid(a, b + 1.0)
    assert kid(a, b + 0.3) < kid(a, b + 1.0) < kid(a, b + 2.0)
    # the unbiased MMD², written out pair by pair on small sets
    x, y = rng.standard_normal((6, 3)), rng.standard_normal((5, 3)) + 0.5
    k = lambda u, v: (u @ v / 3 + 1.0) ** 3  # noqa: E731
    xx = sum(k(x[i], x[j]) for i in range(6) for j in range(6) if i != j) / 30
    yy = sum(k(y[i], y[j]) for i in range(5) for j in range(5) if i != j) / 20
    xy = sum(k(x[i], y[j]) for i in range(6) for j in range(5)) / 30
    assert kid(x, y) == pytest.approx(xx + yy - 2 * xy, rel=1e-10)


def test_precision_and_recall_see_a_collapsed_and_an_overspread_generator() -> None:
    rng = np.random.default_rng(1)
    real = rng.standard_normal((500, 2))
    same = rng.standard_normal((500, 2))
    collapsed = 0.1 * rng.standard_normal((500, 2))
    p, r = precision_recall(real, same)
    assert p > 0.9 and r > 0.9
    p, r = precision_recall(real, collapsed)
    assert p > 0.95 and r < 0.3  # every sample is realistic, most of the real set is missed
    p, _ = precision_recall(real, 6.0 + rng.standard_normal((500, 2)))
    assert p < 0.05


def test_action_shares_and_their_kl() -> None:
    real = np.repeat(np.arange(4), 25)
    np.testing.assert_allclose(action_shares(real, 4), 0.25)
    assert action_kl(real, real, 4) == pytest.approx(0.0, abs=1e-12)
    missing = np.repeat([0, 1, 2], 33)
    assert action_kl(real, missing, 4) > 1.0  # an action never generated costs a lot
    assert action_shares(np.array([0, -1]), 2).tolist() == [0.5, 0.0]


def test_decoding_on_another_device_string_is_refused(tiny_modi_dir: Path) -> None:
    with pytest.raises(ConfigError, match="unknown device"):
        open_generator(tiny_modi_dir, device="tpu")
