"""Dataset folders: Bandai-Namco layout, pattern and sidecar labels, HumanAct12 names, cache, errors."""

from __future__ import annotations

import json
import re
import shutil
from pathlib import Path

import numpy as np
import pytest

from engine.errors import CancelledError, ConfigError, DataError
from engine.motion import Motion, Skeleton
from engine.motion.bvh import read_bvh
from engine.motion.datasets import drop_extra_joints, load_folder
from engine.motion.npz import write_npz
from tests.fixtures.tamper import rewrite_npz

BANDAI_ACTIONS = [
    "walk",
    "walk-turn-left",
    "walk-turn-right",
    "run",
    "wave-both-hands",
    "wave-left-hand",
    "wave-right-hand",
    "raise-up-both-hands",
    "raise-up-left-hand",
    "raise-up-right-hand",
]
MINI_STEMS = (
    "walk_normal_001",
    "walk_elderly_002",
    "run_active_001",
    "run_normal_003",
    "wave-left-hand_feminine_001",
    "wave-left-hand_youthful_002",
)


@pytest.fixture(autouse=True)
def private_cache(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> Path:
    """Each test gets its own empty cache folder."""
    cache = tmp_path / "cache"
    monkeypatch.setenv("ODMO_CACHE_DIR", str(cache))
    return cache


@pytest.fixture
def mini_bandai(bandai_dir: Path, tmp_path: Path) -> Path:
    """A copy of the Bandai layout with 6 clips of 3 actions."""
    root = tmp_path / "bandai"
    shutil.copytree(bandai_dir / "cfg", root / "cfg")
    (root / "data").mkdir()
    for stem in MINI_STEMS:
        for suffix in (".bvh", ".json"):
            shutil.copy(bandai_dir / "data" / f"dataset-2_{stem}{suffix}", root / "data")
    return root


def tiny_clip(rng: np.random.Generator, frames: int = 6) -> Motion:
    """A random 3-joint clip."""
    skel = Skeleton(("a", "b", "c"), np.array([-1, 0, 1]), [[0, 0, 0], [0, 0.5, 0], [0, 0.4, 0]])
    return Motion(rng.normal(size=(frames, 3, 3)), 25.0, skel)


def test_real_bandai_folder(bandai_dir: Path, private_cache: Path) -> None:
    calls: list[tuple[int, int]] = []
    data = load_folder(bandai_dir, limit=25, progress=lambda i, n: calls.append((i, n)))
    assert data.layout == "bandai" and len(data) == 25 and data.action_names == BANDAI_ACTIONS
    assert data.skeleton.n_joints == 21 and data.skeleton.names[data.skeleton.root] == "Hips"
    assert "joint_Root" not in data.skeleton.names
    assert calls[-1] == (25, 25) and len(calls) == 25
    for clip in data.clips:
        name = Path(clip.meta["source"]).stem
        assert name.startswith(f"dataset-2_{clip.action}_{clip.meta['style']}_")
        assert clip.fps == pytest.approx(30.0, rel=1e-4) and clip.local_rotations is None
    # The subset keeps Hips' world positions: the clip equals the BVH's joints without joint_Root.
    first = read_bvh(bandai_dir / data.clips[0].meta["source"])
    assert np.allclose(data.clips[0].joints, first.joints[:, 1:], atol=1e-6)
    assert list(private_cache.glob("datasets/*.npz"))


def test_bandai_drop_joints_is_an_option(mini_bandai: Path) -> None:
    data = load_folder(mini_bandai, drop_joints=())
    assert data.skeleton.n_joints == 22 and data.skeleton.names[0] == "joint_Root"
    assert data.action_names == BANDAI_ACTIONS
    assert sorted({c.action for c in data.clips}) == ["run", "walk", "wave-left-hand"]


def test_cache_is_reused_and_follows_content(mini_bandai: Path, private_cache: Path) -> None:
    first = load_folder(mini_bandai)
    (cache_file,) = private_cache.glob("datasets/*.npz")
    stamp = cache_file.stat().st_mtime_ns
    second = load_folder(mini_bandai)
    assert cache_file.stat().st_mtime_ns == stamp, "an unchanged folder must not rewrite its cache"
    assert second.fingerprint == first.fingerprint
    for a, b in zip(first.clips, second.clips, strict=True):
        assert np.array_equal(a.joints, b.joints) and a.meta == b.meta and a.action == b.action
        assert np.array_equal(a.skeleton.offsets, b.skeleton.offsets)
    # Change one clip's content: its cache entry must not be reused.
    victim = mini_bandai / "data" / "dataset-2_run_active_001.bvh"
    shorter = victim.read_text().splitlines()
    frames_at = next(i for i, line in enumerate(shorter) if line.startswith("Frames:"))
    shorter[frames_at] = "Frames: 10"
    victim.write_text("\n".join(shorter[: frames_at + 2 + 10]) + "\n")
    third = load_folder(mini_bandai)
    changed = next(c for c in third.clips if c.meta["source"].endswith("run_active_001.bvh"))
    assert changed.n_frames == 10 and third.fingerprint != first.fingerprint
    assert cache_file.stat().st_mtime_ns != stamp


def test_pattern_labels_with_extra_groups(tmp_path: Path) -> None:
    rng = np.random.default_rng(0)
    for name in ["jump_01", "jump_02", "crawl_01", "notes"]:
        write_npz(tmp_path / f"{name}.npz", tiny_clip(rng))
    data = load_folder(tmp_path, pattern=r"^(?P<action>[a-z]+)_(?P<take>\d+)")
    assert data.action_names == ["crawl", "jump"] and len(data) == 3
    assert [c.meta["take"] for c in data.clips] == ["01", "01", "02"]
    with pytest.raises(ConfigError, match="action"):
        load_folder(tmp_path, pattern=r"(?P<label>\w+)")


def test_z_up_folders_turn_upright_and_are_cached_apart(tmp_path: Path) -> None:
    rng = np.random.default_rng(2)
    folder = tmp_path / "zup"
    folder.mkdir()
    for name in ["jump_01", "crawl_01"]:
        write_npz(folder / f"{name}.npz", tiny_clip(rng))
    pattern = r"^(?P<action>[a-z]+)_"
    as_is = load_folder(folder, pattern=pattern)
    turned = load_folder(folder, pattern=pattern, up_axis="z")
    again = load_folder(folder, pattern=pattern)  # from the cache: the Y-up entries, not the turned ones
    for a, b, c in zip(as_is.clips, turned.clips, again.clips, strict=True):
        x, y, z = np.moveaxis(a.joints, 2, 0)
        np.testing.assert_allclose(b.joints, np.stack([x, z, -y], axis=2), atol=1e-6)
        np.testing.assert_array_equal(c.joints, a.joints)
    with pytest.raises(ConfigError, match="up axis must be one of y, z, got 'up'"):
        load_folder(folder, pattern=pattern, up_axis="up")


@pytest.mark.parametrize("kind", ["csv", "json"])
def test_sidecar_labels(tmp_path: Path, kind: str) -> None:
    rng = np.random.default_rng(1)
    for name in ["a", "b", "c"]:
        write_npz(tmp_path / f"{name}.npz", tiny_clip(rng))
    if kind == "csv":
        (tmp_path / "labels.csv").write_text("file,action,style\na.npz,kick,old\nb.npz,punch,young\n")
    else:
        (tmp_path / "labels.json").write_text(
            json.dumps({"a.npz": {"action": "kick", "style": "old"}, "b": "punch"})
        )
    data = load_folder(tmp_path, labels=f"labels.{kind}")
    assert data.action_names == ["kick", "punch"] and len(data) == 2
    assert data.clips[0].meta["style"] == "old"


def test_bad_sidecar_names_its_line(tmp_path: Path) -> None:
    write_npz(tmp_path / "a.npz", tiny_clip(np.random.default_rng(2)))
    (tmp_path / "labels.csv").write_text("file,action\na.npz,kick,extra\n")
    with pytest.raises(DataError, match=r"labels\.csv:2"):
        load_folder(tmp_path, labels="labels.csv")


def test_humanact12_names_label_npy_files(tmp_path: Path) -> None:
    for name in ["P01G01R01F0001T0010A0101", "P02G01R01F0001T0010A0201", "P02G01R01F0001T0010A0203"]:
        np.save(tmp_path / f"{name}.npy", np.zeros((5, 24, 3), np.float32))
    data = load_folder(tmp_path)
    assert data.action_names == ["walk", "warm_up"] and data.skeleton.n_joints == 24
    assert data.clips[2].meta["fine_class"] == "0203"


def test_unlabelled_or_unreadable_folders(tmp_path: Path) -> None:
    rng = np.random.default_rng(3)
    write_npz(tmp_path / "x.npz", tiny_clip(rng))
    with pytest.raises(DataError, match=r"no labelled clips \(name the label with --pattern"):
        load_folder(tmp_path)
    (tmp_path / "walk_2.npz").write_bytes(b"garbage")
    write_npz(tmp_path / "walk_1.npz", tiny_clip(rng))
    with pytest.raises(DataError, match=r"walk_2\.npz") as info:
        load_folder(tmp_path, pattern=r"(?P<action>walk)")
    assert str(info.value).count("walk_2.npz") == 1, "the file is named once"
    data = load_folder(tmp_path, pattern=r"(?P<action>walk)", on_error="skip")
    assert len(data) == 1 and data.skipped == [str(tmp_path / "walk_2.npz")]


def test_cancel_stops_loading(mini_bandai: Path) -> None:
    seen: list[int] = []
    with pytest.raises(CancelledError):
        load_folder(mini_bandai, progress=lambda i, n: seen.append(i), cancel=lambda: len(seen) >= 2)
    assert seen == [1, 2]


def test_bandai_clips_copied_out_of_the_dataset_keep_their_labels(bandai_dir: Path, tmp_path: Path) -> None:
    for stem in MINI_STEMS:
        shutil.copy(bandai_dir / "data" / f"dataset-2_{stem}.bvh", tmp_path)
    data = load_folder(tmp_path)
    assert data.layout == "generic" and data.action_names == ["run", "walk", "wave-left-hand"]
    by_name = {Path(c.meta["source"]).name: c for c in data.clips}
    clip = by_name["dataset-2_wave-left-hand_feminine_001.bvh"]
    assert clip.action == "wave-left-hand" and clip.meta["style"] == "feminine"
    # The raw files keep Bandai's ground-projected root; drop_extra_joints drops it by name.
    assert clip.skeleton.names[0] == "joint_Root"
    model_names = clip.skeleton.names[1:]
    on_model = drop_extra_joints(clip, model_names)
    assert on_model.skeleton.names == model_names
    np.testing.assert_array_equal(on_model.joints, clip.joints[:, 1:])
    assert drop_extra_joints(clip, (*model_names, "Tail")) is clip


def _cache_file(private_cache: Path) -> Path:
    (found,) = private_cache.glob("datasets/*.npz")
    return found


def _zero_joints(arrays: dict) -> None:
    arrays["joints"] = np.zeros_like(arrays["joints"])


def _nan_joints(arrays: dict) -> None:
    arrays["joints"] = arrays["joints"].copy()
    arrays["joints"][5] = np.nan


def _rename_joint(arrays: dict) -> None:
    names = arrays["names"].tolist()
    names[1] = "Renamed"
    arrays["names"] = np.asarray(names)


def _flip_bytes(path: Path) -> None:
    data = bytearray(path.read_bytes())
    middle = len(data) // 2
    data[middle : middle + 64] = bytes(b ^ 0xFF for b in data[middle : middle + 64])
    path.write_bytes(bytes(data))


@pytest.mark.parametrize(
    "damage",
    [
        lambda p: rewrite_npz(p, _zero_joints),
        lambda p: rewrite_npz(p, _nan_joints),
        lambda p: rewrite_npz(p, _rename_joint),
        _flip_bytes,
        lambda p: p.write_bytes(p.read_bytes()[: p.stat().st_size // 3]),
        lambda p: p.write_bytes(b"not a zip at all"),
    ],
    ids=["zeroed-joints", "nan-joints", "renamed-joint", "flipped-bytes", "truncated", "junk"],
)
def test_damaged_cache_is_rebuilt_from_the_source_files(
    mini_bandai: Path, private_cache: Path, damage, caplog: pytest.LogCaptureFixture
) -> None:
    fresh = load_folder(mini_bandai)
    cache = _cache_file(private_cache)
    damage(cache)
    with caplog.at_level("WARNING", logger="engine.motion.datasets"):
        again = load_folder(mini_bandai)
    assert any(str(cache) in r.getMessage() for r in caplog.records), "the damage must be reported"
    assert again.fingerprint == fresh.fingerprint
    for a, b in zip(fresh.clips, again.clips, strict=True):
        np.testing.assert_array_equal(a.joints, b.joints)
        assert a.skeleton.names == b.skeleton.names
    caplog.clear()
    with caplog.at_level("WARNING", logger="engine.motion.datasets"):
        third = load_folder(mini_bandai)  # the rebuilt cache is clean again
    assert not caplog.records
    np.testing.assert_array_equal(third.clips[0].joints, fresh.clips[0].joints)


def test_damaged_cache_gives_no_traceback_in_the_cli(mini_bandai: Path, private_cache: Path) -> None:
    import os
    import subprocess
    import sys

    load_folder(mini_bandai)
    _flip_bytes(_cache_file(private_cache))
    env = os.environ | {"ODMO_CACHE_DIR": str(private_cache)}
    run = subprocess.run(
        [sys.executable, "-m", "engine", "info", str(mini_bandai)], capture_output=True, text=True, env=env
    )
    assert run.returncode == 0, run.stderr
    assert "Traceback" not in run.stderr and re.search(r"clips:\s+6 ", run.stdout)
    assert "failed their checksum" in run.stderr or "unreadable cache" in run.stderr
