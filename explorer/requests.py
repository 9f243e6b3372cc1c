"""Frozen decode requests: built on the GUI thread from what a gesture needs, run in the decode worker.

A request holds everything its job reads (the generator, the bank, codes, clips), so no job reads the
controller from the worker; the worker drops a result older than the newest request.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

from explorer.decoding import condition, decode_one, full_end, map_codes
from explorer.map_layers import mode_labels
from explorer.state import Decoded

if TYPE_CHECKING:
    from engine.generators.base import Generator
    from engine.latent.bank import LatentBank
    from engine.latent.directions import EditDirection
    from engine.latent.projection import Projection
    from engine.motion.motion import Motion


def frozen_array(array: np.ndarray | None, dtype: type = np.float32) -> np.ndarray | None:
    """A read-only copy of a code, end location or map point for a request (None stays None)."""
    if array is None:
        return None
    out = np.array(array, dtype=dtype)
    out.flags.writeable = False
    return out


@dataclass(frozen=True, eq=False)
class BankDecode:
    """Decode bank codes ``indices``, each followed by the window of its real clip where one is given."""

    generator: Generator
    bank: LatentBank
    indices: tuple[int, ...]
    clips: tuple[Motion | None, ...]
    note: str = ""

    def run(self) -> tuple[Decoded, ...]:
        """The decoded motions (and real windows), labelled with bank index and clip name."""
        bank, items = self.bank, []
        labels = mode_labels(bank)
        with_end = "end" in self.generator.capabilities
        for i, clip in zip(self.indices, self.clips, strict=True):
            code, action = bank.codes[i].copy(), int(bank.actions[i])
            end = bank.ends[i].copy() if with_end else None
            mode = None if labels[i] < 0 else int(labels[i])
            motion = decode_one(self.generator, code, action, end, mode)
            name = f"#{i} {bank.sources[i]}"
            items.append(Decoded(motion, f"{name} (decoded)", code, action, end, mode, None, i, self.note))
            if clip is not None:  # the window the code encodes, placed and turned as the decode is
                start = bank.meta[i].get("window_start") if "window_stride" in bank.meta[i] else None
                items.append(
                    Decoded(self.generator.real_window(clip, start), f"{name} (real clip)", None, action)
                )
        return tuple(items)


@dataclass(frozen=True, eq=False)
class CodeDecode:
    """Decode one code of ``action`` (or, when ``code`` is None, the inverse projection of map point
    ``xy``), with end location ``end`` ((2,) floor point, (3,), or None for the predicted one)."""

    generator: Generator
    bank: LatentBank
    projection: Projection | None
    action: int
    label: str
    code: np.ndarray | None = None
    xy: np.ndarray | None = None
    end: np.ndarray | None = None

    def run(self) -> tuple[Decoded, ...]:
        """The one decoded motion, with the end location and mode it was decoded with."""
        code = self.code
        if code is None:
            code = self.projection.inverse_transform(np.asarray(self.xy, np.float64)[None])[0]
        code = np.asarray(code, dtype=np.float32)
        end = full_end(self.generator, code, self.action, self.end)
        modes = self.bank.modes.get(self.action)
        mode = None if modes is None else int(modes.predict(map_codes(self.generator, code[None]))[0])
        motion = decode_one(self.generator, code, self.action, end, mode)
        return (Decoded(motion, self.label, code, self.action, end, mode),)


@dataclass(frozen=True, eq=False)
class StripDecode:
    """Decode ``steps`` codes from ``code_a`` (of ``action_a``) to ``code_b`` (of ``action_b``); ends are
    blended when the kind takes them (``end_a``/``end_b`` None otherwise)."""

    generator: Generator
    code_a: np.ndarray
    code_b: np.ndarray
    action_a: int
    action_b: int
    steps: int
    what: str
    end_a: np.ndarray | None = None
    end_b: np.ndarray | None = None

    def run(self) -> tuple[Decoded, ...]:
        """The strip's motions, each labelled with its step and the action it was decoded as."""
        from engine import generate

        g, names, steps = self.generator, self.generator.label_names, self.steps
        ends = {} if self.end_a is None else {"end_a": self.end_a, "end_b": self.end_b}
        a, b = condition(g, self.action_a), condition(g, self.action_b)
        if a != b:
            samples = g.interpolate_across(self.code_a, a, self.code_b, b, steps, **ends)
        else:  # one action, or an unconditional kind (its codes' labels are not a condition)
            samples = g.interpolate(self.code_a, self.code_b, a, steps, **ends)
        note = f"{a} → {b}: {generate.ACROSS_RULE}" if a != b else ""
        return tuple(
            Decoded(
                s.motion,
                f"{self.what} step {k + 1}/{steps} {names[s.action] if s.action >= 0 else ''}".rstrip(),
                s.code,
                s.action,
                s.end,
                s.mode,
                note=note,
            )
            for k, s in enumerate(samples)
        )


def label_index(generator: Generator, motion: Motion) -> int:
    """Index in ``generator.label_names`` of the label a decoded ``motion`` carries (0 when it has none)."""
    names = generator.label_names
    return names.index(motion.action) if motion.action in names else 0


@dataclass(frozen=True, eq=False)
class MixDecode:
    """The motion taking ``code_a``'s coarse levels (below ``split``) and ``code_b``'s fine ones, shown
    before the motions of A and B."""

    generator: Generator
    code_a: np.ndarray
    code_b: np.ndarray
    split: int
    label_a: str
    label_b: str

    def run(self) -> tuple[Decoded, ...]:
        """The mixed motion (its W+ code), then A's and B's."""
        g = self.generator
        mixed = g.mix(self.code_a.copy(), self.code_b.copy(), self.split)  # (torch takes no read-only arrays)
        note = f"levels 0..{self.split - 1} from A, the rest from B" if self.split else "every level from B"
        items = [
            Decoded(mixed.motion, f"mix A|B @ {self.split}", mixed.code, max(mixed.action, 0), note=note)
        ]
        for code, label in ((self.code_a, self.label_a), (self.code_b, self.label_b)):
            [motion] = g.decode(np.array(code, np.float32)[None], None)
            items.append(Decoded(motion, label, code, label_index(g, motion)))
        return tuple(items)


@dataclass(frozen=True, eq=False)
class EditDecode:
    """``code`` (picked as action index ``action``) moved along each direction by its amount (spreads), one
    direction after the other, decoded before the unedited code; the unedited code alone without edits."""

    generator: Generator
    code: np.ndarray
    action: int
    label: str
    edits: tuple[tuple[EditDirection, float], ...]

    def run(self) -> tuple[Decoded, ...]:
        """The edited motion (its code), then the unedited one; decoded as ``generator.edit`` decodes."""
        g, code = self.generator, np.array(self.code, np.float32).reshape(-1)
        edited = code
        for direction, amount in self.edits:
            edited = direction.apply(edited, amount)
        what = ", ".join(f"{d.name} {a:+.1f}" for d, a in self.edits)
        items = [(edited, f"edited {self.label} · {what}")] if self.edits else []
        items.append((code, self.label))
        motions = g.decode(np.stack([c for c, _ in items]), condition(g, self.action))
        note = "moved along each direction in turn; the unedited code plays beside it" if self.edits else ""
        return tuple(
            Decoded(m, label, c, label_index(g, m), note=note)
            for m, (c, label) in zip(motions, items, strict=True)
        )
