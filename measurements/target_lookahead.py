"""What the offered targets allow: a planner that sees, before it chooses, what each target would give.

At every decision the *lookahead* planner steps a copy of the env (``copy.deepcopy``: the world, the filter
and every random generator) to each target the action mask offers, scores the copy against the ground truth
(:meth:`~emmi_gym.env.EmmiEnv.ground_truth_scores`) and takes the target whose outcome is best in ``--objective``.
It is privileged (it reads the truth) and, with ``--noise foreseen`` (the default), clairvoyant: the copy draws
the noise the env will draw next, so no policy that chooses among the same targets one decision at a time maps
better by that score. With ``--noise fresh`` each copy draws noise of its own (the planner knows the world and
the map's errors, not the laser's and the odometry's next draws): what is left of its gain is what knowing the
truth, not the future, buys. Played beside the scripted policies on a configuration's held-out episodes (those
``emmi-gym benchmark`` evaluates its agents on), it says how much better than active loop-closing a choice
among the offered targets can be, final and at equal robot time; where it is not, the targets the agents are
offered, not the learning, bound them. It looks one decision ahead: a policy that plans several (active
loop-closing's route is such a plan) is not bounded by it.

    python measurements/target_lookahead.py --config agents/ppo_plans_scratch.yaml --episodes 50 \\
        --baselines active_loop_closing frontier --played runs/plans_scratch/played --out runs/lookahead

The episodes are kept in ``--played`` as they end (:mod:`emmi_gym.tools.evaluation.played_episodes`; default
``OUT/played``): a benchmark's ``played/`` folder of the same configuration shares its baselines' episodes, and a
run stopped part-way goes on where it stopped. ``--out`` gets ``episodes.csv``, ``traces.csv`` and ``summary.md``
(the planner's means and its paired tables against each baseline, final and at equal robot time).
"""

from __future__ import annotations

import argparse
import copy
import hashlib
import json
from dataclasses import replace
from pathlib import Path

import _arguments as arguments
import gymnasium as gym
import numpy as np

from emmi_gym.env.config import EnvConfig
from emmi_gym.formats.atomic_files import write_csv, write_text_atomically
from emmi_gym.inputs.validation import build
from emmi_gym.tools.evaluation.comparison import (
    SCORES,
    compare_on,
    evaluation_tables,
    format_table,
    policy_means,
    policy_name,
)
from emmi_gym.tools.evaluation.directions import better_side
from emmi_gym.tools.evaluation.played_episodes import PlayedEpisodes
from emmi_gym.tools.evaluation.robot_time import trace_rows, without_traces
from emmi_gym.tools.training.config import load_agent_config
from emmi_gym.tools.training.evaluate import EVALUATION_SEED, run_episodes

#: Ground-truth scores the planner can choose by (those :meth:`ground_truth_scores` gives).
OBJECTIVES = ("building_accuracy", "oracle_accuracy", "map_accuracy", "wall_consistency", "ate")


#: Whose noise the copies draw: the env's own next draws (clairvoyant), or draws of their own.
NOISE = ("foreseen", "fresh")


class LookaheadActor:
    """Takes, among the offered targets, the one whose step (played on a copy of the env) leaves the best
    ``objective``; ties go to the lowest slot (the nearest frontier first). With ``noise="fresh"`` each copy's
    random generator (the one the simulator and the filter share) is reseeded first, from a stream of the
    episode's seed."""

    def __init__(self, objective: str, noise: str = "foreseen"):
        if noise not in NOISE:
            raise ValueError(f"noise: expected one of {list(NOISE)}, got {noise!r}")
        self.objective, self.noise = objective, noise
        self.sign = -1.0 if better_side(objective) == "lower" else 1.0
        self.seeds = np.random.default_rng(0)

    def reset(self, seed: int) -> None:
        self.seeds = np.random.default_rng([seed, 1])

    def outcome(self, env, slot: int) -> float:
        """The objective, signed so that more is better, after ``slot`` is played on a copy of ``env``."""
        trial = copy.deepcopy(env)
        try:
            if self.noise == "fresh":
                generator = trial.unwrapped.np_random
                generator.bit_generator.state = type(generator.bit_generator)(self.seeds.integers(2**63)).state
            trial.step(slot)
            return self.sign * trial.unwrapped.ground_truth_scores()[self.objective]
        finally:
            trial.close()

    def __call__(self, env, observation) -> int:
        slots = np.flatnonzero(env.unwrapped.action_masks())
        outcomes = [self.outcome(env, int(slot)) for slot in slots]
        return int(slots[int(np.argmax(outcomes))])


class Lookahead:
    """The planner as a policy of :func:`~emmi_gym.tools.evaluation.comparison.compare_on`, named ``name``."""

    def __init__(self, objective: str, name: str | None = None, noise: str = "foreseen"):
        self.objective, self.noise = objective, noise
        self.name = name or f"lookahead_{objective}{'' if noise == 'foreseen' else '_' + noise}"

    def make_actor(self) -> LookaheadActor:
        return LookaheadActor(self.objective, self.noise)

    def identity(self) -> dict:
        """What it plays (:mod:`~emmi_gym.tools.evaluation.played_episodes`): its objective, its noise and this
        script's digest (an edited script plays anew)."""
        return {"lookahead": self.objective, "noise": self.noise,
                "script": hashlib.sha256(Path(__file__).read_bytes()).hexdigest()}


def kept_or_played(players, episodes, played: Path, workers: int | None) -> list[dict]:
    """Every ``(policy, settings)`` of ``players`` on ``episodes``: the rows kept in ``played`` read back, the rest
    played in ``workers`` processes (each kept as it comes back)."""
    rows = []
    for policy, settings in players:
        kept = PlayedEpisodes.in_folder(played, policy_name(policy), settings, policy)
        missing = [(world, seed) for world, seed in episodes if kept.get(world, seed) is None]
        print(f"{policy_name(policy)}: {len(episodes) - len(missing)} episodes kept in {kept.path}, "
              f"{len(missing)} to play", flush=True)
        if missing:
            spawn = "spawn" if not isinstance(policy, (str, Lookahead)) else None  # torch and fork do not mix
            for row in compare_on(missing, [policy], settings, workers=workers, keep_trace=True, start_method=spawn):
                row.pop("policy")
                kept.add(row)
        rows += [{**kept.get(world, seed), "policy": policy_name(policy)} for world, seed in episodes]
    return sorted(rows, key=lambda r: (r["world"], r["seed"]))


def add_planner_arguments(parser: argparse.ArgumentParser) -> None:
    """``--objective`` and ``--noise``: the planner, as this script and ``lookahead_demonstrations.py`` take it."""
    parser.add_argument("--objective", choices=OBJECTIVES, default="building_accuracy",
                        help="the ground-truth score the planner chooses by (default building_accuracy: the share "
                             "of the building mapped correctly, unmapped cells counting as wrong)")
    parser.add_argument("--noise", choices=NOISE, default="foreseen",
                        help="the copies draw the env's own next noise (foreseen: clairvoyant, the default) or noise "
                             "of their own (fresh)")


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0],
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--config", type=Path, default=Path("agents/ppo_plans_scratch.yaml"),
                        help="the agent configuration whose held-out evaluation env and episodes are played "
                             "(default agents/ppo_plans_scratch.yaml)")
    parser.add_argument("--episodes", type=arguments.EPISODES, default=50,
                        help="held-out plans of its map set (default 50)")
    parser.add_argument("--seeds-per-plan", type=arguments.integer(1, 64), default=1, metavar="K",
                        help="episode seeds per plan (default 1)")
    parser.add_argument("--eval-seed", type=arguments.SEED, default=EVALUATION_SEED,
                        help=f"the first episode seed (default {EVALUATION_SEED}, as the benchmark's)")
    add_planner_arguments(parser)
    parser.add_argument("--planner-options", default="{}", metavar="JSON",
                        help="gym.make options of the planner's env over the configuration's, e.g. the targets it is "
                             "offered ('{\"n_revisits\": 4, \"min_loop_spread\": 0.0}'); the baselines play the "
                             "configuration's")
    parser.add_argument("--name", default=None,
                        help="the planner's name in the rows (default lookahead_OBJECTIVE, with _fresh for --noise "
                             "fresh): a run with other --planner-options under another name pairs with this one "
                             "(evaluations_paired.py)")
    parser.add_argument("--baselines", nargs="+", default=["active_loop_closing"], metavar="POLICY",
                        help="scripted policies or shipped agents on the same episodes (default active_loop_closing)")
    parser.add_argument("--played", type=Path, default=None,
                        help="where the episodes are kept (default OUT/played; a benchmark's played/ of the same "
                             "configuration shares its baselines' episodes)")
    parser.add_argument("--out", type=Path, required=True, help="folder for the episodes, traces and summary")
    arguments.add_workers(parser)
    return arguments.run_command(parser, run, argv)


def planner_options(text: str) -> dict:
    """The JSON object of ``--planner-options``; a ``ValueError`` saying what it is instead."""
    try:
        options = json.loads(text)
    except json.JSONDecodeError as error:
        raise ValueError(f"--planner-options: not JSON ({error.msg} at character {error.pos})") from None
    if not isinstance(options, dict):
        raise ValueError(f"--planner-options: a JSON object of gym.make options expected, got {text[:60]!r}")
    return options


def run(args) -> int:
    config = load_agent_config(args.config)
    baselines = arguments.baseline_policies(args.baselines)
    settings, episodes = run_episodes(config, episodes=args.episodes, seed=args.eval_seed,
                                      seeds_per_plan=args.seeds_per_plan)
    offer = planner_options(args.planner_options)
    own = replace(settings, env_options={**settings.env_options, **offer})
    build(EnvConfig, {**gym.spec(own.env_id).kwargs, **own.env_options}, "", source="--planner-options")
    planner = Lookahead(args.objective, args.name, args.noise)
    players = [(planner, own)] + [(baseline, settings) for baseline in baselines]
    rows = kept_or_played(players, episodes, args.played or args.out / "played", args.workers)
    names = [policy_name(b) for b in baselines]
    tables = evaluation_tables(rows, planner.name, names)
    means = policy_means(rows)
    offered = f", the planner with {offer}" if offer else ""
    title = f"{planner.name} beside {', '.join(names)} on {len(episodes)} episodes of {args.config} " \
            f"({settings.env_id}{offered})"
    summary = "\n\n".join([title, format_table(means, ["policy", *SCORES]), *tables])
    args.out.mkdir(parents=True, exist_ok=True)
    write_csv(args.out / "episodes.csv", without_traces(rows))
    write_csv(args.out / "traces.csv", trace_rows(rows))
    write_text_atomically(args.out / "summary.md", summary + "\n")
    print(summary)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
