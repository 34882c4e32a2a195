"""Stopping a command on a signal as on Ctrl-C: SIGTERM (what ``timeout``, Slurm and ``docker stop`` send)
is handled as SIGINT, so that a run saves a checkpoint either way, and the exit status says which it was
(130 after Ctrl-C, 143 after SIGTERM, as a shell reports a process those signals ended)."""

from __future__ import annotations

import signal
import threading
from contextlib import contextmanager

#: Exit statuses of a command stopped by Ctrl-C (SIGINT) and by SIGTERM: 128 + the signal's number.
EXIT_INTERRUPTED, EXIT_TERMINATED = 128 + signal.SIGINT, 128 + signal.SIGTERM


class Interrupted(KeyboardInterrupt):
    """A command was stopped by Ctrl-C or SIGTERM; says what it kept and how to go on."""


class RunStopped(RuntimeError):
    """A run stopped before its end by a failure outside its own code (a worker process that died or made no
    progress); says which, what the run saved and how to go on."""


def as_ctrl_c(signum, frame) -> None:
    """A signal handler: do what Ctrl-C does now (the current SIGINT handler), or raise KeyboardInterrupt where
    Ctrl-C has none or is ignored: a job a shell started in the background ignores Ctrl-C, and SIGTERM must still
    stop it (a run saving its checkpoint first), as it would have without this handler."""
    handler = signal.getsignal(signal.SIGINT)
    if callable(handler):
        handler(signal.SIGINT, frame)
    else:
        raise KeyboardInterrupt


@contextmanager
def terminate_as_interrupt():
    """Within the block SIGTERM does what Ctrl-C does (:func:`as_ctrl_c`); yields a list that holds True once a
    SIGTERM arrived (the exit status is then :data:`EXIT_TERMINATED`). Signals are the main thread's: elsewhere,
    and where SIGTERM is ignored, nothing changes."""
    received: list[bool] = []
    if threading.current_thread() is not threading.main_thread() or \
            signal.getsignal(signal.SIGTERM) is signal.SIG_IGN:
        yield received
        return

    def terminated(signum, frame):
        received.append(True)
        as_ctrl_c(signum, frame)

    previous = signal.signal(signal.SIGTERM, terminated)
    try:
        yield received
    finally:
        signal.signal(signal.SIGTERM, previous)
