"""An allow-list unpickler for data-only pickles (numpy arrays, lists, dicts, numbers, strings).

Only numpy's array, dtype and scalar reconstructors (and latin-1 ``_codecs.encode``, which protocol-2
pickles use for bytes) resolve; any other global refuses the whole file. Sizes are bounded too: the file
by the stated file limit, each length-prefixed item by the bytes left in the file, and each array an
allowed constructor makes by the size of the file (a data pickle carries its arrays' bytes), so a crafted
pickle of a few bytes cannot ask for terabytes.
"""

from __future__ import annotations

import contextvars
import io
import math
import pickle
from pathlib import Path
from typing import Any

import numpy as np

from engine.errors import MotionFormatError, OdmoError
from engine.limits import read_bytes

_LIMIT: contextvars.ContextVar[int] = contextvars.ContextVar("pickle_array_limit", default=0)


def _latin1_bytes(text: str, encoding: str = "latin1") -> bytes:
    """``_codecs.encode`` as protocol-2 pickles use it for bytes, limited to latin-1 text."""
    if not isinstance(text, str) or encoding not in ("latin1", "latin-1"):
        raise pickle.UnpicklingError(f"refused _codecs.encode with encoding {encoding!r}")
    return text.encode("latin1")


def _check_size(shape: Any, dtype: Any) -> tuple[int, ...]:
    """``shape`` as a tuple, or UnpicklingError when the array would be larger than the pickle read."""
    try:
        dims = (int(shape),) if isinstance(shape, int) else tuple(int(n) for n in shape)
        nbytes = math.prod(dims) * np.dtype(dtype).itemsize
    except (TypeError, ValueError) as exc:
        raise pickle.UnpicklingError(f"refused array of shape {shape!r}: {exc}") from None
    limit = _LIMIT.get()
    if min(dims, default=1) < 0 or nbytes > limit:
        raise pickle.UnpicklingError(
            f"refused array of shape {dims} ({nbytes:,} bytes; the whole file has {limit:,})"
        )
    return dims


class _BoundedArray(np.ndarray):
    """What the name ``numpy.ndarray`` resolves to: calling it makes a plain, size-checked ndarray."""

    def __new__(cls, shape: Any, dtype: Any = float, *args: Any, **kwargs: Any) -> np.ndarray:
        return np.ndarray(_check_size(shape, dtype), dtype, *args, **kwargs)


def _reconstruct(subtype: Any, shape: Any, dtype: Any) -> np.ndarray:
    """numpy's ``_reconstruct`` for plain ndarrays only, size-checked."""
    if subtype is not _BoundedArray:
        raise pickle.UnpicklingError(f"refused array subtype {subtype!r}")
    return np._core.multiarray._reconstruct(np.ndarray, _check_size(shape, dtype), dtype)


# Globals a data pickle of numpy arrays needs; anything else (os.system, eval, ...) is refused.
# Lists, dicts, tuples, ints, floats and strings have their own opcodes and need no global.
_ALLOWED = {
    ("numpy", "ndarray"): _BoundedArray,
    ("numpy", "dtype"): np.dtype,
    ("numpy._core.multiarray", "_reconstruct"): _reconstruct,
    ("numpy._core.multiarray", "scalar"): np._core.multiarray.scalar,
    ("numpy._core.numeric", "_frombuffer"): np._core.numeric._frombuffer,
    ("_codecs", "encode"): _latin1_bytes,
}
_LEGACY_MODULES = {
    "numpy.core.multiarray": "numpy._core.multiarray",
    "numpy.core.numeric": "numpy._core.numeric",
}


class _BoundedReader(io.BytesIO):
    """The file's bytes, refusing any read longer than what is left (a length field that lies)."""

    def read(self, n: int | None = -1) -> bytes:
        """``n`` bytes, or UnpicklingError when fewer are left."""
        if n is not None and n > len(self.getbuffer()) - self.tell():
            raise pickle.UnpicklingError(f"an item claims {n:,} bytes, more than the file holds")
        return super().read(n)


class _AllowListUnpickler(pickle._Unpickler):
    """Resolves only the globals in the allow-list; the pure-Python unpickler, whose reads are bounded."""

    def find_class(self, module: str, name: str) -> Any:
        """The allowed object for ``module.name``; refuses everything else."""
        found = _ALLOWED.get((_LEGACY_MODULES.get(module, module), name))
        if found is None:
            raise pickle.UnpicklingError(f"refused global {module}.{name}")
        return found


def load_data_pickle(path: str | Path) -> Any:
    """Unpickle ``path`` allowing only data (numpy arrays and dtypes, lists, dicts, tuples, numbers, str)."""
    path = Path(path)
    try:
        data = read_bytes(path, "pickle")
    except OSError as exc:
        raise MotionFormatError(f"cannot read ({exc.strerror or exc})", path) from None
    token = _LIMIT.set(max(len(data), 1))
    try:
        return _AllowListUnpickler(_BoundedReader(data)).load()
    except pickle.UnpicklingError as exc:
        raise MotionFormatError(f"unsafe or corrupt pickle, not loaded: {exc}", path) from None
    except (EOFError, ValueError, TypeError, AttributeError, IndexError, KeyError, OverflowError) as exc:
        raise MotionFormatError(f"corrupt pickle ({type(exc).__name__}: {exc})", path) from None
    except MemoryError:
        raise MotionFormatError("the pickle asks for more memory than there is; not loaded", path) from None
    except OdmoError:
        raise
    finally:
        _LIMIT.reset(token)
