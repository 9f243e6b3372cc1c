"""The stated limits on what the engine reads and allocates: file sizes, model sizes, request sizes.

Inputs beyond them are refused with :class:`engine.errors.TooLargeError` before anything big is read or
allocated. ``ODMO_MAX_FILE_MB`` raises (or lowers) the file limit for one run.
"""

from __future__ import annotations

import dataclasses
import math
import os
from collections.abc import Mapping
from pathlib import Path

from engine.errors import ConfigError, TooLargeError

#: Largest motion, label, pickle or model file read, in bytes (512 MiB; ``ODMO_MAX_FILE_MB`` overrides).
DEFAULT_MAX_FILE_BYTES = 512 * 2**20
#: Most conditioning inputs (actions × latent size, ODMO's outer product) a model may have.
MAX_CONDITIONING = 65_536
#: Most values a training step may hold per layer (batch × window × the widest hidden size).
MAX_STEP_VALUES = 2**26
#: Upper bounds of the size fields of every model config.
MAX_SIZES: Mapping[str, float] = {
    "n_actions": 1_000,
    "n_joints": 256,
    "window": 1_000,
    "tape_windows": 64,
    "fps": 1_000.0,
    "latent_dim": 1_024,
    "enc_hidden": 2_048,
    "enc_fc": 4_096,
    "traj_hidden": 2_048,
    "motion_hidden": 2_048,
    "hidden": 2_048,
    "gen_layers": 16,
    "code_rhythms": 256,
    "batch_size": 8_192,
    "epoch_size": 10_000_000,
    "epochs": 1_000_000,
    "tf_decay_epochs": 1_000_000,
}
#: Most motions one sample / interpolate request may produce.
MAX_MOTIONS_PER_REQUEST = 10_000


def max_file_bytes() -> int:
    """The file-size limit in bytes (``ODMO_MAX_FILE_MB`` when set to a positive number)."""
    text = os.environ.get("ODMO_MAX_FILE_MB", "").strip()
    if not text:
        return DEFAULT_MAX_FILE_BYTES
    try:
        megabytes = float(text)
    except ValueError:
        raise ConfigError(f"ODMO_MAX_FILE_MB must be a number of megabytes, got {text!r}") from None
    if not megabytes > 0:
        raise ConfigError(f"ODMO_MAX_FILE_MB must be positive, got {text!r}")
    return int(megabytes * 2**20)


def check_file_size(path: str | Path, what: str = "file") -> int:
    """The size of ``path`` in bytes; TooLargeError naming it when it is over the file limit."""
    size = os.stat(path).st_size
    _refuse_over_limit(path, size, what)
    return size


def _refuse_over_limit(path: str | Path, size: int, what: str) -> None:
    limit = max_file_bytes()
    if size > limit:
        raise TooLargeError(
            f"{path}: {what} of {size / 2**20:,.0f} MB is over the {limit / 2**20:,.0f} MB limit "
            "(set ODMO_MAX_FILE_MB to raise it)"
        )


def read_bytes(path: str | Path, what: str = "file") -> bytes:
    """The bytes of ``path``, refused (TooLargeError) without reading when it is over the file limit."""
    with open(path, "rb") as handle:
        _refuse_over_limit(path, os.fstat(handle.fileno()).st_size, what)
        return handle.read()


def check_sizes(kind: str, values: Mapping[str, object]) -> None:
    """ConfigError unless each size field in ``values`` is at most its bound in :data:`MAX_SIZES`."""
    for name, value in values.items():
        bound = MAX_SIZES.get(name)
        if bound is not None and isinstance(value, int | float) and value > bound:
            raise ConfigError(f"{kind} {name} = {value!r} is over the limit of {bound:g}")


def check_count(what: str, n: int, bound: int = MAX_MOTIONS_PER_REQUEST) -> int:
    """``n`` when it is a whole number in 1..``bound``, else ConfigError naming ``what``."""
    if isinstance(n, bool) or not isinstance(n, int) or not 1 <= n <= bound:
        raise ConfigError(f"{what} must be a whole number from 1 to {bound:,}, got {n!r}")
    return n


_TYPES: Mapping[str, tuple[type, ...]] = {
    "int": (int,), "float": (int, float), "bool": (bool,), "str": (str,)
}  # fmt: skip


def check_config(config: object) -> None:
    """ConfigError unless each field of a config dataclass has its declared type and is within bounds."""
    kind = type(config).__name__
    for f in dataclasses.fields(config):
        value = getattr(config, f.name)
        allowed = _TYPES.get(str(f.type))
        if allowed is None:
            continue
        if (isinstance(value, bool) and bool not in allowed) or not isinstance(value, allowed):
            raise ConfigError(f"{kind} {f.name} must be {f.type}, got {value!r}")
        if isinstance(value, float) and not math.isfinite(value):
            raise ConfigError(f"{kind} {f.name} must be a finite number, got {value!r}")
    values = {f.name: getattr(config, f.name) for f in dataclasses.fields(config)}
    check_sizes(kind, values)
    conditioning = values.get("n_actions", 1) * values.get("latent_dim", 1)
    if conditioning > MAX_CONDITIONING:
        raise ConfigError(
            f"{kind} n_actions × latent_dim = {conditioning:,} is over the limit of {MAX_CONDITIONING:,}"
        )
    widest = max([v for k, v in values.items() if "hidden" in k or k.endswith("_fc")] or [1])
    step = values.get("batch_size", 1) * values.get("window", 1) * widest
    if step > MAX_STEP_VALUES:
        raise ConfigError(
            f"{kind} batch_size × window × hidden size = {step:,} is over the limit of {MAX_STEP_VALUES:,}"
        )
