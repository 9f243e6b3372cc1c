"""Model folders that cannot be silently wrong: checksums, banks tied to their weights, validated banks."""

from __future__ import annotations

import json
import shutil
from pathlib import Path

import numpy as np
import pytest

from engine.errors import ConfigError, ModelFormatError
from engine.latent.bank import LatentBank
from engine.model.config import OdmoConfig
from engine.modelio import BANK_FILE, META_FILE, WEIGHTS_FILE, load_model, read_meta
from tests.fixtures.tamper import record_bank_checksum, rewrite_npz

pytestmark = pytest.mark.usefixtures("torch_single_thread")


@pytest.fixture
def folder(tiny_model_dir: Path, tmp_path: Path) -> Path:
    """A private copy of the tiny trained model folder (weights, model.json, bank)."""
    return Path(shutil.copytree(tiny_model_dir, tmp_path / "model"))


def _meta(folder: Path) -> dict:
    return json.loads((folder / META_FILE).read_text())


def _write_meta(folder: Path, meta: dict) -> None:
    (folder / META_FILE).write_text(json.dumps(meta))


def test_trained_folder_records_checksums_of_weights_and_bank(folder: Path) -> None:
    meta = read_meta(folder / META_FILE)
    assert meta["format_version"] == 2
    assert len(meta["weights_sha256"]) == 64 and len(meta["bank_sha256"]) == 64
    bank = load_model(folder).bank
    assert bank is not None and bank.weights_sha256 == meta["weights_sha256"]


def test_flipped_weight_bytes_are_refused(folder: Path) -> None:
    data = bytearray((folder / WEIGHTS_FILE).read_bytes())
    data[-64:] = bytes(b ^ 0x5A for b in data[-64:])  # inside the last tensor: still a valid file
    (folder / WEIGHTS_FILE).write_bytes(bytes(data))
    with pytest.raises(ModelFormatError, match=r"model\.safetensors: content does not match the checksum"):
        load_model(folder)


def test_edited_bank_fails_its_checksum(folder: Path) -> None:
    def huge_means(arrays: dict) -> None:
        arrays["modes/0/means"] = np.full_like(arrays["modes/0/means"], 1e30)

    rewrite_npz(folder / BANK_FILE, huge_means)
    with pytest.raises(ModelFormatError, match=r"latent_bank\.npz: content does not match the checksum"):
        load_model(folder)


def test_bank_of_other_weights_is_refused(folder: Path) -> None:
    """A bank whose checksum is recorded but that names other weights (e.g. a stale copy) is refused."""
    rewrite_npz(folder / BANK_FILE, lambda arrays: arrays.update(weights_sha256=np.asarray("0" * 64)))
    record_bank_checksum(folder)
    with pytest.raises(ModelFormatError, match="built from other weights"):
        load_model(folder)


def test_interrupted_training_leaves_a_detectably_incomplete_folder(folder: Path) -> None:
    """Weights and model.json of a new run next to the old run's bank: the bank is not trusted."""
    meta = _meta(folder)
    del meta["bank_sha256"]
    _write_meta(folder, meta)
    with pytest.raises(ModelFormatError, match=r"not recorded in model\.json"):
        load_model(folder)
    assert load_model(folder, with_bank=False).bank is None


def test_retraining_into_a_folder_removes_the_old_bank(folder: Path) -> None:
    from engine.modelio import save_model

    loaded = load_model(folder)
    save_model(
        folder, loaded.model, loaded.config, loaded.skeleton, loaded.action_names, {}, loaded.root_height
    )
    assert not (folder / BANK_FILE).exists() and "bank_sha256" not in _meta(folder)
    assert load_model(folder).bank is None


@pytest.mark.parametrize(
    ("key", "value", "match"),
    [
        ("modes/0/weights", lambda w: np.full_like(w, np.nan), "mixture weights"),
        ("modes/0/weights", lambda w: -w, "mixture weights"),
        ("modes/0/covariances", lambda c: -c, "positive definite"),
        ("modes/0/covariances", lambda c: np.full_like(c, np.nan), "finite and symmetric"),
        ("modes/0/means", lambda m: np.full_like(m, 1e30), "means must be finite"),
        ("projections/pca/components", lambda c: np.full_like(c, np.inf), "components holds non-finite"),
        ("projections/pca/embedding", lambda e: np.full_like(e, np.nan), "embedding holds non-finite"),
    ],
)
def test_bank_values_are_validated_on_load(folder: Path, key: str, value, match: str) -> None:
    rewrite_npz(folder / BANK_FILE, lambda arrays: arrays.update({key: value(arrays[key])}))
    with pytest.raises(ModelFormatError, match=match):
        LatentBank.load(folder / BANK_FILE)


@pytest.mark.parametrize(
    ("change", "match"),
    [
        ({"format_version": True}, "bad format_version"),
        ({"mystery": 1}, "unknown keys: mystery"),
    ],
)
def test_model_json_is_strict(folder: Path, change: dict, match: str) -> None:
    _write_meta(folder, _meta(folder) | change)
    with pytest.raises(ModelFormatError, match=match):
        load_model(folder)


@pytest.mark.parametrize(
    ("field", "value"),
    [("window", 10_000_000), ("window", True), ("motion_hidden", 100_000), ("lr", float("inf"))],
)
def test_model_json_sizes_are_bounded_before_allocating(folder: Path, field: str, value: object) -> None:
    meta = _meta(folder)
    meta["config"][field] = value
    _write_meta(folder, meta)
    with pytest.raises(ModelFormatError, match=rf"model\.json: invalid model config: .*{field}"):
        load_model(folder)


def test_config_limits_name_the_field() -> None:
    with pytest.raises(ConfigError, match=r"window = 100000 is over the limit"):
        OdmoConfig(n_actions=3, n_joints=21, window=100_000)
    with pytest.raises(ConfigError, match=r"n_actions × latent_dim"):
        OdmoConfig(n_actions=1_000, n_joints=21, latent_dim=1_000)
    with pytest.raises(ConfigError, match=r"batch_size × window × hidden"):
        OdmoConfig(n_actions=3, n_joints=21, window=1_000, batch_size=8_192)
