"""Shared helper of the benchmark scripts: the wall time of repeated calls, and the wall time spent inside
chosen methods while a run goes on."""

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


_OPEN: list = []  # [key, seconds spent in the timed calls inside it] of each timed call under way, innermost last


def timed(owner, name: str, bucket: dict, key: str, when=None) -> None:
    """Accumulate the wall time of every call of ``owner.name`` (a class's method, or a function as the module
    that calls it names it) into ``bucket[key]``, less the time of the timed calls made inside it (which go
    to their own keys). With ``when``, only the calls for which ``when(*args)`` holds are timed (for a
    method, ``args[0]`` is the instance)."""
    original = getattr(owner, name)

    def wrapper(*args, **kwargs):
        if when is not None and not when(*args):
            return original(*args, **kwargs)
        _OPEN.append([key, 0.0])
        t0 = time.perf_counter()
        try:
            return original(*args, **kwargs)
        finally:
            spent = time.perf_counter() - t0
            inner = _OPEN.pop()[1]
            bucket[key] += spent - inner
            if _OPEN:
                _OPEN[-1][1] += spent

    setattr(owner, name, wrapper)


def inside(key: str) -> bool:
    """Whether a timed call of ``key`` is under way (for a ``when`` of :func:`timed`)."""
    return any(open_key == key for open_key, _ in _OPEN)
