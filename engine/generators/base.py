"""One interface for every generator kind: capability names, the Generator protocol and the registry.

A model folder names its kind in ``model.json``'s ``arch`` (folders written before the field existed are
ODMO). :func:`open_generator` reads it and calls the opener registered for that kind; a command or a tool
that needs more than decoding and sampling asks :func:`require` first, so a kind without a capability is
refused with one line saying what the model can do instead.
"""

from __future__ import annotations

import functools
import importlib
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any, Protocol, runtime_checkable

import numpy as np

from engine.errors import CancelledError, ConfigError, ModelFormatError

if TYPE_CHECKING:
    from engine.generate import Sample, WindowCodes
    from engine.latent.bank import LatentBank
    from engine.latent.directions import EditDirection
    from engine.motion.motion import Motion
    from engine.motion.skeleton import Skeleton

#: Metadata keys of bank codes that get an edit direction per value.
EDIT_KEYS = ("style",)
#: Bank codes decoded at once while fitting edit directions.
DIRECTION_BATCH = 512

#: Every ``SampleRequest.strategy`` a kind may take: its prior, then its bank modes' ("mode" samples
#: ``request.mode``).
SAMPLE_STRATEGIES = ("prior", "mode_preserving", "conventional", "mode")

#: Every capability a kind may declare, with what it lets a user do (used in refusals and tooltips).
CAPABILITIES: dict[str, str] = {
    "sample": "sample motions",
    "decode": "decode a given latent code",
    "modes": "sample from discovered modes (mode-preserving, conventional, one mode)",
    "bank": "map its training codes (latent bank)",
    "interpolate": "interpolate between two codes",
    "interpolate_across": "interpolate between codes of two actions",
    "encode": "encode a motion into a code",
    "end": "set where the motion ends",
    "follow_path": "follow a path on the floor",
    "invert": "invert a motion by optimisation",
    "edit": "edit along semantic directions",
    "mix": "mix styles",
    "truncate": "sample with truncation",
    "crowd": "sample a crowd around a code",
    "complete": "complete a motion from a prefix",
    "extend": "extend a motion past its window",
}


def check_psi(psi: float) -> None:
    """ConfigError unless ``psi`` is a finite truncation in [0, 2]."""
    if not np.isfinite(psi) or not 0.0 <= psi <= 2.0:
        raise ConfigError(f"truncation psi must lie in [0, 2], got {psi}")


def check_strategy(strategy: str) -> None:
    """ConfigError unless ``strategy`` is one of ``SAMPLE_STRATEGIES``."""
    if strategy not in SAMPLE_STRATEGIES:
        raise ConfigError(f"unknown strategy {strategy!r}; choose from {', '.join(SAMPLE_STRATEGIES)}")


class CapabilityError(ConfigError):
    """The loaded generator kind cannot do what was asked."""


@dataclass(frozen=True)
class CodeSpace:
    """The space a kind's codes live in: its name (e.g. "z", "W+") and size per code."""

    name: str
    size: int


@dataclass(frozen=True, eq=False)
class SampleRequest:
    """What to sample: ``n`` motions of ``action`` (None for an unconditional kind) from ``seed``.

    ``strategy`` and ``mode`` pick how codes are drawn (None: the kind's default); ``end`` (3,) is where
    the motion should end, for kinds with the "end" capability; ``weights`` weigh the action's modes;
    ``truncation`` ψ pulls codes towards the mean code (1: none), for kinds with "truncate".
    """

    action: str | None
    n: int
    seed: int
    strategy: str | None = None
    mode: int | None = None
    end: np.ndarray | None = None
    weights: tuple[float, ...] | None = None  # per-mode weights, for the "weights" strategy
    truncation: float = 1.0


class FolderGenerator:
    """What every kind reads from its loaded folder ``loaded``: path, skeleton, fps, window, actions; and
    the edit directions of its bank."""

    loaded: Any

    @property
    def path(self) -> Path:
        """The model folder."""
        return self.loaded.path

    @property
    def skeleton(self) -> Skeleton:
        """The skeleton generated motions are on."""
        return self.loaded.skeleton

    @property
    def fps(self) -> float:
        """Frames per second of generated motions."""
        return self.loaded.fps

    @property
    def window(self) -> int:
        """Frames per generated motion."""
        return self.loaded.window

    @property
    def action_names(self) -> list[str] | None:
        """The actions it is conditioned on (None for an unconditional kind)."""
        return list(self.loaded.action_names)

    @property
    def label_names(self) -> list[str]:
        """The action labels of its training data (a conditional kind's ``action_names``), which its bank
        codes carry."""
        return list(self.loaded.action_names)

    @property
    def strategies(self) -> tuple[str, ...]:
        """The ``SampleRequest.strategy`` names its ``sample`` takes, its default first: its prior, then,
        with modes, the bank's mode strategies."""
        return SAMPLE_STRATEGIES if "modes" in self.capabilities else ("prior",)

    @property
    def root_height(self) -> float:
        """Height (m) of the root above the floor in the training clips: decoded motions stand at it."""
        return float(self.loaded.root_height)

    def real_window(self, clip: Motion, start: int | None = None) -> Motion:
        """The window of a real ``clip`` a bank code encodes (from ``start``, or its centre), placed and
        turned as decoded motions are, at display height."""
        from engine.generate import bank_window

        return bank_window(self, clip, start)

    def vary(self, code: np.ndarray, action: str, n: int, radius: float, seed: int) -> list[Sample]:
        """``n`` motions of codes drawn uniformly from the ball of ``radius`` around ``code`` ("decode")."""
        from engine.generate import Sample, ball_codes

        codes = ball_codes(code, n, radius, seed)
        index = self.action_names.index(action)
        motions = self.decode(codes, action, seed=seed)
        return [Sample(c, index, -1, None, m) for c, m in zip(codes, motions, strict=True)]

    def encode_bank(
        self,
        clips: Sequence[Motion],
        stride: int | None = None,
        progress: Callable[[int, int], None] | None = None,
        cancel: Callable[[], bool] | None = None,
    ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray | None]:
        """Codes (N, D), end locations (N, 3; zeros for kinds without), clip index (N,) and window start
        (N,; None for one code per clip) of ``clips`` for a latent bank ("encode"), clip by clip;
        progress(clips done, clips in all); CancelledError between clips."""
        codes, starts = [], []
        for k, clip in enumerate(clips):
            if cancel is not None and cancel():
                raise CancelledError(f"encoding cancelled after {k} of {len(clips)} clips")
            if stride is None:
                codes.append(self.encode(clip)[0][None])
            else:
                windows = self.encode_windows(clip, stride)
                codes.append(windows.codes)
                starts.append(windows.starts)
            if progress is not None:
                progress(k + 1, len(clips))
        owners = np.concatenate([np.full(len(c), k, dtype=np.int64) for k, c in enumerate(codes)])
        stacked = np.concatenate(codes).astype(np.float32)
        first = np.concatenate(starts) if stride is not None else None
        return stacked, np.zeros((len(stacked), 3), np.float32), owners, first

    @functools.cached_property
    def edit_directions(self) -> dict[str, EditDirection]:
        """Directions of the bank's metadata labels (``EDIT_KEYS``) and of its codes' motions' speed (root,
        m/s) and energy (mean joint speed), fitted once ("edit")."""
        from engine.latent.directions import fit_directions
        from engine.motion.ops import motion_energy

        require(self, "edit")
        bank = self.bank
        joints = np.zeros((len(bank.codes), self.window, self.skeleton.n_joints, 3), np.float32)
        for a in np.unique(bank.actions):
            rows = np.flatnonzero(bank.actions == a)
            for lo in range(0, len(rows), DIRECTION_BATCH):
                part = rows[lo : lo + DIRECTION_BATCH]
                motions = self.decode(bank.codes[part], self.label_names[int(a)])
                joints[part] = [m.joints for m in motions]
        root = joints[:, :, self.skeleton.root][:, :, [0, 2]]
        speed = np.linalg.norm(np.diff(root, axis=1), axis=-1).mean(axis=1) * self.fps
        attributes = {"speed": speed, "energy": motion_energy(joints, self.fps)}
        return fit_directions(bank.codes, bank.meta, EDIT_KEYS, attributes)

    def edit(self, code: np.ndarray, action: str | None, direction: str, amount: float) -> Sample:
        """The motion of ``code`` moved ``amount`` spreads along the named edit direction ("edit")."""
        from engine.generate import Sample

        found = self.edit_directions
        if direction not in found:
            raise ConfigError(f"{self.path}: no edit direction {direction!r}; it has {', '.join(found)}")
        edited = found[direction].apply(np.asarray(code, np.float32).reshape(-1), amount)
        [motion] = self.decode(edited[None], action)
        index = -1 if action is None else self.label_names.index(action)
        return Sample(edited, index, -1, None, motion)

    def encode_windows(self, motion: Motion, stride: int) -> WindowCodes:
        """``motion``'s T-frame windows every ``stride`` frames, each encoded ("encode")."""
        from engine.generate import WindowCodes, clip_windows

        starts, pieces = clip_windows(self, motion, stride)
        found = [self.encode(piece) for piece in pieces]
        codes = np.stack([code for code, _ in found]).astype(np.float32)
        actions = np.array([-1 if a is None else a for _, a in found], dtype=np.int64)
        return WindowCodes(codes, np.zeros((len(codes), 3), np.float32), starts, stride, actions)


@runtime_checkable
class Generator(Protocol):
    """What the CLI and the app need of a generator kind; optional methods follow ``capabilities``."""

    kind: str
    path: Path
    skeleton: Skeleton
    fps: float
    window: int
    action_names: list[str] | None
    label_names: list[str]
    code_space: CodeSpace
    capabilities: frozenset[str]
    strategies: tuple[str, ...]
    bank: LatentBank | None

    def sample(self, request: SampleRequest) -> list[Sample]:
        """The motions ``request`` asks for; the same request, the same motions."""
        ...

    def decode(
        self,
        codes: np.ndarray,
        actions: Sequence[str] | str | None,
        end: np.ndarray | None = None,
        seed: int | None = None,
    ) -> list[Motion]:
        """One motion per code (N, code_space.size) ("decode" capability)."""
        ...


Opener = Callable[[Path, str, bool], Generator]  # (folder, device, with_bank)
_KINDS: dict[str, Opener] = {}
# The kinds this program ships, as module and opener names: each is imported only when a folder of its
# kind is opened, so that opening one kind does not load the others' modules.
_BUILTIN = {
    "odmo": ("engine.generators.odmo", "open_odmo"),
    "a2m": ("engine.generators.a2m", "open_a2m"),
    "modi": ("engine.generators.modi", "open_modi"),
    "dvgan": ("engine.generators.dvgan", "open_dvgan"),
}


def register_kind(arch: str, opener: Opener) -> None:
    """Make :func:`open_generator` open folders whose ``model.json`` says ``"arch": arch``."""
    _KINDS[arch] = opener


def kinds() -> list[str]:
    """The registered kinds, sorted."""
    return sorted(set(_KINDS) | set(_BUILTIN))


def model_kind(path: str | Path) -> str:
    """The registered kind a model folder's ``model.json`` names (ModelFormatError for any other)."""
    from engine.modelio import META_FILE, read_meta

    folder = Path(path)
    if not folder.is_dir():
        raise ModelFormatError(f"{folder}: not a model folder")
    arch = read_meta(folder / META_FILE).get("arch", "odmo")
    if not isinstance(arch, str) or arch not in kinds():
        raise ModelFormatError(
            f"{folder / META_FILE}: unknown model kind {arch!r}; this program opens {', '.join(kinds())}"
        )
    return arch


def open_generator(path: str | Path, device: str = "cpu", with_bank: bool = True) -> Generator:
    """The generator in a model folder, of whichever registered kind its ``model.json`` names; without
    its latent bank when ``with_bank`` is False (so that a damaged bank can be rebuilt)."""
    return _opener(model_kind(path))(Path(path), device, with_bank)


def refusal(generator: Generator, capability: str, asked: str | None = None) -> CapabilityError:
    """The error saying that ``generator`` lacks ``capability`` and what it can do instead."""
    if capability not in CAPABILITIES:
        raise ValueError(f"unknown capability {capability!r}")
    can = ", ".join(CAPABILITIES[c] for c in CAPABILITIES if c in generator.capabilities)
    what = asked or CAPABILITIES[capability]
    return CapabilityError(f"{generator.path}: this {generator.kind} model cannot {what}; it can {can}")


def require(generator: Generator, capability: str, asked: str | None = None) -> None:
    """CapabilityError unless ``generator`` declares ``capability`` (``asked`` names the request)."""
    if capability not in generator.capabilities:
        raise refusal(generator, capability, asked)


def _opener(arch: str) -> Opener:
    """The opener of a registered kind; a shipped kind's module is imported on first use."""
    if arch not in _KINDS:
        module, name = _BUILTIN[arch]
        _KINDS[arch] = getattr(importlib.import_module(module), name)
    return _KINDS[arch]
