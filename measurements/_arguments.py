"""Shared helper of the scripts: the argument types they share with the ``emmi-gym`` command (whole and real
numbers checked against their bounds, seeds, counts of episodes, ranges of seeds, worker processes, the
baselines' names, a command's one-line error), taken from the command's module in this one place, and
:func:`non_negative`, which the command has no use for."""

import argparse
import math

from emmi_gym.tools.commands.arguments import (
    EPISODES,
    SEED,
    add_seed_range,
    add_workers,
    baseline_policies,
    integer,
    number,
    run_command,
    seed_range,
)

__all__ = ["EPISODES", "SEED", "add_seed_range", "add_workers", "baseline_policies", "integer", "non_negative",
           "number", "run_command", "seed_range"]


def non_negative(text: str) -> float:
    """An argparse type: a finite number of 0 or more (:func:`number` takes those above its bound only)."""
    try:
        value = float(text)
    except ValueError:
        value = math.nan
    if not (math.isfinite(value) and value >= 0):
        raise argparse.ArgumentTypeError(f"expected a finite number >= 0, got {text!r}")
    return value
