"""The newest-wins runner and cancellable tasks, with real threads."""

from __future__ import annotations

import threading

from engine.errors import CancelledError
from explorer.workers import LatestRunner, TaskRunner


def test_newer_requests_make_pending_ones_stale(qtbot) -> None:
    runner = LatestRunner("test")
    gate = threading.Event()
    ran: list[int] = []
    results: list[tuple[int, object]] = []
    runner.finished.connect(lambda request, result: results.append((request, result)))

    def job(k: int) -> int:
        if k == 0:
            gate.wait(5)
        ran.append(k)
        return k * 10

    ids = [runner.submit(job, k) for k in range(6)]
    gate.set()
    runner.wait_idle()
    qtbot.waitUntil(lambda: len(results) == 2)
    assert ran == [0, 5]
    assert results == [(ids[0], 0), (ids[-1], 50)]
    assert runner.skipped == 4
    runner.shutdown()
    assert runner.submit(job, 9) == -1


def test_failures_are_reported_on_the_gui_thread(qtbot) -> None:
    runner = LatestRunner("test")
    seen: list[tuple[str, bool]] = []
    main = threading.current_thread()
    runner.failed.connect(lambda _r, exc: seen.append((str(exc), threading.current_thread() is main)))
    runner.submit(lambda: 1 / 0)
    qtbot.waitUntil(lambda: bool(seen))
    assert seen == [("division by zero", True)]
    runner.shutdown()


def test_task_progress_result_and_cancel(qtbot) -> None:
    tasks = TaskRunner(1)
    progress: list[float] = []
    done: list[object] = []
    errors: list[BaseException] = []
    release = threading.Event()

    def long_job(report, cancel) -> str:
        for k in range(100):
            report("working", k / 100)
            if cancel():
                raise CancelledError("stopped")
            release.wait(0.01)
        return "finished"

    task = tasks.run("long", long_job, done.append, errors.append)
    task.progress.connect(lambda _t, f: progress.append(f))
    qtbot.waitUntil(lambda: len(progress) > 2)
    with qtbot.waitSignal(task.cancelled, timeout=5_000):
        tasks.cancel_all()
    assert done == [] and errors == []
    tasks.run("quick", lambda report, cancel: 42, done.append, errors.append)
    qtbot.waitUntil(lambda: done == [42])
    qtbot.waitUntil(lambda: tasks.active == [])
    tasks.shutdown()
