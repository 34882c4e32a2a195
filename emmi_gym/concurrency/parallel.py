"""Work in local worker processes: independent jobs behind a progress bar (the A/B runs, the benchmark), and
objects that live in a process of their own and answer calls one at a time (:class:`ProcessActor`)."""

from __future__ import annotations

import multiprocessing as mp
import os
import signal
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


#: The start method of :class:`ProcessActor` processes, as Stable-Baselines3's ``SubprocVecEnv`` picks it: a fork
#: of a process running torch's or the kernels' threads can deadlock.
ACTOR_START_METHOD = "forkserver" if "forkserver" in mp.get_all_start_methods() else "spawn"


class ActorFailed(RuntimeError):
    """A :class:`ProcessActor`'s process stopped, or its object raised; says which actor and what happened."""


def _serve(connection, factory, args) -> None:
    """The actor process: build ``factory(*args)``, then run each ``(method, args)`` received and send back
    ``("ok", result)`` or ``("error", message)`` until ``None`` arrives. Ctrl-C is the parent's to handle."""
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    try:
        target = factory(*args)
        connection.send(("ok", None))
        while (call := connection.recv()) is not None:
            method, call_args = call
            try:
                connection.send(("ok", getattr(target, method)(*call_args)))
            except Exception as error:  # noqa: BLE001 - any failure goes back to the caller
                connection.send(("error", f"{type(error).__name__}: {error}"))
    except Exception as error:  # noqa: BLE001 - the object could not be built
        connection.send(("error", f"{type(error).__name__}: {error}"))
    except (EOFError, KeyboardInterrupt):  # the parent went away
        pass
    finally:
        connection.close()


class ProcessActor:
    """An object built by ``factory(*args)`` in a local process of its own (the Ray actor's model, with
    ``multiprocessing``): :meth:`submit` starts one of its methods there, :meth:`result` waits for what it
    returned. A failure in the process, or its end, is an :class:`ActorFailed` naming ``name``, never a hang.
    The process ignores Ctrl-C (the parent handles it and closes the actor)."""

    def __init__(self, name: str, factory, *args, start_method: str = ACTOR_START_METHOD):
        context = mp.get_context(start_method)
        self.name = name
        self._connection, child = context.Pipe()
        self.process = context.Process(target=_serve, args=(child, factory, args), daemon=True, name=name)
        self.process.start()
        child.close()  # only the process holds its end: its exit ends the pipe, and recv raises EOFError
        self._waiting = True  # for the object to be built
        self._closing = False

    def submit(self, method: str, *args) -> None:
        """Start ``method(*args)`` in the process (after the previous call's result was read)."""
        if self._waiting:
            self.result()
        try:
            self._connection.send((method, args))
        except (OSError, ValueError) as error:
            raise ActorFailed(f"{self.name}: the process has stopped ({error})") from None
        self._waiting = True

    def result(self):
        """What the submitted call returned; raises :class:`ActorFailed` if it raised or the process ended."""
        self._waiting = False
        try:
            status, value = self._connection.recv()
        except (EOFError, OSError):
            self.process.join(1.0)
            raise ActorFailed(f"{self.name}: the process has stopped (exit code {self.process.exitcode})") from None
        if status == "error":
            raise ActorFailed(f"{self.name}: {value}")
        return value

    def ask_to_close(self) -> None:
        """Ask the process to end once the call under way, if any, is done."""
        if not self._closing:
            self._closing = True
            try:
                self._connection.send(None)
            except (OSError, ValueError):
                pass

    def close(self, timeout: float) -> None:
        """Ask the process to end, wait up to ``timeout`` seconds (it may be amid a call), then terminate it."""
        self.ask_to_close()
        self.process.join(timeout)
        if self.process.is_alive():
            self.process.terminate()
            self.process.join()
        self._connection.close()
