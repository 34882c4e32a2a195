"""Running a parsed ``emmi-gym`` command: the one place where what a command raises becomes a line on
stderr and an exit status, so that no command ends in a traceback for bad input, a missing extra, a
stopped worker or an interrupt."""

from __future__ import annotations

import argparse
import sys
import time
from contextlib import contextmanager

from ...concurrency.interrupts import EXIT_INTERRUPTED, EXIT_TERMINATED, RunStopped, terminate_as_interrupt
from ...concurrency.progress import LINE_INTERVAL, Heartbeat, note
from ...inputs.extras import MissingExtraError, missing_extra
from ...slam.kernel_cache import cached_kernels, first_run_note

#: Commands that run none of the numba kernels (no note on their first run).
NO_KERNELS = ("learning-curves",)


def run_subcommand(parser: argparse.ArgumentParser, args: argparse.Namespace) -> int:
    """``args.func(args)``, the exit status it returns, or the status and line of what it raised: bad input
    (a ``ValueError``, ``KeyError`` or ``OSError``) 2, a missing optional extra 2 (naming its install line), a
    worker that died or stalled 1, Ctrl-C 130 and SIGTERM 143 (a run saves a checkpoint first). Before a
    command that compiles the numba kernels for the first time, a note says so."""
    compiling = args.command not in NO_KERNELS and (first_run := first_run_note()) is not None
    if compiling:
        print(first_run, file=sys.stderr, flush=True)
    with terminate_as_interrupt() as terminated, compile_progress(compiling):  # SIGTERM stops it as Ctrl-C does
        try:
            status = args.func(args)
        except MissingExtraError as exc:
            parser.exit(2, f"emmi-gym {args.command}: error: {exc}\n")
        except ModuleNotFoundError as exc:  # an optional extra the command needs: the line that installs it
            missing = missing_extra(exc, f"{args.command!r}")
            if missing is None:
                raise
            parser.exit(2, f"emmi-gym {args.command}: error: {missing}\n")
        except (ValueError, KeyError, OSError) as exc:  # bad input, a file or folder: a message, not a traceback
            message = exc.args[0] if isinstance(exc, KeyError) and exc.args else str(exc)
            parser.exit(2, f"emmi-gym {args.command}: error: {message}\n")
        except RunStopped as exc:  # a worker died or stalled: what the run saved, and how to go on
            parser.exit(1, f"emmi-gym {args.command}: error: {exc}\n")
        except KeyboardInterrupt as exc:  # before a run could save anything, or with what it kept
            parser.exit(EXIT_TERMINATED if terminated else EXIT_INTERRUPTED,
                        f"\nemmi-gym {args.command}: interrupted{f': {exc}' if str(exc) else ''}\n")
    return EXIT_TERMINATED if terminated and status == EXIT_INTERRUPTED else status


@contextmanager
def compile_progress(compiling: bool, interval: float = LINE_INTERVAL):
    """While the block runs and ``compiling`` (the kernels are not cached yet), say every ``interval`` seconds
    how many of the package's numba kernels are compiled (:func:`~emmi_gym.slam.kernel_cache.cached_kernels`,
    counting the worker processes' too), until the count stops growing for two lines."""
    if not compiling:
        yield
        return
    started = time.monotonic()
    counts = []

    def beat() -> None:
        cached, total = cached_kernels([m for name, m in list(sys.modules.items()) if name.startswith("emmi_gym.")])
        if cached and counts[-2:] == [cached, cached]:  # compiled, and none since two beats: only unused ones left
            heartbeat.stop()
            return
        counts.append(cached)
        minutes, seconds = divmod(int(time.monotonic() - started), 60)
        note(f"numba: {cached} of {total} kernels compiled and cached, {minutes}:{seconds:02d} in (once per install)")

    heartbeat = Heartbeat(beat, interval)
    heartbeat.start()
    try:
        yield
    finally:
        heartbeat.stop()
