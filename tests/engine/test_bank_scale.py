"""Banks at scale: streamed encoding in batches (same codes, bounded memory, progress, cancel) and the
columnar bank format 3 (round trip, damaged files, version 2 files still load)."""

from __future__ import annotations

import json
import re
import shutil
import tracemalloc
from pathlib import Path

import numpy as np
import pytest

from engine import cli
from engine.errors import CancelledError, DataError, ModelFormatError
from engine.fileio import LOCK_FILE
from engine.generate import encode_bank_windows, encode_clips, encode_windows
from engine.latent.bank import FORMAT_VERSION, LatentBank, build_bank
from engine.latent.columns import MetaColumns
from engine.modelio import LoadedModel, load_model
from engine.motion.datasets import load_folder, open_folder
from engine.motion.motion import Motion
from tests.fixtures.procedural import make_procedural_clips
from tests.fixtures.tiny_model import single_thread

BUNDLED = sorted(Path(__file__).resolve().parents[2].glob("resources/models/*/latent_bank.npz"))


def _bank_format(path: Path) -> int:
    """The format version a bank file was written in."""
    with np.load(path, allow_pickle=False) as npz:
        return int(npz["version"])


#: Bundled banks written before format 3 (which keeps metadata in columns): the older readers' cases.
BEFORE_FORMAT_3 = [p for p in BUNDLED if _bank_format(p) <= 2]


@pytest.fixture(scope="module")
def loaded(tiny_model_dir: Path) -> LoadedModel:
    return load_model(tiny_model_dir, with_bank=False)


def test_streamed_codes_equal_the_one_clip_at_a_time_codes(
    loaded: LoadedModel, procedural_clips: list[Motion]
) -> None:
    with single_thread():
        codes, ends, owners, starts = encode_bank_windows(loaded, procedural_clips, 10, batch=7)
        whole = [encode_windows(loaded, clip, 10) for clip in procedural_clips]
        centre_codes, centre_ends, centre_owners, none = encode_bank_windows(
            loaded, procedural_clips, None, batch=5
        )
        expected_centres = encode_clips(loaded, procedural_clips)
    np.testing.assert_allclose(codes, np.concatenate([w.codes for w in whole]), atol=1e-6)
    np.testing.assert_allclose(ends, np.concatenate([w.ends for w in whole]), atol=1e-6)
    np.testing.assert_array_equal(
        owners, np.concatenate([np.full(len(w.codes), k) for k, w in enumerate(whole)])
    )
    np.testing.assert_array_equal(starts, np.concatenate([w.starts for w in whole]))
    np.testing.assert_allclose(centre_codes, expected_centres[0], atol=1e-6)
    np.testing.assert_allclose(centre_ends, expected_centres[1], atol=1e-6)
    np.testing.assert_array_equal(centre_owners, np.arange(len(procedural_clips)))
    assert none is None and len(codes) > 2 * len(procedural_clips)


def test_progress_counts_windows_and_cancel_stops_between_batches(
    loaded: LoadedModel, procedural_clips: list[Motion]
) -> None:
    reports: list[tuple[int, int]] = []
    cancelled: list[tuple[int, int]] = []
    with single_thread():
        codes, *_ = encode_bank_windows(
            loaded, procedural_clips, 10, batch=50, progress=lambda d, t: reports.append((d, t))
        )
        with pytest.raises(CancelledError, match=r"after 100 windows of \d+ of 72 clips"):
            encode_bank_windows(
                loaded,
                procedural_clips,
                10,
                batch=50,
                progress=lambda d, t: cancelled.append((d, t)),
                cancel=lambda: len(cancelled) == 2,
            )
    n = len(codes)
    assert [d for d, _ in reports] == [*range(50, n, 50), n] and reports[-1] == (n, n)
    assert all(d <= t for d, t in reports) and 0.8 * n < reports[0][1] < 1.25 * n  # estimated from clips seen
    assert [d for d, _ in cancelled] == [50, 100]


def _peak_bytes(loaded: LoadedModel, clips: list[Motion]) -> tuple[int, int]:
    """Peak traced bytes of a streamed encoding of ``clips`` (batches of 32 windows) and its window count."""
    tracemalloc.start()
    try:
        codes, *_ = encode_bank_windows(loaded, clips, 5, batch=32)
        return tracemalloc.get_traced_memory()[1], len(codes)
    finally:
        tracemalloc.stop()


def test_streamed_memory_grows_with_the_codes_not_the_clips(loaded: LoadedModel) -> None:
    few, many = make_procedural_clips(n_per_style=2, seed=3), make_procedural_clips(n_per_style=8, seed=3)
    with single_thread():
        _peak_bytes(loaded, few)  # imports and caches
        small, n_small = _peak_bytes(loaded, few)
        large, n_large = _peak_bytes(loaded, many)
    per_window = 8 * (loaded.config.latent_dim + 3 + 4)  # codes, ends, owner, start: the output rows
    assert n_large > 3 * n_small
    # All windows at once held each window's T x J x 3 floats several times over (about 8 kB each here).
    assert large - small < 2 * per_window * (n_large - n_small) + 200_000, (small, large, n_small, n_large)


def _columnar_bank(n_clips: int = 6, per_clip: int = 5) -> LatentBank:
    """A bank of ``n_clips`` clips' windows with mixed metadata (text, numbers, lists, a missing key)."""
    rng = np.random.default_rng(0)
    table = [{"style": ["calm", "wild"][k % 2], "take": k, "tags": [k, "x"]} for k in range(n_clips)]
    table[2].pop("style")
    owners = np.repeat(np.arange(n_clips), per_clip)
    starts = np.tile(np.arange(per_clip) * 10, n_clips)
    meta = MetaColumns.from_table(table, owners, {"window_start": starts})
    n = len(owners)
    return build_bank(
        rng.normal(size=(n, 4)).astype(np.float32),
        owners % 2,
        rng.normal(size=(n, 3)).astype(np.float32),
        np.asarray([f"clips/take_{k}.bvh" for k in range(n_clips)], dtype=object)[owners],
        meta,
        ["walk", "run"],
        k_range=(1, 2),
        projections=("pca",),
    )


def test_format_3_round_trip_keeps_every_row(tmp_path: Path) -> None:
    bank = _columnar_bank()
    path = tmp_path / "bank.npz"
    bank.save(path)
    back = LatentBank.load(path)
    assert back.meta[7] == {"style": "wild", "take": 1, "tags": [1, "x"], "window_start": 20}
    assert back.meta[12] == {"take": 2, "tags": [2, "x"], "window_start": 20}  # no style: none made up
    assert back.meta == bank.meta and list(back.meta) == [bank.meta[i] for i in range(len(bank.meta))]
    assert back.sources[7] == "clips/take_1.bvh" and list(back.sources) == list(bank.sources)
    np.testing.assert_array_equal(back.codes, bank.codes)
    np.testing.assert_array_equal(back.windows_of(12), np.arange(10, 15))
    with np.load(path, allow_pickle=False) as npz:
        assert int(npz["version"]) == FORMAT_VERSION == 3
        assert "meta" not in npz.files and "sources" not in npz.files
        assert npz["source_names"].shape == (6,) and npz["meta/window_start/values"].shape == (5,)
        assert npz["meta/style/index"].dtype == np.int32 and npz["meta/style/index"][12] == -1


def _damaged(path: Path, tmp_path: Path, **changes: np.ndarray | None) -> Path:
    """A copy of the bank file with arrays replaced (None: removed)."""
    with np.load(path, allow_pickle=False) as npz:
        arrays = {key: npz[key] for key in npz.files}
    for key, value in changes.items():
        arrays.pop(key) if value is None else arrays.__setitem__(key, value)
    out = tmp_path / "damaged.npz"
    np.savez(out, **arrays)
    return out


def test_damaged_columns_are_refused_naming_the_file(tmp_path: Path) -> None:
    path = tmp_path / "bank.npz"
    _columnar_bank().save(path)
    n = 30
    cases = {
        "source_index": {"source_index": np.full(n, 6, dtype=np.int32)},
        "meta/style/index": {"meta/style/index": None},
        "indexes past": {"meta/take/index": np.full(n, 9, dtype=np.int32)},
        "must index": {"meta/take/index": np.zeros(n - 1, dtype=np.int32)},
        "malformed": {"meta/take/values": np.asarray(["{not json"] * 6)},
    }
    for message, changes in cases.items():
        with pytest.raises(ModelFormatError, match=message) as caught:
            LatentBank.load(_damaged(path, tmp_path, **changes))
        assert "damaged.npz" in str(caught.value)


@pytest.mark.parametrize("path", BEFORE_FORMAT_3, ids=[p.parent.name for p in BEFORE_FORMAT_3])
def test_bundled_banks_before_format_3_load_row_for_row(path: Path) -> None:
    with np.load(path, allow_pickle=False) as npz:
        sources, rows = npz["sources"], [json.loads(str(m)) for m in npz["meta"]]
    bank = LatentBank.load(path)
    assert list(bank.sources) == sources.tolist() and len(bank.meta) == len(rows)
    assert list(bank.meta) == rows and bank.meta[len(rows) // 2] == rows[len(rows) // 2]


def test_folder_clips_are_read_one_at_a_time_as_load_folder_reads_them(
    procedural_npz_dir: Path, tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.setenv("ODMO_CACHE_DIR", str(tmp_path / "cache"))
    pattern = r"^(?P<action>[a-z]+)_(?P<style>[a-z-]+)_\d+"
    loaded_all = load_folder(procedural_npz_dir, pattern=pattern)
    lazy = open_folder(procedural_npz_dir, pattern=pattern)  # through the cache load_folder wrote
    parsed = open_folder(procedural_npz_dir, pattern=pattern, cache=False)
    assert lazy.store is not None and parsed.store is None
    assert len(lazy) == len(loaded_all) and lazy.action_names == loaded_all.action_names
    for k in (0, 31, len(lazy) - 1):
        for clip, expected in ((lazy[k], loaded_all.clips[k]), (parsed[k], loaded_all.clips[k])):
            np.testing.assert_array_equal(clip.joints, expected.joints)
            assert (clip.action, clip.meta) == (expected.action, expected.meta) == lazy.label(k)
    folder = tmp_path / "some bad"
    shutil.copytree(procedural_npz_dir, folder)
    bad = sorted(folder.iterdir())[3]
    bad.write_bytes(b"not an npz")
    damaged = open_folder(folder, pattern=pattern)  # nothing is read until asked for
    assert damaged[2].n_frames > 0 and damaged.label(3)[1]["source"] == bad.name
    with pytest.raises(DataError, match=re.escape(bad.name)):
        damaged[3]


def test_a_cancelled_odmo_bank_leaves_the_model_folder_as_it_was(
    tiny_model_dir: Path, procedural_npz_dir: Path, tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    model = Path(shutil.copytree(tiny_model_dir, tmp_path / "model"))
    before = _files(model)
    streamed = encode_bank_windows

    def cancelled_after_one_batch(*args: object, **kwargs: object) -> object:
        calls: list[int] = []
        kwargs["progress"] = lambda done, total: calls.append(done)
        return streamed(*args, **kwargs | {"batch": 16, "cancel": lambda: len(calls) >= 1})

    monkeypatch.setattr("engine.generate.encode_bank_windows", cancelled_after_one_batch)
    monkeypatch.setenv("ODMO_CACHE_DIR", str(tmp_path / "cache"))
    argv = ["bank", "--model", model, "--data", procedural_npz_dir, "--pattern", r"^(?P<action>[a-z]+)_"]
    assert cli.main([str(a) for a in [*argv, "--stride", "10", "--projections", "pca"]]) != 0
    assert _files(model) == before  # the old bank, and no temporary


def _files(folder: Path) -> dict[str, bytes]:
    """Every file of ``folder`` (but its advisory lock file, which stays by design) and its bytes."""
    return {p.name: p.read_bytes() for p in folder.iterdir() if p.is_file() and p.name != LOCK_FILE}
