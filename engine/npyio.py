"""Bounded reading of .npy and .npz files: no pickles, and no array larger than the bytes that hold it.

``numpy.load`` allocates an array from the shape its header declares before reading the data, so a few
bytes of header can ask for terabytes; these readers check each header against the file (or archive
member) first. Errors are ``ValueError`` with a message for the caller to wrap in its own typed error.
"""

from __future__ import annotations

import io
import zipfile
import zlib
from pathlib import Path
from typing import IO

import numpy as np
from numpy.lib import format as npformat

from engine.limits import check_file_size, max_file_bytes

_CHUNK = 2**24


def _read_array(handle: IO[bytes], available: int) -> np.ndarray:
    """The array in an open .npy stream whose data may take at most ``available`` bytes."""
    version = npformat.read_magic(handle)
    if version not in ((1, 0), (2, 0), (3, 0)):
        raise ValueError(f"unsupported .npy format version {version}")
    reader = npformat.read_array_header_1_0 if version == (1, 0) else npformat.read_array_header_2_0
    shape, fortran, dtype = reader(handle)
    if dtype.hasobject:
        raise ValueError("it holds Python objects (pickled data), which are never loaded")
    nbytes = int(np.prod(shape, dtype=np.float64)) * dtype.itemsize
    if nbytes > available:
        raise ValueError(f"its header declares a {shape} array of {nbytes:,} bytes in {available:,} bytes")
    array = np.empty(int(np.prod(shape)), dtype=dtype)
    view, got = memoryview(array).cast("B"), 0
    while got < nbytes and (n := handle.readinto(view[got : got + _CHUNK])):
        got += n
    if got != nbytes or handle.read(1):  # reading to the end also checks a zip member's CRC
        raise ValueError(f"{got:,} bytes of array data where the header declares {nbytes:,}")
    return array.reshape(shape[::-1]).T if fortran else array.reshape(shape)


def load_npy(path: str | Path) -> np.ndarray:
    """The array of a .npy file, within the file-size limit."""
    size = check_file_size(path, ".npy file")
    with open(path, "rb") as handle:
        return _read_array(handle, size)


def load_npz(source: str | Path | bytes) -> dict[str, np.ndarray]:
    """Every array of an .npz archive (a path or its bytes) by name, within the file-size limit."""
    if isinstance(source, bytes):
        handle: IO[bytes] = io.BytesIO(source)
    else:
        check_file_size(source, ".npz file")
        handle = open(source, "rb")  # noqa: SIM115 (closed below, also when ZipFile fails)
    try:
        with zipfile.ZipFile(handle) as archive:
            members = archive.infolist()
            declared = sum(m.file_size for m in members)
            if declared > max_file_bytes():
                raise ValueError(f"its members declare {declared:,} bytes, over the file-size limit")
            arrays = {}
            for member in members:
                name = member.filename.removesuffix(".npy")
                with archive.open(member) as stream:
                    arrays[name] = _read_array(stream, member.file_size)
            return arrays
    except (zipfile.BadZipFile, zlib.error, EOFError, KeyError, NotImplementedError) as exc:
        raise ValueError(f"{type(exc).__name__}: {exc}") from None
    finally:
        handle.close()
