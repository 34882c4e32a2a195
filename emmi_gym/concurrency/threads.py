"""Threads for the numba kernels whose work splits into independent items: the particles' scan
matching and map copies, the expected map's disputed cells.

The items are split into chunks that run at once on a thread pool, each chunk one call of a
numba kernel compiled with ``nogil=True`` that writes only its own items' results: the result
is the same whatever the number of threads (or whichever thread runs a call: the calling thread,
once done with its own, runs the calls no pool thread has started). Calls of different kernels
that touch different arrays may share the pool the same way. Python threads rather than numba's ``parallel=True``:
numba's OpenMP layer aborts a process that forks after using it (gymnasium's
``AsyncVectorEnv`` and ``ProcessPoolExecutor`` fork on Linux), its work-queue layer gained little
here, and the TBB layer is a separate install. The pool is made per process, on first use.

Its threads are daemons. ``concurrent.futures.ThreadPoolExecutor``'s are not: the interpreter
joins them at exit after telling each registered one to stop, and a thread whose start is cut
short by a Ctrl-C (``Thread.start`` waits for the new thread to run) is never registered, so
the process hung at exit for ever (seen as a rare hang of ``emmi-gym train`` after SIGINT).
"""

from __future__ import annotations

import os
import queue
import threading
from concurrent.futures import Future

_threads = max(1, os.cpu_count() or 1)

#: Kernels whose items are grid cells give a thread at least this many (fewer are not worth its start).
MIN_CELLS_PER_THREAD = 20000


class _Call:
    """A submitted call, run once by whichever thread claims it first; its result goes to ``future``."""

    def __init__(self, fn, args):
        self.fn, self.args = fn, args
        self.future: Future = Future()
        self._claim = threading.Lock()

    def run_unless_taken(self) -> None:
        if not self._claim.acquire(blocking=False):  # another thread has it
            return
        try:
            self.future.set_result(self.fn(*self.args))
        except BaseException as error:  # handed to the caller, which raises it
            self.future.set_exception(error)


class _DaemonPool:
    """Worker threads that take calls from one queue and never keep the process alive."""

    def __init__(self, workers: int):
        self._calls: queue.SimpleQueue = queue.SimpleQueue()
        self.pid = os.getpid()
        for k in range(workers):
            threading.Thread(target=self._work, name=f"emmi-kernel-{k}", daemon=True).start()
        self.workers = workers

    def submit(self, fn, *args) -> _Call:
        call = _Call(fn, args)
        self._calls.put(call)
        return call

    def shutdown(self) -> None:
        for _ in range(self.workers):
            self._calls.put(None)

    def _work(self) -> None:
        while (call := self._calls.get()) is not None:
            call.run_unless_taken()


_pool: _DaemonPool | None = None


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
        _pool.shutdown()
        _pool = None


def chunk_bounds(n: int, min_chunk: int = 1) -> list[tuple[int, int]]:
    """``range(n)`` split into one (start, stop) chunk per thread, each of at least ``min_chunk`` items
    (one chunk if ``n`` is smaller). The first chunk, which :func:`run_calls` runs on the calling thread
    while the pool's threads wake up, is the largest (15 particles on two threads: 8 and 7; the other
    way round the caller waited for the eighth, 3-4% of an update)."""
    chunks = max(1, min(_threads, n // max(1, min_chunk)))
    bounds = [n - n * (chunks - k) // chunks for k in range(chunks + 1)]
    return list(zip(bounds[:-1], bounds[1:], strict=False))


def run_calls(calls: list[tuple]) -> list:
    """Run each call ``(function, *args)`` at once on the pool: this thread takes the first, then, in
    order, those no pool thread has started (so calls of unequal length, or more calls than threads,
    keep every thread busy); their results, in order."""
    global _pool
    if len(calls) == 1 or _threads == 1:
        return [call[0](*call[1:]) for call in calls]
    if _pool is None or _pool.pid != os.getpid():  # none yet, or a fork's copy of the parent's
        _pool = _DaemonPool(_threads - 1)
    submitted = [_pool.submit(*call) for call in calls[1:]]
    first = calls[0][0](*calls[0][1:])
    for call in submitted:
        call.run_unless_taken()
    return [first] + [call.future.result() for call in submitted]


def run_in_chunks(kernel, n: int, *args, min_chunk: int = 1) -> None:
    """``kernel(start, stop, *args)`` over ``range(n)`` split by :func:`chunk_bounds`, all at once."""
    run_calls([(kernel, start, stop, *args) for start, stop in chunk_bounds(n, min_chunk)])
