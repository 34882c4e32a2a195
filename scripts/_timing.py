"""Shared helper of the benchmark scripts: the median wall time of repeated calls."""

from __future__ import annotations

import time

import numpy as np


def median_seconds(fn, repeats: int) -> float:
    """Median wall time of ``repeats`` calls of ``fn``, after one warm-up call (numba compiles or loads)."""
    fn()
    times = []
    for _ in range(repeats):
        t0 = time.perf_counter()
        fn()
        times.append(time.perf_counter() - t0)
    return float(np.median(times))
