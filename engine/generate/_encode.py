"""Encode a motion into a latent code and guess its action."""

from __future__ import annotations

import dataclasses
import logging
from collections.abc import Callable, Sequence

import numpy as np
import torch
from scipy.special import logsumexp

from engine.errors import CancelledError, ConfigError
from engine.generate._decode import as_codes
from engine.modelio import LoadedModel
from engine.motion.datasets import conform_to
from engine.motion.motion import Motion
from engine.motion.resample import resample_motion
from engine.train.windows import crop_windows, prepare_clips

log = logging.getLogger(__name__)

BANK_BATCH = 256  # windows encoded together when building a bank: the memory bound beside the codes


def guess_action(loaded: LoadedModel, code: np.ndarray) -> int | None:
    """The action whose mode mixture gives ``code`` (D,) the highest density; None without a bank."""
    bank = loaded.bank
    if bank is None or not bank.modes:
        return None
    x = as_codes(loaded, code)
    actions = sorted(bank.modes)
    scores = [float(logsumexp(bank.modes[a].log_responsibilities(x)[0])) for a in actions]
    return actions[int(np.argmax(scores))]


def encode_clips(loaded: LoadedModel, motions: Sequence[Motion]) -> tuple[np.ndarray, np.ndarray]:
    """Posterior mean codes (N, D) and end locations (N, 3) of ``motions``, as the training bank has them.

    Each motion is resampled to the model's fps and canonicalised like a training window (frame-0 root
    at the origin, facing +z); a clip longer than T frames is represented by its centre window, a
    shorter one is padded with its last frame and masked. Action labels are not used.
    """
    if not motions:
        raise ConfigError("no motions to encode")
    # The label only routes clips through the training preparation; it does not affect the codes.
    first = loaded.action_names[0]
    unlabelled = [dataclasses.replace(conform_to(loaded.skeleton, m), action=first) for m in motions]
    prepared = prepare_clips(unlabelled, loaded.action_names, loaded.fps, loaded.window)
    window = crop_windows(prepared, np.arange(len(motions)), None)
    model = loaded.model
    device = next(model.parameters()).device
    with torch.inference_mode():
        lmp = torch.as_tensor(window.lmp, dtype=torch.float32, device=device)
        mask = torch.as_tensor(window.mask, device=device)
        mu, _ = model.encode(lmp, mask)
    return mu.cpu().numpy().astype(np.float32), window.ends.astype(np.float32)


def encode(loaded: LoadedModel, motion: Motion) -> tuple[np.ndarray, int | None]:
    """Posterior mean code (D,) of ``motion`` (its centre window, see :func:`encode_clips`) and a guess
    of its action index (None without a latent bank)."""
    codes, _ = encode_clips(loaded, [motion])
    return codes[0], guess_action(loaded, codes[0])


@dataclasses.dataclass(frozen=True, eq=False)
class WindowCodes:
    """A clip encoded window by window.

    Parameters
    ----------
    codes : (W, D) float32 posterior mean codes, one per window.
    ends : (W, 3) float32 end locations of the windows.
    starts : (W,) first frame of each window, at the model's frame rate.
    stride : frames between window starts.
    actions : (W,) guessed action of each window (-1 without a latent bank).
    """

    codes: np.ndarray
    ends: np.ndarray
    starts: np.ndarray
    stride: int
    actions: np.ndarray


def window_starts(n_frames: int, window: int, stride: int) -> np.ndarray:
    """First frames of ``window``-frame windows every ``stride`` frames over ``n_frames``; the last
    window ends at the clip's last frame; one window (start 0) for a clip no longer than a window."""
    if stride < 1:
        raise ConfigError(f"stride must be at least 1 frame, got {stride}")
    last = max(int(n_frames) - int(window), 0)
    starts = np.arange(0, last + 1, int(stride))
    return np.unique(np.append(starts, last)).astype(np.int64)


def _at_model_rate(loaded: LoadedModel, motion: Motion) -> Motion:
    """``motion`` on the model's skeleton at the model's frame rate."""
    moved = conform_to(loaded.skeleton, motion)
    return resample_motion(moved, loaded.fps) if abs(moved.fps - loaded.fps) > 1e-6 else moved


def clip_windows(loaded: LoadedModel, motion: Motion, stride: int) -> tuple[np.ndarray, list[Motion]]:
    """First frames (W,) and the T-frame windows of ``motion`` every ``stride`` frames at the model's fps
    (the last window ends at the clip's end), on the model's skeleton."""
    moved = _at_model_rate(loaded, motion)
    starts = window_starts(moved.n_frames, loaded.window, stride)
    return starts, [moved.with_joints(moved.joints[s : s + loaded.window]) for s in starts]


def encode_windows(loaded: LoadedModel, motion: Motion, stride: int | None = None) -> WindowCodes:
    """Encode ``motion`` as its T-frame windows every ``stride`` frames (default T / 2) at the model's fps,
    so that a long clip becomes a path of codes; each window is canonicalised like a training window."""
    stride = loaded.window // 2 if stride is None else int(stride)
    starts, pieces = clip_windows(loaded, motion, stride)
    codes, ends = encode_clips(loaded, pieces)
    guesses = [guess_action(loaded, c) for c in codes]
    actions = np.array([-1 if g is None else g for g in guesses], dtype=np.int64)
    return WindowCodes(codes, ends, starts, stride, actions)


def _room(array: np.ndarray, rows: int) -> np.ndarray:
    """``array`` with room for ``rows`` rows: a copy of twice the size when it is short."""
    if rows <= len(array):
        return array
    grown = np.empty((max(rows, 2 * len(array)), *array.shape[1:]), dtype=array.dtype)
    grown[: len(array)] = array
    return grown


def encode_bank_windows(
    loaded: LoadedModel,
    clips: Sequence[Motion],
    stride: int | None,
    *,
    batch: int = BANK_BATCH,
    progress: Callable[[int, int], None] | None = None,
    cancel: Callable[[], bool] | None = None,
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray | None]:
    """Codes (N, D), ends (N, 3), clip index (N,) and first frame (N,; None without a stride) of the
    windows of ``clips`` every ``stride`` frames (None: each clip's centre window), taking one clip at a
    time (each read once: ``clips`` may read them from disk) and encoding ``batch`` windows at a time, so
    memory holds one batch and one clip beside the codes. progress(windows done, windows in all) after
    each batch, the total estimated from the clips seen until the last; CancelledError between batches.

    The rows go into arrays that double when full rather than into many small ones: small arrays that
    outlive each batch's large temporaries fragment the C heap (RSS grew 15 kB a window past 30k).
    """
    if batch < 1:
        raise ConfigError(f"batch must be at least 1 window, got {batch}")
    pending: list[Motion] = []
    codes = np.empty((batch, loaded.config.latent_dim), dtype=np.float32)
    ends = np.empty((batch, 3), dtype=np.float32)
    owners = np.empty(batch, dtype=np.int64)
    starts = np.zeros(batch, dtype=np.int64)
    done = queued = seen = 0

    def flush(count: int) -> None:
        nonlocal done, codes, ends
        if cancel is not None and cancel():
            raise CancelledError(f"encoding cancelled after {done} windows of {seen} of {len(clips)} clips")
        codes, ends = _room(codes, done + count), _room(ends, done + count)
        codes[done : done + count], ends[done : done + count] = encode_clips(loaded, pending[:count])
        del pending[:count]
        done += count
        if progress is not None:
            progress(done, max(queued, round(queued * len(clips) / seen)))

    for k, clip in enumerate(clips):
        if stride is None:
            pieces = [clip]
        else:
            first, pieces = clip_windows(loaded, clip, stride)
            starts = _room(starts, queued + len(pieces))
            starts[queued : queued + len(pieces)] = first
        owners = _room(owners, queued + len(pieces))
        owners[queued : queued + len(pieces)] = k
        pending += pieces
        queued, seen = queued + len(pieces), k + 1
        while len(pending) >= batch:
            flush(batch)
    if pending:
        flush(len(pending))
    if not done:
        raise ConfigError("no clips to encode")
    log.info("encoded %d windows of %d clips", done, len(clips))
    first_frames = starts[:done].copy() if stride is not None else None
    return codes[:done].copy(), ends[:done].copy(), owners[:done].copy(), first_frames


def bank_window(loaded: LoadedModel, clip: Motion, start: int | None = None) -> Motion:
    """The window of ``clip`` that a bank code of it encodes (its T frames from ``start`` at the model's
    fps; its centre T frames when None), canonicalised as the model's output is (frame-0 root at the
    origin, facing +z) at display height."""
    if start is not None:
        clip = _at_model_rate(loaded, clip)
        last = max(clip.n_frames - loaded.window, 0)
        if not 0 <= start <= last:
            raise ConfigError(f"window start {start} is outside the clip's 0..{last}")
        clip = clip.with_joints(clip.joints[start : start + loaded.window])
    moved = dataclasses.replace(conform_to(loaded.skeleton, clip), action=loaded.action_names[0])
    prepared = prepare_clips([moved], loaded.action_names, loaded.fps, loaded.window)
    window = crop_windows(prepared, np.arange(1), None)
    length = int(window.mask[0].sum())
    joints = window.joints[0, :length] + np.array([0.0, loaded.root_height, 0.0], dtype=np.float32)
    first = int(window.starts[0]) if start is None else int(start)
    meta = dict(clip.meta) | {"window_start": first}
    return Motion(joints, loaded.fps, loaded.skeleton, action=clip.action, meta=meta)
