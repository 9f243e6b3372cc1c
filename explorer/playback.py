"""Playback: the only code that writes to the 3-D viewport, the timeline and the trajectory canvas."""

from __future__ import annotations

from collections.abc import Sequence
from typing import TYPE_CHECKING

import numpy as np
from PySide6.QtCore import QTimer

from engine.motion.motion import Motion
from engine.motion.ops import padded_joints, root_floor_path
from explorer.scene import action_name, build_scene
from explorer.state import Decoded

if TYPE_CHECKING:
    from explorer.controller import Controller


LIVE_INTERVAL_MS = (
    150  # during a drag: marker, root path, ghosts, canvas, timeline, status at most this often
)


class Playback:
    """Shows controller ``c``'s ``state.shown`` motions and plays them."""

    def __init__(self, c: Controller) -> None:
        self.c = c
        self.played: list[Motion] = []  # the motions in the viewport, layout applied
        self.rig: tuple[bytes, int, str] | None = None  # (parents, count, layout) of the skeleton actors
        self.shown_request = 0  # id of the newest decode request shown
        # During a drag only the poses follow every decode; the rest is throttled (see flush_live).
        self.live_timer = QTimer(c)
        self.live_timer.setSingleShot(True)
        self.live_timer.setInterval(LIVE_INTERVAL_MS)
        self.live_timer.timeout.connect(self.flush_live)
        self.live_marker: np.ndarray | None = None
        self.live_details = False
        self.keep_frame = False  # the next shown motions play on from the current frame (a continuation)

    def decoded(self, request: int, items: tuple[Decoded, ...]) -> None:
        self.shown_request = max(self.shown_request, request)
        self.c.state.shown = items

    def show_motions(self, shown: tuple[Decoded, ...]) -> None:
        """Put ``shown`` in the viewport: the poses and end marker at once; during a drag, the rest
        (root path, ghosts, trajectory canvas, timeline, status) at most every ``DETAILS_INTERVAL_MS``;
        from frame 0, unless ``keep_frame`` was set (a continuation plays on from the current frame)."""
        w = self.c.window
        keep, self.keep_frame = self.keep_frame, False
        if not shown:  # nothing to play (e.g. another model opened): the old motions stop with it
            self.played, self.rig = [], None
            w.timeline.pause()
            if w.has_viewport():  # and their root path, ghosts, end marker and labels go
                w.viewport.set_trajectory(None)
                w.viewport.set_ghosts(None)
                w.viewport.set_end_marker(None)
                w.viewport.set_labels(None)
            return
        loaded = self.c.generator
        scene = build_scene(shown, self.c.state.layout, loaded.root_height, loaded.label_names)
        played = scene.played
        self.played = played
        live = self.c.gestures.drag_from is not None
        rig = (played[0].skeleton.parents.tobytes(), len(played), self.c.state.layout)
        if rig != self.rig:  # rebuilding the actors is the slow part of an update: only when needed
            self.rig, live = rig, False
            w.viewport.set_skeletons(played[0].skeleton.parents, len(played))
            w.viewport.set_layout("overlay" if self.c.state.layout == "overlay" else "side_by_side", 1.0)
        w.viewport.set_colors(_skeleton_colors(shown, len(played), len(loaded.label_names)))
        lead = w.viewport.offsets[0]  # the end marker and root path belong to the first skeleton
        w.viewport.set_end_marker(None if scene.end is None else scene.end + lead)
        w.viewport.set_labels(scene.labels if w.labels_action.isChecked() else None)
        if live:  # keep playing from the current frame; the timeline catches up with the details
            self.set_frame(self.c.state.frame)
            self.live_details = True
            self.schedule_live()
        else:
            self.live_details = False
            self.show_details(shown, restart=not keep)
            if shown[0].code is not None:  # the Action box and the mode panel follow what plays
                self.c.state.focus_action = int(shown[0].action)
        self.c.shownChanged.emit()

    def reset_camera(self) -> None:
        """Aim the camera at the whole of what plays (every frame), as after a decode."""
        played = self.played
        if played:
            length = max(m.n_frames for m in played)
            self.c.window.viewport.frame_motion(padded_joints(played, length))
        else:
            self.c.window.viewport.reset_camera()

    def follow_camera(self, on: bool) -> None:
        self.c.window.viewport.set_follow(on)
        if not on:
            self.reset_camera()

    def schedule_live(self) -> None:
        """Flush the throttled part of a drag's updates within ``LIVE_INTERVAL_MS`` (at most that often)."""
        if not self.live_timer.isActive():
            self.live_timer.start()

    def flush_live(self) -> None:
        """The throttled part of a drag: the map marker and the details of the motion shown."""
        if self.live_marker is not None:
            self.c.state.marker, self.live_marker = self.live_marker, None
        if self.live_details:
            self.live_details = False
            self.show_details(self.c.state.shown, restart=False)

    def show_details(self, shown: tuple[Decoded, ...], restart: bool) -> None:
        """Root path, ghost trail, trajectory canvas, timeline and status text of ``shown``;
        ``restart`` plays from frame 0."""
        w, played = self.c.window, self.played
        if not shown or not played:
            return
        first = played[0]
        w.viewport.set_trajectory(first.joints[:, first.skeleton.root] + w.viewport.offsets[0])
        count = w.ghosts_spin.value()
        ghosts = first.joints[np.unique(np.linspace(0, first.n_frames - 1, count).round().astype(int))]
        w.viewport.set_ghosts(ghosts if len(played) == 1 and count > 0 else None)
        w.trajectory.set_generated(root_floor_path(first), None)
        length = max(m.n_frames for m in played)
        frame = 0 if restart else min(self.c.state.frame, length - 1)
        w.timeline.set_length(length, first.fps)
        if restart:
            w.timeline.set_frame(0)
            if not w.viewport.follow:
                w.viewport.frame_motion(padded_joints(played, length))
        else:  # during a drag: re-aim only when the new motion leaves the view
            w.viewport.keep_in_view(padded_joints(played, length))
        self.c.state.frame = frame
        self.set_frame(frame)
        if restart or not w.timeline.is_playing():
            w.timeline.play()
        head = shown[0]
        more = f" (+{len(shown) - 1} more)" if len(shown) > 1 else ""
        mode = "" if head.mode is None else f" · mode {head.mode}"
        end = "" if head.end is None else " · end ({:.2f}, {:.2f}, {:.2f}) m".format(*np.ravel(head.end))
        note = f" · {head.note}" if head.note else ""
        w.show_status(
            f"Playing {head.label}{more} · {action_name(head, self.c.generator.label_names)}{mode}{end} · "
            f"{first.n_frames} frames @ {first.fps:.4g} fps{note}"
        )

    def set_frame(self, frame: int) -> None:
        played = self.played
        if not played:
            return
        poses = np.stack([m.joints[min(frame, m.n_frames - 1)] for m in played])
        self.c.window.viewport.set_poses(poses)


def _skeleton_colors(shown: Sequence[Decoded], n: int, n_actions: int) -> np.ndarray:
    """(n, 3) uint8 skeleton colours: each motion's action colour (as on the map), in lighter to darker
    shades when several share an action (completions too); real clips are light grey."""
    from widgets._colors import palette_rgb, shades

    palette = palette_rgb(max(n_actions, 1))
    rows = np.zeros((len(shown), 3), dtype=np.uint8)
    actions = np.array([d.action for d in shown])
    for action in np.unique(actions):
        same = [k for k, d in enumerate(shown) if d.action == action and not d.real]
        if same:
            rows[same] = shades(palette[int(action) % len(palette)], len(same))
    rows[[k for k, d in enumerate(shown) if d.real]] = (205, 205, 205)
    return rows[:n]
