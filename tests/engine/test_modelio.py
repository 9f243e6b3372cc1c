"""Model folder I/O: exact round trip and strict loading."""

from __future__ import annotations

import json
import shutil
from pathlib import Path

import pytest
import torch
from safetensors.torch import load_file, save_file

from engine.errors import ConfigError, ModelFormatError
from engine.model.config import OdmoConfig
from engine.model.odmo import OdmoModel
from engine.modelio import load_model, read_meta, resolve_device, save_model
from tests.fixtures.procedural import PROCEDURAL_ACTIONS, procedural_skeleton

pytestmark = pytest.mark.usefixtures("torch_single_thread")


def _saved(folder: Path) -> OdmoModel:
    cfg = OdmoConfig(n_actions=3, n_joints=11, window=16, enc_fc=32, traj_hidden=16, motion_hidden=16)
    model = OdmoModel(cfg, seed=4).eval()
    save_model(folder, model, cfg, procedural_skeleton(), PROCEDURAL_ACTIONS, {"seed": 4}, 0.95)
    return model


def test_save_load_decode_is_bit_identical(tmp_path: Path) -> None:
    model = _saved(tmp_path)
    loaded = load_model(tmp_path)
    assert loaded.bank is None and loaded.action_names == PROCEDURAL_ACTIONS
    assert loaded.skeleton.same_topology(procedural_skeleton()) and loaded.root_height == 0.95
    assert not loaded.model.training and loaded.window == 16 and loaded.provenance == {"seed": 4}
    z, action, end = torch.randn(3, 20), torch.tensor([0, 2, 1]), torch.randn(3, 3)
    with torch.inference_mode():
        a = model.decode(z, action, end)
        b = loaded.model.decode(z, action, end)
        c = loaded.model.decode(z[:1], action[:1], end[:1])
    assert torch.equal(a[0], b[0]) and torch.equal(a[1], b[1])
    torch.testing.assert_close(c[0][0], a[0][0], atol=1e-6, rtol=1e-6)


def test_tiny_model_folder_loads_with_bank(tiny_model_dir: Path) -> None:
    loaded = load_model(tiny_model_dir)
    assert {p.name for p in tiny_model_dir.iterdir()} >= {
        "model.safetensors", "model.json", "latent_bank.npz", "train_log.csv", "checkpoints"
    }  # fmt: skip
    assert loaded.bank is not None and loaded.bank.codes.shape == (72, loaded.config.latent_dim)
    assert {m["split"] for m in loaded.bank.meta} == {"train", "val"}
    assert loaded.provenance["versions"]["torch"] == torch.__version__
    assert len(loaded.provenance["data_fingerprint"]) == 64


def _expect(folder: Path, match: str) -> None:
    with pytest.raises(ModelFormatError, match=match):
        load_model(folder)


def test_strict_loading_errors(tmp_path: Path) -> None:
    good = tmp_path / "good"
    _saved(good)

    def copy(name: str) -> Path:
        return Path(shutil.copytree(good, tmp_path / name))

    _expect(tmp_path / "absent", "not a model folder")
    (folder := copy("nojson")).joinpath("model.json").unlink()
    _expect(folder, r"model\.json: missing")
    (folder := copy("badjson")).joinpath("model.json").write_text("{oops")
    _expect(folder, r"model\.json: unreadable")
    meta = json.loads((good / "model.json").read_text())
    (folder := copy("newer")).joinpath("model.json").write_text(json.dumps(meta | {"format_version": 99}))
    _expect(folder, "newer than this program")
    with pytest.raises(ModelFormatError, match="newer than this program"):
        read_meta(folder / "model.json")
    assert read_meta(good / "model.json") == meta
    meta_unknown = meta | {"config": meta["config"] | {"mystery": 3}}
    (folder := copy("unknown")).joinpath("model.json").write_text(json.dumps(meta_unknown))
    _expect(folder, "unknown model config keys: mystery")
    (folder := copy("noweights")).joinpath("model.safetensors").unlink()
    _expect(folder, r"model\.safetensors: missing weights")
    weights = (good / "model.safetensors").read_bytes()
    (folder := copy("truncated")).joinpath("model.safetensors").write_bytes(weights[: len(weights) // 2])
    _expect(folder, r"model\.safetensors: corrupt")
    tensors = load_file(good / "model.safetensors")
    save_file(tensors | {"extra": torch.zeros(2)}, (folder := copy("extra")) / "model.safetensors")
    _expect(folder, r"unexpected \['extra'\]")
    shaped = dict(tensors)
    shaped["motion_gen.out.bias"] = torch.zeros(5)
    save_file(shaped, (folder := copy("shape")) / "model.safetensors")
    _expect(folder, r"motion_gen\.out\.bias is \(5,\)")
    missing = {k: v for k, v in tensors.items() if k != "encoder.lstm.weight_ih_l0"}
    save_file(missing, (folder := copy("missing")) / "model.safetensors")
    _expect(folder, r"missing \['encoder\.lstm\.weight_ih_l0'\]")


def test_resolve_device() -> None:
    assert resolve_device("auto").type == ("cuda" if torch.cuda.is_available() else "cpu")
    assert resolve_device("cpu") == torch.device("cpu")
    with pytest.raises(ConfigError):
        resolve_device("potato")
