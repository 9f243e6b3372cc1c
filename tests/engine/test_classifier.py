"""The evaluation classifier: accuracy on procedural data, determinism, strict files."""

from __future__ import annotations

import json
import shutil
from pathlib import Path

import numpy as np
import pytest

from engine.errors import ConfigError, ModelFormatError
from engine.metrics.classifier import META_FILE, WEIGHTS_FILE, Classifier, load_classifier, train_classifier
from engine.motion.motion import Motion
from engine.train.pairs import split_clips
from engine.train.windows import crop_windows, every_window, prepare_clips, windows_at
from tests.fixtures.procedural import PROCEDURAL_ACTIONS


@pytest.fixture(scope="module")
def trained(
    tmp_path_factory: pytest.TempPathFactory, procedural_clips: list[Motion]
) -> tuple[Classifier, Path]:
    """A classifier trained briefly on the procedural clips (a quarter held out)."""
    out = tmp_path_factory.mktemp("classifier")
    clf = train_classifier(
        procedural_clips, PROCEDURAL_ACTIONS, out, epochs=8, batch_size=8, seed=0, val_fraction=0.25
    )
    return clf, out


def _windows(clips: list[Motion], seed: int = 1):
    prepared = prepare_clips(clips, PROCEDURAL_ACTIONS, 20.0, 60)
    return crop_windows(prepared, np.arange(len(clips)), np.random.default_rng(seed))


def test_accuracy_well_above_chance(trained: tuple[Classifier, Path], procedural_clips: list[Motion]) -> None:
    clf, out = trained
    assert clf.n_test == 18  # 3 actions x 24 clips, a quarter held out per action
    assert clf.test_accuracy >= 0.7  # chance is 1/3
    meta = json.loads((out / META_FILE).read_text())
    assert meta["test_accuracy"] == pytest.approx(clf.test_accuracy)
    # held out: every window (stride 10) of the held-out clips, recounted here, and per action
    prepared = prepare_clips(procedural_clips, PROCEDURAL_ACTIONS, 20.0, 60)
    _, held = split_clips(prepared.actions, 0.25, 0)
    rows = every_window(prepared, held, 10)
    assert clf.n_test_windows == len(rows) == meta["n_test_windows"] > len(held)
    batch = windows_at(prepared, rows[:, 0], rows[:, 1])
    _, pred = clf.classify(batch.joints, batch.mask)
    assert clf.test_accuracy == pytest.approx(np.mean(pred == batch.actions))
    for a, name in enumerate(PROCEDURAL_ACTIONS):
        wanted = batch.actions == a
        assert clf.test_accuracy_per_action[name] == pytest.approx(np.mean(pred[wanted] == a))
    assert load_classifier(out).test_accuracy_per_action == clf.test_accuracy_per_action
    batch = _windows(procedural_clips)
    _, pred = clf.classify(batch.joints, batch.mask)
    assert np.mean(pred == batch.actions) >= 0.8


def test_same_input_gives_identical_output(
    trained: tuple[Classifier, Path], procedural_clips: list[Motion]
) -> None:
    clf, out = trained
    batch = _windows(procedural_clips[:20], seed=2)
    f1, p1 = clf.classify(batch.joints, batch.mask)
    f2, p2 = clf.classify(batch.joints, batch.mask)
    assert f1.shape == (20, 30)
    assert np.array_equal(f1, f2) and np.array_equal(p1, p2)
    f3, _ = clf.classify(batch.joints, batch.mask, batch=3)  # batching does not change a window's features
    np.testing.assert_allclose(f1, f3, atol=1e-6)
    again = load_classifier(out)
    f4, p4 = again.classify(batch.joints, batch.mask)
    assert np.array_equal(f1, f4) and np.array_equal(p1, p4)
    assert again.action_names == PROCEDURAL_ACTIONS and again.config == clf.config


def test_wrong_window_shape_is_a_config_error(trained: tuple[Classifier, Path]) -> None:
    with pytest.raises(ConfigError):
        trained[0].classify(np.zeros((2, 60, 5, 3)))


def _copy(src: Path, dst: Path) -> Path:
    shutil.copytree(src, dst)
    return dst


def _edit_meta(folder: Path, **changes: object) -> None:
    meta = json.loads((folder / META_FILE).read_text())
    for key, value in changes.items():
        if key.startswith("config."):
            meta["config"][key.removeprefix("config.")] = value
        else:
            meta[key] = value
    (folder / META_FILE).write_text(json.dumps(meta))


def test_loading_is_strict(trained: tuple[Classifier, Path], tmp_path: Path) -> None:
    _, out = trained
    missing = _copy(out, tmp_path / "missing")
    (missing / WEIGHTS_FILE).unlink()
    newer = _copy(out, tmp_path / "newer")
    _edit_meta(newer, format_version=99)
    unknown = _copy(out, tmp_path / "unknown")
    _edit_meta(unknown, **{"config.dropout": 0.5})
    shape = _copy(out, tmp_path / "shape")
    _edit_meta(shape, **{"config.hidden": 64})
    corrupt = _copy(out, tmp_path / "corrupt")
    (corrupt / WEIGHTS_FILE).write_bytes(b"not safetensors at all")
    for folder in (missing, newer, unknown, shape, corrupt, tmp_path / "nowhere"):
        with pytest.raises(ModelFormatError):
            load_classifier(folder)


def test_every_window_starts_stride_apart_and_ends_at_the_last_frame(procedural_clips: list[Motion]) -> None:
    prepared = prepare_clips(procedural_clips, PROCEDURAL_ACTIONS, 20.0, 60)
    lengths = prepared.lengths
    long, short = int(np.argmax(lengths)), int(np.argmin(lengths))
    rows = every_window(prepared, [long, short], 10)
    last = lengths[long] - 60
    expected = sorted({*range(0, last + 1, 10), last})
    assert rows[rows[:, 0] == long, 1].tolist() == expected
    assert rows[rows[:, 0] == short, 1].tolist() == [0]  # shorter than a window: one, padded
    batch = windows_at(prepared, rows[:, 0], rows[:, 1])
    assert batch.mask[rows[:, 0] == long].all()
    assert batch.mask[-1].sum() == min(lengths[short], 60)
