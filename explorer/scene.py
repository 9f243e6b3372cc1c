"""What the 3-D view draws for the motions shown: the played motions, the end marker, the labels.

Pure functions of the app state (numpy and the engine's chaining); the controller hands the result
to the viewport.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from engine.motion.motion import Motion
from explorer.state import Decoded


@dataclass(frozen=True, eq=False)
class Scene:
    """The motions to play and what decorates them.

    Parameters
    ----------
    played : the motions played together (one when a strip is chained in sequence).
    end : (3,) end location of the requested end, in view coordinates (before layout offsets), or None.
    labels : one short text per played motion.
    steps : (S,) first frame of each chained step within the one played motion ([0] otherwise).
    """

    played: list[Motion]
    end: np.ndarray | None
    labels: list[str]
    steps: np.ndarray


def end_in_view(item: Decoded, root_height: float) -> np.ndarray | None:
    """(3,) where ``item``'s end location is drawn: the model's end is relative to the frame-0 root on
    the floor, so the display height and the motion's origin (a followed path's start) are added."""
    if item.end is None:
        return None
    end = np.asarray(item.end, dtype=np.float64).reshape(-1)
    if end.shape != (3,):
        return None
    origin = np.asarray(item.motion.meta.get("origin", (0.0, 0.0, 0.0)), dtype=np.float64).reshape(3)
    return end + origin + np.array([0.0, float(root_height), 0.0])


def action_name(item: Decoded, action_names: Sequence[str]) -> str:
    """The action ``item`` is shown as: a real clip's own label ("unlabelled" without one), else the label
    it was decoded or guessed as."""
    if item.real or not 0 <= item.action < len(action_names):
        return item.motion.action or "unlabelled"
    return action_names[item.action]


def short_label(item: Decoded, action_names: Sequence[str]) -> str:
    """A few words over a skeleton: its action and what it is (real clip, step, sample …)."""
    name = action_name(item, action_names)
    if item.real:
        return f"{name} (real)"
    words = item.label.split(" · ")[0].split()
    steps = [w for w in words if "/" in w and not w.endswith((".bvh", ".npz"))]
    what = steps[-1] if steps else next((w for w in words if w.startswith("#")), "")
    if words and words[0] == "edited":  # an edit plays beside its unedited code (see requests.EditDecode)
        what = f"{what} edited"
    return f"{name} {what}".strip()


def build_scene(
    shown: Sequence[Decoded], layout: str, root_height: float, action_names: Sequence[str]
) -> Scene:
    """The scene of ``shown`` under ``layout``: in "sequence" the motions are chained (each starts
    where and facing how the previous ended) and the end marker is the last step's end."""
    motions = [d.motion for d in shown]
    labels = [short_label(d, action_names) for d in shown]
    if layout == "sequence" and len(motions) > 1:
        from engine.generate import apply_transform, chain_motions

        chained, transforms = chain_motions(motions)
        end = end_in_view(shown[-1], root_height)
        if end is not None:
            end = apply_transform(transforms[-1], end[None])[0]
        starts = np.cumsum([0] + [m.n_frames for m in motions[:-1]])
        return Scene([chained], end, [f"{labels[0]} → {labels[-1]}"], starts)
    return Scene(motions, end_in_view(shown[0], root_height), labels, np.zeros(1, dtype=np.int64))
