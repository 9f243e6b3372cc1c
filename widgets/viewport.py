"""SkeletonViewport: n stick-figure skeletons on a floor grid, updated in place (pyvistaqt)."""

from __future__ import annotations

from collections.abc import Sequence
from typing import Literal

import numpy as np
import pyvista as pv
from PySide6.QtGui import QCloseEvent
from PySide6.QtWidgets import QVBoxLayout, QWidget
from pyvistaqt import QtInteractor

from widgets._colors import ACCENT, BACKGROUND, GENERATED, GHOST, GRID, palette_rgb

Layout = Literal["overlay", "side_by_side"]


def _bone_cells(parents: np.ndarray, n: int) -> np.ndarray:
    """VTK line cells ``[2, parent, child, ...]`` for ``n`` copies of the tree ``parents`` (J,)."""
    n_joints = len(parents)
    child = np.flatnonzero(parents >= 0)
    pairs = np.stack([parents[child], child], axis=1)
    copies = pairs[None, :, :] + (np.arange(n) * n_joints)[:, None, None]
    cells = np.concatenate([np.full((n * len(pairs), 1), 2), copies.reshape(-1, 2)], axis=1)
    return cells.reshape(-1).astype(np.int64)


def _stick_figures(parents: np.ndarray, joints: np.ndarray) -> pv.PolyData:
    """Line mesh of skeletons with joint positions ``joints`` (n, J, 3)."""
    points = np.ascontiguousarray(joints.reshape(-1, 3), dtype=np.float32)
    return pv.PolyData(points, lines=_bone_cells(parents, len(joints)))


def _floor_grid(size: float, step: float) -> pv.PolyData:
    """Grid lines on the floor (y = 0), ``size`` metres across, one line every ``step`` metres."""
    ticks = np.arange(-size / 2, size / 2 + step / 2, step)
    ends = np.full_like(ticks, size / 2)
    zeros = np.zeros_like(ticks)
    along_z = np.stack([np.c_[ticks, zeros, -ends], np.c_[ticks, zeros, ends]], axis=1)
    along_x = np.stack([np.c_[-ends, zeros, ticks], np.c_[ends, zeros, ticks]], axis=1)
    points = np.concatenate([along_z, along_x]).reshape(-1, 3).astype(np.float32)
    pairs = np.arange(len(points)).reshape(-1, 2)
    return pv.PolyData(points, lines=np.c_[np.full(len(pairs), 2), pairs].reshape(-1))


class SkeletonViewport(QWidget):
    """A 3-D view of ``n`` skeletons (y up) whose poses are updated in place, plus path, end and ghosts."""

    def __init__(
        self, parent: QWidget | None = None, *, floor_size: float = 10.0, multi_samples: int = 0
    ) -> None:
        """Create the view; ``multi_samples`` > 0 turns on MSAA (cheap on a GPU, slow in software GL)."""
        super().__init__(parent)
        self.plotter = QtInteractor(self, auto_update=False, multi_samples=multi_samples)
        self.plotter.set_background(BACKGROUND)
        layout = QVBoxLayout(self)
        layout.setContentsMargins(0, 0, 0, 0)
        layout.addWidget(self.plotter.interactor)

        self.plotter.add_mesh(_floor_grid(floor_size, 0.5), color=GRID, pickable=False)
        self._parents = np.zeros(0, dtype=np.int64)
        self._n = 0
        self._spacing = 1.0
        self._layout: Layout = "overlay"
        self._offsets = np.zeros((0, 3), dtype=np.float32)
        self._poses = np.zeros((0, 0, 3), dtype=np.float32)
        self._mesh: pv.PolyData | None = None
        self._actors: list[object] = []
        self._trajectory_actor: object | None = None
        self._ghost_actor: object | None = None
        self._end_actor = self.plotter.add_mesh(
            pv.Sphere(radius=0.06, center=(0.0, 0.0, 0.0)), color=GENERATED, pickable=False
        )
        self._end_actor.SetVisibility(False)
        self._follow = False
        self._follow_anchor: np.ndarray | None = None
        self._closed = False
        self.reset_camera()

    # ----- skeletons ----------------------------------------------------------------------------
    def set_skeletons(self, parents: Sequence[int] | np.ndarray, n: int) -> None:
        """Build bones and joints for ``n`` skeletons of the tree ``parents`` (J,) int, -1 for the root."""
        parents = np.asarray(parents, dtype=np.int64).reshape(-1)
        if parents.size == 0 or np.count_nonzero(parents < 0) != 1 or np.any(parents >= len(parents)):
            raise ValueError("parents must be a tree: one root (-1) and indices below J")
        if n < 1:
            raise ValueError(f"need at least one skeleton, got {n}")
        for actor in self._actors:
            self.plotter.remove_actor(actor, render=False)
        self._parents, self._n = parents, int(n)
        self._poses = np.zeros((n, len(parents), 3), dtype=np.float32)
        self._mesh = _stick_figures(parents, self._poses)
        self._mesh.point_data["rgb"] = np.repeat(palette_rgb(n), len(parents), axis=0)
        self._actors = [
            self.plotter.add_mesh(
                self._mesh, scalars="rgb", rgb=True, line_width=4, pickable=False, reset_camera=False
            ),
            self.plotter.add_mesh(
                self._mesh,
                scalars="rgb",
                rgb=True,
                style="points",
                point_size=9,
                render_points_as_spheres=True,
                pickable=False,
                reset_camera=False,
            ),
        ]
        self._follow_anchor = None
        self._apply_layout()

    def set_poses(self, poses: np.ndarray) -> None:
        """Move the skeletons to joint positions ``poses`` (n, J, 3) metres, in place (no rebuild)."""
        poses = np.asarray(poses, dtype=np.float32)
        if self._mesh is None or poses.shape != self._poses.shape:
            raise ValueError(f"poses must have shape {self._poses.shape} (call set_skeletons first)")
        self._poses = poses
        self._mesh.points[:] = (poses + self._offsets[:, None, :]).reshape(-1, 3)
        if self._follow:
            self._follow_root()
        self._schedule_render()

    def render_now(self) -> None:
        """Render synchronously (for timing; updates otherwise render at the next paint)."""
        if not self._closed:
            self.plotter.ren_win.Render()

    def _schedule_render(self) -> None:
        # The interactor renders in paintGL; Qt merges the update requests of one event-loop pass.
        self.plotter.interactor.update()

    def set_layout(self, layout: Layout, spacing: float = 1.0) -> None:
        """Overlay the skeletons, or place them ``spacing`` metres apart along x."""
        if layout not in ("overlay", "side_by_side"):
            raise ValueError(f"unknown layout {layout!r}; expected 'overlay' or 'side_by_side'")
        self._layout, self._spacing = layout, float(spacing)
        self._apply_layout()

    def _apply_layout(self) -> None:
        self._offsets = np.zeros((self._n, 3), dtype=np.float32)
        if self._layout == "side_by_side":
            self._offsets[:, 0] = (np.arange(self._n) - (self._n - 1) / 2) * self._spacing
        if self._mesh is not None:
            self.set_poses(self._poses)

    @property
    def offsets(self) -> np.ndarray:
        """(n, 3) layout offset of each skeleton (zeros when overlaid), metres."""
        return self._offsets.copy()

    def skeleton_points(self) -> np.ndarray:
        """Joint positions as drawn (layout offsets included), (n, J, 3)."""
        return (
            np.asarray(self._mesh.points).reshape(self._poses.shape)
            if self._mesh is not None
            else self._poses
        )

    # ----- decorations --------------------------------------------------------------------------
    def set_trajectory(self, polyline: np.ndarray | None) -> None:
        """Draw a root path ``polyline`` (T, 3) in world coordinates; None removes it."""
        if self._trajectory_actor is not None:
            self.plotter.remove_actor(self._trajectory_actor, render=False)
            self._trajectory_actor = None
        if polyline is not None and len(polyline) >= 2:
            pts = np.asarray(polyline, dtype=np.float32).reshape(-1, 3)
            self._trajectory_actor = self.plotter.add_mesh(
                pv.lines_from_points(pts), color=ACCENT, line_width=3, pickable=False, reset_camera=False
            )
        self._schedule_render()

    def set_end_marker(self, xyz: Sequence[float] | np.ndarray | None) -> None:
        """Show a marker at the requested end location ``xyz`` (3,); None hides it."""
        if xyz is None:
            self._end_actor.SetVisibility(False)
        else:
            self._end_actor.SetPosition(*np.asarray(xyz, dtype=np.float64).reshape(3))
            self._end_actor.SetVisibility(True)
        self._schedule_render()

    def set_ghosts(self, frames: np.ndarray | None) -> None:
        """Draw faint copies of one skeleton at ``frames`` (G, J, 3) (a time-lapse trail); None clears."""
        if self._ghost_actor is not None:
            self.plotter.remove_actor(self._ghost_actor, render=False)
            self._ghost_actor = None
        if frames is not None and len(frames):
            frames = np.asarray(frames, dtype=np.float32)
            if frames.ndim != 3 or frames.shape[1:] != (len(self._parents), 3):
                raise ValueError(
                    f"ghost frames must have shape (G, {len(self._parents)}, 3), got {frames.shape}"
                )
            self._ghost_actor = self.plotter.add_mesh(
                _stick_figures(self._parents, frames),
                color=GHOST,
                line_width=2,
                pickable=False,
                reset_camera=False,
            )
        self._schedule_render()

    # ----- camera -------------------------------------------------------------------------------
    def reset_camera(self) -> None:
        """Look at the skeletons from the front-right, slightly above, y up."""
        if self._mesh is not None and self._n:
            self._look_at(self.skeleton_points().reshape(-1, 3))
        else:
            self._look_at(np.array([[-0.5, 0.0, -0.5], [0.5, 1.8, 0.5]]))

    def frame_motion(self, frames: np.ndarray) -> None:
        """Aim the camera (as ``reset_camera``) so that every frame of the skeletons stays in view.

        ``frames`` is (n, T, J, 3): each skeleton's joint positions over a whole motion, before the
        layout offsets, which are added here.
        """
        frames = np.asarray(frames, dtype=np.float64)
        if frames.ndim != 4 or frames.shape[0] != self._n or frames.shape[3] != 3:
            raise ValueError(f"frames must be ({self._n}, T, J, 3), got {frames.shape}")
        self._look_at((frames + self._offsets[:, None, None, :]).reshape(-1, 3))

    def _look_at(self, points: np.ndarray) -> None:
        """Front-right, slightly-above view of the bounding box of ``points`` (N, 3)."""
        lo, hi = points.min(0), points.max(0)
        center = (lo + hi) / 2
        extent = max(float(np.max(hi - lo)), 1.8)
        position = center + np.array([0.5, 0.35, 1.0]) * 1.6 * extent
        self.plotter.camera_position = [tuple(position), tuple(center), (0.0, 1.0, 0.0)]
        self._follow_anchor = None
        self._schedule_render()

    @property
    def follow(self) -> bool:
        """Whether the camera follows the skeletons' root (see ``set_follow``)."""
        return self._follow

    def set_follow(self, follow: bool) -> None:
        """Make the camera follow the (mean) root of the skeletons on the floor plane."""
        self._follow = bool(follow)
        self._follow_anchor = None

    def _follow_root(self) -> None:
        root = int(np.flatnonzero(self._parents < 0)[0])
        ground = self.skeleton_points()[:, root, :].mean(axis=0) * np.array([1.0, 0.0, 1.0])
        if self._follow_anchor is not None:
            shift = ground - self._follow_anchor
            camera = self.plotter.camera
            camera.position = tuple(np.asarray(camera.position) + shift)
            camera.focal_point = tuple(np.asarray(camera.focal_point) + shift)
        self._follow_anchor = ground

    # ----- lifetime -----------------------------------------------------------------------------
    def closeEvent(self, event: QCloseEvent) -> None:  # noqa: N802
        """Finalise the VTK plotter before the widget goes away."""
        self._closed = True
        self.plotter.close()
        super().closeEvent(event)
