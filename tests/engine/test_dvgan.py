"""DVGAN: its motion features, critic parts, the generator kind (sampling, decoding, interpolation,
completion, seamless continuation, phrases) and its CLI."""

from __future__ import annotations

import dataclasses
import hashlib
from pathlib import Path

import numpy as np
import pytest
import torch
from scipy.spatial.transform import Rotation

from engine.cli import main
from engine.errors import ConfigError
from engine.generators import SampleRequest, open_generator
from engine.generators import dvgan as dvgan_kind
from engine.generators.dvgan import DvganGenerator, load_dvgan
from engine.metrics.by_kind import evaluate_generator
from engine.metrics.dvgan_eval import HORIZONS_MS, completion_errors, long_sequences
from engine.metrics.physics import bone_length_cv
from engine.model.dvgan import (
    DvganConfig,
    DvganNetwork,
    LanguageModel,
    final_cut,
    gradient_penalty,
    phrase_words,
    shifted,
)
from engine.model.dvgan_features import feature_joints, motion_features, solve_pose, typical_skeleton
from engine.motion.contact import foot_joints
from engine.motion.formats import read_motion, write_motion
from engine.motion.motion import Motion
from engine.motion.skeleton import Skeleton
from engine.train.dvgan_loop import train_dvgan
from engine.train.kind_run import WarmStart
from tests.fixtures.procedural import PROCEDURAL_ACTIONS, procedural_skeleton
from tests.fixtures.tiny_model import tiny_dvgan_config

pytestmark = pytest.mark.usefixtures("torch_single_thread")


@pytest.fixture(scope="module")
def dvgan(tiny_dvgan_dir: Path) -> DvganGenerator:
    generator = open_generator(tiny_dvgan_dir)
    assert isinstance(generator, DvganGenerator)
    return generator


def _turned(joints: np.ndarray, degrees: float, shift: tuple[float, float]) -> np.ndarray:
    moved = Rotation.from_euler("y", degrees, degrees=True).apply(joints.reshape(-1, 3)).reshape(joints.shape)
    return (moved + np.array([shift[0], 0.0, shift[1]])).astype(np.float32)


def test_features_round_trip_and_do_not_depend_on_where_the_motion_stands(procedural_clips) -> None:
    clip = procedural_clips[0]
    skeleton = clip.skeleton
    rest = np.zeros(len(foot_joints(skeleton)), np.float32)
    features, heading, start = motion_features(clip.joints, clip.fps, skeleton, rest)
    joints, _ = feature_joints(features, skeleton, heading, start)
    np.testing.assert_allclose(joints, clip.joints, atol=2e-3)  # fixed bone lengths: IK is exact
    elsewhere, heading2, start2 = motion_features(_turned(clip.joints, 70, (3, -2)), clip.fps, skeleton, rest)
    np.testing.assert_allclose(elsewhere, features, atol=1e-4)
    assert heading2 == pytest.approx(heading + np.radians(70), abs=1e-4)
    assert not np.allclose(start2, start)


def test_a_rest_bone_against_the_data_no_longer_flips_the_exponential_maps(procedural_clips) -> None:
    base = procedural_skeleton()
    offsets = np.array(base.offsets)
    knee = base.names.index("LeftFoot")
    offsets[knee] *= -1.0  # the leg's rest direction points up; the data's leg hangs down
    upside = Skeleton(base.names, base.parents, offsets)
    frames = np.concatenate([c.joints for c in procedural_clips])
    hip = base.names.index("LeftUpLeg")

    def angles(skeleton: Skeleton) -> np.ndarray:
        local, _, _ = solve_pose(frames, 30.0, skeleton)
        return Rotation.from_quat(local[:, hip], scalar_first=True).magnitude()

    assert np.median(angles(upside)) > 2.5  # shortest arcs near π: their axis is unstable
    typical = typical_skeleton(upside, frames, 30.0)
    assert np.max(angles(typical)) < 1.5
    np.testing.assert_allclose(
        np.linalg.norm(typical.offsets, axis=1), np.linalg.norm(offsets, axis=1), atol=1e-9
    )  # bone lengths kept


def test_shift_moves_each_window_and_pads_with_zeros() -> None:
    frames = torch.arange(1.0, 9.0).view(1, 8, 1).repeat(64, 1, 2)
    out = shifted(frames, torch.Generator().manual_seed(0))
    seen = set()
    for row in out[:, :, 0]:
        kept = row[row != 0]
        shift = int(torch.nonzero(row)[0]) - int(kept[0]) + 1
        seen.add(shift)
        np.testing.assert_array_equal(kept.numpy(), np.arange(kept[0], kept[0] + len(kept)))
        assert -4 <= shift <= 4
    assert len(seen) > 4  # uniform over [−N/2, N/2]


def test_final_cut_is_a_window_of_the_tape() -> None:
    tape = torch.arange(20.0).view(1, 20, 1).repeat(30, 1, 3)
    cut = final_cut(tape, 8, torch.Generator().manual_seed(1))
    starts = cut[:, 0, 0]
    np.testing.assert_array_equal((cut[:, :, 0] - starts[:, None]).numpy(), np.tile(np.arange(8.0), (30, 1)))
    assert starts.min() >= 0 and starts.max() <= 12 and len(set(starts.tolist())) > 3


def test_a_tape_is_as_many_windows_as_the_config_asks() -> None:
    """``tape_windows`` sets the generated tape a window is cut from (default 2: the paper's 2N); a CNN
    tape must be a power of two; a model.json from before the field reads the paper's tape."""
    long = DvganConfig(n_actions=2, n_joints=3, n_features=5, window=16, max_prefix=8, tape_windows=8)
    assert long.tape == 128 and DvganConfig(n_actions=2, n_joints=3).tape == 64
    net = DvganNetwork(dataclasses.replace(long, words=("walk",)))
    z = net.noise(3, long.tape - 1, torch.Generator().manual_seed(0))
    with torch.no_grad():
        tape = net.tape(net.language(["walk"]).expand(3, -1), torch.zeros(3, long.noise_dim), z)
    assert tape.shape == (3, 128, 5)
    with pytest.raises(ConfigError, match="power-of-two tape"):
        DvganConfig(n_actions=2, n_joints=3, window=16, max_prefix=8, tape_windows=3, generator="cnn")
    with pytest.raises(ConfigError, match="tape_windows"):
        DvganConfig(n_actions=2, n_joints=3, tape_windows=0)
    with pytest.raises(ConfigError, match="tape_windows = 10000 is over the limit"):
        DvganConfig(n_actions=2, n_joints=3, tape_windows=10_000)
    older = {k: v for k, v in DvganConfig(n_actions=2, n_joints=3).to_dict().items() if k != "tape_windows"}
    assert DvganConfig.from_dict(older).tape == 64


def test_a_fine_tune_starts_from_a_saved_generator_and_names_it(
    tiny_dvgan_dir: Path, procedural_clips, tmp_path: Path
) -> None:
    """A warm start with a longer tape and no epochs gives back the saved generator's weights exactly;
    one epoch moves them; the provenance names the source by sha256."""
    source = WarmStart.from_folder(tiny_dvgan_dir, load_dvgan)
    saved = load_dvgan(tiny_dvgan_dir, with_bank=False).model.state_dict()
    config = tiny_dvgan_config(tape_windows=4, epochs=0)
    options = {"seed": 0, "device": "cpu", "bank_per_action": 4, "bank_projections": ("pca",)}
    options |= {"bank_k_range": (1, 2), "warm_start": source}
    train_dvgan(procedural_clips, PROCEDURAL_ACTIONS, tmp_path / "same", config, **options)
    same = load_dvgan(tmp_path / "same", with_bank=False)
    assert same.config.tape == 64
    for name, tensor in same.model.state_dict().items():
        torch.testing.assert_close(tensor, saved[name], rtol=0, atol=0, msg=name)
    weights = hashlib.sha256((tiny_dvgan_dir / "model.safetensors").read_bytes()).hexdigest()
    assert same.provenance["warm_start"]["weights_sha256"] == weights
    config = tiny_dvgan_config(tape_windows=4, epochs=1)
    train_dvgan(procedural_clips, PROCEDURAL_ACTIONS, tmp_path / "tuned", config, **options)
    tuned = load_dvgan(tmp_path / "tuned", with_bank=False).model.state_dict()
    assert not torch.equal(tuned["net.diff.weight"], saved["net.diff.weight"])


def test_gradient_penalty_of_a_critic_with_gradient_norm_two_is_one() -> None:
    w = torch.zeros(4, 3)
    w[0, 0] = 2.0

    def critic(x: torch.Tensor, text: torch.Tensor) -> torch.Tensor:
        return (x * w).sum(dim=(1, 2))

    real, fake = torch.randn(5, 4, 3), torch.randn(5, 4, 3)
    assert float(gradient_penalty(critic, real, fake, torch.zeros(5, 1), None)) == pytest.approx(1.0)


def test_phrases_are_read_word_by_word_and_unknown_words_are_named() -> None:
    assert phrase_words("walk-turn-left") == ["walk", "turn", "left"]
    assert phrase_words("Raise up_both  hands") == ["raise", "up", "both", "hands"]
    language = LanguageModel(("left", "turn", "walk"), 8)
    assert language(["walk turn left", "walk"]).shape == (2, 8)
    with pytest.raises(ConfigError, match="unknown words dance"):
        language(["dance left"])


def test_it_opens_with_its_capabilities_and_samples_repeatably(dvgan: DvganGenerator) -> None:
    assert dvgan.kind == "dvgan" and dvgan.code_space.size == 8
    assert {"sample", "decode", "interpolate", "complete", "extend", "bank", "modes"} <= dvgan.capabilities
    assert "encode" not in dvgan.capabilities
    a = dvgan.sample(SampleRequest("walk", 3, 5))
    b = dvgan.sample(SampleRequest("walk", 3, 5))
    c = dvgan.sample(SampleRequest("walk", 3, 6))
    for x, y in zip(a, b, strict=True):
        np.testing.assert_array_equal(x.motion.joints, y.motion.joints)
    assert not np.allclose(a[0].motion.joints, c[0].motion.joints)
    for s in a:
        assert s.motion.joints.shape == (16, 11, 3) and s.motion.action == "walk"
        assert bone_length_cv(s.motion.joints, dvgan.skeleton.parents) < 1e-4
    strip = dvgan.interpolate(a[0].code, a[1].code, "walk", 4)
    ends = dvgan.decode(np.stack([a[0].code, a[1].code]), "walk", seed=0)
    np.testing.assert_allclose(strip[0].motion.joints, ends[0].joints, atol=1e-5)
    np.testing.assert_allclose(strip[-1].motion.joints, ends[1].joints, atol=1e-5)


def test_a_new_phrase_of_known_words_is_generated_and_unknown_words_refused(dvgan: DvganGenerator) -> None:
    [sample] = dvgan.sample(SampleRequest("walk jump", 1, 0))
    assert sample.action == -1 and sample.motion.action == "walk jump"
    with pytest.raises(ConfigError, match="unknown words swim"):
        dvgan.sample(SampleRequest("swim", 1, 0))


def test_completion_keeps_the_prefix_and_gives_several_futures(
    dvgan: DvganGenerator, procedural_clips
) -> None:
    clip = next(c for c in procedural_clips if c.action == "walk")
    prefix = clip.with_joints(clip.joints[:30], fps=2 * dvgan.fps)  # 15 frames at the model's rate
    futures = dvgan.complete(prefix, 12, n=3, seed=1)
    assert len(futures) == 3
    shown = int(futures[0].meta["prefix_frames"])
    assert shown == 15
    expected = dvgan_kind.resample_motion(prefix, dvgan.fps).joints
    for motion in futures:
        assert motion.n_frames == shown + 12
        np.testing.assert_allclose(motion.joints[:shown], expected, atol=0.05)  # where the prefix stands
    assert not np.allclose(futures[0].joints[shown:], futures[1].joints[shown:])


def test_long_sequences_stream_without_a_seam(dvgan: DvganGenerator, monkeypatch) -> None:
    [whole] = dvgan.sample(SampleRequest("wave", 1, 3), frames=300)
    monkeypatch.setattr(dvgan_kind, "CHUNK", 37)
    [chunked] = dvgan.sample(SampleRequest("wave", 1, 3), frames=300)
    assert whole.motion.n_frames == 300
    np.testing.assert_allclose(chunked.motion.joints, whole.motion.joints, atol=1e-4)
    longer = dvgan.extend(whole.motion, 50, seed=2)
    assert longer.n_frames == 350
    np.testing.assert_allclose(longer.joints[:300], whole.motion.joints, atol=0.05)


def test_cli_completes_a_file_and_samples_long_motions(
    dvgan: DvganGenerator, procedural_clips, tmp_path, capsys
) -> None:
    clip = next(c for c in procedural_clips if c.action == "wave")
    source = tmp_path / "wave.npz"
    write_motion(clip, source)
    out = tmp_path / "futures"
    code = main(["complete", "--model", str(dvgan.path), "--prefix", str(source), "--prefix-frames", "24",
                 "--frames", "10", "--n", "2", "--out", str(out)])  # fmt: skip
    assert code == 0
    files = sorted(out.glob("*.npz"))
    assert len(files) == 2
    assert read_motion(files[0]).n_frames == 24 + 10  # procedural clips are at the model's 20 fps
    long = tmp_path / "long.bvh"
    assert (
        main(
            ["sample", "--model", str(dvgan.path), "--action", "jump", "--frames", "120", "--out", str(long)]
        )
        == 0
    )
    assert read_motion(long).n_frames == 120
    bad = tmp_path / "bad.npz"
    bad.write_bytes(b"not a zip")
    capsys.readouterr()
    assert main(["complete", "--model", str(dvgan.path), "--prefix", str(bad), "--frames", "5",
                 "--out", str(tmp_path / "x.npz")]) != 0  # fmt: skip
    err = capsys.readouterr().err
    assert "bad.npz" in err and "Traceback" not in err


def test_models_without_extend_refuse_long_samples(tiny_model_dir: Path, tmp_path, capsys) -> None:
    code = main(["sample", "--model", str(tiny_model_dir), "--action", "walk", "--frames", "500",
                 "--out", str(tmp_path / "x.npz")])  # fmt: skip
    assert code != 0
    assert "cannot make 500-frame motions" in capsys.readouterr().err
    assert not (tmp_path / "x.npz").exists()


@pytest.fixture(scope="module")
def classifier(tmp_path_factory, procedural_clips):
    from engine.metrics.classifier import train_classifier

    out = tmp_path_factory.mktemp("dvgan_clf")
    return train_classifier(
        procedural_clips, PROCEDURAL_ACTIONS, out, epochs=2, batch_size=16, seed=0, window=12
    )


def test_zero_velocity_error_is_the_distance_moved_over_the_horizon(dvgan: DvganGenerator) -> None:
    skeleton = dvgan.skeleton
    t = np.arange(60) / dvgan.fps
    pose = np.zeros((skeleton.n_joints, 3))  # the rest pose, carried at 1.5 m/s along +z
    for j, p in enumerate(skeleton.parents):
        pose[j] = skeleton.offsets[j] + (pose[p] if p >= 0 else 0.0)
    joints = pose[None] + np.stack([np.zeros_like(t), np.zeros_like(t), 1.5 * t], 1)[:, None]
    clip = Motion(joints.astype(np.float32), dvgan.fps, skeleton, action="walk")
    report = completion_errors(dvgan, [clip], prefix_frames=10, n_futures=2)
    zero = report["walk"]["zero_velocity"]
    for ms in HORIZONS_MS:
        frames = max(1, round(ms / 1000 * dvgan.fps))
        assert zero[str(ms)] == pytest.approx(1.5 * frames / dvgan.fps, rel=1e-4)
    assert report["walk"]["n_clips"] == 1 and all(v >= 0 for v in report["walk"]["model"].values())


def test_evaluation_reports_windows_and_long_sequences(
    dvgan: DvganGenerator, procedural_clips, classifier
) -> None:
    result = evaluate_generator(dvgan, procedural_clips, classifier, repeats=1, n_per_action=4)
    assert result["meta"]["arch"] == "dvgan" and result["meta"]["window"] == 12
    assert 0.0 <= result["generated"]["accuracy"]["mean"] <= 1.0
    assert result["generated"]["fid"]["mean"] >= 0.0
    assert set(result["per_action"]) == set(PROCEDURAL_ACTIONS)
    long = long_sequences(dvgan, procedural_clips, classifier, frames=120)
    for row in long.values():
        assert 0.0 <= row["accuracy"] <= 1.0 and 0.0 <= row["windows_in_real_height_range"] <= 1.0
        assert row["bone_length_cv_whole"] < 1e-4  # ten windows, one skeleton
        assert row["root_height_min_m"] <= row["root_height_max_m"]


def test_long_rollouts_stay_within_the_training_range(dvgan: DvganGenerator, procedural_clips) -> None:
    [sample] = dvgan.sample(SampleRequest("jump", 1, 4), frames=2000)
    height = sample.motion.joints[:, dvgan.skeleton.root, 1]
    real = np.concatenate([c.joints[:, c.skeleton.root, 1] for c in procedural_clips])
    span = real.max() - real.min()
    assert real.min() - 0.2 * span <= height.min() and height.max() <= real.max() + 0.2 * span
