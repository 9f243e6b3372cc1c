"""Issue 12 exports: video (MP4 / GIF) of the 3-D view, the plain map PNG, the side-view time-lapse."""

from __future__ import annotations

import re
import subprocess
from pathlib import Path

import numpy as np
import pytest
from PySide6.QtGui import QImage

from explorer.export import timelapse_image
from explorer.exporting import suggested_name
from tests.explorer.conftest import Opened, close_message_boxes


def _play(qtbot, opened: Opened, index: int) -> None:
    with qtbot.waitSignal(opened.controller.shownChanged, timeout=20_000):
        opened.controller.gestures.click_point(index)


def _walker(opened: Opened) -> int:
    bank = opened.controller.bank
    reach = np.linalg.norm(bank.ends[:, [0, 2]], axis=1)
    return int(np.argmax(reach))


def _read_mp4(path: Path) -> tuple[list[np.ndarray], tuple[int, int]]:
    """Decode an MP4 with the bundled ffmpeg: its frames (H, W, 3) and size (W, H)."""
    import imageio_ffmpeg

    exe = imageio_ffmpeg.get_ffmpeg_exe()
    probe = subprocess.run([exe, "-i", str(path)], capture_output=True, text=True, check=False)
    w, h = map(int, re.search(r"Video:.*?(\d{2,5})x(\d{2,5})", probe.stderr).groups())
    raw = subprocess.run(
        [exe, "-loglevel", "error", "-i", str(path), "-f", "rawvideo", "-pix_fmt", "rgb24", "-"],
        capture_output=True, check=True,
    ).stdout  # fmt: skip
    data = np.frombuffer(raw, np.uint8).reshape(-1, h, w, 3)
    return list(data), (w, h)


def test_mp4_and_gif_hold_every_frame_of_the_3d_view(qtbot, explorer: Opened, tmp_path: Path) -> None:
    c = explorer.controller
    _play(qtbot, explorer, _walker(explorer))
    motion = c.state.shown[0].motion
    mp4 = c.exporter.export_video(tmp_path / "walk.mp4")
    assert mp4 == tmp_path / "walk.mp4"
    frames, (w, h) = _read_mp4(mp4)
    assert len(frames) == motion.n_frames
    assert w % 2 == 0 and h % 2 == 0 and w >= 200
    assert np.abs(frames[0].astype(int) - frames[-1].astype(int)).mean() > 0.2, "the skeleton moves"
    from PIL import Image

    gif = c.exporter.export_video(tmp_path / "walk.gif")
    with Image.open(gif) as image:  # (GIF merges identical consecutive frames: count the play time)
        total = 0
        for k in range(image.n_frames):
            image.seek(k)
            total += image.info["duration"]
        assert total == pytest.approx(motion.n_frames * 1000 / motion.fps, rel=0.05)
        assert image.n_frames > motion.n_frames // 2
    assert sorted(p.name for p in tmp_path.iterdir()) == ["walk.gif", "walk.mp4"]


def test_video_export_to_an_unwritable_place_says_so_and_leaves_nothing(
    qtbot, explorer: Opened, tmp_path: Path
) -> None:
    c = explorer.controller
    _play(qtbot, explorer, 0)
    blocked = tmp_path / "a_file"
    blocked.write_text("not a folder")
    taken = tmp_path / "taken.mp4"
    taken.mkdir()  # a folder where the video should go: the final move fails
    for target in (blocked / "clip.mp4", taken, tmp_path / "clip.avi"):
        with qtbot.waitSignal(c.errorOccurred, timeout=30_000):
            assert c.exporter.export_video(target) is None
    assert close_message_boxes()
    assert sorted(p.name for p in tmp_path.iterdir()) == ["a_file", "taken.mp4"]
    assert list(taken.iterdir()) == []
    assert explorer.window.isVisible() and explorer.window.timeline.is_playing()


def test_map_png_is_the_plot_alone_at_the_chosen_width(qtbot, explorer: Opened, tmp_path: Path) -> None:
    c, w = explorer.controller, explorer.window
    assert w.latent_map.axis_names() == ("PCA 1", "PCA 2")
    path = c.exporter.export_map(tmp_path / "map.png", width=1200)
    image = QImage(str(path))
    assert image.width() == 1200
    plot = w.latent_map.plot
    assert image.height() == pytest.approx(1200 * plot.height() / plot.width(), abs=3)
    assert image.text("projection") == "pca"


def test_suggested_file_names_come_from_the_label() -> None:
    assert (
        suggested_name("#12 data/dataset-2_walk_01.bvh (decoded)", ".bvh")
        == "12_dataset_2_walk_01_decoded.bvh"
    )
    assert suggested_name("", ".png") == "odmo.png"


def test_time_lapse_spreads_a_walk_along_its_path(explorer: Opened) -> None:
    c = explorer.controller
    from engine import generate

    i = _walker(explorer)
    walk = generate.decode(
        c.generator.loaded, c.bank.codes[i], int(c.bank.actions[i]), c.bank.ends[i : i + 1]
    )
    standing = walk.with_joints(np.repeat(walk.joints[:1], walk.n_frames, axis=0))

    def bone_columns(image: QImage) -> np.ndarray:
        cols = []
        for x in range(0, image.width(), 2):
            if any(image.pixelColor(x, y).blue() > 90 and image.pixelColor(x, y).red() < 90
                   for y in range(30, image.height() - 20, 3)):  # fmt: skip
                cols.append(x)
        return np.asarray(cols)

    moving = bone_columns(timelapse_image(walk, 6, title="walk"))
    assert np.ptp(moving) > 0.5 * 6 * 180, "the poses are spread along the path"
    still = timelapse_image(standing, 6, title="still")
    assert still.width() == 6 * 180


def test_time_lapse_video_grows_pose_by_pose(qtbot, explorer: Opened, tmp_path: Path) -> None:
    c = explorer.controller
    _play(qtbot, explorer, _walker(explorer))
    motion = c.state.shown[0].motion
    gif = c.exporter.export_timelapse_video(tmp_path / "strip.gif")
    from PIL import Image

    with Image.open(gif) as image:
        # GIF merges repeated frames into longer ones: the play time is the motion's, one step per new pose
        durations = []
        for k in range(image.n_frames):
            image.seek(k)
            durations.append(image.info["duration"])
        assert sum(durations) == pytest.approx(motion.n_frames * 1000 / motion.fps, rel=0.05)
        assert 2 <= image.n_frames <= 9
        image.seek(0)
        first = np.asarray(image.convert("RGB"), dtype=int)
        image.seek(image.n_frames - 1)
        last = np.asarray(image.convert("RGB"), dtype=int)
    # more of the strip is drawn at the end than at the start
    assert (np.abs(last - 30).sum(axis=2) > 60).sum() > 2 * (np.abs(first - 30).sum(axis=2) > 60).sum()
