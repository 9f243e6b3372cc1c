"""Exports: motions (BVH / NPZ through the engine writers), map PNGs and time-lapse PNG strips.

Every export carries its provenance (model, code, action, mode, end location, seed): in ``Motion.meta``
for motion files, as PNG text chunks for images. Files are written atomically; when one file of a
multi-file export fails, the files already written by that export are removed.
"""

from __future__ import annotations

import contextlib
import json
import logging
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np
from PySide6.QtCore import QBuffer, QByteArray, QIODevice, QPointF, Qt
from PySide6.QtGui import QColor, QFont, QImage, QPainter, QPen
from PySide6.QtWidgets import QWidget

from engine.errors import ConfigError
from engine.fileio import atomic_write_bytes
from engine.motion.bvh import provenance_path
from engine.motion.formats import write_motion
from engine.motion.motion import Motion
from explorer.state import Decoded

log = logging.getLogger(__name__)

MOTION_SUFFIXES = (".bvh", ".npz")


def motion_with_provenance(item: Decoded, model_path: str) -> Motion:
    """A copy of ``item.motion`` whose meta records model, code, action, mode, end and seed."""
    meta = dict(item.motion.meta)
    meta.update(item.metadata(model_path))
    return Motion(
        joints=item.motion.joints,
        fps=item.motion.fps,
        skeleton=item.motion.skeleton,
        local_rotations=item.motion.local_rotations,
        root_translation=item.motion.root_translation,
        action=item.motion.action,
        meta=meta,
    )


def numbered_paths(path: Path, n: int) -> list[Path]:
    """``path`` itself for one item, else ``stem_000.ext``, ``stem_001.ext``, ... beside it."""
    if n == 1:
        return [path]
    return [path.with_name(f"{path.stem}_{i:03d}{path.suffix}") for i in range(n)]


def export_motions(items: Sequence[Decoded], path: str | Path, model_path: str) -> list[Path]:
    """Write each motion to ``path`` (numbered when several) as BVH or NPZ; all or nothing."""
    path = Path(path)
    if path.suffix.lower() not in MOTION_SUFFIXES:
        raise ConfigError(f"{path}: export a motion as .bvh or .npz, not {path.suffix or 'no extension'!r}")
    if not items:
        raise ConfigError("nothing to export: no motion is shown or selected")
    targets = numbered_paths(path, len(items))
    written: list[Path] = []
    try:
        for item, target in zip(items, targets, strict=True):
            write_motion(motion_with_provenance(item, model_path), target)
            written.append(target)
    except BaseException:
        for done in written:
            for file in (done, provenance_path(done)):
                with contextlib.suppress(OSError):
                    file.unlink()
        raise
    log.info("exported %d motion(s) to %s", len(written), path)
    return written


def png_bytes(image: QImage, meta: dict[str, Any]) -> bytes:
    """``image`` encoded as PNG with ``meta`` stored as text chunks (JSON values)."""
    image = image.copy()
    for key, value in meta.items():
        image.setText(str(key), value if isinstance(value, str) else json.dumps(value))
    data = QByteArray()
    buffer = QBuffer(data)
    buffer.open(QIODevice.OpenModeFlag.WriteOnly)
    if not image.save(buffer, "PNG"):
        raise OSError("PNG encoding failed")
    buffer.close()
    return bytes(data.data())


def save_png(image: QImage, path: str | Path, meta: dict[str, Any]) -> Path:
    """Write ``image`` to ``path`` as a PNG with ``meta`` text chunks, atomically."""
    path = Path(path)
    if path.suffix.lower() != ".png":
        raise ConfigError(f"{path}: images are exported as .png")
    atomic_write_bytes(path, png_bytes(image, meta))
    return path


def save_widget_png(widget: QWidget, path: str | Path, meta: dict[str, Any]) -> Path:
    """Render ``widget`` (e.g. the latent map) to a PNG at ``path``."""
    return save_png(widget.grab().toImage(), path, meta)


def timelapse_frames(n_frames: int, count: int) -> np.ndarray:
    """(min(count, n_frames),) evenly spaced frame indices, first and last included."""
    count = max(1, min(int(count), int(n_frames)))
    return np.unique(np.round(np.linspace(0, n_frames - 1, count)).astype(int))


TRAVEL_MIN_M = 0.3  # below this the poses are drawn one per panel (they would overlap on the path)


def travel_direction(motion: Motion) -> tuple[np.ndarray, float]:
    """Unit floor direction (x, z) from the root's first to last position, and that distance (m)."""
    root = motion.joints[:, motion.skeleton.root][:, [0, 2]].astype(np.float64)
    delta = root[-1] - root[0]
    distance = float(np.linalg.norm(delta))
    return (delta / distance if distance > 1e-9 else np.array([1.0, 0.0])), distance


def timelapse_image(
    motion: Motion, count: int = 8, panel: int = 180, title: str = "", upto: int | None = None
) -> QImage:
    """``count`` poses of ``motion`` seen from the side of its travel: a pose is drawn where the body is
    along the path (the horizontal axis is the distance travelled), so the strip shows progress; a
    motion that stays in place gets one panel per pose instead. With ``upto``, only the poses up to
    that frame are drawn (same layout), which makes the frames of a time-lapse video."""
    frames = timelapse_frames(motion.n_frames, count)
    joints = motion.joints[frames].astype(np.float64)
    parents = motion.skeleton.parents
    root = motion.skeleton.root
    direction, distance = travel_direction(motion)
    along = joints[:, :, [0, 2]] @ direction  # (F, J) distance along the travel
    along -= joints[:1, root, [0, 2]] @ direction
    spread = distance >= TRAVEL_MIN_M
    if not spread:  # one panel per pose, each centred on its root
        along = along - along[:, root : root + 1] + (np.arange(len(frames)) * 1.0)[:, None]
    floor = float(min(0.0, motion.joints[:, :, 1].min()))
    height = max(float(motion.joints[:, :, 1].max()) - floor, 1e-3)
    header = 28 if title else 0
    margin, footer = 14, 18
    width_px = panel * len(frames)
    span = max(float(along.max() - along.min()), 1e-3)
    scale = min((width_px - 2 * margin - 40) / span, (panel - 2 * margin - footer) / height)
    left = margin + 20 - float(along.min()) * scale
    image = QImage(width_px, panel + header, QImage.Format.Format_RGB32)
    image.fill(QColor("#1e1f22"))
    painter = QPainter(image)
    painter.setRenderHint(QPainter.RenderHint.Antialiasing)
    painter.setFont(QFont("Sans", 9))
    if title:
        painter.setPen(QColor("#d0d0d0"))
        painter.drawText(8, 0, image.width() - 16, header, Qt.AlignmentFlag.AlignVCenter, title)
    floor_y = header + panel - margin - footer
    painter.setPen(QPen(QColor("#5a5d63"), 1))
    painter.drawLine(QPointF(6, floor_y), QPointF(width_px - 6, floor_y))
    for k, frame in enumerate(frames):
        if upto is not None and frame > upto:
            break

        def to_px(j: int, k: int = k) -> QPointF:
            return QPointF(left + along[k, j] * scale, floor_y - (joints[k, j, 1] - floor) * scale)

        shade = 0.45 + 0.55 * (k + 1) / len(frames)  # later poses brighter: the direction of time
        bone = QColor.fromRgbF(0.31 * shade, 0.47 * shade, 0.65 * shade + 0.2 * (1 - shade))
        painter.setPen(QPen(bone, 2.5))
        for j, p in enumerate(parents):
            if p >= 0:
                painter.drawLine(to_px(int(p)), to_px(j))
        painter.setPen(QPen(QColor("#f28e2b"), 4))
        for j in range(len(parents)):
            painter.drawPoint(to_px(j))
        painter.setPen(QColor("#d0d0d0"))
        x = to_px(root).x()
        painter.drawText(
            int(x - 40), int(floor_y + 2), 80, 16, Qt.AlignmentFlag.AlignCenter, f"{frame / motion.fps:.2f}s"
        )
    if spread:
        painter.setPen(QColor("#a0a0a0"))
        painter.drawText(8, header + 4, width_px - 16, 16, Qt.AlignmentFlag.AlignRight,
                         f"side view: {distance:.2f} m travelled →")  # fmt: skip
    painter.end()
    return image


def qimage_rgb(image: QImage) -> np.ndarray:
    """(H, W, 3) uint8 RGB pixels of ``image``."""
    rgb = image.convertToFormat(QImage.Format.Format_RGB888)
    data = np.frombuffer(rgb.constBits(), np.uint8, rgb.sizeInBytes()).reshape(
        rgb.height(), rgb.bytesPerLine()
    )
    return data[:, : rgb.width() * 3].reshape(rgb.height(), rgb.width(), 3).copy()


def timelapse_video_frames(motion: Motion, count: int = 8, title: str = "") -> list[np.ndarray]:
    """One (H, W, 3) image per frame of ``motion``: the time-lapse drawn up to that frame."""
    return [qimage_rgb(timelapse_image(motion, count, title=title, upto=f)) for f in range(motion.n_frames)]


def save_timelapse(item: Decoded, path: str | Path, model_path: str, count: int = 8) -> Path:
    """Write a time-lapse PNG strip of ``item``'s motion with its provenance as text chunks."""
    title = f"{item.label}  ·  {item.motion.n_frames} frames @ {item.motion.fps:g} fps"
    return save_png(timelapse_image(item.motion, count, title=title), path, item.metadata(model_path))
