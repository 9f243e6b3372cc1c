"""Safe file writing: atomic replaces, cleanup of temporaries a killed writer left, folder locks.

A temporary file is named ``.<target>.odmo-<pid>-<random>.tmp`` next to its target, so a later writer
into the same folder can tell a live writer's temporary (its process still runs) from one that a killed
process left behind, and removes only the latter.
"""

from __future__ import annotations

import contextlib
import errno
import fcntl
import logging
import os
import re
import tempfile
import time
from collections.abc import Iterator
from pathlib import Path
from typing import IO

from engine.errors import FolderBusyError, OutputError

log = logging.getLogger(__name__)

LOCK_FILE = ".odmo-lock"
_TEMP_RE = re.compile(r"^\..+\.odmo-(?P<pid>\d+)-[A-Za-z0-9_]+\.tmp$")


@contextlib.contextmanager
def atomic_write(path: str | Path, mode: str = "w", **kwargs) -> Iterator[IO]:
    """Open a temporary sibling of ``path`` for writing and move it into place on success."""
    path = Path(path)
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
        remove_stale_temporaries(path.parent)
        fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.odmo-{os.getpid()}-", suffix=".tmp", dir=path.parent)
    except OSError as exc:
        raise OutputError(f"{path}: cannot write there ({_reason(exc)})") from None
    try:
        with os.fdopen(fd, mode, **kwargs) as handle:
            yield handle
            handle.flush()
            os.fsync(handle.fileno())
        os.chmod(tmp, 0o666 & ~_umask())
        os.replace(tmp, path)
    except BaseException as exc:
        with contextlib.suppress(FileNotFoundError):
            os.unlink(tmp)
        if isinstance(exc, OSError):
            raise OutputError(f"{path}: writing failed, nothing was written ({_reason(exc)})") from None
        raise


def _reason(exc: OSError) -> str:
    """The plain reason of an OS error (no errno, no repeated path)."""
    reasons = {
        errno.EEXIST: "a file is in the way of a folder",
        errno.ENOTDIR: "a file is in the way of a folder",
    }
    return reasons.get(exc.errno, exc.strerror or str(exc))


def remove_stale_temporaries(folder: str | Path) -> list[Path]:
    """Delete the temporaries of our naming in ``folder`` whose writing process no longer runs."""
    removed = []
    try:
        names = os.listdir(folder)
    except OSError:
        return removed
    for name in names:
        match = _TEMP_RE.match(name)
        if match is None or _process_alive(int(match["pid"])):
            continue
        stale = Path(folder) / name
        with contextlib.suppress(FileNotFoundError):
            stale.unlink()
            removed.append(stale)
            log.info("removed %s, left by a writer that was killed", stale)
    return removed


def _process_alive(pid: int) -> bool:
    """Whether a process with this id runs on this machine."""
    if pid == os.getpid():
        return True
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except PermissionError:
        return True
    except OverflowError:
        return False
    return True


def _umask() -> int:
    """The process umask (mkstemp creates files 0600; finished files get the usual permissions)."""
    mask = os.umask(0)
    os.umask(mask)
    return mask


def atomic_write_bytes(path: str | Path, data: bytes) -> None:
    """Write ``data`` to ``path`` atomically."""
    with atomic_write(path, "wb") as handle:
        handle.write(data)


def atomic_write_text(path: str | Path, text: str) -> None:
    """Write ``text`` (UTF-8) to ``path`` atomically."""
    with atomic_write(path, "w", encoding="utf-8", newline="\n") as handle:
        handle.write(text)


HOLDER_WAIT_S = 0.5  # how long a refused locker waits for the holder to write its pid


def _lock_holder(fd: int) -> str:
    """The lock holder's "pid N" from the lock file; the holder writes it just after locking, so an empty
    file is read again for up to ``HOLDER_WAIT_S``."""
    deadline = time.monotonic() + HOLDER_WAIT_S
    while True:
        text = os.pread(fd, 64, 0).decode("ascii", "replace").strip()
        if text or time.monotonic() > deadline:
            return text or "another process"
        time.sleep(0.01)


@contextlib.contextmanager
def folder_lock(folder: str | Path, what: str = "writing") -> Iterator[Path]:
    """Hold an advisory exclusive lock on ``folder`` (created if missing) while the block runs.

    A second holder, in this process or another, gets FolderBusyError at once instead of waiting; the
    lock goes with the process, so a killed writer never leaves the folder locked.
    """
    folder = Path(folder)
    try:
        folder.mkdir(parents=True, exist_ok=True)
        fd = os.open(folder / LOCK_FILE, os.O_RDWR | os.O_CREAT, 0o666)
    except OSError as exc:
        raise OutputError(f"{folder}: cannot write there ({_reason(exc)})") from None
    try:
        try:
            fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except OSError as exc:
            if exc.errno not in (errno.EWOULDBLOCK, errno.EAGAIN, errno.EACCES):
                raise
            holder = _lock_holder(fd)
            raise FolderBusyError(
                f"{folder}: another odmo process ({holder}) is {what} there; wait for it to finish "
                "or choose another folder"
            ) from None
        os.ftruncate(fd, 0)
        os.pwrite(fd, f"pid {os.getpid()}\n".encode(), 0)
        yield folder
    finally:
        os.close(fd)
