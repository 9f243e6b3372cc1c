"""Background work: a newest-wins runner for live decoding and cancellable tasks with progress.

Results re-enter Qt through signals of QObjects living on the GUI thread (queued connections), so
every slot connected to them runs on the main thread.
"""

from __future__ import annotations

import logging
import threading
import time
from collections.abc import Callable
from concurrent.futures import Future, ThreadPoolExecutor
from typing import Any

from PySide6.QtCore import QObject, Signal

from engine.errors import CancelledError

log = logging.getLogger(__name__)

Progress = Callable[[str, float], None]
Cancel = Callable[[], bool]


class LatestRunner(QObject):
    """A one-thread executor where a newer request makes every older, not yet started one stale.

    ``submit(fn, *args)`` returns a request id; ``finished(id, result)`` or ``failed(id, exc)`` is
    emitted on the GUI thread for requests that ran. Stale requests are skipped and never reported.
    """

    finished = Signal(int, object)
    failed = Signal(int, object)

    def __init__(self, name: str = "decode", parent: QObject | None = None) -> None:
        super().__init__(parent)
        self._executor = ThreadPoolExecutor(max_workers=1, thread_name_prefix=f"odmo-{name}")
        self._lock = threading.Lock()
        self._newest = 0
        self._closed = False
        self.skipped = 0
        self.last_run_s = 0.0  # seconds the last request that ran took in the worker (for benchmarks)

    @property
    def newest(self) -> int:
        """Id of the newest request submitted."""
        return self._newest

    def submit(self, fn: Callable[..., Any], *args: Any) -> int:
        """Queue ``fn(*args)``; any older request that has not started yet will be skipped."""
        with self._lock:
            if self._closed:
                return -1
            self._newest += 1
            request = self._newest
        self._executor.submit(self._run, request, fn, args)
        return request

    def _run(self, request: int, fn: Callable[..., Any], args: tuple) -> None:
        with self._lock:
            stale = request != self._newest or self._closed
        if stale:
            self.skipped += 1
            return
        start = time.perf_counter()
        try:
            result = fn(*args)
        except Exception as exc:
            log.debug("request %d failed: %s", request, exc)
            self.failed.emit(request, exc)
            return
        finally:
            self.last_run_s = time.perf_counter() - start
        self.finished.emit(request, result)

    def wait_idle(self, timeout: float = 10.0) -> None:
        """Block until every request queued so far has run or been skipped."""
        self._executor.submit(lambda: None).result(timeout)

    def shutdown(self) -> None:
        """Drop pending requests and join the thread."""
        with self._lock:
            self._closed = True
        self._executor.shutdown(wait=True, cancel_futures=True)


class Task(QObject):
    """One long job run off the GUI thread with progress and a cancel flag.

    The job is called as ``fn(progress, cancel)``: ``progress(text, fraction)`` may be called from the
    worker thread, ``cancel()`` returns True once :meth:`cancel` was requested. Exactly one of
    ``finished(result)``, ``failed(exc)`` or ``cancelled()`` is emitted, on the GUI thread.
    """

    progress = Signal(str, float)
    finished = Signal(object)
    failed = Signal(object)
    cancelled = Signal()

    def __init__(self, title: str, fn: Callable[[Progress, Cancel], Any], parent: QObject | None = None):
        super().__init__(parent)
        self.title = title
        self._fn = fn
        self._cancel = threading.Event()
        self._future: Future | None = None

    def start(self, executor: ThreadPoolExecutor) -> None:
        """Run the job on ``executor``."""
        self._future = executor.submit(self._run)

    def cancel(self) -> None:
        """Ask the job to stop at its next cancel check; its result is dropped either way."""
        self._cancel.set()

    @property
    def is_cancelled(self) -> bool:
        """True once cancel was requested."""
        return self._cancel.is_set()

    def done(self) -> bool:
        """True when the job has returned (or was never started)."""
        return self._future is None or self._future.done()

    def _run(self) -> None:
        try:
            result = self._fn(
                lambda text, frac: self.progress.emit(str(text), float(frac)), self._cancel.is_set
            )
        except CancelledError:
            self.cancelled.emit()
            return
        except Exception as exc:
            log.debug("task %r failed: %s", self.title, exc, exc_info=True)
            self.failed.emit(exc)
            return
        if self._cancel.is_set():
            self.cancelled.emit()
        else:
            self.finished.emit(result)


class TaskRunner(QObject):
    """Runs :class:`Task` jobs on a small thread pool and keeps them alive until they report."""

    started = Signal(object)
    ended = Signal(object)

    def __init__(self, threads: int = 2, parent: QObject | None = None) -> None:
        super().__init__(parent)
        self._executor = ThreadPoolExecutor(max_workers=threads, thread_name_prefix="odmo-task")
        self._tasks: list[Task] = []

    @property
    def active(self) -> list[Task]:
        """Tasks that have not reported yet."""
        return list(self._tasks)

    def run(
        self,
        title: str,
        fn: Callable[[Progress, Cancel], Any],
        on_done: Callable[[Any], None],
        on_error: Callable[[BaseException], None],
    ) -> Task:
        """Start ``fn`` in the background; ``on_done`` / ``on_error`` run on the GUI thread."""
        task = Task(title, fn, self)
        task.finished.connect(on_done)
        task.failed.connect(on_error)
        for signal in (task.finished, task.failed, task.cancelled):
            signal.connect(lambda *_a, t=task: self._forget(t))
        self._tasks.append(task)
        self.started.emit(task)
        task.start(self._executor)
        return task

    def _forget(self, task: Task) -> None:
        if task in self._tasks:
            self._tasks.remove(task)
            self.ended.emit(task)
            task.deleteLater()

    def cancel_all(self) -> None:
        """Ask every running task to stop."""
        for task in self._tasks:
            task.cancel()

    def shutdown(self) -> None:
        """Cancel every task and join the threads."""
        self.cancel_all()
        self._executor.shutdown(wait=True, cancel_futures=True)
