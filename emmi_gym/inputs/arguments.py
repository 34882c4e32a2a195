"""Command-line arguments, checked when they are parsed: bounded argparse types (argparse names the option
in its error), and the one-line message a command prints for bad input instead of a traceback."""

from __future__ import annotations

import argparse
import math

#: The most episodes one command plays or scores (a count past it is a typo, not an experiment: at a
#: second an episode it would take a day on 16 cores).
MAX_EPISODES = 100_000


def integer(lo: int = 0, hi: int | None = None):
    """An argparse type: a whole number in [lo, hi]."""
    def parse(text: str) -> int:
        try:
            value = int(text)
        except ValueError:
            value = None
        if value is None or value < lo or (hi is not None and value > hi):
            bounds = f"in [{lo}, {hi}]" if hi is not None else f">= {lo}"
            raise argparse.ArgumentTypeError(f"expected an integer {bounds}, got {text!r}")
        return value
    return parse


def number(lo: float = 0.0, hi: float | None = None, unit: str = ""):
    """An argparse type: a finite number above ``lo`` and at most ``hi``, in ``unit``."""
    def parse(text: str) -> float:
        try:
            value = float(text)
        except ValueError:
            value = math.nan
        if not (math.isfinite(value) and value > lo and (hi is None or value <= hi)):
            bounds = f"in ({lo:g}, {hi:g}]" if hi is not None else f"above {lo:g}"
            raise argparse.ArgumentTypeError(f"expected a finite number {bounds}{f' ({unit})' if unit else ''}, "
                                             f"got {text!r}")
        return value
    return parse


#: Seeds of numpy's generators, as the configurations bound them.
SEED = integer(0, 2**32 - 1)
#: A count of episodes.
EPISODES = integer(1, MAX_EPISODES)


def run_command(parser: argparse.ArgumentParser, command, argv=None) -> int:
    """Parse ``argv`` with ``parser`` and return ``command(args)``; bad input (a ``ValueError``, such as the
    package's :class:`~.errors.FieldError`, or an ``OSError``: a missing file, a folder that cannot be
    written) ends the program with its one-line message and exit status 2, not a traceback."""
    args = parser.parse_args(argv)
    try:
        return command(args)
    except (ValueError, OSError) as exc:
        parser.exit(2, f"{parser.prog}: error: {exc}\n")
