"""Whether a training run's policy has settled: on held-out episodes played by its final model, the share
of decisions at which each earlier checkpoint would have taken the same action (the policy churn across
checkpoints, :mod:`emmi_gym.tools.training.policy_churn`). A share near 1 over many thousand decisions of
training: the policy no longer changes; well below 1 with a level learning curve: it still changes, along
a plateau of its reward.

    python measurements/policy_churn.py RUN [RUN ...] [--checkpoints D [D ...]] [--episodes 4] [--seed S]

``RUN``: a run folder of ``emmi-gym train`` or ``emmi-gym benchmark`` (``runs/<reward>_seed<k>``), of a waypoint
env (discrete actions). By default each run's checkpoints nearest a quarter, half and three quarters of its final
model's decisions are compared; the episodes are the run's held-out evaluation env, seeds ``S``, ``S + 1``, ...
"""

from __future__ import annotations

import argparse
from pathlib import Path

import _arguments as arguments

from emmi_gym.tools.training.evaluate import EVALUATION_SEED
from emmi_gym.tools.training.policy_churn import agreement_with_final, checkpoints_to_compare


def churn_of(args: argparse.Namespace) -> int:
    print("| run | final model (decisions) | checkpoint (decisions) | decisions compared | same action | share |")
    print("| --- | --- | --- | --- | --- | --- |")
    for run in args.runs:
        (final_decisions, final), checkpoints = checkpoints_to_compare(run, args.checkpoints)
        rows = agreement_with_final(final, [path for _, path in checkpoints], args.episodes, args.seed)
        for (count, _), row in zip(checkpoints, rows, strict=True):
            print(f"| {run.name} | {final_decisions} | {count} | {row['decisions']} | {row['same_action']} | "
                  f"{row['agreement']:.2f} |", flush=True)
    return 0


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("runs", type=Path, nargs="+", help="run folders of 'emmi-gym train' or 'benchmark'")
    parser.add_argument("--checkpoints", type=arguments.integer(0), nargs="+", default=None,
                        help="the decisions of the checkpoints to compare (default: those nearest 1/4, 1/2, 3/4)")
    parser.add_argument("--episodes", type=arguments.EPISODES, default=4, help="held-out episodes (default 4)")
    parser.add_argument("--seed", type=arguments.SEED, default=EVALUATION_SEED,
                        help=f"the first episode's seed (default {EVALUATION_SEED})")
    return arguments.run_command(parser, churn_of)


if __name__ == "__main__":
    raise SystemExit(main())
