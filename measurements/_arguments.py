"""Shared helper of the scripts: the argument types they share with the ``emmi-gym`` command (whole and real
numbers checked against their bounds, seeds, counts of episodes, ranges of seeds, worker processes, the
baselines' names, a command's one-line error), taken from the command's module in this one place."""

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

__all__ = ["EPISODES", "SEED", "add_seed_range", "add_workers", "baseline_policies", "integer", "number",
           "run_command", "seed_range"]
