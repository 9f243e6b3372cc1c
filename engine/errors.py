"""Typed errors raised by the engine; the CLI and the app turn them into one readable line."""

from __future__ import annotations

from pathlib import Path


class OdmoError(Exception):
    """Base class of every error the engine raises on bad input."""


class MotionFormatError(OdmoError):
    """A motion file (BVH, NPZ, NPY, pickle) is malformed; names the file and, if known, the line."""

    def __init__(self, message: str, path: str | Path | None = None, line: int | None = None):
        self.path = None if path is None else str(path)
        self.line = line
        self.reason = message
        where = ""
        if self.path is not None:
            where = self.path if line is None else f"{self.path}:{line}"
            where += ": "
        super().__init__(f"{where}{message}")


class DataError(OdmoError):
    """A dataset folder or its labels cannot be used."""


class ModelFormatError(OdmoError):
    """A model folder, its weights or its latent bank are missing, corrupt or of a newer format."""


class ConfigError(OdmoError):
    """A user-supplied parameter is invalid (unknown action, wrong shape, bad range)."""


class CancelledError(OdmoError):
    """Long work was cancelled by its caller."""


class FolderBusyError(OdmoError):
    """Another process holds the write lock of an output or model folder."""


class TooLargeError(OdmoError):
    """An input file or a requested size exceeds the stated limits (see :mod:`engine.limits`)."""


class OutputError(OdmoError):
    """An output file or folder cannot be written (no such folder, a file in the way, no space, no right)."""
