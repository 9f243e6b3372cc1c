"""The bundled MoDi: its folder, the CLI, motions on the skeleton above the floor, every action among its
samples, and W+ inversion of held-out real clips."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from engine import cli
from engine.generators import SampleRequest, open_generator
from engine.generators.modi import ModiGenerator
from engine.metrics.classifier import load_classifier
from engine.metrics.features import canonical_windows
from engine.metrics.physics import bone_length_cv
from engine.motion.bvh import read_bvh
from engine.motion.datasets import load_folder
from engine.motion.motion import Motion

ROOT = Path(__file__).resolve().parents[2]
BUNDLED = ROOT / "resources" / "models" / "bandai2-modi"
CLASSIFIER = ROOT / "resources" / "models" / "bandai2-odmo" / "classifier"

# Bounds a sound model clears with room; the card and eval.json hold the full evaluation.
MIN_ACTIONS_SEEN = 9  # of 10, each at least 1 % of 300 prior samples (the card: 2.3 % for the rarest)
MAX_INVERSION_ERROR_M = (
    0.08  # mean over 4-5 held-out clips, 150 W+ steps (the card: 4.6 cm, 40 clips, 300 steps)
)

pytestmark = pytest.mark.usefixtures("torch_single_thread")


@pytest.fixture(scope="module")
def modi() -> ModiGenerator:
    generator = open_generator(BUNDLED)
    assert isinstance(generator, ModiGenerator)
    return generator


def test_the_folder_is_complete_small_and_licensed() -> None:
    names = {p.name for p in BUNDLED.iterdir()}
    assert {"model.safetensors", "model.json", "latent_bank.npz", "MODEL_CARD.md", "LICENSE"} <= names
    assert {"eval.json", "heldout_clips.txt"} <= names
    assert sum(p.stat().st_size for p in BUNDLED.rglob("*") if p.is_file()) < 20 * 2**20
    card = (BUNDLED / "MODEL_CARD.md").read_text()
    assert "CC BY-NC 4.0" in card and "bench/train_modi.py" in card
    report = json.loads((BUNDLED / "eval.json").read_text())
    assert f"{report['generated']['fid']['mean']:.2f}" in card  # the card's figures are the evaluation's


def test_it_opens_unconditional_with_the_bandai_actions_as_bank_labels(modi: ModiGenerator) -> None:
    assert modi.kind == "modi" and modi.action_names is None
    assert len(modi.label_names) == 10 and "walk" in modi.label_names
    assert {"sample", "truncate", "mix", "crowd", "invert", "edit", "bank"} <= modi.capabilities
    bank = modi.bank
    assert bank.codes.shape[1] == modi.code_space.size
    assert {"pca", "tsne", "umap"} <= set(bank.projections)
    assert set(np.unique(bank.actions)) == set(range(10))


def test_cli_samples_bvh_on_the_skeleton_above_the_floor(tmp_path: Path, modi: ModiGenerator) -> None:
    out = tmp_path / "s.bvh"
    argv = ["sample", "--model", str(BUNDLED), "--n", "4", "--seed", "3", "--truncation", "0.7"]
    assert cli.main([*argv, "--out", str(out)]) == 0
    files = sorted(tmp_path.glob("s_*.bvh"))
    assert len(files) == 4
    for f in files:
        joints = read_bvh(f).joints
        assert joints.shape[0] == modi.window and np.all(np.isfinite(joints))
        assert bone_length_cv(joints, modi.skeleton.parents) < 1e-3
        assert joints[..., 1].min() > -0.02  # no foot more than 2 cm under the floor


def test_prior_samples_cover_the_actions(modi: ModiGenerator) -> None:
    clf = load_classifier(CLASSIFIER)
    start, width = (modi.window - clf.config.window) // 2, clf.config.window  # the centre, as eval.json
    motions = [s.motion for s in modi.sample(SampleRequest(None, 300, 0))]
    centres = [Motion(m.joints[start : start + width], m.fps, m.skeleton) for m in motions]
    _, predicted = clf.classify(canonical_windows(centres, width))
    shares = np.bincount(predicted, minlength=10) / len(predicted)
    assert np.sum(shares >= 0.01) >= MIN_ACTIONS_SEEN


def test_w_plus_inversion_fits_held_out_clips(modi: ModiGenerator, bandai_dir: Path) -> None:
    held = (BUNDLED / "heldout_clips.txt").read_text().split()
    picked = {held[i] for i in range(0, len(held), len(held) // 4)}
    data = load_folder(bandai_dir)
    clips = [c for c in data.clips if Path(str(c.meta["source"])).name in picked]
    assert len(clips) == len(picked) >= 4
    errors = [modi.invert(clip, "W+", steps=150)[1] for clip in clips]
    assert np.mean(errors) < MAX_INVERSION_ERROR_M


def test_the_results_file_shows_the_bundled_evaluation(tmp_path: Path) -> None:
    from bench.compare import main as compare

    results = tmp_path / "RESULTS.md"
    shipped = (ROOT / "docs" / "RESULTS.md").read_text()
    results.write_text(shipped)
    assert compare(["--modi-only", "--results", str(results), "--modi", str(BUNDLED)]) == 0
    assert results.read_text() == shipped  # docs/RESULTS.md already holds the bundled model's section
    start = shipped.index("## Unconditional: MoDi")
    end = shipped.index("\n## ", start) + 1
    results.write_text(shipped[:start] + shipped[end:])  # the MoDi section alone removed
    assert compare(["--modi-only", "--results", str(results), "--modi", str(BUNDLED)]) == 0
    assert results.read_text() == shipped
    report = json.loads((BUNDLED / "eval.json").read_text())
    assert f"{report['generated']['fid']['mean']:.3f}" in shipped.split("## Unconditional: MoDi")[1]


def test_a_full_results_write_and_the_modi_only_rewrite_agree(tmp_path: Path) -> None:
    from bench.compare import main as compare
    from bench.compare import results_markdown

    real = {"accuracy": {"mean": 0.9, "ci95": 0.01}}
    report = json.loads((BUNDLED / "eval.json").read_text())
    results = tmp_path / "RESULTS.md"
    full = results_markdown(real, [], {"Command": "test"}, unconditional=report)
    results.write_text(full)
    assert compare(["--modi-only", "--results", str(results), "--modi", str(BUNDLED)]) == 0
    assert results.read_text() == full
