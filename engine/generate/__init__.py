"""Generation: decode codes, sample per action, interpolate, vary a code, encode motions, follow paths.

Decoded motions are returned at display height: the model works with the frame-0 root at the origin
(height included), so ``LoadedModel.root_height`` is added to y.
"""

from engine.generate._decode import action_index, decode, decode_array, decode_batch, resolve_ends
from engine.generate._encode import encode, encode_clips, guess_action
from engine.generate._path import PathResult, follow_path, resample_path
from engine.generate._sampling import Sample, interpolate, interpolation_codes, neighbours, sample

__all__ = [
    "PathResult",
    "Sample",
    "action_index",
    "decode",
    "decode_array",
    "decode_batch",
    "encode",
    "encode_clips",
    "follow_path",
    "guess_action",
    "interpolate",
    "interpolation_codes",
    "neighbours",
    "resample_path",
    "resolve_ends",
    "sample",
]
