"""The bundled default model: strict loading, CLI sampling, and motions recognised as their action."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
import torch

from engine import cli
from engine.generate import decode_array, sample
from engine.metrics.classifier import load_classifier
from engine.metrics.features import canonical_windows
from engine.modelio import load_model
from engine.motion.bvh import read_bvh
from engine.motion.ik import PLANT_RAMP, PLANT_REACH

BUNDLED = Path(__file__).resolve().parents[2] / "resources" / "models" / "bandai2-odmo"

pytestmark = pytest.mark.usefixtures("torch_single_thread")


@pytest.fixture(scope="module")
def bundled():
    """The bundled model with its latent bank."""
    return load_model(BUNDLED)


def test_bundled_model_is_complete_and_small() -> None:
    names = {p.name for p in BUNDLED.iterdir()}
    assert {"model.safetensors", "model.json", "latent_bank.npz", "MODEL_CARD.md", "classifier"} <= names
    size = sum(p.stat().st_size for p in BUNDLED.rglob("*") if p.is_file())
    assert size < 20 * 2**20
    card = (BUNDLED / "MODEL_CARD.md").read_text()
    assert "CC BY-NC 4.0" in card and "bench/train_default.py" in card


def test_bank_covers_every_action_with_modes_and_maps(bundled) -> None:
    bank = bundled.bank
    assert len(bundled.action_names) == 10
    assert sorted(bank.modes) == list(range(10))
    for modes in bank.modes.values():
        assert len(modes.weights_) >= 1 and np.isclose(np.sum(modes.weights_), 1.0)
    assert {"pca", "tsne", "umap"} <= set(bank.projections)
    assert bank.codes.shape == (len(bank.actions), bundled.config.latent_dim)


def test_cli_samples_walks_from_the_bundled_model(tmp_path, capsys) -> None:
    out = tmp_path / "walk.bvh"
    assert (
        cli.main(["sample", "--model", str(BUNDLED), "--action", "walk", "--n", "3", "--out", str(out)]) == 0
    )
    files = sorted(tmp_path.glob("walk_*.bvh"))
    assert len(files) == 3
    motion = read_bvh(files[0])
    assert motion.n_frames == bundled_window() and np.all(np.isfinite(motion.joints))


def bundled_window() -> int:
    """T of the bundled model, read from its model.json."""
    return int(json.loads((BUNDLED / "model.json").read_text())["config"]["window"])


def test_generated_motions_are_recognised_as_their_action(bundled) -> None:
    clf = load_classifier(BUNDLED / "classifier")
    rng = np.random.default_rng(0)
    windows, labels = [], []
    for index in range(len(bundled.action_names)):
        for s in sample(bundled, index, 8, rng):
            windows.append(s.motion)
            labels.append(index)
    _, predicted = clf.classify(canonical_windows(windows, clf.config.window))
    # Chance is 0.1; the model card records the full evaluation.
    assert np.mean(predicted == np.array(labels)) > 0.5


def test_cli_evaluates_raw_bandai_clips_copied_out_of_the_dataset(bandai_dir, tmp_path, capsys) -> None:
    heldout = (BUNDLED / "heldout_clips.txt").read_text().split()
    picked = [name for name in heldout if "_walk_" in name][:3] + [n for n in heldout if "_run_" in n][:3]
    folder = tmp_path / "mine"
    folder.mkdir()
    for name in picked:
        (folder / name).write_bytes((bandai_dir / "data" / name).read_bytes())
    out = tmp_path / "eval.json"
    argv = ["eval", "--model", str(BUNDLED), "--real", str(folder), "--repeats", "2", "--n-per-action", "4"]
    assert cli.main([*argv, "--json", str(out)]) == 0
    report = json.loads(out.read_text())
    assert report["meta"]["n_real_clips"] == 6
    assert 0.0 <= report["generated"]["accuracy"]["mean"] <= 1.0
    assert report["real"]["accuracy"]["mean"] > 0.5


def test_bundled_motion_keeps_its_bones_and_exports_as_shown(bundled, tmp_path, capsys) -> None:
    from engine.metrics.physics import bone_length_cv
    from engine.motion.formats import read_motion

    motions = [s.motion for s in sample(bundled, "run", 6, np.random.default_rng(1))]
    assert max(bone_length_cv(m.joints, bundled.skeleton.parents) for m in motions) < 1e-4
    for suffix in ("bvh", "npz"):
        argv = ["sample", "--model", str(BUNDLED), "--action", "run", "--seed", "7"]
        assert cli.main([*argv, "--out", str(tmp_path / f"x.{suffix}")]) == 0
    assert cli.main(["convert", str(tmp_path / "x.bvh"), str(tmp_path / "y.npz")]) == 0
    from_bvh, direct = read_motion(tmp_path / "y.npz").joints, read_motion(tmp_path / "x.npz").joints
    assert np.linalg.norm(from_bvh - direct, axis=-1).max() < 1e-3
    assert "per action" in (BUNDLED / "MODEL_CARD.md").read_text().lower()


def test_the_decoded_trajectory_is_the_shown_root_also_where_the_clean_up_lowered_the_clip(bundled) -> None:
    bank = bundled.bank
    joints, trajectory = decode_array(bundled, bank.codes[:200], bank.actions[:200], bank.ends[:200])
    lowered = bundled.root_height - trajectory[:, 0, 1]
    assert np.sum(lowered > 1e-4) >= 10  # some decodes float and are lowered onto the floor
    np.testing.assert_allclose(joints[:, :, bundled.skeleton.root], trajectory, atol=1e-5)


def test_the_foot_clean_up_never_makes_a_gait_jump_more_than_its_raw_decode(bundled) -> None:
    from engine.generate._decode import display_lift, plant, ready_model

    bank = bundled.bank
    gaits = [bundled.action_names.index(a) for a in ("walk", "walk-turn-left", "walk-turn-right", "run")]
    rows = np.flatnonzero(np.isin(bank.actions, gaits))[:200]
    codes, actions, ends = (torch.as_tensor(a[rows]) for a in (bank.codes, bank.actions, bank.ends))
    with torch.inference_mode():
        out = ready_model(bundled).decode_full(codes, actions, ends)
    raw = out.joints.numpy() + display_lift(bundled)
    cleaned = plant(bundled, raw, out.contact.numpy())
    assert np.abs(cleaned - raw).max() > 0.05  # the clean-up does move feet in these gaits

    def largest_step(joints: np.ndarray) -> np.ndarray:
        return np.linalg.norm(np.diff(joints, axis=1), axis=-1).max(axis=(1, 2))

    # Pinning a foot out of the leg's reach, or switching pins across a short gap, made 1 m jumps. A pin
    # fades over PLANT_RAMP + 1 steps and holds the foot at most PLANT_REACH from where it was decoded:
    # at most 0.075 m a step at the ankle, and the re-solved knee about twice that (measured 0.13 m at
    # most, the stop-42 model's runs releasing a pin; 0.07 m before it).
    bound = 2 * PLANT_REACH / (PLANT_RAMP + 1)
    assert (largest_step(cleaned) - largest_step(raw)).max() < bound
