"""Timing shared by the benchmarks: the median of repeated wall-clock runs."""

from __future__ import annotations

import statistics
import time


def median_time(fn, repeat: int) -> tuple[float, object]:
    """Median wall-clock seconds of ``repeat`` calls of ``fn``, and the last call's result."""
    times, out = [], None
    for _ in range(repeat):
        t0 = time.perf_counter()
        out = fn()
        times.append(time.perf_counter() - t0)
    return statistics.median(times), out
