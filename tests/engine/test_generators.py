"""The contract every generator kind keeps, run over each kind this program ships.

Shapes and units of what it samples, seed reproducibility, a saved folder reopened giving the same motions,
each declared capability exercised through the CLI and each undeclared one refused with one line.
"""

from __future__ import annotations

import json
import shutil
from pathlib import Path

import numpy as np
import pytest

from engine.cli import main
from engine.errors import ModelFormatError
from engine.generators import (
    CAPABILITIES,
    CapabilityError,
    Generator,
    SampleRequest,
    kinds,
    open_generator,
    require,
)
from engine.motion.formats import write_motion
from engine.motion.npz import read_npz

pytestmark = pytest.mark.usefixtures("torch_single_thread")


FOLDERS = {
    "odmo": "tiny_model_dir",
    "a2m": "tiny_a2m_dir",
    "a2m-baseline": "tiny_a2m_old_dir",
    "bandai2-a2m": "bundled_a2m_dir",
    "modi": "tiny_modi_dir",
    "bandai2-modi": "bundled_modi_dir",
    "dvgan": "tiny_dvgan_dir",
    "bandai2-dvgan": "bundled_dvgan_dir",
}
BUNDLED_A2M = Path(__file__).resolve().parents[2] / "resources" / "models" / "bandai2-a2m"


@pytest.fixture(scope="session")
def bundled_a2m_dir() -> Path:
    """The bundled Action2Motion model trained on Bandai-Namco-2."""
    return BUNDLED_A2M


@pytest.fixture(scope="session")
def bundled_modi_dir() -> Path:
    """The bundled MoDi trained on Bandai-Namco-2."""
    return BUNDLED_A2M.parent / "bandai2-modi"


@pytest.fixture(scope="session")
def bundled_dvgan_dir() -> Path:
    """The bundled DVGAN trained on Bandai-Namco-2."""
    return BUNDLED_A2M.parent / "bandai2-dvgan"


@pytest.fixture(params=sorted(FOLDERS))
def folder(request: pytest.FixtureRequest) -> Path:
    """The folder of a tiny trained model of each kind, of the old A2M baseline (which only samples) and
    the bundled Action2Motion."""
    return request.getfixturevalue(FOLDERS[request.param])


def action_of(generator: Generator, k: int) -> str | None:
    """The k-th action of a conditional kind; None for an unconditional one."""
    return None if generator.action_names is None else generator.action_names[k]


def test_every_shipped_kind_is_registered() -> None:
    assert kinds() == ["a2m", "dvgan", "modi", "odmo"]


def test_open_picks_the_kind_from_model_json(folder: Path) -> None:
    generator = open_generator(folder)
    assert isinstance(generator, Generator)
    assert generator.kind == json.loads((folder / "model.json").read_text()).get("arch", "odmo")
    assert generator.capabilities <= set(CAPABILITIES) and "sample" in generator.capabilities
    assert generator.code_space.size > 0 and generator.window > 1 and generator.fps > 0


def test_samples_have_the_models_shape_units_and_skeleton(folder: Path) -> None:
    generator = open_generator(folder)
    action = action_of(generator, 1)
    samples = generator.sample(SampleRequest(action, 3, 5))
    assert len(samples) == 3
    for s in samples:
        m = s.motion
        assert m.joints.shape == (generator.window, generator.skeleton.n_joints, 3)
        assert m.joints.dtype == np.float32 and np.isfinite(m.joints).all()
        assert m.fps == generator.fps and (action is None or m.action == action)
        assert m.skeleton.same_topology(generator.skeleton)
        height = m.joints[:, :, 1]
        assert 0.3 < float(np.median(height)) < 2.5, "metres, y up, standing at display height"


def test_same_seed_same_motions_other_seed_others(folder: Path) -> None:
    generator = open_generator(folder)
    action = action_of(generator, 0)
    a = [s.motion.joints for s in generator.sample(SampleRequest(action, 2, 11))]
    b = [s.motion.joints for s in generator.sample(SampleRequest(action, 2, 11))]
    c = [s.motion.joints for s in generator.sample(SampleRequest(action, 2, 12))]
    assert all(np.array_equal(x, y) for x, y in zip(a, b, strict=True))
    assert not np.allclose(a[0], c[0])


def test_a_copied_folder_reopens_to_the_same_motions(folder: Path, tmp_path: Path) -> None:
    copy = Path(shutil.copytree(folder, tmp_path / "copy"))
    action = action_of(open_generator(folder), 2)
    first = open_generator(folder).sample(SampleRequest(action, 2, 3))
    again = open_generator(copy).sample(SampleRequest(action, 2, 3))
    for x, y in zip(first, again, strict=True):
        np.testing.assert_array_equal(x.motion.joints, y.motion.joints)


def test_cli_sample_opens_every_kind(folder: Path, tmp_path: Path) -> None:
    generator = open_generator(folder)
    action = action_of(generator, 0)
    out = tmp_path / "out"
    named = [] if action is None else ["--action", action]
    argv = ["sample", "--model", str(folder), *named, "--n", "2", "--seed", "4", "--out", str(out)]
    assert main(argv) == 0
    files = sorted(out.glob("*.npz"))
    stem = action or "sample"
    assert [f.name for f in files] == [f"{stem}_000.npz", f"{stem}_001.npz"]
    expected = generator.sample(SampleRequest(action, 2, 4))
    for f, s in zip(files, expected, strict=True):
        np.testing.assert_allclose(read_npz(f).joints, s.motion.joints, atol=1e-6)


def test_declared_capabilities_work_and_the_others_are_refused(
    folder: Path, tmp_path: Path, capsys: pytest.CaptureFixture
) -> None:
    generator = open_generator(folder)
    action = action_of(generator, 0)
    clip = generator.sample(SampleRequest(action, 1, 0))[0].motion
    write_motion(clip, tmp_path / "clip.npz")
    named = [] if action is None else ["--action", action]
    model = ["--model", str(folder), *named]
    bank = generator.bank
    label = action if action is not None else bank.action_names[0]  # an unconditional kind's bank label
    ends = ["i0", "i1"] if bank is None else [f"i{i}" for i in np.flatnonzero(bank.actions == 0)[:2]]
    runs = {
        "encode": ["encode", "--model", str(folder), str(tmp_path / "clip.npz")],
        "interpolate": ["interpolate", *model, "--from", ends[0], "--to", ends[1], "--steps", "3", "--out",
                        str(tmp_path / "strip")],
        "modes": ["sample", "--model", str(folder), "--action", label, "--mode", "0", "--out",
                  str(tmp_path / "m.npz")],
        "end": ["sample", *model, "--end", "1", "2", "--out", str(tmp_path / "e.npz")],
        "truncate": ["sample", *model, "--truncation", "0.5", "--out", str(tmp_path / "t.npz")],
    }  # fmt: skip
    for capability, argv in runs.items():
        code = main(argv)
        err = capsys.readouterr().err
        if capability in generator.capabilities:
            assert code == 0, (capability, err)
        else:
            assert code == 1 and err.count("\n") == 1, (capability, err)
            assert f"this {generator.kind} model cannot" in err and str(folder) in err
    if "decode" in generator.capabilities:
        z = np.zeros((2, generator.code_space.size), dtype=np.float32)
        motions = generator.decode(z, action)
        assert len(motions) == 2  # vectorised sin/cos may round the rows of one batch differently
        np.testing.assert_allclose(motions[0].joints, motions[1].joints, atol=1e-5)
        assert motions[0].joints.shape == (generator.window, generator.skeleton.n_joints, 3)
    else:
        with pytest.raises(CapabilityError, match="cannot decode a given latent code"):
            generator.decode(np.zeros((1, generator.code_space.size)), action)
    if "bank" in generator.capabilities:
        assert bank is not None and bank.codes.shape[1] == generator.code_space.size
        assert bank.action_names == generator.label_names
        pca = bank.projections["pca"]
        np.testing.assert_allclose(pca.transform(bank.codes[:5]), pca.embedding_[:5], atol=1e-4)
    else:
        assert bank is None


def test_each_declared_strategy_samples_and_the_first_is_the_default(folder: Path) -> None:
    generator = open_generator(folder)
    action = action_of(generator, 0)
    default = generator.sample(SampleRequest(action, 2, 3))
    for strategy in generator.strategies:
        label = action if strategy == "prior" or action is not None else generator.label_names[0]
        modes = None if strategy == "prior" else generator.bank.modes[generator.label_names.index(label)]
        weights = None if strategy != "weights" else tuple(np.ones(modes.n_modes_))
        mode = 0 if strategy == "mode" else None
        samples = generator.sample(SampleRequest(label, 2, 3, strategy, mode, weights=weights))
        assert [s.motion.joints.shape for s in samples] == [
            (generator.window, generator.skeleton.n_joints, 3)
        ] * 2
        if strategy == generator.strategies[0]:
            for s, d in zip(samples, default, strict=True):
                np.testing.assert_array_equal(s.motion.joints, d.motion.joints)
    assert ("modes" in generator.capabilities) == ("mode" in generator.strategies)


def test_require_names_what_the_model_can_do(
    tiny_a2m_old_dir: Path, tiny_a2m_dir: Path, capsys: pytest.CaptureFixture
) -> None:
    generator = open_generator(tiny_a2m_old_dir)
    only = r"it can sample motions, sample with truncation$"
    with pytest.raises(CapabilityError, match=rf"cannot encode a motion into a code; {only}"):
        require(generator, "encode")
    with pytest.raises(CapabilityError, match=r"cannot set where the motion ends; it can sample motions, "):
        require(open_generator(tiny_a2m_dir), "end")
    assert main(["bank", "--model", str(tiny_a2m_old_dir), "--data", str(tiny_a2m_old_dir)]) == 1
    assert "cannot build a latent bank" in capsys.readouterr().err


def test_unknown_kinds_are_refused_by_name(tiny_a2m_dir: Path, tmp_path: Path) -> None:
    copy = Path(shutil.copytree(tiny_a2m_dir, tmp_path / "copy"))
    meta = json.loads((copy / "model.json").read_text())
    (copy / "model.json").write_text(json.dumps(meta | {"arch": "gan9"}))
    with pytest.raises(
        ModelFormatError,
        match=r"model\.json: unknown model kind 'gan9'; this program opens a2m, dvgan, modi, odmo",
    ):
        open_generator(copy)
