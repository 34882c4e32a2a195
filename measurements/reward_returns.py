"""Reward alignment: which reward, time cost and discount pay more to the policy that maps better.

Plays the scripted policies on the same (world, seed) episodes, keeps every step's reward components
(every registered reward's: the env's ``info_rewards="all"``), and prints for each reward, time cost and
discount each policy's mean return, on how many pairs of episodes the better final map also earned more,
the within-episode correlation of return and final map quality, and the policy the reward prefers
(emmi_gym/tools/experiments/reward_alignment.py); beside each reward what it reads, the filter or the
ground truth (a privileged reward).

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

``--paired-with POLICY`` adds each policy's return minus POLICY's on the same episodes, with its 95% interval.
``--episodes-from FILE ...`` reads the ``episodes.json`` of earlier runs (``--out``) instead of playing, pooled: an
agent played later beside the policies played once (an episode two files hold must be the same in both); by
default the rewards every step of them holds. ``--against-episodes FILE ...`` sets each agreement beside that of the
same episodes played otherwise (another filter: ``--options`` of its ``slam``, another version) and gives the
change with its interval, paired by plan: does a change to the filter make a reward see the better map? The
``episodes.csv`` of ``--out`` (the final scores) pairs two such runs' maps with ``measurements/versions_paired.py``.
``--against-reward NAME`` sets each reward's agreement beside NAME's on the same episodes, the change paired by
plan: does one reward side with the better map more often than another?

    python measurements/reward_returns.py --episodes-from after/episodes.json --against-episodes before/episodes.json

``--worlds`` takes map sets (a shipped set, a folder, a glob: their first ``--plans`` maps, each with
every ``--seeds``) or worlds (names, files: one episode per seed). Choose on the train split; the
test split is for reporting.
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path

import _arguments as arguments
import gymnasium as gym
from _options import checked, json_object

from emmi_gym.env import REWARDS, EnvConfig
from emmi_gym.env.reward_registry import privileged_rewards
from emmi_gym.inputs.validation import build
from emmi_gym.tools.evaluation.comparison import ComparisonSettings, compare_on, policy_name, worlds_of
from emmi_gym.tools.experiments.report import write_csv
from emmi_gym.tools.experiments.reward_alignment import (
    QUALITIES,
    Discount,
    agreement_change,
    alignment,
    change_markdown,
    markdown,
    paired_markdown,
    paired_returns,
    policy_front,
)
from emmi_gym.tools.training.evaluate import TrainedAgent
from emmi_gym.world.map_sets import world_name


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
    parser.add_argument("--rewards", nargs="+", choices=REWARDS,
                        help="registered rewards (default: every one; with --episodes-from, those the steps hold)")
    parser.add_argument("--time-costs", type=float, nargs="+", default=[0.0, EnvConfig.time_cost])
    parser.add_argument("--discounts", nargs="+", default=["none", "0.9@100", "0.99@100"],
                        help="'none', GAMMA (per decision) or GAMMA@STEPS (per STEPS simulator steps)")
    arguments.add_workers(parser)
    parser.add_argument("--paired-with", metavar="POLICY",
                        help="also each policy's return minus this policy's, paired by episode, with 95%% intervals")
    parser.add_argument("--episodes-from", nargs="+", type=Path, metavar="FILE",
                        help="episodes.json files of earlier runs, pooled, instead of playing")
    parser.add_argument("--against-episodes", nargs="+", type=Path, metavar="FILE",
                        help="episodes.json of the same episodes played otherwise (another filter, another version): "
                             "each agreement beside theirs, and the change paired by plan")
    parser.add_argument("--against-reward", choices=list(REWARDS), default=None, metavar="NAME",
                        help="each reward's agreement beside that of the reward NAME on the same episodes, and the "
                             "change paired by plan")
    parser.add_argument("--out", type=Path, default=None,
                        help="write summary.md, episodes.json and episodes.csv (the final scores) here")
    args = parser.parse_args()
    if args.episodes_from:
        rows = pooled_episodes(parser, args.episodes_from, "--episodes-from")
        held = [name for name in REWARDS if all(name in step for row in rows for step in row["steps"])]
        missing = sorted(set(args.rewards or ()) - set(held))
        if missing:
            parser.error(f"--rewards: the steps of --episodes-from do not hold {missing} (they hold {held})")
        args.rewards = args.rewards or held
        report(parser, args, rows, discounts_of(parser, args),
               f"Reward alignment over {', '.join(map(str, args.episodes_from))}")
        return
    if args.env_id not in gym.registry:
        parser.error(f"--env-id: no environment {args.env_id!r} is registered")
    args.rewards = args.rewards or list(REWARDS)
    discounts = discounts_of(parser, args)
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
    title = (f"Reward alignment on {args.env_id}{f' {settings.env_options}' if settings.env_options else ''}: "
             f"{len(episodes)} episodes ({', '.join(args.worlds)}; seeds from {args.first_seed}) of "
             f"{', '.join(policy_name(policy) for policy in policies)}")
    report(parser, args, rows, discounts, title)


def discounts_of(parser: argparse.ArgumentParser, args) -> list[Discount]:
    """``--discounts`` parsed; a malformed one is a usage error naming it."""
    try:
        return [Discount.parse(text) for text in args.discounts]
    except ValueError as error:
        parser.error(f"--discounts: {error}")


def report(parser: argparse.ArgumentParser, args, rows: list[dict], discounts: list[Discount], title: str) -> None:
    """The alignment tables of ``rows`` (and the paired returns, with ``--paired-with``) to stdout and ``--out``."""
    privileged = privileged_rewards()
    reads = {name: "ground truth" if name in privileged else "filter" for name in args.rewards}
    table = markdown(alignment(rows, args.rewards, args.time_costs, discounts, tuple(QUALITIES), reads),
                     policy_front(rows), title)
    if args.paired_with is not None:
        if args.paired_with not in {row["policy"] for row in rows}:
            parser.error(f"--paired-with: no episodes of {args.paired_with!r}")
        try:
            paired = paired_returns(rows, args.rewards, args.time_costs, discounts, args.paired_with)
        except ValueError as error:
            parser.error(f"--paired-with: {error}")
        table += "\n\n" + paired_markdown(paired, args.paired_with, privileged)
    if args.against_episodes:
        baseline = pooled_episodes(parser, args.against_episodes, "--against-episodes")
        missing = sorted({name for name in args.rewards for row in baseline for step in row["steps"]
                          if name not in step})
        if missing:
            parser.error(f"--against-episodes: their steps do not hold {missing}")
        try:
            changes = agreement_change(rows, baseline, args.rewards, args.time_costs, discounts, tuple(QUALITIES))
        except ValueError as error:
            parser.error(f"--against-episodes: {error}")
        table += "\n\n" + change_markdown(changes, ", ".join(map(str, args.against_episodes)))
    if args.against_reward is not None:
        if args.against_reward not in args.rewards:
            parser.error(f"--against-reward: {args.against_reward!r} is not one of --rewards {args.rewards}")
        others = [name for name in args.rewards if name != args.against_reward]
        changes = agreement_change(rows, rows, others, args.time_costs, discounts, tuple(QUALITIES),
                                   baseline_reward=args.against_reward)
        table += "\n\n" + change_markdown(changes, f"the reward {args.against_reward}")
    print(table)
    if args.out is not None:
        args.out.mkdir(parents=True, exist_ok=True)
        (args.out / "summary.md").write_text(table + "\n")
        (args.out / "episodes.json").write_text(json.dumps(rows))
        write_csv(args.out / "episodes.csv", [{k: v for k, v in row.items() if k != "steps"} for row in rows])
        print(f"\nwrote {args.out / 'summary.md'}, {args.out / 'episodes.json'} and {args.out / 'episodes.csv'}")


def pooled_episodes(parser: argparse.ArgumentParser, files: list[Path], option: str) -> list[dict]:
    """The episodes (with their steps) of earlier runs' ``episodes.json``, pooled; one (world, seed, policy) in two
    files is kept once if the two are the same episode, and a usage error (naming ``option``) if they differ. A world
    is named as :func:`~emmi_gym.world.map_sets.world_name` says, so that runs made from two installs pair."""
    rows, seen = [], {}
    for path in files:
        try:
            episodes = json.loads(path.read_text())
        except OSError as error:
            parser.error(f"{option}: {path}: cannot be read ({error.strerror or error})")
        except (UnicodeDecodeError, json.JSONDecodeError) as error:
            parser.error(f"{option}: {path}: not an episodes.json of this script ({error})")
        if not isinstance(episodes, list) or not all(isinstance(row, dict) and "steps" in row for row in episodes):
            parser.error(f"{option}: {path}: a list of episodes with their steps expected")
        for row in episodes:
            if "world" in row:
                row["world"] = world_name(row["world"])
            key = (row.get("world"), row.get("seed"), row.get("policy"))
            if key in seen:
                if seen[key][1] != row:
                    parser.error(f"{option}: {path}: the episode {key} differs from the one in {seen[key][0]}")
                continue
            seen[key] = (path, row)
            rows.append(row)
    return rows


def model_argument(parser: argparse.ArgumentParser, text: str) -> tuple[str, str]:
    """``NAME=MODEL`` of ``--models`` as (name, path), the file checked to exist."""
    name, _, path = text.partition("=")
    if not name or not path or not Path(path).is_file():
        parser.error(f"--models: {text!r}: NAME=MODEL with an existing model file expected")
    return name, path


if __name__ == "__main__":
    main()
