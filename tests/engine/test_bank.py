"""The latent bank: building, exact save/load, refusal of bad files, end locations."""

from __future__ import annotations

import json
import zipfile
from collections.abc import Iterator
from pathlib import Path

import numpy as np
import pytest
from threadpoolctl import threadpool_limits

from engine.errors import CancelledError, ConfigError, ModelFormatError
from engine.latent.bank import FORMAT_VERSION, LatentBank, build_bank

ACTIONS = ["walk", "jump", "wave", "unused"]


def inputs(seed: int = 0) -> dict:
    """Codes of three actions (two clusters each) with ends that depend smoothly on the code."""
    rng = np.random.default_rng(seed)
    codes, actions = [], []
    for action in range(3):
        for _ in range(2):
            center = rng.normal(0.0, 6.0, 8)
            codes.append(center + rng.normal(size=(30, 8)))
            actions += [action] * 30
    codes = np.concatenate(codes).astype(np.float32)
    ends = np.column_stack([np.sin(codes[:, 0]), codes[:, 1] * 0.1, np.cos(codes[:, 2])]).astype(np.float32)
    n = len(codes)
    return {
        "codes": codes,
        "actions": np.asarray(actions),
        "ends": ends,
        "sources": [f"clip_{i:03d}.bvh" for i in range(n)],
        "meta": [{"style": ["happy", "tired"][i % 2], "subject": i % 3} for i in range(n)],
        "action_names": ACTIONS,
    }


@pytest.fixture(scope="module", autouse=True)
def one_thread() -> Iterator[None]:
    """OpenMP and BLAS on one thread: on a busy 2-core machine their spinning threads slow t-SNE 10x."""
    with threadpool_limits(1):
        yield


@pytest.fixture(scope="module")
def bank() -> LatentBank:
    return build_bank(**inputs(), k_range=(2, 4), projections=("pca", "tsne", "umap"), seed=0)


@pytest.fixture(scope="module")
def saved(bank: LatentBank, tmp_path_factory: pytest.TempPathFactory) -> Path:
    path = tmp_path_factory.mktemp("bank") / "bank.npz"
    bank.save(path)
    return path


def test_build_finds_modes_and_maps(bank: LatentBank) -> None:
    assert sorted(bank.modes) == [0, 1, 2]  # "unused" has no codes and no modes
    for action, model in bank.modes.items():
        assert model.k_chosen_ == 2 and model.n_modes_ == 2
        assert len(model.labels_) == len(bank.indices_of(action)) == 60
        assert sorted(model.sizes()) == [30, 30]
    assert sorted(bank.projections) == ["pca", "tsne", "umap"]
    for projection in bank.projections.values():
        assert projection.embedding_.shape == (180, 2)
    assert bank.codes.dtype == np.float32 and bank.ends.dtype == np.float32


def test_save_load_round_trip_is_exact(bank: LatentBank, saved: Path) -> None:
    back = LatentBank.load(saved)
    for name in ("codes", "actions", "ends", "sources"):
        np.testing.assert_array_equal(getattr(back, name), getattr(bank, name))
        assert getattr(back, name).dtype == getattr(bank, name).dtype
    assert back.action_names == bank.action_names and back.meta == bank.meta
    assert sorted(back.modes) == sorted(bank.modes)
    for action, model in bank.modes.items():
        np.testing.assert_array_equal(back.modes[action].means_, model.means_)
        np.testing.assert_array_equal(back.modes[action].labels_, model.labels_)
        assert back.modes[action].silhouette_ == model.silhouette_
    points = np.random.default_rng(0).normal(size=(5, 2))
    for name, projection in bank.projections.items():
        np.testing.assert_array_equal(back.projections[name].embedding_, projection.embedding_)
        np.testing.assert_array_equal(
            back.projections[name].inverse_transform(points), projection.inverse_transform(points)
        )
    np.testing.assert_array_equal(
        back.end_location(bank.codes[:4] + 0.1, 0), bank.end_location(bank.codes[:4] + 0.1, 0)
    )


def test_file_has_no_object_arrays_and_a_version(saved: Path) -> None:
    with np.load(saved, allow_pickle=False) as npz:
        assert all(npz[key].dtype.kind != "O" for key in npz.files)
        assert int(npz["version"]) == FORMAT_VERSION
    assert sorted(p.name for p in saved.parent.iterdir()) == ["bank.npz"]  # no temporary left behind


def test_maps_fitted_on_the_bank_codes_store_no_copy_and_version_1_files_still_load(
    bank: LatentBank, saved: Path, tmp_path: Path
) -> None:
    with np.load(saved, allow_pickle=False) as npz:
        assert not [key for key in npz.files if key.startswith("projections/") and key.endswith("/codes")]
    copies = {f"projections/{name}/codes": bank.codes for name in bank.projections}
    rows = old_rows(bank)
    old = rewritten(saved, tmp_path, version=np.asarray(1, dtype=np.int64), **copies, **rows)
    back = LatentBank.load(old)
    for name, projection in bank.projections.items():
        np.testing.assert_array_equal(back.projections[name].codes_, projection.codes_)
    assert back.meta == bank.meta and list(back.sources) == list(bank.sources)
    without = rewritten(saved, tmp_path, version=np.asarray(1, dtype=np.int64), **rows)
    with pytest.raises(ModelFormatError, match=r"projections/.*/codes"):
        LatentBank.load(without)  # version 1 kept the copies: a file without them is damaged


def old_rows(bank: LatentBank) -> dict[str, np.ndarray]:
    """Sources and meta as format versions 1 and 2 stored them: names and one JSON dict per row."""
    return {
        "sources": np.asarray(list(bank.sources), dtype=np.str_),
        "meta": np.asarray([json.dumps(m, sort_keys=True) for m in bank.meta], dtype=np.str_),
    }


def rewritten(saved: Path, tmp_path: Path, **changes: np.ndarray | None) -> Path:
    """A copy of the saved bank with some arrays replaced (None: removed)."""
    with np.load(saved, allow_pickle=False) as npz:
        arrays = {key: npz[key] for key in npz.files}
    for key, value in changes.items():
        if value is None:
            del arrays[key]
        else:
            arrays[key] = value
    path = tmp_path / "changed.npz"
    np.savez(path, **arrays)
    return path


def test_load_refuses_bad_files(saved: Path, tmp_path: Path) -> None:
    truncated = tmp_path / "truncated.npz"
    truncated.write_bytes(saved.read_bytes()[: saved.stat().st_size // 2])
    garbage = tmp_path / "garbage.npz"
    garbage.write_bytes(b"not a zip file at all")
    cases = {
        truncated: "not a readable",
        garbage: "not a readable",
        tmp_path / "missing.npz": "not found",
        rewritten(saved, tmp_path, version=np.asarray(FORMAT_VERSION + 1)): "newer",
    }
    for path, message in cases.items():
        with pytest.raises(ModelFormatError, match=message) as caught:
            LatentBank.load(path)
        assert path.name in str(caught.value)
    for changes in ({"codes": None}, {"format": np.asarray("something-else")}, {"ends": np.zeros((3, 3))}):
        with pytest.raises(ModelFormatError):
            LatentBank.load(rewritten(saved, tmp_path, **changes))
    with pytest.raises(ModelFormatError, match="modes/1/means"):
        LatentBank.load(rewritten(saved, tmp_path, **{"modes/1/means": None}))


def test_load_refuses_pickled_arrays(saved: Path, tmp_path: Path) -> None:
    with np.load(saved, allow_pickle=False) as npz:
        arrays = {key: npz[key] for key in npz.files}
    arrays["meta/style/values"] = np.array([{"style": "x"}] * 2, dtype=object)
    path = tmp_path / "pickled.npz"
    np.savez(path, **arrays)
    assert zipfile.is_zipfile(path)
    with pytest.raises(ModelFormatError):
        LatentBank.load(path)


def test_end_location_is_exact_on_codes_and_smooth(bank: LatentBank) -> None:
    idx = bank.indices_of(1)
    np.testing.assert_array_equal(bank.end_location(bank.codes[idx[:10]], 1), bank.ends[idx[:10]])
    a, b = bank.codes[idx[0]].astype(np.float64), bank.codes[idx[45]].astype(np.float64)
    path = a + np.linspace(0, 1, 2001)[:, None] * (b - a)
    ends = bank.end_location(path, 1)
    pool = bank.codes[idx]
    nearest = bank.ends[idx][np.argmin(((path[:, None] - pool[None]) ** 2).sum(-1), axis=1)]
    assert np.abs(np.diff(ends, axis=0)).max() < 0.2 * np.abs(np.diff(nearest, axis=0)).max()
    np.testing.assert_allclose(ends[[0, -1]], bank.ends[idx[[0, 45]]])


def test_end_location_uses_only_that_action(bank: LatentBank) -> None:
    other = bank.indices_of(2)[0]
    own = bank.end_location(bank.codes[other][None], 2)[0]
    elsewhere = bank.end_location(bank.codes[other][None], 0)[0]
    np.testing.assert_array_equal(own, bank.ends[other])
    assert not np.allclose(elsewhere, bank.ends[other])
    with pytest.raises(ConfigError):
        bank.end_location(bank.codes[:1], 3)  # an action without codes
    with pytest.raises(ConfigError):
        bank.end_location(bank.codes[:1], 7)
    with pytest.raises(ConfigError):
        bank.end_location(np.zeros((1, 5)), 0)


def test_progress_cancel_and_bad_input() -> None:
    reports: list[tuple[str, float]] = []
    build_bank(
        **inputs(1), k_range=(2, 3), projections=("pca",), progress=lambda m, f: reports.append((m, f))
    )
    fractions = [f for _, f in reports]
    assert fractions == sorted(fractions) and fractions[0] == 0.0 and fractions[-1] == 1.0
    assert any("walk" in m for m, _ in reports)
    with pytest.raises(CancelledError):
        build_bank(**inputs(1), k_range=(2, 3), projections=("pca",), cancel=lambda: True)
    bad = inputs(1)
    bad["ends"] = bad["ends"][:-1]
    with pytest.raises(ConfigError):
        build_bank(**bad, projections=("pca",))
    bad = inputs(1)
    bad["actions"] = bad["actions"] + 5
    with pytest.raises(ConfigError):
        build_bank(**bad, projections=("pca",))
    with pytest.raises(ConfigError):
        build_bank(**inputs(1), projections=("pca", "isomap"))
