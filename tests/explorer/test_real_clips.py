"""``--data``: a clicked code plays its real clip beside the decode, as the same window, start and heading."""

from __future__ import annotations

import shutil
from pathlib import Path

import numpy as np
import pytest

from engine import cli
from engine.latent.bank import LatentBank
from engine.modelio import save_bank
from engine.motion.formats import read_motion, write_motion
from engine.motion.motion import Motion
from engine.train.windows import canonicalize
from tests.explorer.conftest import Opened
from tests.explorer.gestures import click_map, outside_view, played_points


@pytest.fixture(scope="module")
def model_and_data(tmp_path_factory, tiny_model_dir: Path, procedural_clips: list[Motion]) -> tuple:
    """The tiny model with its bank naming Bandai-style files, and a folder of those files as BVH."""
    root = tmp_path_factory.mktemp("real_clips")
    model = root / "model"
    shutil.copytree(tiny_model_dir, model)
    bank = LatentBank.load(model / "latent_bank.npz")
    names = {clip.meta["source"]: _bandai_name(clip) for clip in procedural_clips}
    bank.sources = np.array([f"clips/{names[s]}" for s in bank.sources])  # trained from another folder
    save_bank(model, bank)
    data = root / "data"
    data.mkdir()
    for clip in procedural_clips:
        write_motion(clip, data / names[clip.meta["source"]])
    return model, data


def _bandai_name(clip: Motion) -> str:
    """The clip's name as the Bandai-Namco files are named (no hyphen in a style)."""
    number = Path(clip.meta["source"]).name.rsplit("_", 1)[1]
    return f"dataset-2_{clip.action}_{clip.meta['style'].replace('-', '')}_{number}.bvh"


def _distances(joints: np.ndarray) -> np.ndarray:
    """(T, J, J) joint-to-joint distances: unchanged by any placement or turn of the body."""
    return np.linalg.norm(joints[:, :, None] - joints[:, None], axis=-1)


def test_real_clip_is_the_encoded_window_at_the_decodes_start_and_heading(
    qtbot, open_explorer, model_and_data
) -> None:
    model, data = model_and_data
    opened: Opened = open_explorer(model)
    c = opened.controller
    qtbot.waitUntil(lambda: c.state.model is not None, timeout=60_000)
    c.loader.open_data(data)
    qtbot.waitUntil(lambda: c.state.data_dir is not None, timeout=60_000)
    assert f"{len(list(data.glob('*.bvh')))} clips" in opened.window.status_label.text()
    walks = np.flatnonzero(c.bank.actions == c.bank.action_names.index("walk"))
    index = int(walks[0])
    with qtbot.waitSignal(c.shownChanged, timeout=30_000):
        click_map(qtbot, opened, c.state.embedding[index])
    assert [d.label.split(" (")[-1] for d in c.state.shown] == ["decoded)", "real clip)"]
    decoded, real = (d.motion for d in c.state.shown)
    assert real.n_frames == decoded.n_frames == c.generator.window

    source = read_motion(data / Path(str(c.bank.sources[index])).name)
    start = real.meta["window_start"]
    assert start == (source.n_frames - c.generator.window) // 2  # the centre window, as the bank encodes it
    window = source.joints[start : start + c.generator.window]
    np.testing.assert_allclose(_distances(real.joints), _distances(window), atol=1e-4)

    # Both start at the origin; the clip faces +z as the model's training windows do (the tiny model's
    # decode is too rough to measure its facing on).
    root = real.skeleton.root
    for motion in (real, decoded):
        assert np.hypot(*motion.joints[0, root, [0, 2]]) < 0.02
    assert abs(canonicalize(real.joints, real.skeleton)[1]) < np.radians(3)
    np.testing.assert_allclose(real.joints[0, root, 1], decoded.joints[0, root, 1], atol=0.1)

    travel = real.joints[-1, root, [0, 2]] - real.joints[0, root, [0, 2]]
    assert travel[1] > 0.5 * np.linalg.norm(travel)  # a walk facing +z walks along +z
    assert outside_view(opened.window.viewport, played_points(opened)) == 0


@pytest.fixture(scope="module")
def strided_model(tmp_path_factory, model_and_data) -> Path:
    """The model above, its bank rebuilt by ``odmo bank --stride 20`` (a code every 20 frames of a clip)."""
    model, data = model_and_data
    strided = tmp_path_factory.mktemp("strided") / "model"
    shutil.copytree(model, strided)
    with pytest.MonkeyPatch.context() as env:
        env.setenv("ODMO_CACHE_DIR", str(strided.parent / "cache"))
        argv = [
            "bank",
            "--model",
            str(strided),
            "--data",
            str(data),
            "--projections",
            "pca",
            "--stride",
            "20",
        ]
        assert cli.main(argv) == 0
    return strided


def test_a_long_clip_is_a_path_of_codes_that_plays_in_time_order(
    qtbot, open_explorer, strided_model, model_and_data
):
    _, data = model_and_data
    opened: Opened = open_explorer(strided_model)
    window, c = opened.window, opened.controller
    qtbot.waitUntil(lambda: c.state.model is not None, timeout=60_000)
    c.loader.open_data(data)
    qtbot.waitUntil(lambda: c.state.data_dir is not None, timeout=60_000)
    embedding = c.state.embedding

    def latest_window(source: str) -> int:
        rows = np.flatnonzero(c.bank.sources == source)
        return int(rows[np.argmax([c.bank.meta[i]["window_start"] for i in rows])])

    def clearance(i: int) -> float:  # map distance to the nearest other code: a click must pick this one
        gaps = np.linalg.norm(embedding - embedding[i], axis=1)
        return float(np.delete(gaps, i).min())

    long_clips = sorted(s for s in set(c.bank.sources) if (c.bank.sources == s).sum() >= 3)
    assert long_clips
    late = max((latest_window(s) for s in long_clips), key=clearance)
    source = c.bank.sources[late]
    rows = np.flatnonzero(c.bank.sources == source)
    click_map(qtbot, opened, c.state.embedding[late])
    # wait for this click's decode, not for any earlier one still arriving (e.g. the data's re-show)
    qtbot.waitUntil(lambda: len(c.state.shown) == 2 and c.state.shown[0].bank_index == late, timeout=30_000)
    _, real = (d.motion for d in c.state.shown)
    start = c.bank.meta[late]["window_start"]
    assert real.meta["window_start"] == start > 0  # the clicked window of the clip, not its centre
    clip = read_motion(data / source).joints[start : start + c.generator.window]
    np.testing.assert_allclose(_distances(real.joints), _distances(clip), atol=1e-4)

    window.select_clip_action.trigger()
    starts = [c.bank.meta[i]["window_start"] for i in c.state.selection]
    assert sorted(c.state.selection) == sorted(rows) and starts == sorted(starts)
    window.layout_combo.setCurrentIndex(window.layout_combo.findData("sequence"))
    with qtbot.waitSignal(c.shownChanged, timeout=60_000):
        window.play_selection_action.trigger()
    played = [d.bank_index for d in c.state.shown]
    assert played == list(c.state.selection)[: len(played)] and len(played) == min(len(rows), 12)
    [chained] = c.playback.played  # in sequence: one motion, each window starting where the last ended
    step = np.linalg.norm(np.diff(chained.joints[:, chained.skeleton.root, [0, 2]], axis=0), axis=1)
    assert chained.n_frames == sum(d.motion.n_frames for d in c.state.shown)
    assert step.max() < 0.2, "the skeleton jumps between windows"
