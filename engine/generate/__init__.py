"""Generation: decode codes, sample per action, interpolate, vary a code, encode motions, follow paths.

Decoded motions are returned at display height: the model works with the frame-0 root at the origin
(height included), so ``LoadedModel.root_height`` is added to y.
"""

from engine.generate._across import RULE as ACROSS_RULE
from engine.generate._across import interpolate_across, step_actions
from engine.generate._chain import apply_transform, chain_motions, chain_transforms
from engine.generate._decode import action_index, decode, decode_array, decode_batch, resolve_ends
from engine.generate._encode import (
    BANK_BATCH,
    WindowCodes,
    bank_window,
    clip_windows,
    encode,
    encode_bank_windows,
    encode_clips,
    encode_windows,
    guess_action,
    window_starts,
)
from engine.generate._path import PathResult, follow_path, resample_path
from engine.generate._sampling import (
    Sample,
    ball_codes,
    interpolate,
    interpolation_codes,
    neighbours,
    sample,
)

__all__ = [
    "ACROSS_RULE",
    "BANK_BATCH",
    "PathResult",
    "Sample",
    "WindowCodes",
    "action_index",
    "apply_transform",
    "ball_codes",
    "bank_window",
    "chain_motions",
    "chain_transforms",
    "clip_windows",
    "decode",
    "decode_array",
    "decode_batch",
    "encode",
    "encode_bank_windows",
    "encode_clips",
    "encode_windows",
    "follow_path",
    "guess_action",
    "interpolate",
    "interpolate_across",
    "interpolation_codes",
    "neighbours",
    "resample_path",
    "resolve_ends",
    "sample",
    "step_actions",
    "window_starts",
]
