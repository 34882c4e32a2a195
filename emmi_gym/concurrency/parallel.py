"""Independent jobs in local worker processes behind a progress bar (the A/B runs, the benchmark)."""

from __future__ import annotations

import multiprocessing as mp
import os
from concurrent.futures import ProcessPoolExecutor, as_completed

from tqdm.auto import tqdm


def one_kernel_thread() -> None:
    """Run the particle kernels on one thread in this process: where processes are the parallelism
    (worker pools, vectorised envs), threads in each would only compete for the cores."""
    from .threads import set_kernel_threads

    set_kernel_threads(1)


def run_in_processes(function, jobs: list, *, workers: int | None = None, desc: str = "runs",
                     progress: bool = True, start_method: str | None = None) -> list:
    """``function(job)`` for every job, in ``workers`` processes (default one per core, each running
    its kernels on one thread; 1 = in this process), in the order they finish. ``start_method`` picks the multiprocessing context
    ("spawn" for jobs that use torch)."""
    workers = max(1, min(len(jobs), workers or os.cpu_count() or 1))
    results = []
    with tqdm(total=len(jobs), desc=desc, unit="run", disable=not progress) as bar:
        if workers == 1:
            for job in jobs:
                results.append(function(job))
                bar.update()
            return results
        context = mp.get_context(start_method) if start_method else None
        with ProcessPoolExecutor(workers, mp_context=context, initializer=one_kernel_thread) as pool:
            for future in as_completed([pool.submit(function, job) for job in jobs]):
                results.append(future.result())
                bar.update()
    return results
