"""Running a parsed ``emmi-gym`` command: the one place where what a command raises becomes a line on
stderr and an exit status, so that no command ends in a traceback for bad input, a missing extra, a
stopped worker or an interrupt."""

from __future__ import annotations

import argparse
import sys

from ...concurrency.interrupts import EXIT_INTERRUPTED, EXIT_TERMINATED, RunStopped, terminate_as_interrupt
from ...inputs.extras import MissingExtraError, missing_extra
from ...slam.kernel_cache import first_run_note

#: Commands that run none of the numba kernels (no note on their first run).
NO_KERNELS = ("learning-curves",)


def run_subcommand(parser: argparse.ArgumentParser, args: argparse.Namespace) -> int:
    """``args.func(args)``, the exit status it returns, or the status and line of what it raised: bad input
    (a ``ValueError``, ``KeyError`` or ``OSError``) 2, a missing optional extra 2 (naming its install line), a
    worker that died or stalled 1, Ctrl-C 130 and SIGTERM 143 (a run saves a checkpoint first). Before a
    command that compiles the numba kernels for the first time, a note says so."""
    if args.command not in NO_KERNELS and (note := first_run_note()) is not None:
        print(note, file=sys.stderr, flush=True)
    with terminate_as_interrupt() as terminated:  # SIGTERM stops a command as Ctrl-C does
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
