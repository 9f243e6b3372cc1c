"""``odmo train | bank | sample | interpolate | encode`` through engine.cli.main."""

from __future__ import annotations

import hashlib
import json
import shutil
from pathlib import Path

import numpy as np
import pytest

from engine import cli
from engine.generate import bank_window, decode, encode, encode_clips, sample
from engine.generators import open_generator
from engine.modelio import BANK_FILE, WEIGHTS_FILE, load_model
from engine.motion.formats import read_motion, write_motion
from engine.motion.motion import Motion

PATTERN = r"^(?P<action>[a-z]+)_(?P<style>[a-z-]+)_\d+"


@pytest.fixture
def odmo(monkeypatch, tmp_path):
    """Run ``odmo`` in-process; returns its exit code (the dataset cache goes to a temporary folder)."""
    monkeypatch.setenv("ODMO_CACHE_DIR", str(tmp_path / "cache"))

    def run(*argv: object) -> int:
        return cli.main([str(a) for a in argv])

    return run


@pytest.fixture
def model_copy(tiny_model_dir, tmp_path) -> Path:
    """A copy of the tiny model folder that a test may change."""
    return Path(shutil.copytree(tiny_model_dir, tmp_path / "model"))


def _bank_argv(model: Path, data: Path) -> list[object]:
    """``odmo bank`` of ``model`` on the procedural clips in ``data``, PCA only."""
    return ["bank", "--model", model, "--data", data, "--pattern", PATTERN, "--projections", "pca"]


def _train_argv(data: Path, out: Path, *options: object) -> list[object]:
    """``odmo train`` (with ``options``) on the procedural clips in ``data`` into ``out``."""
    return ["train", *options, "--data", data, "--pattern", PATTERN, "--out", out]


def _one_error_line(capsys, *needles: str) -> None:
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1, err
    for needle in needles:
        assert needle in err


def test_sample_numbers_files_and_matches_the_api(odmo, tiny_model_dir, tmp_path, capsys):
    out = tmp_path / "walk.npz"
    assert (
        odmo("sample", "--model", tiny_model_dir, "--action", "walk", "--n", 3, "--seed", 4, "--out", out)
        == 0
    )
    files = sorted(tmp_path.glob("walk_*.npz"))
    assert [f.name for f in files] == ["walk_000.npz", "walk_001.npz", "walk_002.npz"]
    expected = sample(load_model(tiny_model_dir), "walk", 3, 4)
    for path, s in zip(files, expected, strict=True):
        motion = read_motion(path)
        assert motion.action == "walk" and motion.meta["mode"] == s.mode and motion.meta["seed"] == 4
        np.testing.assert_allclose(motion.joints, s.motion.joints, atol=1e-6)
    assert str(files[0]) in capsys.readouterr().out


def test_sample_one_mode_into_a_folder_with_an_end(odmo, tiny_model_dir, tmp_path):
    out = tmp_path / "clips"
    argv = ["sample", "--model", tiny_model_dir, "--action", "wave", "--mode", 0, "--n", 2, "--end", 0.5, 1.5]
    assert odmo(*argv, "--out", out) == 0
    motions = [read_motion(p) for p in sorted(out.glob("*.npz"))]
    assert len(motions) == 2
    for m in motions:
        assert m.meta["mode"] == 0
        assert m.meta["end"][0] == pytest.approx(0.5) and m.meta["end"][2] == pytest.approx(1.5)


def test_sample_writes_bvh(odmo, tiny_model_dir, tmp_path):
    out = tmp_path / "jump.bvh"
    assert odmo("sample", "--model", tiny_model_dir, "--action", "jump", "--out", out) == 0
    motion = read_motion(out)
    loaded = load_model(tiny_model_dir)
    assert motion.n_frames == loaded.window and motion.skeleton.names == loaded.skeleton.names


def test_interpolate_from_a_mode_to_a_bank_code(odmo, tiny_model_dir, tmp_path):
    loaded = load_model(tiny_model_dir)
    walk = loaded.action_names.index("walk")
    i = int(loaded.bank.indices_of(walk)[5])
    out = tmp_path / "interp"
    argv = ["interpolate", "--model", tiny_model_dir, "--action", "walk", "--from", "m0", "--to", f"i{i}"]
    assert odmo(*argv, "--steps", 4, "--method", "slerp", "--out", out) == 0
    files = sorted(out.glob("*.npz"))
    assert len(files) == 4
    first, last = read_motion(files[0]), read_motion(files[-1])
    np.testing.assert_allclose(
        first.joints, decode(loaded, loaded.bank.modes[walk].means_[0], walk).joints, atol=1e-6
    )
    np.testing.assert_allclose(last.joints, decode(loaded, loaded.bank.codes[i], walk).joints, atol=1e-6)


def test_encode_prints_code_action_and_mode(odmo, tiny_model_dir, procedural_npz_dir, capsys):
    path = sorted(procedural_npz_dir.glob("wave_*.npz"))[0]
    assert odmo("encode", "--model", tiny_model_dir, path, "--json") == 0
    report = json.loads(capsys.readouterr().out)
    code, guess = encode(load_model(tiny_model_dir), read_motion(path))
    np.testing.assert_allclose(report["code"], code, atol=1e-5)
    assert report["action"] == "wave" == load_model(tiny_model_dir).action_names[guess]
    assert isinstance(report["mode"], int)
    assert odmo("encode", "--model", tiny_model_dir, path) == 0
    assert "action guess: wave" in capsys.readouterr().out


def test_unknown_action_is_one_line(odmo, tiny_model_dir, tmp_path, capsys):
    assert odmo("sample", "--model", tiny_model_dir, "--action", "fly", "--out", tmp_path / "x.npz") == 1
    _one_error_line(capsys, "unknown action 'fly'", "walk")
    assert not list(tmp_path.iterdir())


def test_bad_endpoints_are_one_line(odmo, tiny_model_dir, tmp_path, capsys):
    loaded = load_model(tiny_model_dir)
    other = int(loaded.bank.indices_of(loaded.action_names.index("jump"))[0])
    base = ["interpolate", "--model", tiny_model_dir, "--action", "walk", "--out", tmp_path]
    assert odmo(*base, "--from", "x3", "--to", "m0") == 1
    _one_error_line(capsys, "bad endpoint 'x3'")
    assert odmo(*base, "--from", f"i{other}", "--to", "m0") == 1
    _one_error_line(capsys, "'jump' code")


def test_wrong_skeleton_is_one_line(odmo, tiny_model_dir, procedural_clips, tmp_path, capsys):
    clip = procedural_clips[0]
    keep = list(range(clip.n_joints - 2))
    small = Motion(clip.joints[:, keep], clip.fps, clip.skeleton.subset(keep))
    path = tmp_path / "small.npz"
    write_motion(small, path)
    assert odmo("encode", "--model", tiny_model_dir, path) == 1
    _one_error_line(capsys, "skeleton does not match", "RightUpLeg")


def test_corrupt_weights_are_one_line(odmo, model_copy, tmp_path, capsys):
    (model_copy / WEIGHTS_FILE).write_bytes(b"\x00not safetensors")
    assert odmo("sample", "--model", model_copy, "--action", "walk", "--out", tmp_path / "a.npz") == 1
    _one_error_line(capsys, "corrupt weights")


def test_bank_rebuilds_the_training_codes(odmo, model_copy, procedural_npz_dir, tiny_model_dir):
    (model_copy / BANK_FILE).unlink()
    argv = _bank_argv(model_copy, procedural_npz_dir)
    assert odmo(*argv) == 0
    rebuilt = load_model(model_copy).bank
    original = load_model(tiny_model_dir).bank
    assert len(rebuilt.codes) == len(original.codes) and set(rebuilt.projections) == {"pca"}
    gaps = np.linalg.norm(rebuilt.codes[:, None] - original.codes[None], axis=2).min(axis=1)
    assert gaps.max() < 1e-4
    assert {m.get("style") for m in rebuilt.meta} >= {"stroll", "march", "sidestep"}


def _distances(joints: np.ndarray) -> np.ndarray:
    """(T, J, J) joint-to-joint distances, which no placement or turn of the body changes."""
    return np.linalg.norm(joints[:, None] - joints[:, :, None], axis=-1)


def test_bank_with_a_stride_makes_each_long_clip_a_path_of_window_codes(
    odmo, model_copy, procedural_npz_dir, capsys
):
    argv = _bank_argv(model_copy, procedural_npz_dir)
    assert odmo(*argv, "--stride", 20) == 0
    loaded = load_model(model_copy)
    bank, window = loaded.bank, loaded.window
    for path in sorted(procedural_npz_dir.glob("*.npz"))[::9]:
        clip = read_motion(path)
        rows = [i for i, source in enumerate(bank.sources) if source == path.name]
        starts = [bank.meta[i]["window_start"] for i in rows]
        last = max(clip.n_frames - window, 0)  # the clips are at the model's 20 fps
        assert starts == sorted({*range(0, last + 1, 20), last})
        assert all(bank.meta[i]["window_stride"] == 20 for i in rows)
        for i, start in zip(rows, starts, strict=True):
            piece = clip.with_joints(clip.joints[start : start + window])
            np.testing.assert_allclose(bank.codes[i], encode_clips(loaded, [piece])[0][0], atol=1e-5)
        shown = bank_window(loaded, clip, starts[-1])
        assert shown.meta["window_start"] == starts[-1] and shown.n_frames == min(window, clip.n_frames)
        moved = clip.joints[starts[-1] : starts[-1] + window]
        np.testing.assert_allclose(_distances(shown.joints), _distances(moved), atol=1e-4)
    with pytest.raises(SystemExit, match="2"):
        odmo(*argv, "--stride", 0)
    assert "--stride: must be at least 1" in capsys.readouterr().err


def test_bank_takes_any_kind_that_encodes(odmo, tiny_a2m_dir, procedural_npz_dir, tmp_path):
    model = Path(shutil.copytree(tiny_a2m_dir, tmp_path / "a2m"))
    argv = _bank_argv(model, procedural_npz_dir)
    assert odmo(*argv) == 0
    generator = open_generator(model)
    bank = generator.bank
    files = sorted(procedural_npz_dir.glob("*.npz"))
    assert sorted(bank.sources) == sorted(p.name for p in files)
    for path in files[::17]:
        [row] = np.flatnonzero(bank.sources == path.name)
        code, _ = generator.encode(read_motion(path))
        np.testing.assert_allclose(bank.codes[row], code, atol=1e-5)
    assert odmo(*argv, "--stride", 20) == 0
    windows = open_generator(model).bank
    assert len(windows.codes) > len(bank.codes) and {"window_start", "window_stride"} <= set(windows.meta[0])


@pytest.mark.slow
def test_train_writes_a_loadable_model(odmo, procedural_npz_dir, tmp_path, capsys):
    sizes = [
        "enc_hidden=8",
        "enc_fc=16",
        "traj_hidden=8",
        "motion_hidden=8",
        "batch_size=16",
        "epoch_size=32",
    ]
    settings = [x for s in sizes for x in ("--set", s)]
    out = tmp_path / "m"
    argv = [*_train_argv(procedural_npz_dir, out), "--epochs", 1, "--device", "cpu"]
    assert odmo(*argv, *settings, "--projections", "pca") == 0
    captured = capsys.readouterr()
    assert "epoch 1/1" in captured.err and "steps/s" in captured.err
    loaded = load_model(out)
    assert loaded.action_names == ["jump", "walk", "wave"] and loaded.config.motion_hidden == 8
    assert loaded.bank is not None and len(loaded.bank.codes) == len(list(procedural_npz_dir.glob("*.npz")))


@pytest.mark.slow
def test_train_fine_tunes_from_a_model_folder_and_names_its_weights(
    odmo, tiny_model_dir, procedural_npz_dir, tmp_path, capsys
):
    """``--warm-start`` starts from a folder's weights with another loss weight (the sizes must match)
    and the provenance names them by sha256; another kind or other sizes get one error line."""
    sizes = ["enc_hidden=32", "enc_fc=64", "traj_hidden=64", "motion_hidden=64", "batch_size=16"]
    settings = [x for s in [*sizes, "epoch_size=32", "w_skim=1"] for x in ("--set", s)]
    out = tmp_path / "tuned"
    argv = [*_train_argv(procedural_npz_dir, out, "--warm-start", tiny_model_dir), "--epochs", 1]
    assert odmo(*argv, *settings, "--device", "cpu", "--projections", "pca") == 0
    tuned = load_model(out)
    weights = hashlib.sha256((tiny_model_dir / "model.safetensors").read_bytes()).hexdigest()
    assert tuned.provenance["warm_start"]["weights_sha256"] == weights
    assert tuned.provenance["warm_start"]["model"] == tiny_model_dir.name and tuned.config.w_skim == 1.0
    capsys.readouterr()
    modi = [
        *_train_argv(procedural_npz_dir, tmp_path / "m", "--arch", "modi", "--warm-start", tiny_model_dir)
    ]
    assert odmo(*modi) == 1
    _one_error_line(capsys, "--warm-start", "modi")
    narrow = [x for s in [*sizes[:3], "motion_hidden=8"] for x in ("--set", s)]
    assert (
        odmo(*_train_argv(procedural_npz_dir, tmp_path / "n", "--warm-start", tiny_model_dir), *narrow) == 1
    )
    _one_error_line(capsys, f"cannot start from {tiny_model_dir.name}")


def test_train_rejects_unknown_settings(odmo, procedural_npz_dir, tmp_path, capsys):
    argv = [*_train_argv(procedural_npz_dir, tmp_path / "m"), "--set", "depth=3"]
    assert odmo(*argv) == 1
    _one_error_line(capsys, "depth")


@pytest.mark.slow
def test_train_a2m_baseline_writes_a_loadable_model(odmo, procedural_npz_dir, tmp_path):
    from engine.generators.a2m import load_a2m

    settings = [
        x for s in ("hidden=8", "latent_dim=4", "batch_size=8", "epoch_size=16") for x in ("--set", s)
    ]
    out = tmp_path / "a2m"
    argv = [*_train_argv(procedural_npz_dir, out, "--arch", "a2m"), "--epochs", 1]
    assert odmo(*argv, *settings) == 0
    loaded = load_a2m(out)
    assert loaded.config.hidden == 8 and loaded.action_names == ["jump", "walk", "wave"]


@pytest.mark.slow
def test_train_modi_writes_a_model_that_samples_without_an_action(odmo, procedural_npz_dir, tmp_path):
    from engine.generators import SampleRequest, open_generator

    small = ("levels=3", "window=16", "channels=16", "min_channels=8", "w_dim=16", "mapping_layers=2",
             "batch_size=4", "epoch_size=8")  # fmt: skip
    settings = [x for s in small for x in ("--set", s)]
    out = tmp_path / "modi"
    argv = [*_train_argv(procedural_npz_dir, out, "--arch", "modi"), "--epochs", 1]
    assert odmo(*argv, *settings, "--projections", "pca") == 0
    generator = open_generator(out)
    assert generator.kind == "modi" and generator.label_names == ["jump", "walk", "wave"]
    assert generator.bank is not None and generator.code_space.size == 16
    [sample] = generator.sample(SampleRequest(None, 1, 0))
    assert sample.motion.joints.shape[0] == 16
