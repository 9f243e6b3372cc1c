"""SkeletonViewport: n stick-figure skeletons on a floor grid, updated in place (pyvistaqt)."""

from __future__ import annotations

from collections.abc import Sequence
from typing import Literal

import numpy as np
import pyvista as pv
from PySide6.QtCore import QEvent, QObject
from PySide6.QtGui import QCloseEvent, QResizeEvent
from PySide6.QtWidgets import QVBoxLayout, QWidget
from pyvistaqt import QtInteractor
from vtkmodules.vtkRenderingCore import vtkTextActor

from widgets._colors import ACCENT, BACKGROUND, GENERATED, GHOST, GRID, palette_rgb

Layout = Literal["overlay", "side_by_side"]
VIEW_MARGIN = 0.9  # framed points stay within this fraction of the view's half-width and half-height
LABEL_LIFT = 0.25  # metres above a skeleton's highest joint where its label is drawn


class _NoVtkKeys(QObject):
    """Event filter that keeps key presses from VTK's interactor style (3: stereo, w: wireframe, …)."""

    def eventFilter(self, watched: QObject, event: QEvent) -> bool:  # noqa: N802
        """Swallow key presses and releases; let everything else through."""
        return event.type() in (QEvent.Type.KeyPress, QEvent.Type.KeyRelease)


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
        self, parent: QWidget | None = None, *, floor_size: float = 30.0, multi_samples: int = 0
    ) -> None:
        """Create the view; ``multi_samples`` > 0 turns on MSAA (cheap on a GPU, slow in software GL)."""
        super().__init__(parent)
        self.plotter = QtInteractor(self, auto_update=False, multi_samples=multi_samples)
        self.plotter.set_background(BACKGROUND)
        layout = QVBoxLayout(self)
        layout.setContentsMargins(0, 0, 0, 0)
        layout.addWidget(self.plotter.interactor)
        self._key_filter = _NoVtkKeys(self)
        self.plotter.interactor.installEventFilter(self._key_filter)

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
        self._trajectory = np.zeros((0, 3))
        self._ghosts = np.zeros((0, 0, 3))
        self._end_actor = self.plotter.add_mesh(
            pv.Sphere(radius=0.06, center=(0.0, 0.0, 0.0)), color=GENERATED, pickable=False
        )
        self._end_actor.SetVisibility(False)
        self._follow = False
        self._follow_anchor: np.ndarray | None = None
        self._framed: np.ndarray | None = None  # the points the camera was last aimed at
        self._labels: list[str] = []
        self._label_actors: list[object] = []
        self._closed = False
        self.plotter.renderer.AddObserver("StartEvent", self._place_labels)
        self.reset_camera()

    # ----- skeletons ----------------------------------------------------------------------------
    def set_skeletons(self, parents: Sequence[int] | np.ndarray, n: int) -> None:
        """Build bones and joints for ``n`` skeletons of the tree ``parents`` (J,) int, -1 for the root."""
        parents = np.asarray(parents, dtype=np.int64).reshape(-1)
        if parents.size == 0 or np.count_nonzero(parents < 0) != 1 or np.any(parents >= len(parents)):
            raise ValueError("parents must be a tree: one root (-1) and indices below J")
        if n < 1:
            raise ValueError(f"need at least one skeleton, got {n}")
        for actor in self._label_actors:  # first: a render during the rebuild must not see old labels
            self.plotter.renderer.RemoveViewProp(actor)
        self._label_actors, self._labels = [], []
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
        for actor in self._actors:
            actor.SetVisibility(False)  # no stray dot at the origin before the first pose
        self._follow_anchor = None
        self._apply_layout()

    def set_colors(self, rgb: np.ndarray) -> None:
        """Colour each skeleton: ``rgb`` (n, 3) uint8, one row per skeleton."""
        rgb = np.asarray(rgb, dtype=np.uint8).reshape(-1, 3)
        if self._mesh is None or len(rgb) != self._n:
            raise ValueError(f"need {self._n} colours (call set_skeletons first), got {len(rgb)}")
        if np.array_equal(rgb, self.colors()):
            return  # unchanged (every live decode of a drag sets them): no new colour buffer
        self._mesh.point_data["rgb"] = np.repeat(rgb, len(self._parents), axis=0)
        self._schedule_render()

    def colors(self) -> np.ndarray:
        """(n, 3) uint8 colour of each skeleton."""
        if self._mesh is None:
            return np.zeros((0, 3), dtype=np.uint8)
        return np.asarray(self._mesh.point_data["rgb"]).reshape(self._n, -1, 3)[:, 0].copy()

    def set_poses(self, poses: np.ndarray) -> None:
        """Move the skeletons to joint positions ``poses`` (n, J, 3) metres, in place (no rebuild)."""
        poses = np.asarray(poses, dtype=np.float32)
        if self._mesh is None or poses.shape != self._poses.shape:
            raise ValueError(f"poses must have shape {self._poses.shape} (call set_skeletons first)")
        self._poses = poses
        self._mesh.points[:] = (poses + self._offsets[:, None, :]).reshape(-1, 3)
        for actor in self._actors:
            actor.SetVisibility(True)
        self._place_labels()
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
            self._mesh.points[:] = (self._poses + self._offsets[:, None, :]).reshape(-1, 3)
            self._place_labels()
            self._schedule_render()

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
        self._trajectory = np.zeros((0, 3))
        if polyline is not None and len(polyline) >= 2:
            pts = np.asarray(polyline, dtype=np.float32).reshape(-1, 3)
            self._trajectory = pts
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
        self._ghosts = np.zeros((0, len(self._parents), 3))
        if frames is not None and len(frames):
            frames = np.asarray(frames, dtype=np.float32)
            if frames.ndim != 3 or frames.shape[1:] != (len(self._parents), 3):
                raise ValueError(
                    f"ghost frames must have shape (G, {len(self._parents)}, 3), got {frames.shape}"
                )
            self._ghosts = frames
            self._ghost_actor = self.plotter.add_mesh(
                _stick_figures(self._parents, frames),
                color=GHOST,
                line_width=2,
                pickable=False,
                reset_camera=False,
            )
        self._schedule_render()

    def trajectory_points(self) -> np.ndarray:
        """(T, 3) root path as drawn (empty when none)."""
        return self._trajectory.copy()

    def ghost_frames(self) -> np.ndarray:
        """(G, J, 3) ghost poses as drawn (G = 0 when none)."""
        return self._ghosts.copy()

    def end_marker(self) -> np.ndarray | None:
        """(3,) position of the end marker, or None when it is hidden."""
        if not self._end_actor.GetVisibility():
            return None
        return np.asarray(self._end_actor.GetPosition(), dtype=np.float64)

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
        """Front-right, slightly-above view of ``points`` (N, 3), as close as keeps each one in view.

        The camera looks at the centre of the points' bounding box along a fixed direction; its distance
        is the smallest at which every point lies within ``VIEW_MARGIN`` of the view's half-width and
        half-height, for the view angle and the widget's current aspect ratio.
        """
        points = np.asarray(points, dtype=np.float64).reshape(-1, 3)
        lo, hi = points.min(0), points.max(0)
        center = (lo + hi) / 2
        back = np.array([0.5, 0.35, 1.0])
        back /= np.linalg.norm(back)
        up = np.array([0.0, 1.0, 0.0])
        right = np.cross(up, back)
        right /= np.linalg.norm(right)
        true_up = np.cross(back, right)
        rel = points - center
        x, y, depth = rel @ right, rel @ true_up, rel @ back
        tan_v = np.tan(np.radians(self.plotter.camera.view_angle) / 2) * VIEW_MARGIN
        tan_h = tan_v * self._aspect()
        distance = float(np.max(np.maximum(depth + np.abs(x) / tan_h, depth + np.abs(y) / tan_v)))
        distance = max(distance, float(np.max(depth)) + 0.5, 2.5)
        position = center + back * distance
        self.plotter.camera_position = [tuple(position), tuple(center), (0.0, 1.0, 0.0)]
        self.plotter.renderer.ResetCameraClippingRange()
        self._framed = points
        self._follow_anchor = None
        self._schedule_render()

    def _aspect(self) -> float:
        """Width / height of the 3-D view in pixels."""
        widget = self.plotter.interactor
        return max(widget.width(), 1) / max(widget.height(), 1)

    def project(self, points: np.ndarray) -> np.ndarray:
        """(N, 2) normalised view coordinates (-1..1 across the view) of world ``points`` (N, 3);
        a point behind the camera gets inf."""
        pts = np.asarray(points, dtype=np.float64).reshape(-1, 3)
        matrix = self.plotter.camera.GetCompositeProjectionTransformMatrix(self._aspect(), -1.0, 1.0)
        m = np.array([[matrix.GetElement(i, j) for j in range(4)] for i in range(4)])
        h = np.c_[pts, np.ones(len(pts))] @ m.T
        w = h[:, 3:4]
        return np.where(w > 1e-9, h[:, :2] / np.where(w > 1e-9, w, 1.0), np.inf)

    def in_view(self, points: np.ndarray) -> bool:
        """Whether every world point (N, 3) projects inside the view."""
        return bool(np.all(np.abs(self.project(points)) <= 1.0))

    def keep_in_view(self, frames: np.ndarray) -> bool:
        """Re-aim the camera (as ``frame_motion``) only if part of ``frames`` (n, T, J, 3) is out of view;
        True when it moved."""
        frames = np.asarray(frames, dtype=np.float64)
        if self._follow or self.in_view((frames + self._offsets[:, None, None, :]).reshape(-1, 3)):
            return False
        self.frame_motion(frames)
        return True

    def resizeEvent(self, event: QResizeEvent) -> None:  # noqa: N802
        """Keep what was framed in view when the widget's aspect ratio changes."""
        super().resizeEvent(event)
        if self._framed is not None and not self._follow and not self._closed:
            self._look_at(self._framed)

    # ----- labels -------------------------------------------------------------------------------
    def set_labels(self, labels: Sequence[str] | None) -> None:
        """Draw ``labels`` (one per skeleton) above the skeletons' heads; None or [] removes them.

        They are 2-D text actors placed, before every render, where the point ``LABEL_LIFT`` above each
        head projects (3-D billboard text costs ~4 ms a label per frame in software GL; these cost nothing).
        """
        labels = list(labels or [])
        if labels == self._labels and len(labels) == len(self._label_actors):
            return
        if labels and len(labels) != self._n:
            raise ValueError(f"expected {self._n} labels, got {len(labels)}")
        while len(self._label_actors) > len(labels):
            self.plotter.renderer.RemoveViewProp(self._label_actors.pop())
        while len(self._label_actors) < len(labels):
            actor = vtkTextActor()
            prop = actor.GetTextProperty()
            prop.SetFontSize(14)
            prop.SetJustificationToCentered()
            prop.SetColor(0.9, 0.9, 0.9)
            self.plotter.renderer.AddViewProp(actor)
            self._label_actors.append(actor)
        for actor, text in zip(self._label_actors, labels, strict=True):
            actor.SetInput(text)
        self._labels = labels
        self._place_labels()
        self._schedule_render()

    def labels(self) -> list[str]:
        """The labels drawn above the skeletons."""
        return list(self._labels)

    def label_positions(self) -> np.ndarray:
        """(n, 3) world points the labels are drawn at (empty without labels)."""
        if not self._label_actors:
            return np.zeros((0, 3))
        points = self.skeleton_points()
        tops = points[np.arange(len(points)), np.argmax(points[:, :, 1], axis=1)].astype(np.float64)
        return tops + np.array([0.0, LABEL_LIFT, 0.0])

    def _place_labels(self, *_args: object) -> None:
        """Put each label where its world point projects (called before every render)."""
        if not self._label_actors or len(self._label_actors) != len(self._poses):
            return
        width, height = self.plotter.renderer.GetSize()
        ndc = self.project(self.label_positions())
        for actor, (x, y) in zip(self._label_actors, ndc, strict=True):
            visible = bool(np.isfinite(x) and np.isfinite(y))
            actor.SetVisibility(visible)
            if visible:
                actor.SetDisplayPosition(int((x + 1) / 2 * width), int((y + 1) / 2 * height))

    @property
    def follow(self) -> bool:
        """Whether the camera follows the skeletons' root (see ``set_follow``)."""
        return self._follow

    def set_follow(self, follow: bool) -> None:
        """Make the camera follow the (mean) root of the skeletons on the floor plane; turning it on
        centres the view on that root at once (keeping the camera's direction and distance)."""
        self._follow = bool(follow)
        self._follow_anchor = None
        if self._follow and self._mesh is not None and self._actors and self._actors[0].GetVisibility():
            root = int(np.flatnonzero(self._parents < 0)[0])
            ground = self.skeleton_points()[:, root, :].mean(axis=0).astype(np.float64)
            camera = self.plotter.camera
            focal = np.asarray(camera.focal_point)
            shift = np.array([ground[0] - focal[0], 0.0, ground[2] - focal[2]])
            camera.position = tuple(np.asarray(camera.position) + shift)
            camera.focal_point = tuple(focal + shift)
            self._follow_anchor = ground * np.array([1.0, 0.0, 1.0])
            self._schedule_render()

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
