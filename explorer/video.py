"""Write frames (H, W, 3) uint8 as an MP4 (imageio-ffmpeg's bundled ffmpeg) or a GIF (Pillow), atomically.

A temporary file in the target folder is written and moved into place only when complete, so a failed
or cancelled export leaves nothing behind.
"""

from __future__ import annotations

import contextlib
import io
import os
import subprocess
from collections.abc import Iterable
from pathlib import Path

import numpy as np

from engine.errors import ConfigError
from engine.fileio import atomic_write_bytes

VIDEO_SUFFIXES = (".mp4", ".gif")


def _even(frame: np.ndarray) -> np.ndarray:
    """``frame`` cropped to even width and height (H.264 in yuv420p needs both)."""
    h, w = frame.shape[:2]
    return np.ascontiguousarray(frame[: h - h % 2, : w - w % 2, :3])


def write_gif(frames: Iterable[np.ndarray], path: Path, fps: float) -> Path:
    """Write ``frames`` as a looping GIF at ``fps``."""
    from PIL import Image

    images = [Image.fromarray(np.asarray(f, dtype=np.uint8)[..., :3]) for f in frames]
    if not images:
        raise ConfigError("no frames to write")
    buffer = io.BytesIO()
    first = images[0].quantize(colors=128)
    rest = [im.quantize(palette=first) for im in images[1:]]
    first.save(buffer, format="GIF", save_all=True, append_images=rest, duration=round(1000 / fps), loop=0)
    atomic_write_bytes(path, buffer.getvalue())
    return path


def write_mp4(frames: Iterable[np.ndarray], path: Path, fps: float) -> Path:
    """Write ``frames`` as an H.264 MP4 at ``fps`` through the ffmpeg that imageio-ffmpeg ships;
    ConfigError when it is not installed, OSError when ffmpeg fails."""
    try:
        import imageio_ffmpeg
    except ImportError as exc:
        raise ConfigError("MP4 export needs imageio-ffmpeg (pip install imageio-ffmpeg)") from exc
    frames = [_even(np.asarray(f, dtype=np.uint8)) for f in frames]
    if not frames:
        raise ConfigError("no frames to write")
    h, w = frames[0].shape[:2]
    tmp = path.with_name(f".{path.stem}.{os.getpid()}.tmp.mp4")
    command = [
        imageio_ffmpeg.get_ffmpeg_exe(), "-y", "-loglevel", "error", "-f", "rawvideo", "-pix_fmt", "rgb24",
        "-s", f"{w}x{h}", "-r", f"{fps:g}", "-i", "-", "-an", "-c:v", "libx264", "-pix_fmt", "yuv420p",
        "-movflags", "+faststart", str(tmp),
    ]  # fmt: skip
    try:
        done = subprocess.run(
            command, input=b"".join(f.tobytes() for f in frames), capture_output=True, check=False
        )
        if done.returncode != 0:
            raise OSError(f"{path}: ffmpeg failed: {done.stderr.decode(errors='replace').strip()[-300:]}")
        os.replace(tmp, path)
    except BaseException:
        with contextlib.suppress(OSError):
            tmp.unlink()
        raise
    return path


def write_video(frames: Iterable[np.ndarray], path: str | Path, fps: float) -> Path:
    """Write ``frames`` to ``path`` as MP4 or GIF, chosen by its extension."""
    path = Path(path)
    suffix = path.suffix.lower()
    if suffix not in VIDEO_SUFFIXES:
        raise ConfigError(f"{path}: export a video as .mp4 or .gif, not {suffix or 'no extension'!r}")
    if not path.parent.is_dir():
        raise ConfigError(f"{path.parent}: no such folder")
    return write_mp4(frames, path, fps) if suffix == ".mp4" else write_gif(frames, path, fps)
