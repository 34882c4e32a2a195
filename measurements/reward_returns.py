"""Reward alignment: which reward, time cost and discount pay more to the policy that maps better.

Plays the scripted policies on the same (world, seed) episodes, keeps every step's reward components,
and prints for each reward variant, time cost and discount each policy's mean return, on how many
pairs of episodes the better final map also earned more, the within-episode correlation of return
and final map quality, and the policy the reward prefers (emmi_gym/tools/experiments/reward_alignment.py).

    python measurements/reward_returns.py --worlds dungeon_maps/train --plans 12 \\
        --policies frontier active_loop_closing random --out results/alignment_train
    python measurements/reward_returns.py --env-id emmi_gym/LoopCorridor-v1 --worlds loop_corridor --seeds 4 \\
        --policies close_loop_first explore_first frontier --discounts none 0.95 0.9@100
    python measurements/reward_returns.py --worlds dungeon_maps/test --plans 50 --first-seed 1000000 \\
        --policies frontier active_loop_closing explore_plans_emmi --models emmi=runs/emmi_seed0/model.zip \\
        --options '{"min_loop_spread": 0.15, "revisit_spacing": 3.0}' --rewards emmi --time-costs 0.0005 \\
        --discounts none 0.97@100

``--policies`` takes scripted policies and shipped agents, ``--models`` trained models (``NAME=MODEL``): did
an agent earn more than the policies whose maps are better (then its reward, not its learning, is what keeps it
from them), or less (then the learning falls short of what the reward pays)? Give ``--options`` the agent's
own env keywords.

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
from emmi_gym.tools.experiments.comparison import ComparisonSettings, compare_on, policy_name, worlds_of
from emmi_gym.tools.experiments.reward_alignment import QUALITIES, Discount, alignment, markdown, policy_front
from emmi_gym.tools.training.evaluate import TrainedAgent


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--env-id", default="emmi_gym/ExplorePlans-v1")
    parser.add_argument("--options", default="{}", help="JSON of further gym.make options")
    parser.add_argument("--worlds", nargs="+", default=["dungeon_maps/train"])
    parser.add_argument("--plans", type=arguments.integer(1), default=12, help="maps taken from each map set")
    arguments.add_seed_range(parser, 1)
    parser.add_argument("--policies", nargs="+", default=["frontier", "active_loop_closing", "random"],
                        help="scripted policies and shipped agents")
    parser.add_argument("--models", nargs="*", default=[], metavar="NAME=MODEL",
                        help="trained models ('emmi-gym train' .zip files) played beside the policies")
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
    try:
        policies = arguments.baseline_policies(args.policies, "--policies")
    except ValueError as error:
        parser.error(str(error))
    policies += [TrainedAgent(*reversed(model_argument(parser, text))) for text in args.models]
    settings = ComparisonSettings(args.env_id, json_object(parser, "--options", args.options))
    checked(parser, build, EnvConfig, {**gym.spec(args.env_id).kwargs, **settings.env_options}, "", source="--options")
    if args.out is not None:
        args.out.mkdir(parents=True, exist_ok=True)

    episodes = [(w, s) for w in worlds_of(args.worlds, args.plans) for s in arguments.seed_range(args)]
    rows = compare_on(episodes, policies, settings, workers=args.workers, keep_steps=True,
                      start_method="spawn" if args.models else None)  # torch and fork do not mix
    results = alignment(rows, args.rewards, args.time_costs, discounts, tuple(QUALITIES))
    title = (f"Reward alignment on {args.env_id}{f' {settings.env_options}' if settings.env_options else ''}: "
             f"{len(episodes)} episodes ({', '.join(args.worlds)}; seeds from {args.first_seed}) of "
             f"{', '.join(policy_name(policy) for policy in policies)}")
    table = markdown(results, policy_front(rows), title)
    print(table)
    if args.out is not None:
        (args.out / "summary.md").write_text(table + "\n")
        (args.out / "episodes.json").write_text(json.dumps(rows))
        print(f"\nwrote {args.out / 'summary.md'} and {args.out / 'episodes.json'}")


def model_argument(parser: argparse.ArgumentParser, text: str) -> tuple[str, str]:
    """``NAME=MODEL`` of ``--models`` as (name, path), the file checked to exist."""
    name, _, path = text.partition("=")
    if not name or not path or not Path(path).is_file():
        parser.error(f"--models: {text!r}: NAME=MODEL with an existing model file expected")
    return name, path


if __name__ == "__main__":
    main()
