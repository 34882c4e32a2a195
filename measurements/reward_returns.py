"""Reward alignment: which reward, time cost and discount pay more to the policy that maps better.

Plays the scripted policies on the same (world, seed) episodes, keeps every step's reward components,
and prints for each reward variant, time cost and discount each policy's mean return, on how many
pairs of episodes the better final map also earned more, the within-episode correlation of return
and final map quality, and the policy the reward prefers (emmi_gym/tools/experiments/reward_alignment.py).

    python measurements/reward_returns.py --worlds dungeon_maps/train --plans 12 \\
        --policies frontier active_loop_closing random --out results/alignment_train
    python measurements/reward_returns.py --env-id emmi_gym/LoopCorridor-v1 --worlds loop_corridor --seeds 4 \\
        --policies close_loop_first explore_first frontier --discounts none 0.95 0.9@100

``--worlds`` takes map sets (a shipped set, a folder, a glob: their first ``--plans`` maps, each with
every ``--seeds``) or worlds (names, files: one episode per seed). Choose on the train split; the
test split is for reporting.
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path

import gymnasium as gym
from _options import checked, json_object

from emmi_gym.env import REWARDS, EnvConfig
from emmi_gym.inputs.validation import build
from emmi_gym.tools.commands import arguments
from emmi_gym.tools.experiments.comparison import ComparisonSettings, compare_on, worlds_of
from emmi_gym.tools.experiments.reward_alignment import QUALITIES, Discount, alignment, markdown, policy_front
from emmi_gym.tools.policies import POLICY_NAMES


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--env-id", default="emmi_gym/ExplorePlans-v1")
    parser.add_argument("--options", default="{}", help="JSON of further gym.make options")
    parser.add_argument("--worlds", nargs="+", default=["dungeon_maps/train"])
    parser.add_argument("--plans", type=arguments.integer(1), default=12, help="maps taken from each map set")
    arguments.add_seed_range(parser, 1)
    parser.add_argument("--policies", nargs="+", default=["frontier", "active_loop_closing", "random"],
                        choices=POLICY_NAMES)
    parser.add_argument("--rewards", nargs="+", default=list(REWARDS), choices=REWARDS)
    parser.add_argument("--time-costs", type=float, nargs="+", default=[0.0, EnvConfig.time_cost])
    parser.add_argument("--discounts", nargs="+", default=["none", "0.9@100", "0.99@100"],
                        help="'none', GAMMA (per decision) or GAMMA@STEPS (per STEPS simulator steps)")
    arguments.add_workers(parser)
    parser.add_argument("--out", type=Path, default=None, help="write summary.md and episodes.json here")
    args = parser.parse_args()
    if args.env_id not in gym.registry:
        parser.error(f"--env-id: no environment {args.env_id!r} is registered")
    try:
        discounts = [Discount.parse(text) for text in args.discounts]
    except ValueError as error:
        parser.error(f"--discounts: {error}")
    settings = ComparisonSettings(args.env_id, json_object(parser, "--options", args.options))
    checked(parser, build, EnvConfig, {**gym.spec(args.env_id).kwargs, **settings.env_options}, "", source="--options")
    if args.out is not None:
        args.out.mkdir(parents=True, exist_ok=True)

    episodes = [(w, s) for w in worlds_of(args.worlds, args.plans) for s in arguments.seed_range(args)]
    rows = compare_on(episodes, args.policies, settings, workers=args.workers, keep_steps=True)
    results = alignment(rows, args.rewards, args.time_costs, discounts, tuple(QUALITIES))
    title = (f"Reward alignment on {args.env_id}{f' {settings.env_options}' if settings.env_options else ''}: "
             f"{len(episodes)} episodes ({', '.join(args.worlds)}; seeds from {args.first_seed}) of "
             f"{', '.join(args.policies)}")
    table = markdown(results, policy_front(rows), title)
    print(table)
    if args.out is not None:
        (args.out / "summary.md").write_text(table + "\n")
        (args.out / "episodes.json").write_text(json.dumps(rows))
        print(f"\nwrote {args.out / 'summary.md'} and {args.out / 'episodes.json'}")


if __name__ == "__main__":
    main()
