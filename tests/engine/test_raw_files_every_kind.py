"""Every bundled kind takes a raw Bandai-Namco-2 BVH file (its ground-projected ``joint_Root`` included)
through the command that reads a motion file, and reads it as it reads the file without that joint."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from engine import cli
from engine.errors import ConfigError
from engine.generators import open_generator
from engine.motion.bvh import read_bvh
from engine.motion.datasets import conform_to
from engine.motion.formats import read_motion, write_motion
from engine.motion.resample import resample_motion

MODELS = Path(__file__).resolve().parents[2] / "resources" / "models"

pytestmark = pytest.mark.usefixtures("torch_single_thread")


@pytest.fixture(scope="module")
def raw_clip(bandai_dir: Path) -> Path:
    """A raw 22-joint wave clip of the dataset."""
    return bandai_dir / "data" / "dataset-2_wave-both-hands_normal_001.bvh"


@pytest.fixture(scope="module")
def trimmed_clip(raw_clip: Path, tmp_path_factory: pytest.TempPathFactory) -> Path:
    """The same clip as an NPZ file without ``joint_Root``."""
    motion = read_bvh(raw_clip)
    assert motion.skeleton.names[0] == "joint_Root"
    path = tmp_path_factory.mktemp("trimmed") / "wave.npz"
    write_motion(motion.without_joints(["joint_Root"]), path)
    return path


@pytest.mark.parametrize("kind", ["odmo", "a2m"])
def test_encode_reads_a_raw_file_as_the_file_without_its_ground_root(
    kind: str, raw_clip: Path, trimmed_clip: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    codes = []
    for path in (raw_clip, trimmed_clip):
        assert cli.main(["encode", "--model", str(MODELS / f"bandai2-{kind}"), str(path), "--json"]) == 0
        codes.append(np.array(json.loads(capsys.readouterr().out)["code"]))
    assert codes[0].shape == codes[1].shape and np.all(np.isfinite(codes[0]))
    np.testing.assert_allclose(codes[0], codes[1], atol=1e-5)


def test_dvgan_completes_a_raw_file_from_where_it_stands(
    raw_clip: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    out = tmp_path / "futures"
    args = ["complete", "--model", str(MODELS / "bandai2-dvgan"), "--prefix", str(raw_clip),
            "--prefix-frames", "30", "--frames", "20", "--n", "2", "--action", "wave both hands",
            "--out", str(out)]  # fmt: skip
    assert cli.main(args) == 0, capsys.readouterr().err
    files = sorted(out.glob("*.npz"))
    assert len(files) == 2
    given = conform_to(open_generator(MODELS / "bandai2-dvgan").skeleton, read_bvh(raw_clip))
    given = resample_motion(type(given)(given.joints[:30], given.fps, given.skeleton), 20.0)
    for path in files:
        made = read_motion(path)
        assert made.n_frames == given.n_frames + 20
        gap = np.linalg.norm(made.joints[: given.n_frames] - given.joints, axis=-1)
        assert gap.max() < 0.015, path


def test_modi_inverts_a_raw_file(raw_clip: Path, capsys: pytest.CaptureFixture[str]) -> None:
    args = ["invert", "--model", str(MODELS / "bandai2-modi"), str(raw_clip), "--steps", "5", "--json"]
    assert cli.main(args) == 0, capsys.readouterr().err
    code = np.array(json.loads(capsys.readouterr().out)["code"])
    assert code.size > 0 and np.all(np.isfinite(code))


def test_another_rig_is_refused_naming_the_file_and_both_joint_lists() -> None:
    cmu = read_bvh(Path(__file__).resolve().parents[1] / "data" / "cmu_style.bvh")
    for kind in ("odmo", "a2m", "modi", "dvgan"):
        skeleton = open_generator(MODELS / f"bandai2-{kind}").skeleton
        with pytest.raises(ConfigError, match=r"cmu_style\.bvh: .*LHipJoint.*Toes_R"):
            conform_to(skeleton, cmu)
