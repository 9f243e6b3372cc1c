"""The timing loop the widget benchmarks share."""

from __future__ import annotations

import time
from collections.abc import Callable


def timings_ms(step: Callable[[int], None], repeats: int) -> list[float]:
    """Times in ms of ``step(i)`` for i = 0 … ``repeats`` − 1, after one warm-up call ``step(-1)``."""
    step(-1)
    times = []
    for i in range(repeats):
        start = time.perf_counter()
        step(i)
        times.append((time.perf_counter() - start) * 1e3)
    return times
