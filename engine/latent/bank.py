"""The latent bank: every training code with its action, end location, source, modes and 2D maps."""

from __future__ import annotations

import io
import json
import logging
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from engine.errors import CancelledError, ConfigError, ModelFormatError
from engine.fileio import atomic_write_bytes
from engine.latent.columns import MetaColumns
from engine.latent.geometry import NeighbourBlend
from engine.latent.modes import ModeModel
from engine.latent.projection import Projection, make_projection
from engine.limits import read_bytes
from engine.npyio import load_npz

log = logging.getLogger(__name__)

FORMAT = "odmo-latent-bank"
# 2: a map fitted on the bank's own codes stores no copy of them; 3: sources and meta stored as columns
FORMAT_VERSION = 3


@dataclass
class LatentBank:
    """Codes of the training clips and what was learned from them.

    Attributes
    ----------
    codes : (N, D) float32; actions : (N,) int64 indices into ``action_names``.
    ends : (N, 3) float32 end locations; sources : (N,) object array of clip names (str, one per clip).
    meta : N rows of extra clip information (e.g. style) as :class:`MetaColumns` (a list of dicts given is
        turned into them); ``meta[i]`` is a dict; never used in training.
    modes : action index -> its modes (actions without codes have none).
    projections : "pca" | "tsne" | "umap" -> a fitted map of all N codes.
    weights_sha256 : checksum of the model weights the codes were encoded with ("" when unknown).
    """

    codes: np.ndarray
    actions: np.ndarray
    action_names: list[str]
    ends: np.ndarray
    sources: np.ndarray
    meta: Sequence[dict[str, Any]]
    modes: dict[int, ModeModel] = field(default_factory=dict)
    projections: dict[str, Projection] = field(default_factory=dict)
    weights_sha256: str = ""
    # (action, k) -> end-location lookup, built on first use (the bank's arrays are not edited in place).
    _end_blends: dict[tuple[int, int], NeighbourBlend] = field(
        default_factory=dict, init=False, repr=False, compare=False
    )

    def __post_init__(self) -> None:
        """Hold sources as shared str objects and meta as columns, whatever sequences were given."""
        self.sources = np.asarray(self.sources, dtype=object)
        self.meta = MetaColumns.from_dicts(self.meta)

    def indices_of(self, action: int) -> np.ndarray:
        """(n,) indices of the codes of one action."""
        if not 0 <= int(action) < len(self.action_names):
            raise ConfigError(f"unknown action {action}; the bank has {len(self.action_names)} actions")
        return np.flatnonzero(self.actions == int(action))

    def windows_of(self, index: int) -> np.ndarray:
        """Indices of every code of ``index``'s clip in time order (its windows in a bank built with a
        stride; just ``index`` in a bank of one code per clip)."""
        same = np.flatnonzero(self.sources == self.sources[int(index)])
        return same[np.argsort([int(self.meta[i].get("window_start", 0)) for i in same], kind="stable")]

    def end_location(self, codes: np.ndarray, action: int, k: int = 8) -> np.ndarray:
        """End locations (M, 3) of codes (M, D): continuous blend of the action's k nearest codes' ends."""
        idx = self.indices_of(action)
        if len(idx) == 0:
            raise ConfigError(f"action {self.action_names[int(action)]!r} has no codes in the bank")
        x = np.asarray(codes, dtype=np.float64)
        if x.ndim == 1:
            x = x[None]
        if x.ndim != 2 or x.shape[1] != self.codes.shape[1]:
            raise ConfigError(f"codes must have shape (M, {self.codes.shape[1]}), got {np.shape(codes)}")
        key = (int(action), k)
        if key not in self._end_blends:
            self._end_blends[key] = NeighbourBlend(self.codes[idx], self.ends[idx], k)
        return self._end_blends[key](x).astype(np.float32)

    def to_bytes(self, weights_sha256: str | None = None) -> bytes:
        """The bank as .npz bytes (plain arrays only; meta as JSON strings), tied to ``weights_sha256``."""
        built_from = self.weights_sha256 if weights_sha256 is None else weights_sha256
        arrays: dict[str, np.ndarray] = {
            "format": np.asarray(FORMAT),
            "version": np.asarray(FORMAT_VERSION, dtype=np.int64),
            "weights_sha256": np.asarray(built_from),
            "codes": np.asarray(self.codes, dtype=np.float32),
            "actions": np.asarray(self.actions, dtype=np.int64),
            "action_names": np.asarray(self.action_names, dtype=np.str_),
            "ends": np.asarray(self.ends, dtype=np.float32),
            **_source_arrays(self.sources),
            **MetaColumns.from_dicts(self.meta).to_arrays(),
            "mode_actions": np.asarray(sorted(self.modes), dtype=np.int64),
            "projection_names": np.asarray(sorted(self.projections), dtype=np.str_),
        }
        for action, model in self.modes.items():
            arrays.update(model.to_arrays(f"modes/{action}/"))
        for name, projection in self.projections.items():
            prefix = f"projections/{name}/"
            arrays.update(projection.to_arrays(prefix))
            if np.array_equal(arrays[f"{prefix}codes"], arrays["codes"]):
                del arrays[f"{prefix}codes"]
        buffer = io.BytesIO()
        np.savez(buffer, **arrays)
        return buffer.getvalue()

    def save(self, path: str | Path) -> None:
        """Write the bank to one .npz file atomically (in a model folder use ``modelio.save_bank``)."""
        atomic_write_bytes(path, self.to_bytes())
        log.info("saved latent bank of %d codes to %s", len(self.codes), path)

    @classmethod
    def load(cls, path: str | Path) -> LatentBank:
        """Read a bank written by :meth:`save`; ModelFormatError for missing, corrupt or newer files."""
        try:
            data = read_bytes(path, "latent bank")
        except FileNotFoundError as exc:
            raise ModelFormatError(f"{path}: latent bank not found") from exc
        except OSError as exc:
            raise ModelFormatError(f"{path}: not a readable latent bank ({exc})") from exc
        return cls.from_bytes(data, path)

    @classmethod
    def from_bytes(cls, data: bytes, path: str | Path) -> LatentBank:
        """Parse and validate the bytes of a bank file; errors name ``path``."""
        try:
            arrays = load_npz(data)
        except (OSError, ValueError) as exc:
            raise ModelFormatError(f"{path}: not a readable latent bank ({exc})") from exc
        try:
            return cls._from_arrays(arrays)
        except KeyError as exc:
            raise ModelFormatError(f"{path}: latent bank is missing {exc.args[0]!r}") from exc
        except ModelFormatError as exc:
            raise ModelFormatError(f"{path}: {exc}") from exc
        except (TypeError, ValueError, json.JSONDecodeError) as exc:
            raise ModelFormatError(f"{path}: malformed latent bank ({exc})") from exc

    @classmethod
    def _from_arrays(cls, arrays: dict[str, np.ndarray]) -> LatentBank:
        """Validate and assemble the arrays of a bank file."""
        if str(arrays["format"]) != FORMAT:
            raise ModelFormatError(f"not a latent bank (format {str(arrays['format'])!r})")
        version = int(arrays["version"])
        if version > FORMAT_VERSION:
            raise ModelFormatError(
                f"latent bank format {version} is newer than this program's ({FORMAT_VERSION}); upgrade"
            )
        if version < 1:
            raise ModelFormatError(f"invalid latent bank format version {version}")
        if version >= 2:
            shared = {f"projections/{n}/codes": arrays["codes"] for n in arrays["projection_names"]}
            arrays = shared | arrays
        n = len(arrays["codes"])
        if version >= 3:
            sources, meta = _read_sources(arrays, n), MetaColumns.from_arrays(arrays, n)
        else:
            sources, meta = arrays["sources"], [json.loads(str(m)) for m in arrays["meta"]]
        bank = cls(
            codes=arrays["codes"],
            actions=arrays["actions"],
            action_names=[str(name) for name in arrays["action_names"]],
            ends=arrays["ends"],
            sources=sources,
            meta=meta,
            modes={int(a): ModeModel.from_arrays(f"modes/{int(a)}/", arrays) for a in arrays["mode_actions"]},
            projections={
                str(n): Projection.from_arrays(f"projections/{n}/", arrays)
                for n in arrays["projection_names"]
            },
            weights_sha256=str(arrays["weights_sha256"]) if "weights_sha256" in arrays else "",
        )
        _validate(bank, ModelFormatError)
        return bank


def _source_arrays(sources: np.ndarray) -> dict[str, np.ndarray]:
    """Sources (N,) as a file stores them: the distinct names and an (N,) int32 index into them."""
    names, index = np.unique(np.asarray(sources, dtype=object), return_inverse=True)
    return {"source_names": names.astype(np.str_), "source_index": index.astype(np.int32).reshape(-1)}


def _read_sources(arrays: Mapping[str, np.ndarray], n: int) -> np.ndarray:
    """Sources (N,) of a version-3 file; ModelFormatError when the index does not fit the names."""
    names, index = arrays["source_names"], arrays["source_index"]
    fits = index.shape == (n,) and index.dtype.kind in "iu"
    if not fits or (n and not 0 <= index.min() <= index.max() < len(names)):
        raise ModelFormatError(f"source_index must pick one of {len(names)} names for each of {n} codes")
    return names.astype(object)[index]


def _validate(bank: LatentBank, error: type[Exception]) -> None:
    """Raise ``error`` unless the bank's arrays agree in length and range."""
    n = len(bank.codes)
    if bank.codes.ndim != 2:
        raise error(f"codes must be (N, D), got {bank.codes.shape}")
    if bank.actions.shape != (n,) or bank.ends.shape != (n, 3) or bank.sources.shape != (n,):
        raise error(
            f"{n} codes but actions {bank.actions.shape}, ends {bank.ends.shape}, "
            f"sources {bank.sources.shape}"
        )
    if len(bank.meta) != n:
        raise error(f"{n} codes but {len(bank.meta)} meta entries")
    if n and (bank.actions.min() < 0 or bank.actions.max() >= len(bank.action_names)):
        raise error(f"action indices must be in 0..{len(bank.action_names) - 1}")
    if not (np.all(np.isfinite(bank.codes)) and np.all(np.isfinite(bank.ends))):
        raise error("codes and ends must be finite")
    dim = bank.codes.shape[1]
    for name, projection in bank.projections.items():
        if projection.embedding_ is None or projection.embedding_.shape != (n, 2):
            raise error(f"projection {name!r} does not map all {n} codes")
        for key, values in projection.learned_arrays().items():
            if not np.all(np.isfinite(values)):
                raise error(f"projection {name!r}: {key} holds non-finite values")
    for action, model in bank.modes.items():
        if not 0 <= action < len(bank.action_names):
            raise error(f"modes for unknown action {action}")
        if len(model.labels_) != int(np.sum(bank.actions == action)):
            raise error(f"modes of action {action} label {len(model.labels_)} codes")
        if model.means_.shape[1] != dim:
            raise error(f"modes of action {action} are {model.means_.shape[1]}-d, codes {dim}-d")
        problem = model.problem()
        if problem is not None:
            raise error(f"modes of action {bank.action_names[action]!r}: {problem}")


def build_bank(
    codes: np.ndarray,
    actions: np.ndarray,
    ends: np.ndarray,
    sources: Sequence[str] | np.ndarray,
    meta: Sequence[Mapping[str, Any]],
    action_names: Sequence[str],
    *,
    k_range: tuple[int, int] = (3, 11),
    projections: Sequence[str] = ("pca", "tsne", "umap"),
    seed: int = 0,
    progress: Callable[[str, float], None] | None = None,
    cancel: Callable[[], bool] | None = None,
    covariance: str = "full",
) -> LatentBank:
    """Discover each action's modes (``covariance``: full or diagonal Gaussians) and fit the 2D maps of
    codes (N, D); progress(message, fraction 0..1)."""
    bank = LatentBank(
        codes=np.asarray(codes, dtype=np.float32),
        actions=np.asarray(actions, dtype=np.int64),
        action_names=[str(name) for name in action_names],
        ends=np.asarray(ends, dtype=np.float32),
        sources=sources if isinstance(sources, np.ndarray) else list(sources),
        meta=meta,
    )
    _validate(bank, ConfigError)
    maps = {name: make_projection(name, seed=seed) for name in projections}
    present = [int(a) for a in np.unique(bank.actions)]
    steps = len(present) + len(projections)
    done = 0

    def step(message: str) -> None:
        nonlocal done
        if cancel is not None and cancel():
            raise CancelledError("building the latent bank was cancelled")
        if progress is not None:
            progress(message, done / steps if steps else 1.0)
        done += 1

    for action in present:
        step(f"modes of {bank.action_names[action]}")
        model = ModeModel(k_range=k_range, seed=seed, covariance=covariance)
        bank.modes[action] = model.fit(bank.codes[bank.indices_of(action)])
    for name, projection in maps.items():
        step(f"{name} map")
        bank.projections[name] = projection.fit(bank.codes)
    if cancel is not None and cancel():
        raise CancelledError("building the latent bank was cancelled")
    if progress is not None:
        progress("done", 1.0)
    return bank
