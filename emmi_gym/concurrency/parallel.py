"""Work in local worker processes: independent jobs behind a progress bar (the A/B runs, the benchmark), and
objects that live in a process of their own and answer calls one at a time (:class:`ProcessActor`)."""

from __future__ import annotations

import multiprocessing as mp
import os
import pickle
import signal
import threading
import time
import warnings
from collections.abc import Iterable
from concurrent.futures import FIRST_COMPLETED, ProcessPoolExecutor, as_completed, wait
from contextlib import contextmanager
from multiprocessing import resource_tracker

from .progress import progress_bar


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
    jobs that use torch). A Ctrl-C (or SIGTERM, where the command handles it as one) stops every worker's
    job as it would stop the job in this process (:func:`_stop_pool`), and is raised here once they ended."""
    total = len(jobs) if total is None else total
    workers = max(1, min(total, workers or os.cpu_count() or 1))
    results = []
    with progress_bar(total=total, desc=desc, unit="run", disable=not progress) as bar:
        if workers == 1:
            for job in jobs:
                results.append(function(job))
                bar.update()
            return results
        context = mp.get_context(start_method) if start_method else mp.get_context()
        started = context.SimpleQueue()  # each worker's pid, so that a Ctrl-C can be passed on to it
        with ProcessPoolExecutor(workers, mp_context=context, initializer=_pool_worker,
                                 initargs=(started,)) as pool:
            running: set = set()
            try:
                for job in jobs:
                    if len(running) >= 2 * workers:  # a job queued behind each running one keeps every worker busy
                        finished, running = wait(running, return_when=FIRST_COMPLETED)
                        results.extend(future.result() for future in finished)
                        bar.update(len(finished))
                    running.add(pool.submit(_pool_job, function, job))
                for future in as_completed(running):
                    results.append(future.result())
                    bar.update()
            except KeyboardInterrupt:
                _stop_pool(pool, started, running)
                raise
    return results


#: A pool worker's state: whether a job runs in it (Ctrl-C then interrupts the job), and whether the pool stops
#: (no other job starts).
_pool_state = {"job": False, "stopping": False}


def _pool_worker(started) -> None:
    """A pool worker's start: out of the terminal's process group (the parent passes Ctrl-C on, once), Ctrl-C
    handled by :func:`_interrupt_pool_worker` and SIGTERM as Ctrl-C, then its pid to the queue ``started`` (so
    that the Ctrl-C the parent passes on finds the handler in place), then its kernels on one thread."""
    from .interrupts import as_ctrl_c

    leave_terminal_signals()
    signal.signal(signal.SIGINT, _interrupt_pool_worker)
    signal.signal(signal.SIGTERM, as_ctrl_c)
    started.put(os.getpid())
    one_kernel_thread()


def _interrupt_pool_worker(signum, frame) -> None:
    """Ctrl-C in a pool worker: no other job starts, and the job under way is interrupted (an idle worker, whose
    Ctrl-C would print a traceback from the pool's own code, just ends once the pool shuts down)."""
    _pool_state["stopping"] = True
    if _pool_state["job"]:
        raise KeyboardInterrupt


def _pool_job(function, job):
    """``function(job)`` in a pool worker, unless the pool is stopping (a job the pool had queued ahead)."""
    if _pool_state["stopping"]:
        raise KeyboardInterrupt
    _pool_state["job"] = True
    try:
        return function(job)
    except KeyboardInterrupt:  # the job stopped on Ctrl-C (its own handler's, say): none other starts
        _pool_state["stopping"] = True
        raise
    finally:
        _pool_state["job"] = False


def _stop_pool(pool: ProcessPoolExecutor, started, running: set) -> None:
    """After a Ctrl-C in this process: pass it on to each worker that ``started`` says was started, also to one
    that starts meanwhile (their jobs stop as they would here, a training run saving a checkpoint), cancel the
    jobs not started and wait for the ``running`` ones to end; a second Ctrl-C meanwhile is ignored."""
    handlers = {sig: signal.signal(sig, signal.SIG_IGN) for sig in (signal.SIGINT, signal.SIGTERM)} \
        if threading.current_thread() is threading.main_thread() else {}
    try:
        while True:  # a worker that stops its pool (its flag set) starts no job queued behind
            while not started.empty():
                try:
                    os.kill(started.get(), signal.SIGINT)
                except ProcessLookupError:
                    pass
            if not wait(running, timeout=0.5).not_done:
                break
        pool.shutdown(wait=True, cancel_futures=True)
    finally:
        for sig, handler in handlers.items():
            signal.signal(sig, handler)


#: The start method of :class:`ProcessActor` processes, as Stable-Baselines3's ``SubprocVecEnv`` picks it: a fork
#: of a process running torch's or the kernels' threads can deadlock.
ACTOR_START_METHOD = "forkserver" if "forkserver" in mp.get_all_start_methods() else "spawn"
#: Seconds a :class:`ProcessActor` is given to end after ``SIGTERM`` before it is killed (a stopped process
#: takes no signal but ``SIGKILL``).
TERMINATE_TIMEOUT = 1.0
#: Seconds a call to a :class:`ProcessActor` may make no progress before the wait for it is said (a warning naming
#: the actor, the call and how long it is waited for), where its heartbeat timeout is longer.
SILENCE_NOTICE = 60.0


class ActorFailed(RuntimeError):
    """A :class:`ProcessActor`'s process stopped, or its object raised; says which actor and what happened."""


class ActorStalled(ActorFailed):
    """A :class:`ProcessActor`'s process made no progress (:func:`beat`) within its heartbeat timeout."""


#: The actor's heartbeat in an actor's process (a shared counter), None elsewhere.
_heartbeat = None


def beat() -> None:
    """Tell the parent of this actor process that it is making progress (a decision played, say); nothing
    outside an actor's process. See :meth:`ProcessActor.result`."""
    if _heartbeat is not None:
        _heartbeat.value += 1


def leave_terminal_signals() -> None:
    """Ignore Ctrl-C and leave the terminal's process group: Ctrl-C, and a SIGTERM sent to the group (``timeout``
    sends one), reach the parent alone, which stops its work, saves it and closes its workers. Then Ctrl-C is
    unblocked, if this process was started with it blocked (:func:`ctrl_c_held`): one pressed while it started
    is dropped, ignored."""
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    try:
        os.setpgid(0, 0)
    except OSError:  # a group leader already
        pass
    signal.pthread_sigmask(signal.SIG_UNBLOCK, {signal.SIGINT})


@contextmanager
def ctrl_c_held():
    """Within the block Ctrl-C (SIGINT) is blocked in this thread, and so in the processes it starts, which keep
    it blocked until they ignore it (:func:`leave_terminal_signals`): a Ctrl-C sent to the terminal's process
    group while a worker (or the forkserver that forks :class:`ProcessActor` processes) starts up would stop its
    interpreter's start-up ("Fatal Python error: init_import_site") or its imports, with a traceback. A blocked
    signal waits: this process takes a Ctrl-C that came meanwhile when the block ends. Ray starts its processes
    with SIGINT blocked in the same way. multiprocessing's resource tracker, which the first process of a
    forkserver or spawn context starts, unblocks SIGINT in the thread that starts it: it is started first."""
    resource_tracker.ensure_running()
    previous = signal.pthread_sigmask(signal.SIG_BLOCK, {signal.SIGINT})
    try:
        yield
    finally:
        signal.pthread_sigmask(signal.SIG_SETMASK, previous)


def _serve(connection, factory, args, heartbeat) -> None:
    """The actor process: build ``factory(*args)``, then run each ``(method, args)`` received and send back
    ``("ok", result)`` or ``("error", message)`` until ``None`` arrives (each message pickled here, so that no
    tensor is shared through file descriptors the parent must still serve). Signals are the parent's to
    handle; once the parent is gone the process ends quietly."""
    global _heartbeat
    _heartbeat = heartbeat
    leave_terminal_signals()
    try:
        try:
            target = factory(*args)
            reply = ("ok", None)
        except Exception as error:  # noqa: BLE001 - the object could not be built
            target, reply = None, ("error", f"{type(error).__name__}: {error}")
        connection.send_bytes(pickle.dumps(reply, pickle.HIGHEST_PROTOCOL))
        while target is not None and (call := pickle.loads(connection.recv_bytes())) is not None:
            method, call_args = call
            try:
                reply = ("ok", getattr(target, method)(*call_args))
            except Exception as error:  # noqa: BLE001 - any failure goes back to the caller
                reply = ("error", f"{type(error).__name__}: {error}")
            connection.send_bytes(pickle.dumps(reply, pickle.HIGHEST_PROTOCOL))
    except (EOFError, OSError, KeyboardInterrupt):  # the parent went away
        pass
    finally:
        connection.close()


def warn_of_silence(who: str, call: str, timeout: float) -> None:
    """Say (a warning) that ``who`` ("rollout worker 0 (process 12) has made no progress") has been silent for
    :data:`SILENCE_NOTICE` seconds, that ``call`` is waited for, and how long before the run stops."""
    warnings.warn(f"{who} for {SILENCE_NOTICE:g} s: waiting for {call}, up to {timeout:g} s without progress "
                  "(worker_timeout) before the run stops (was it stopped, or is it stuck in its env?)", stacklevel=3)


class ProcessActor:
    """An object built by ``factory(*args)`` in a local process of its own (the Ray actor's model, with
    ``multiprocessing``): :meth:`submit` starts one of its methods there, :meth:`result` waits for what it
    returned. A failure in the process, or its end, is an :class:`ActorFailed` naming ``name``, never a hang,
    and a call that makes no progress (:func:`beat` in the process) within the heartbeat timeout its result is
    waited for with is an :class:`ActorStalled`. The process ignores Ctrl-C from its start (:func:`ctrl_c_held`)
    and leaves the terminal's process group (:func:`leave_terminal_signals`): the parent handles them and closes
    the actor."""

    def __init__(self, name: str, factory, *args, start_method: str = ACTOR_START_METHOD):
        context = mp.get_context(start_method)
        self.name = name
        self._heartbeat = context.Value("Q", 0, lock=False)
        self._connection, child = context.Pipe()
        self.process = context.Process(target=_serve, args=(child, factory, args, self._heartbeat), daemon=True,
                                       name=name)
        with ctrl_c_held():  # the process starts deaf to a Ctrl-C, which this one handles
            self.process.start()
        child.close()  # only the process holds its end: its exit ends the pipe, and recv raises EOFError
        self._waiting = True  # for the object to be built
        self._call = "it to be built"  # what is waited for, in words
        self._closing = False
        self._sending: threading.Thread | None = None
        self._send_error: Exception | None = None

    def submit(self, method: str, *args) -> None:
        """Start ``method(*args)`` in the process (after the previous call's result was read). The call is sent
        on a thread of its own: a process that does not read (stopped) must not block this one, whose
        :meth:`result` then says so."""
        if self._waiting:
            self.result()
        self._send_error = None
        self._sending = threading.Thread(target=self._send, args=(pickle.dumps((method, args),
                                                                               pickle.HIGHEST_PROTOCOL),),
                                         daemon=True, name=f"{self.name}: sending")
        self._sending.start()
        self._waiting = True
        self._call = f"its reply to {method}"

    def _send(self, message: bytes) -> None:
        try:
            self._connection.send_bytes(message)
        except (OSError, ValueError) as error:  # the process has stopped (or was closed meanwhile)
            self._send_error = error

    def result(self, heartbeat_timeout: float | None = None):
        """What the submitted call returned; raises :class:`ActorFailed` if it raised or the process ended, and
        :class:`ActorStalled` if it made no progress for ``heartbeat_timeout`` seconds (None: no bound)."""
        self._waiting = False
        if heartbeat_timeout is not None:
            self._wait_for_progress(heartbeat_timeout)
        elif self._sending is not None:
            self._sending.join()
        if self._send_error is not None:
            raise ActorFailed(f"{self.name}: the process has stopped ({self._send_error})")
        try:
            status, value = pickle.loads(self._connection.recv_bytes())
        except (EOFError, OSError):
            self.process.join(1.0)
            raise ActorFailed(f"{self.name}: the process has stopped (exit code {self.process.exitcode})") from None
        if status == "error":
            raise ActorFailed(f"{self.name}: {value}")
        return value

    def _wait_for_progress(self, timeout: float) -> None:
        """Wait until a reply (or the pipe's end) can be read; :class:`ActorStalled` if the heartbeat stands still
        for ``timeout`` seconds."""
        beats, since = self._heartbeat.value, time.monotonic()
        said = timeout <= SILENCE_NOTICE
        while True:
            if self._sending is not None and self._sending.is_alive():
                self._sending.join(min(1.0, timeout))
            elif self._send_error is not None or self._connection.poll(min(1.0, timeout)):
                return
            if self._heartbeat.value != beats:
                beats, since = self._heartbeat.value, time.monotonic()
            elif time.monotonic() - since > timeout:
                raise ActorStalled(f"{self.name} (process {self.process.pid}) has made no progress for {timeout:g} "
                                   "s: it was stopped, or is stuck in its env")
            elif not said and time.monotonic() - since > SILENCE_NOTICE:
                said = True
                warn_of_silence(f"{self.name} (process {self.process.pid}) has made no progress", self._call, timeout)

    def ask_to_close(self) -> None:
        """Ask the process to end once the call under way, if any, is done."""
        if not self._closing:
            self._closing = True
            if self._sending is not None and self._sending.is_alive():  # not reading: it is ended by close
                return
            try:
                self._connection.send_bytes(pickle.dumps(None))
            except (OSError, ValueError):
                pass

    def close(self, timeout: float) -> None:
        """Ask the process to end, wait up to ``timeout`` seconds (it may be amid a call), then terminate it (and
        kill it if it is still there :data:`TERMINATE_TIMEOUT` s later: stopped, say)."""
        self.ask_to_close()
        self.process.join(timeout)
        if self.process.is_alive():
            self.process.terminate()
            self.process.join(TERMINATE_TIMEOUT)
        if self.process.is_alive():
            self.process.kill()
            self.process.join()
        self._connection.close()
