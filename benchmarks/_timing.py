"""Shared helper of the benchmark scripts: the wall time of repeated calls."""

from __future__ import annotations

import time

import numpy as np


def call_seconds(fn, calls: int, warmup: int = 1) -> np.ndarray:
    """The wall time of each of ``calls`` calls of ``fn``, after ``warmup`` calls (numba compiles or loads)."""
    for _ in range(warmup):
        fn()
    times = np.empty(calls)
    for k in range(calls):
        t0 = time.perf_counter()
        fn()
        times[k] = time.perf_counter() - t0
    return times


def median_seconds(fn, repeats: int) -> float:
    """Median wall time of ``repeats`` calls of ``fn``, after one warm-up call (numba compiles or loads)."""
    return float(np.median(call_seconds(fn, repeats)))
