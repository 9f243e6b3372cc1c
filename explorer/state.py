"""Evented application state: every view subscribes to it, only the controller writes it."""

from __future__ import annotations

import operator
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any

import numpy as np
from psygnal import evented

from engine.motion.motion import Motion

if TYPE_CHECKING:  # engine.modelio loads torch: the state is created before the model is
    from engine.generators.base import Generator
    from engine.latent.directions import EditDirection

PROJECTIONS = ("pca", "tsne", "umap")
COLOR_BY = ("action", "mode", "motion energy")
LAYOUTS = ("side_by_side", "overlay", "sequence")


@dataclass(frozen=True, eq=False)
class Decoded:
    """One motion on screen and what produced it.

    Parameters
    ----------
    motion : the decoded (or real, or completed) motion; a completion's ``meta["prefix_frames"]`` says how
        many of its first frames came from the motion it continues.
    label : short text for the status bar and file names.
    code : (D,) latent code, or None for a real clip.
    action : action index.
    end : (3,) end location used, or None.
    mode : mode index within the action, or None when unknown.
    seed : seed of the random draw that produced the code, or None.
    bank_index : index of the bank code it came from, or None.
    note : what the user should know about how it was made ("" when nothing), shown in the status.
    """

    motion: Motion
    label: str
    code: np.ndarray | None = None
    action: int = 0
    end: np.ndarray | None = None
    mode: int | None = None
    seed: int | None = None
    bank_index: int | None = None
    note: str = ""

    @property
    def real(self) -> bool:
        """True for a clip shown as recorded: no code, and no frames a model added after it."""
        return self.code is None and "prefix_frames" not in self.motion.meta

    def metadata(self, model_path: str) -> dict[str, Any]:
        """JSON-ready provenance: model, code, action, mode, end location, seed."""
        return {
            "model": model_path,
            "label": self.label,
            "action": self.motion.action,
            "action_index": int(self.action),
            "code": None if self.code is None else [float(v) for v in np.ravel(self.code)],
            "mode": self.mode,
            "end": None if self.end is None else [float(v) for v in np.ravel(self.end)],
            "seed": self.seed,
            "bank_index": self.bank_index,
        }


@dataclass(frozen=True, eq=False)
class ExtraPoints:
    """Codes shown on the map besides the bank (samples, variations), with their map positions.

    Parameters
    ----------
    codes : (M, D) latent codes.
    actions : (M,) action indices.
    xy : (M, 2) positions under the current projection.
    """

    codes: np.ndarray
    actions: np.ndarray
    xy: np.ndarray


@dataclass(frozen=True, eq=False)
class Pick:
    """A code the user picked (clicked on the map, or an inverted clip): ``code`` (D,), its label and the
    index of the action (or label) it was decoded as."""

    code: np.ndarray
    label: str
    action: int = 0


_SAME = {name: operator.is_ for name in ("model", "embedding", "marker", "edit_directions")}


@evented(equality_operators=_SAME)
@dataclass
class AppState:
    """What the explorer shows; each field emits ``state.events.<field>`` when it changes.

    Parameters
    ----------
    model : the loaded generator, of any kind (with its latent bank), or None.
    data_dir : dataset folder whose real clips play beside reconstructions, or None.
    projection : name of the map's projection ("pca", "tsne", "umap").
    embedding : (N, 2) map positions of the bank codes under ``projection``, or None.
    color_by : what colours the points (see ``COLOR_BY``).
    hidden_actions : action indices hidden on the map.
    focus_action : the action the mode panel and the sample buttons work on.
    selection : selected bank indices.
    marker : (2,) map position of the last decoded empty-space point, or None.
    extra : codes shown on the map besides the bank, or None.
    shown : the motions in the viewport, played together.
    layout : "side_by_side" or "overlay".
    frame : current frame of the timeline.
    busy : text of the long task in progress ("" when idle).
    truncation : ψ that sampling pulls codes towards the mean code with (1: none), for kinds that truncate.
    picked : the last two picked codes, older first (style mixing takes the older's coarse levels).
    edit_directions : the loaded model's edit directions, once found (empty before, or without "edit").
    edits : (direction name, amount in spreads) of each edit slider off zero, in the directions' order.
    """

    model: Generator | None = None
    data_dir: str | None = None
    projection: str = "pca"
    embedding: np.ndarray | None = None
    color_by: str = "action"
    hidden_actions: frozenset[int] = frozenset()
    focus_action: int = 0
    selection: tuple[int, ...] = ()
    marker: np.ndarray | None = None
    extra: ExtraPoints | None = None
    shown: tuple[Decoded, ...] = field(default_factory=tuple)
    layout: str = "side_by_side"
    frame: int = 0
    busy: str = ""
    truncation: float = 1.0
    picked: tuple[Pick, ...] = ()
    edit_directions: tuple[EditDirection, ...] = ()
    edits: tuple[tuple[str, float], ...] = ()

    def pick(self, code: np.ndarray, label: str, action: int = 0) -> None:
        """Remember ``code`` (copied, read-only) of action index ``action`` as the newest picked code,
        keeping the one before it."""
        frozen = np.array(code, dtype=np.float32)
        frozen.flags.writeable = False
        self.picked = (*self.picked[-1:], Pick(frozen, label, int(action)))
