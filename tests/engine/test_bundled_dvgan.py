"""The bundled DVGAN: its folder and card, phrases, long sequences from the CLI, completion of held-out
real clips, and its section of docs/RESULTS.md."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from engine import cli
from engine.errors import ConfigError
from engine.generators import SampleRequest, open_generator
from engine.generators.dvgan import DvganGenerator
from engine.metrics.physics import bone_length_cv
from engine.motion.bvh import read_bvh
from engine.motion.contact import foot_joints
from engine.motion.datasets import load_folder
from engine.motion.resample import resample_motion

ROOT = Path(__file__).resolve().parents[2]
BUNDLED = ROOT / "resources" / "models" / "bandai2-dvgan"

pytestmark = pytest.mark.usefixtures("torch_single_thread")


@pytest.fixture(scope="module")
def dvgan() -> DvganGenerator:
    generator = open_generator(BUNDLED)
    assert isinstance(generator, DvganGenerator)
    return generator


def test_the_folder_is_complete_small_licensed_and_its_card_is_its_evaluation() -> None:
    names = {p.name for p in BUNDLED.iterdir()}
    assert {"model.safetensors", "model.json", "latent_bank.npz", "MODEL_CARD.md", "LICENSE"} <= names
    assert {"eval.json", "heldout_clips.txt"} <= names
    assert sum(p.stat().st_size for p in BUNDLED.rglob("*") if p.is_file()) < 20 * 2**20
    card = (BUNDLED / "MODEL_CARD.md").read_text()
    assert "CC BY-NC 4.0" in card and "bench/train_dvgan.py" in card
    report = json.loads((BUNDLED / "eval.json").read_text())
    assert f"FID ≤ 1.0 ({report['generated']['fid']['mean']:.2f})" in card
    walk = report["completion"]["walk"]
    assert f"{100 * walk['model']['400']:.1f} / {100 * walk['zero_velocity']['400']:.1f}" in card
    results = (ROOT / "docs" / "RESULTS.md").read_text()
    assert "## DVGAN: generation, completion and long sequences" in results
    assert f"{100 * walk['model']['400']:.1f} / {100 * walk['zero_velocity']['400']:.1f}" in results


def test_it_opens_with_the_bandai_phrases_and_refuses_unknown_words(dvgan: DvganGenerator) -> None:
    assert dvgan.kind == "dvgan" and len(dvgan.action_names) == 10
    assert {"sample", "decode", "interpolate", "complete", "extend", "bank", "modes"} <= dvgan.capabilities
    assert {"walk", "turn", "left", "raise", "hands"} <= set(dvgan.network.language.words)
    assert {"pca", "tsne", "umap"} <= set(dvgan.bank.projections)
    [new] = dvgan.sample(SampleRequest("run turn left", 1, 0))
    assert new.action == -1 and new.motion.n_frames == dvgan.window
    with pytest.raises(ConfigError, match="unknown words jump"):
        dvgan.sample(SampleRequest("jump", 1, 0))


def test_cli_writes_a_long_walk_on_the_skeleton_above_the_floor(
    tmp_path: Path, dvgan: DvganGenerator
) -> None:
    out = tmp_path / "long.bvh"
    assert cli.main(["sample", "--model", str(BUNDLED), "--action", "walk", "--frames", "600",
                     "--out", str(out)]) == 0  # fmt: skip
    motion = read_bvh(out)
    assert motion.n_frames == 600
    assert bone_length_cv(motion.joints, motion.skeleton.parents) < 1e-3
    feet = motion.joints[:, foot_joints(motion.skeleton), 1]
    assert feet.min() > -0.03
    root = motion.joints[:, motion.skeleton.root, 1]
    assert root.min() > 0.5 and root.max() < 1.3  # a standing body's hips over all 30 s


def test_completion_of_held_out_clips_starts_where_they_stand(
    dvgan: DvganGenerator, bandai_dir: Path
) -> None:
    """The prefix comes back as given (re-posed on the model's skeleton, nothing lowered or pinned: the
    clean-up once sank waves' prefixes by up to 30 cm when their futures floated), and the seam steps no
    further than the clip's own frames."""
    data = load_folder(bandai_dir)
    held = set((BUNDLED / "heldout_clips.txt").read_text().split())
    for action in ("walk", "wave-left-hand", "raise-up-right-hand"):
        clip = next(
            c
            for c in data.clips
            if Path(c.meta["source"]).name in held and c.action == action and c.n_frames >= 45
        )
        prefix = clip.with_joints(clip.joints[:45])  # 1.5 s at 30 fps: 30 frames at the model's 20 fps
        futures = dvgan.complete(prefix, 200, n=3, seed=0)
        expected = resample_motion(prefix, dvgan.fps).joints
        for motion in futures:
            assert motion.n_frames == 30 + 200 and motion.meta["prefix_frames"] == 30
            error = np.linalg.norm(motion.joints[:30] - expected, axis=-1).max()
            assert error < 0.015, (action, error)
            steps = np.linalg.norm(np.diff(motion.joints, axis=0), axis=-1).max(axis=1)
            assert steps[29] < 1.25 * steps[:29].max(), action
        assert not np.allclose(futures[0].joints[30:], futures[1].joints[30:], atol=1e-3)
