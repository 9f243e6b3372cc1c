"""Action2Motion: Lie poses through FK, training, prior sampling, the code space and bank, folder I/O (old
baseline folders included), bone-length control, evaluation and the comparison table."""

from __future__ import annotations

import csv
import hashlib
import json
from pathlib import Path

import numpy as np
import pytest
import torch
from scipy.spatial.transform import Rotation

from bench.compare import ROWS, per_action_entries, results_markdown
from bench.truncation import sweep, sweep_table
from bench.warm_start import warm_start_from, warm_start_line
from engine.errors import ConfigError, ModelFormatError
from engine.generators import SampleRequest, open_generator
from engine.generators.a2m import decode_a2m, encode_a2m, generate_a2m, load_a2m
from engine.generators.base import CapabilityError
from engine.metrics.a2m_eval import NOT_APPLICABLE, evaluate_a2m, prior_accuracy
from engine.metrics.by_kind import evaluate_generator
from engine.metrics.classifier import Classifier, train_classifier
from engine.metrics.evaluate import evaluate
from engine.metrics.features import canonical_windows
from engine.metrics.physics import physics_metrics
from engine.model.a2m import A2mConfig, A2mModel, so3_exp
from engine.modelio import load_model, write_model_folder
from engine.motion.ik import joints_to_rotations
from engine.motion.motion import Motion
from engine.train.a2m_loop import A2mSteps, posterior_means, train_a2m
from engine.train.kind_run import WarmStart
from engine.train.windows import prepare_clips
from tests.fixtures.procedural import PROCEDURAL_ACTIONS, procedural_skeleton
from tests.fixtures.tiny_model import single_thread, tiny_a2m_config


@pytest.fixture(scope="module")
def a2m_dir(tiny_a2m_dir: Path) -> Path:
    """Folder of a tiny A2M trained on the procedural clips (the session's)."""
    return tiny_a2m_dir


@pytest.fixture(scope="module")
def classifier(tmp_path_factory: pytest.TempPathFactory, procedural_clips: list[Motion]) -> Classifier:
    """A briefly trained evaluation classifier."""
    out = tmp_path_factory.mktemp("a2m_classifier")
    with single_thread():
        return train_classifier(procedural_clips, PROCEDURAL_ACTIONS, out, epochs=2, batch_size=16, seed=0)


def test_training_lowers_the_loss(a2m_dir: Path) -> None:
    rows = list(csv.DictReader((a2m_dir / "train_log.csv").read_text().splitlines()))
    assert len(rows) == 8
    first, last = rows[0], rows[-1]
    assert float(last["train_recon"]) < 0.5 * float(first["train_recon"])
    assert float(last["val_recon"]) < 0.5 * float(first["val_recon"])
    assert float(last["train_trajectory"]) < float(first["train_trajectory"])
    meta = json.loads((a2m_dir / "model.json").read_text())
    assert meta["arch"] == "a2m"
    assert meta["provenance"]["windows_seen"] == 8 * 64


def test_so3_exp_matches_scipy() -> None:
    w = np.random.default_rng(0).normal(size=(200, 3)) * 1.5
    w[:3] *= 1e-5  # the small-angle branch
    np.testing.assert_allclose(
        so3_exp(torch.tensor(w)).numpy(), Rotation.from_rotvec(w).as_matrix(), atol=1e-12
    )


def test_lie_outputs_are_the_datas_skeleton_posed_by_forward_kinematics(
    procedural_clips: list[Motion],
) -> None:
    clip = procedural_clips[5]
    _, local, root, _ = joints_to_rotations(clip)  # an independent solve: scipy IK on the same skeleton
    model = A2mModel(tiny_a2m_config(), seed=0)
    model.set_skeleton(clip.skeleton)
    w = Rotation.from_quat(local.reshape(-1, 4), scalar_first=True).as_rotvec().reshape(len(clip.joints), -1)
    params = torch.tensor(np.concatenate([w, root], 1), dtype=torch.float32)[None]
    joints = model._pose(params).reshape(len(clip.joints), -1, 3).numpy()
    np.testing.assert_allclose(joints, clip.joints, atol=2e-4)
    bones = np.linalg.norm(joints[:, 1:] - joints[:, clip.skeleton.parents[1:]], axis=-1)
    np.testing.assert_allclose(
        bones, np.broadcast_to(clip.skeleton.bone_lengths()[1:], bones.shape), atol=1e-5
    )


def test_teacher_forced_pass_matches_a_step_by_step_loop(torch_single_thread: None) -> None:
    for rep in ("lie", "joints"):
        model = A2mModel(tiny_a2m_config(pose_rep=rep), seed=3).eval()
        model.set_skeleton(procedural_skeleton()) if rep == "lie" else None
        gen = torch.Generator().manual_seed(0)
        joints = torch.randn(2, 60, 11, 3, generator=gen)
        actions = torch.tensor([0, 2])
        with torch.no_grad():
            out = model(joints, actions, teacher=True, generator=None)
            cond = model._condition(actions)
            x = joints.reshape(2, 60, -1)
            h_q = h_p = h_g = None
            prev = torch.zeros(2, 1, 33)
            for t in range(60):
                c = cond[:, t : t + 1]
                mu_q, _, h_q = model.posterior(torch.cat([x[:, t : t + 1], c], 2), h_q)
                mu_p, _, h_p = model.prior(torch.cat([prev, c], 2), h_p)
                params, h_g = model.generator(torch.cat([prev, c, mu_q], 2), h_g)
                pose = model._pose(params)
                torch.testing.assert_close(out.mu_p[:, t : t + 1], mu_p, atol=1e-5, rtol=1e-5)
                torch.testing.assert_close(out.joints[:, t].reshape(2, 1, -1), pose, atol=1e-5, rtol=1e-5)
                prev = x[:, t : t + 1]


def test_generation_is_deterministic_per_seed(a2m_dir: Path, torch_single_thread: None) -> None:
    loaded = load_a2m(a2m_dir)
    first, z = generate_a2m(loaded, "wave", 3, 7)
    assert first.shape == (3, 60, 11, 3) and first.dtype == np.float32 and z.shape == (3, 60, 8)
    assert np.all(np.isfinite(first))
    np.testing.assert_array_equal(first, generate_a2m(loaded, 1, 3, torch.Generator().manual_seed(7))[0])
    assert not np.allclose(first, generate_a2m(loaded, "wave", 3, 8)[0])
    assert not np.allclose(first[0], first[1])  # the prior is sampled, not its mean
    with pytest.raises(ConfigError):
        generate_a2m(loaded, "dance", 1, 0)
    with pytest.raises(ConfigError):
        generate_a2m(loaded, 3, 1, 0)


def test_prior_samples_keep_their_z_and_land_on_the_map(a2m_dir: Path, torch_single_thread: None) -> None:
    generator = open_generator(a2m_dir)
    samples = generator.sample(SampleRequest("wave", 4, 9))
    joints, z = generate_a2m(generator.loaded, "wave", 4, 9)
    model = generator.loaded.model
    with torch.no_grad():
        expected = model.z_to_codes(torch.from_numpy(z)).numpy()
        z_again = model.codes_to_z(torch.from_numpy(expected)).numpy()
    for s, j, code in zip(samples, joints, expected, strict=True):
        np.testing.assert_array_equal(s.code, code)
        np.testing.assert_allclose(s.motion.joints[..., 0], j[..., 0])
    # the code is the z sequence's orthogonal projection: what it leaves out is orthogonal to the basis
    residual = (z - z_again).reshape(4, -1)
    np.testing.assert_allclose(residual @ model.code_basis.numpy().T, 0.0, atol=1e-4)
    points = generator.bank.projections["pca"].transform(np.stack([s.code for s in samples]))
    assert points.shape == (4, 2) and np.all(np.isfinite(points))


def test_bank_holds_each_clips_posterior_mean_code(
    a2m_dir: Path, procedural_clips: list[Motion], torch_single_thread: None
) -> None:
    loaded = load_a2m(a2m_dir)
    bank = loaded.bank
    assert bank is not None and bank.codes.shape == (len(procedural_clips), 6)
    prepared = prepare_clips(procedural_clips, PROCEDURAL_ACTIONS, loaded.fps, loaded.window)
    means, ends = posterior_means(loaded.model, prepared, np.arange(len(procedural_clips)))
    with torch.no_grad():
        codes = loaded.model.z_to_codes(torch.from_numpy(means)).numpy()
    np.testing.assert_allclose(bank.codes, codes, atol=1e-5)
    np.testing.assert_allclose(bank.ends, ends, atol=1e-6)
    assert {m["split"] for m in bank.meta} == {"train", "val"}
    clip = procedural_clips[7]
    np.testing.assert_allclose(encode_a2m(loaded, clip, clip.action), bank.codes[7], atol=1e-5)
    assert set(bank.modes) == {0, 1, 2}
    # a training clip's code decodes to a motion of that clip's kind: nearer it than the other actions' clips
    motion = decode_a2m(loaded, bank.codes[7], clip.action)[0]
    assert motion.shape == (60, 11, 3) and np.all(np.isfinite(motion))


def test_mode_samples_are_their_codes_decoded(a2m_dir: Path, torch_single_thread: None) -> None:
    generator = open_generator(a2m_dir)
    for strategy in ("mode_preserving", "conventional"):
        samples = generator.sample(SampleRequest("walk", 3, 2, strategy=strategy))
        motions = generator.decode(np.stack([s.code for s in samples]), "walk")
        for s, m in zip(samples, motions, strict=True):
            np.testing.assert_array_equal(s.motion.joints, m.joints)
    one = generator.sample(SampleRequest("walk", 2, 2, mode=0))
    assert [s.mode for s in one] == [0, 0]
    strip = generator.interpolate(one[0].code, one[1].code, "walk", 4)
    np.testing.assert_allclose(strip[0].motion.joints, one[0].motion.joints, atol=1e-5)  # other batches
    np.testing.assert_allclose(strip[-1].motion.joints, one[1].motion.joints, atol=1e-5)
    with pytest.raises(ConfigError, match="unknown strategy"):
        generator.sample(SampleRequest("walk", 1, 0, strategy="greedy"))


def test_truncation_scales_the_priors_spread_and_pulls_mode_codes_to_their_mode(
    a2m_dir: Path, torch_single_thread: None
) -> None:
    generator = open_generator(a2m_dir)
    model = generator.loaded.model
    paper = generator.sample(SampleRequest("wave", 3, 5))
    same = generator.sample(SampleRequest("wave", 3, 5, truncation=1.0))
    np.testing.assert_array_equal(paper[0].motion.joints, same[0].motion.joints)
    # ψ = 0: every z_t is the prior's mean, so every seed rolls out the same motion
    mean = generator.sample(SampleRequest("wave", 2, 5, truncation=0.0))
    np.testing.assert_allclose(mean[0].motion.joints, mean[1].motion.joints, atol=1e-5)
    other = generator.sample(SampleRequest("wave", 1, 6, truncation=0.0))
    np.testing.assert_allclose(mean[0].motion.joints, other[0].motion.joints, atol=1e-5)
    # ψ = 0.5: each z_t lies half as far from the prior mean (the mean of its own rollout) as its draw
    _, z = generate_a2m(generator.loaded, "wave", 2, 7, psi=0.5)
    _, z_full = generate_a2m(generator.loaded, "wave", 2, 7)
    with torch.no_grad():
        cond = model._condition(torch.full((2,), 1))
        _, _, _, mu, logvar = model._rollout(cond, torch.from_numpy(z), None)
        first = torch.randn(mu[:, :1].shape, generator=torch.Generator().manual_seed(7))  # frame 0's draw
    drawn = mu[:, :1] + 0.5 * torch.exp(0.5 * logvar[:, :1]) * first
    np.testing.assert_allclose(z[:, :1], drawn.numpy(), atol=1e-5)
    assert not np.allclose(z, z_full)
    modes = generator.bank.modes[generator.action_names.index("walk")]
    pulled = generator.sample(SampleRequest("walk", 4, 3, strategy="mode_preserving", truncation=0.0))
    for s in pulled:
        np.testing.assert_allclose(s.code, modes.means_[s.mode], atol=1e-5)
    centre = generator.sample(SampleRequest("walk", 1, 3, strategy="conventional", truncation=0.0))[0]
    np.testing.assert_allclose(centre.code, modes.conventional_mean_, atol=1e-5)
    for psi in (-0.1, 2.5, float("nan")):
        with pytest.raises(ConfigError, match="truncation psi"):
            generator.sample(SampleRequest("wave", 1, 0, truncation=psi))


def test_bone_scale_changes_the_body_not_the_motion(a2m_dir: Path, torch_single_thread: None) -> None:
    loaded = load_a2m(a2m_dir)
    base, _ = generate_a2m(loaded, "walk", 2, 5)
    tall, _ = generate_a2m(loaded, "walk", 2, 5, bone_scale=1.25)
    parents = loaded.skeleton.parents
    lengths = loaded.skeleton.bone_lengths()[1:]
    for joints, factor in ((base, 1.0), (tall, 1.25)):
        bones = np.linalg.norm(joints[:, :, 1:] - joints[:, :, parents[1:]], axis=-1)
        np.testing.assert_allclose(bones, np.broadcast_to(factor * lengths, bones.shape), atol=1e-5)
    root = loaded.skeleton.root
    np.testing.assert_array_equal(base[:, :, root], tall[:, :, root])  # the same rollout, a larger body
    arms = np.ones(loaded.skeleton.n_joints, np.float32)
    arms[3] = 2.0
    longer, _ = generate_a2m(loaded, "walk", 2, 5, bone_scale=arms)
    arm = np.linalg.norm(longer[:, :, 3] - longer[:, :, parents[3]], axis=-1)
    np.testing.assert_allclose(arm, 2.0 * lengths[2], atol=1e-5)
    for bad in (0.0, -1.0, np.ones(3), float("nan")):
        with pytest.raises(ConfigError, match="bone_scale"):
            generate_a2m(loaded, "walk", 1, 0, bone_scale=bad)


def test_save_load_generate_identical(a2m_dir: Path, tmp_path: Path, torch_single_thread: None) -> None:
    loaded = load_a2m(a2m_dir)
    write_model_folder(
        tmp_path,
        loaded.model,
        loaded.config.to_dict(),
        loaded.skeleton,
        loaded.action_names,
        loaded.provenance,
        0.9,
        "a2m",
    )
    again = load_a2m(tmp_path)
    assert again.config == loaded.config and again.action_names == loaded.action_names
    np.testing.assert_array_equal(generate_a2m(loaded, 2, 4, 11)[0], generate_a2m(again, 2, 4, 11)[0])


def test_old_baseline_folders_load_as_the_joint_position_model(
    tiny_a2m_old_dir: Path, torch_single_thread: None
) -> None:
    loaded = load_a2m(tiny_a2m_old_dir)
    assert "pose_rep" not in json.loads((tiny_a2m_old_dir / "model.json").read_text())["config"]
    assert (loaded.config.pose_rep, loaded.config.code_dim, loaded.config.trajectory_weight) == (
        "joints",
        0,
        0.0,
    )
    assert loaded.bank is None
    generator = open_generator(tiny_a2m_old_dir)
    assert generator.capabilities == {"sample", "truncate"}
    joints, _ = generate_a2m(loaded, "walk", 2, 3)
    assert joints.shape == (2, 60, 11, 3) and np.all(np.isfinite(joints))
    with pytest.raises(ConfigError, match="no bones to scale"):
        generate_a2m(loaded, "walk", 1, 0, bone_scale=1.1)
    assert A2mConfig.from_dict(loaded.config.to_dict()) == loaded.config


def _copy(src: Path, dst: Path) -> Path:
    dst.mkdir()
    for name in ("model.json", "model.safetensors", "latent_bank.npz"):
        (dst / name).write_bytes((src / name).read_bytes())
    return dst


def test_loading_is_strict(a2m_dir: Path, tiny_model_dir: Path, tmp_path: Path) -> None:
    with pytest.raises(ModelFormatError, match="pose_rep"):
        A2mConfig.from_dict(tiny_a2m_config().to_dict() | {"pose_rep": "quaternions"})
    with pytest.raises(ModelFormatError, match="not 'a2m'"):
        load_a2m(tiny_model_dir)  # an ODMO folder
    with pytest.raises(ModelFormatError):
        load_model(a2m_dir)  # and the ODMO loader refuses an A2M folder
    missing = _copy(a2m_dir, tmp_path / "missing")
    (missing / "model.safetensors").unlink()
    with pytest.raises(ModelFormatError, match="missing weights"):
        load_a2m(missing)
    corrupt = _copy(a2m_dir, tmp_path / "corrupt")
    (corrupt / "model.safetensors").write_bytes(b"\x00" * 40)
    with pytest.raises(ModelFormatError, match="corrupt"):
        load_a2m(corrupt)
    for name, change in {
        "shape": lambda m: m["config"].update(hidden=48),
        "lie": lambda m: m["config"].update(pose_rep="joints"),  # the weights have Lie outputs
        "newer": lambda m: m.update(format_version=99),
        "unknown": lambda m: m["config"].update(dropout=0.1),
        "actions": lambda m: m.update(action_names=["walk"]),
        "arch": lambda m: m.update(arch="odmo"),
    }.items():
        folder = _copy(a2m_dir, tmp_path / name)
        meta = json.loads((folder / "model.json").read_text())
        change(meta)
        (folder / "model.json").write_text(json.dumps(meta))
        with pytest.raises(ModelFormatError):
            load_a2m(folder)
    (tmp_path / "garbled").mkdir()
    (tmp_path / "garbled" / "model.json").write_text("{not json")
    with pytest.raises(ModelFormatError, match="unreadable"):
        load_a2m(tmp_path / "garbled")


def test_resume_continues_exactly(
    procedural_clips: list[Motion], tmp_path: Path, torch_single_thread: None
) -> None:
    config = tiny_a2m_config(epochs=2, epoch_size=32)
    straight = train_a2m(procedural_clips, PROCEDURAL_ACTIONS, tmp_path / "a", config, device="cpu")
    train_a2m(procedural_clips, PROCEDURAL_ACTIONS, tmp_path / "b", tiny_a2m_config(epochs=1, epoch_size=32))
    resumed = train_a2m(
        procedural_clips, PROCEDURAL_ACTIONS, tmp_path / "b", config, device="cpu", resume=True
    )
    assert resumed.train_losses == pytest.approx(straight.train_losses, rel=1e-6)
    with pytest.raises(ModelFormatError, match="different config"):
        train_a2m(
            procedural_clips,
            PROCEDURAL_ACTIONS,
            tmp_path / "b",
            tiny_a2m_config(epochs=3, lr=1e-3),
            resume=True,
        )


def test_evaluation_shares_the_real_sets_with_odmo(
    a2m_dir: Path,
    tiny_model_dir: Path,
    procedural_clips: list[Motion],
    classifier: Classifier,
    torch_single_thread: None,
) -> None:
    clips = procedural_clips[::3]
    a2m = evaluate_a2m(load_a2m(a2m_dir), clips, classifier, repeats=2, n_per_action=6, seed=4)
    odmo = evaluate(load_model(tiny_model_dir), clips, classifier, repeats=2, n_per_action=6, seed=4)
    assert a2m["real"] == odmo["real"]
    expected = {"accuracy", "fid", "kid", "precision", "recall", "action_kl", "diversity", "multimodality"}
    expected |= {"apd", "n_apd", "reconstruction_error_m", "reconstruction_accuracy", "joint_range_excess"}
    assert set(a2m["generated"]) == expected | set(physics_metrics([clips[0].joints], clips[0].skeleton, 20))
    assert set(a2m["per_action"]) == {c.action for c in clips}
    assert all(np.isfinite(v["mean"]) for v in a2m["generated"].values())
    assert set(NOT_APPLICABLE) >= {"mode_homogeneity", "style_nmi", "end_error_m"}
    assert a2m["meta"]["not_applicable"] == list(NOT_APPLICABLE)
    trained = set(load_a2m(a2m_dir).provenance["train_sources"])
    held = [c for c in clips if c.meta["source"] not in trained]  # the model's validation clips
    assert a2m["meta"]["n_reconstruction_clips"] == len(held) > 0
    with pytest.raises(ConfigError):
        evaluate_a2m(load_a2m(a2m_dir), clips, classifier, repeats=0)


def test_truncated_evaluation_samples_the_truncated_prior_and_other_kinds_refuse_it(
    a2m_dir: Path,
    tiny_model_dir: Path,
    procedural_clips: list[Motion],
    classifier: Classifier,
    torch_single_thread: None,
) -> None:
    clips = procedural_clips[::3]
    options = {"repeats": 1, "n_per_action": 4, "seed": 2}
    reports = sweep(open_generator(a2m_dir), clips, classifier, [1.0, 0.5], **options)
    paper, half = reports[1.0], reports[0.5]
    assert paper["meta"]["truncation"] == 1.0 and half["meta"]["truncation"] == 0.5
    assert half["real"] == paper["real"] and half["generated"]["fid"] != paper["generated"]["fid"]
    default = evaluate_generator(open_generator(a2m_dir), clips, classifier, **options)
    assert paper["generated"] == default["generated"]  # ψ 1 is the paper's sampling
    rows = sweep_table(reports).splitlines()
    assert [r.split(" | ")[0] for r in rows[2:]] == ["| real (held-out)", "| ψ 1", "| ψ 0.5"]
    assert rows[4].split(" | ")[2].startswith(f"{half['generated']['fid']['mean']:.4g} ± ")
    with pytest.raises(CapabilityError, match=r"cannot evaluate at truncation 0\.5"):
        evaluate_generator(open_generator(tiny_model_dir), clips, classifier, truncation=0.5, **options)


def test_evaluation_from_the_banks_modes_scores_the_decoded_mode_codes(
    a2m_dir: Path,
    tiny_a2m_old_dir: Path,
    procedural_clips: list[Motion],
    classifier: Classifier,
    torch_single_thread: None,
) -> None:
    clips = procedural_clips[::3]
    options = {"repeats": 1, "n_per_action": 4, "strategy": "conventional", "truncation": 0.0}
    report = evaluate_a2m(load_a2m(a2m_dir), clips, classifier, **options)
    assert report["meta"]["strategy"] == "conventional"
    # ψ 0 pulls every conventional draw onto the action's mean code: one motion per action, so same-action
    # pairs lie at distance 0 and each action's accuracy is whether its mean code's motion is read right
    assert report["generated"]["multimodality"]["mean"] == pytest.approx(0.0, abs=1e-4)
    generator = open_generator(a2m_dir)
    for index, action in enumerate(PROCEDURAL_ACTIONS):
        centre = generator.bank.modes[index].conventional_mean_[None]
        [motion] = generator.decode(centre, action)
        _, [predicted] = classifier.classify(canonical_windows([motion], 60))
        row = report["per_action"][action]["generated"]
        assert row["accuracy"]["mean"] == float(predicted == index)
        hands = physics_metrics([motion.joints], motion.skeleton, motion.fps)["hand_speed_m_s"]
        assert row["hand_speed_m_s"]["mean"] == pytest.approx(hands, rel=1e-4)
    with pytest.raises(ConfigError, match="unknown strategy"):
        evaluate_a2m(load_a2m(a2m_dir), clips, classifier, strategy="weights")
    with pytest.raises(CapabilityError, match="cannot sample mode-preserving codes from modes"):
        evaluate_a2m(load_a2m(tiny_a2m_old_dir), clips, classifier, strategy="mode_preserving")


def test_results_table_from_a_tiny_report() -> None:
    def block(**metrics: float) -> dict[str, dict[str, float]]:
        return {k: {"mean": v, "ci95": v / 10} for k, v in metrics.items()}

    real = block(accuracy=0.95, fid=0.5, diversity=7.0, multimodality=2.5, n_apd=1.0)
    real |= block(bone_length_cv=0.002, hand_speed_m_s=0.5)
    walk = {
        "real": block(hand_speed_m_s=0.5, accuracy=1.0),
        "generated": block(hand_speed_m_s=0.25, accuracy=0.8),
    }
    entries = [
        {
            "row": "odmo",
            "generated": block(
                accuracy=0.9, fid=1.25, mode_homogeneity=15.0, end_error_m=0.1, bone_length_cv=0.0
            ),
            "per_action": {"walk": walk},
        },
        {
            "row": "a2m",
            "generated": block(accuracy=0.5, fid=4.0, reconstruction_error_m=0.05),
            "speed": 1234.4,
        },
    ]
    info = {"command": "python bench/compare.py --data D --epochs 2", "budget": "2 epochs × 2,048 windows"}
    text = results_markdown(real, entries, info)
    lines = text.splitlines()
    header = next(line for line in lines if line.startswith("| Model"))
    cells = {line.split("|")[1].strip(): line.split("|")[2:-1] for line in lines if line.startswith("| ")}
    columns = [c.strip() for c in header.split("|")[2:-1]]
    odmo = dict(zip(columns, (c.strip() for c in cells[ROWS["odmo"]]), strict=True))
    a2m = dict(zip(columns, (c.strip() for c in cells[ROWS["a2m"]]), strict=True))
    real_row = dict(zip(columns, (c.strip() for c in cells["Real motions"]), strict=True))
    assert odmo["Acc ↑"] == "0.900 ± 0.090" and odmo["FID ↓"] == "1.250 ± 0.125"
    assert odmo["Mode homog. (%)"] == "15.00 ± 1.50"
    assert a2m["Mode homog. (%)"] == "n/a" and a2m["End error (m)"] == "n/a"
    assert a2m["Recon. error (m)"] == "0.0500 ± 0.0050" and a2m["Decode (motions/s)"] == "1234"
    assert real_row["Diversity →"] == "7.000 ± 0.700" and real_row["Recon. error (m)"] == "n/a"
    assert real_row["Recon. acc. ↑"] == "n/a" and a2m["Recon. acc. ↑"] == "n/a"
    assert "python bench/compare.py --data D --epochs 2" in text
    assert "generated by `bench/compare.py`" in text
    assert odmo["Bone cv ↓"] == "0.0000 ± 0.0000" and real_row["Hand speed (m/s) →"] == "0.500 ± 0.050"
    assert a2m["Bone cv ↓"] == "n/a"
    assert f"## Per action: {ROWS['odmo']} / real" in text
    walk_row = next(line for line in lines if line.startswith("| walk |"))
    assert walk_row.split("|")[2].strip() == "0.80 / 1.00"  # accuracy, generated / real
    assert walk_row.split("|")[3].strip() == "0.25 / 0.50"  # hand speed


def test_results_show_the_per_action_figures_of_the_bundled_odmo_row_and_the_a2m_row() -> None:
    def entry(row: str, hand: float) -> dict:
        speed = {"mean": hand, "ci95": 0.0}
        return {"row": row, "generated": {}, "per_action": {"walk": {"real": {}, "generated": {"x": speed}}}}

    entries = [entry("odmo", 0.1), entry("odmo_default", 0.2), entry("a2m", 0.3), entry("a2m_no_lie", 0.4)]
    assert [e["row"] for e in per_action_entries(entries)] == ["odmo_default", "a2m"]
    assert [e["row"] for e in per_action_entries(entries[2:])] == ["a2m"]
    assert [e["row"] for e in per_action_entries(entries[3:])] == ["a2m_no_lie"]
    assert per_action_entries([{"row": "a2m", "generated": {}}]) == []


def test_learning_rate_falls_along_its_cosine_to_the_floor(
    procedural_clips: list[Motion], torch_single_thread: None
) -> None:
    config = tiny_a2m_config(epochs=3, lr=1e-3, lr_floor=0.1)
    prepared = prepare_clips(procedural_clips, PROCEDURAL_ACTIONS, config.fps, config.window)
    model = A2mModel(config, seed=0)
    model.set_skeleton(prepared.skeleton)
    steps = A2mSteps(model, prepared, np.arange(prepared.n_clips), None)
    rates = []
    for epoch in range(3):
        steps.step(epoch, np.random.default_rng(0), torch.Generator().manual_seed(0))
        rates.append(steps.optimizer.param_groups[0]["lr"])
    assert rates == pytest.approx([1e-3, 0.55e-3, 1e-4])  # halfway down the cosine at the middle epoch
    assert A2mConfig.from_dict(tiny_a2m_config().to_dict() | {"lr_floor": 1.0}).lr_floor == 1.0
    with pytest.raises(ConfigError, match="lr_floor"):
        tiny_a2m_config(lr_floor=1.5)


def test_warm_start_begins_from_the_saved_weights_and_names_them(
    a2m_dir: Path, procedural_clips: list[Motion], tmp_path: Path, torch_single_thread: None
) -> None:
    source = load_a2m(a2m_dir).model.state_dict()
    warm = WarmStart(source, {"model": a2m_dir.name, "epochs": 8})
    config = tiny_a2m_config(epochs=1, epoch_size=16, lr=1e-12)  # one step that cannot move the weights
    train_a2m(procedural_clips, PROCEDURAL_ACTIONS, tmp_path / "warm", config, device="cpu", warm_start=warm)
    trained = load_a2m(tmp_path / "warm")
    weights = {k: v for k, v in trained.model.state_dict().items() if not k.startswith("code_")}
    assert weights and all(torch.allclose(v, source[k], atol=1e-7) for k, v in weights.items())
    assert trained.provenance["warm_start"] == {"model": a2m_dir.name, "epochs": 8}
    assert trained.provenance["epochs"] == 1
    wider = WarmStart(load_a2m(a2m_dir).model.state_dict(), {"model": "wide"})
    with pytest.raises(ConfigError, match="cannot start from wide"):
        train_a2m(
            procedural_clips, PROCEDURAL_ACTIONS, tmp_path / "w", tiny_a2m_config(hidden=16), warm_start=wider
        )


def test_a_run_chosen_by_its_prior_samples_keeps_the_best_scoring_epoch(
    procedural_clips: list[Motion], classifier: Classifier, tmp_path: Path, torch_single_thread: None
) -> None:
    """Scored at every epoch by the classifier's accuracy on its prior samples, the folder holds the
    epoch that scored best (the log's ``select_score``; the provenance names it), and its weights score
    that again."""
    names, skeleton = list(PROCEDURAL_ACTIONS), procedural_clips[0].skeleton

    def score(model: A2mModel) -> float:
        return prior_accuracy(model, skeleton, names, classifier, n_per_action=8, seed=3)

    out = tmp_path / "chosen"
    config = tiny_a2m_config(epochs=4)
    train_a2m(procedural_clips, names, out, config, device="cpu", checkpoint_every=1, select=score)
    rows = list(csv.DictReader((out / "train_log.csv").read_text().splitlines()))
    scores = [float(r["select_score"]) for r in rows]
    assert len(scores) == 4 and all(0.0 <= s <= 1.0 for s in scores)
    loaded = load_a2m(out)
    assert loaded.provenance["selected_epoch"] == int(np.argmax(scores)) + 1
    assert score(loaded.model) == max(scores)


def test_the_bench_refuses_to_warm_start_from_a_model_that_saw_held_out_clips(
    a2m_dir: Path, procedural_clips: list[Motion]
) -> None:
    seen = [c.meta["source"] for c in procedural_clips]
    trained_on = set(load_a2m(a2m_dir).provenance["train_sources"])
    held_out = [c for c, source in zip(procedural_clips, seen, strict=True) if source in trained_on][:1]
    with pytest.raises(SystemExit, match="trained on held-out clips"):
        warm_start_from(a2m_dir, held_out, load_a2m)
    unseen = [c for c, source in zip(procedural_clips, seen, strict=True) if source not in trained_on]
    assert unseen
    source = warm_start_from(a2m_dir, unseen, load_a2m).source
    assert source["model"] == a2m_dir.name
    weights = hashlib.sha256((a2m_dir / "model.safetensors").read_bytes()).hexdigest()
    assert source["weights_sha256"] == weights
    (line,) = warm_start_line(source)
    assert f"`{a2m_dir.name}`" in line and weights[:12] in line
    assert warm_start_line(None) == []
