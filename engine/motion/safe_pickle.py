"""An allow-list unpickler for data-only pickles (numpy arrays, lists, dicts, numbers, strings).

Only numpy's array, dtype and scalar reconstructors (and latin-1 ``_codecs.encode``, which protocol-2
pickles use for bytes) resolve; any other global refuses the whole file.
"""

from __future__ import annotations

import pickle
from pathlib import Path
from typing import Any

import numpy as np

from engine.errors import MotionFormatError


def _latin1_bytes(text: str, encoding: str = "latin1") -> bytes:
    """``_codecs.encode`` as protocol-2 pickles use it for bytes, limited to latin-1 text."""
    if not isinstance(text, str) or encoding not in ("latin1", "latin-1"):
        raise pickle.UnpicklingError(f"refused _codecs.encode with encoding {encoding!r}")
    return text.encode("latin1")


# Globals a data pickle of numpy arrays needs; anything else (os.system, eval, ...) is refused.
# Lists, dicts, tuples, ints, floats and strings have their own opcodes and need no global.
_ALLOWED = {
    ("numpy", "ndarray"): np.ndarray,
    ("numpy", "dtype"): np.dtype,
    ("numpy._core.multiarray", "_reconstruct"): np._core.multiarray._reconstruct,
    ("numpy._core.multiarray", "scalar"): np._core.multiarray.scalar,
    ("numpy._core.numeric", "_frombuffer"): np._core.numeric._frombuffer,
    ("_codecs", "encode"): _latin1_bytes,
}
_LEGACY_MODULES = {
    "numpy.core.multiarray": "numpy._core.multiarray",
    "numpy.core.numeric": "numpy._core.numeric",
}


class _AllowListUnpickler(pickle.Unpickler):
    """Resolves only the globals in the allow-list."""

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
        with path.open("rb") as handle:
            return _AllowListUnpickler(handle).load()
    except pickle.UnpicklingError as exc:
        raise MotionFormatError(f"unsafe or corrupt pickle, not loaded: {exc}", path) from None
    except (EOFError, ValueError, TypeError, AttributeError, IndexError) as exc:
        raise MotionFormatError(f"corrupt pickle ({type(exc).__name__}: {exc})", path) from None
