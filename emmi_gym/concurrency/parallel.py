"""Independent jobs in local worker processes behind a progress bar (the A/B runs, the benchmark)."""

from __future__ import annotations

import multiprocessing as mp
import os
from collections.abc import Iterable
from concurrent.futures import FIRST_COMPLETED, ProcessPoolExecutor, as_completed, wait

from tqdm.auto import tqdm


def one_kernel_thread() -> None:
    """Run the particle kernels on one thread in this process: where processes are the parallelism
    (worker pools, vectorised envs), threads in each would only compete for the cores."""
    from .threads import set_kernel_threads

    set_kernel_threads(1)


def run_in_processes(function, jobs: Iterable, *, total: int | None = None, workers: int | None = None,
                     desc: str = "runs", progress: bool = True, start_method: str | None = None) -> list:
    """``function(job)`` for every job, in ``workers`` processes (default one per core, each running
    its kernels on one thread; 1 = in this process), in the order they finish. ``jobs`` may be a
    generator (``total``: how many it gives): a few jobs per worker are taken from it at a time, so a
    long list of jobs is never built. ``start_method`` picks the multiprocessing context ("spawn" for
    jobs that use torch)."""
    total = len(jobs) if total is None else total
    workers = max(1, min(total, workers or os.cpu_count() or 1))
    results = []
    with tqdm(total=total, desc=desc, unit="run", disable=not progress) as bar:
        if workers == 1:
            for job in jobs:
                results.append(function(job))
                bar.update()
            return results
        context = mp.get_context(start_method) if start_method else None
        with ProcessPoolExecutor(workers, mp_context=context, initializer=one_kernel_thread) as pool:
            running: set = set()
            for job in jobs:
                if len(running) >= 2 * workers:  # a job queued behind each running one keeps every worker busy
                    finished, running = wait(running, return_when=FIRST_COMPLETED)
                    results.extend(future.result() for future in finished)
                    bar.update(len(finished))
                running.add(pool.submit(function, job))
            for future in as_completed(running):
                results.append(future.result())
                bar.update()
    return results
