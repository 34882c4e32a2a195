"""Threads for the kernels that work particle by particle (the scan matcher).

The particles' proposals are independent, so they are split into chunks that run at once on
a thread pool, each chunk one call of a numba kernel compiled with ``nogil=True``: the result is
the same whatever the number of threads. Python threads rather than numba's ``parallel=True``:
numba's OpenMP layer aborts a process that forks after using it (gymnasium's
``AsyncVectorEnv`` and ``ProcessPoolExecutor`` fork on Linux), its work-queue layer gained little
here, and the TBB layer is a separate install. The pool is made per process, on first use.
"""

from __future__ import annotations

import os
from concurrent.futures import ThreadPoolExecutor

_threads = max(1, os.cpu_count() or 1)
_pool: ThreadPoolExecutor | None = None
_pool_pid: int | None = None


def kernel_threads() -> int:
    """How many threads the particle kernels use in this process (default: one per core)."""
    return _threads


def set_kernel_threads(threads: int) -> None:
    """Use ``threads`` threads for the particle kernels in this process (1: no pool at all)."""
    global _threads, _pool
    if not (isinstance(threads, int) and threads >= 1):
        raise ValueError(f"threads must be an integer >= 1, got {threads!r}")
    _threads = threads
    if _pool is not None:
        _pool.shutdown(wait=False)
        _pool = None


def run_in_chunks(kernel, n: int, *args) -> None:
    """``kernel(start, stop, *args)`` over ``range(n)`` split into one chunk per thread, all at once (this
    thread takes the first)."""
    global _pool, _pool_pid
    chunks = min(_threads, n)
    if chunks <= 1:
        kernel(0, n, *args)
        return
    if _pool is None or _pool_pid != os.getpid():  # none yet, or a fork's copy of the parent's
        _pool, _pool_pid = ThreadPoolExecutor(_threads - 1, thread_name_prefix="emmi-kernel"), os.getpid()
    bounds = [n * k // chunks for k in range(chunks + 1)]
    futures = [_pool.submit(kernel, bounds[k], bounds[k + 1], *args) for k in range(1, chunks)]
    kernel(bounds[0], bounds[1], *args)
    for future in futures:
        future.result()
