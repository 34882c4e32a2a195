"""Demonstrations of the lookahead planner: its decisions in a configuration's training env, for behaviour cloning.

The planner of ``target_lookahead.py`` (privileged, and clairvoyant unless ``--noise fresh``: it plays each
offered target on a copy of the env and takes the best by a ground-truth score) plays ``--episodes`` episodes
of the configuration's *training* env (on ``ExplorePlans`` the train split's plans), and its observations,
action masks and choices are written as ``emmi-gym clone`` reads them. Fitting the configuration's network to
them asks whether a policy that sees only the observation can choose as the planner does (the teacher-student
scheme of privileged training: Chen et al., "Learning by Cheating", CoRL 2019):

    python measurements/lookahead_demonstrations.py --config agents/ppo_plans_scratch.yaml --episodes 160 \\
        --out runs/lookahead_clone/demonstrations.npz
    emmi-gym clone agents/ppo_plans_scratch.yaml --demos runs/lookahead_clone/demonstrations.npz \\
        --out runs/lookahead_clone/clone
    emmi-gym evaluate runs/lookahead_clone/clone/model.zip --episodes 50 --baselines active_loop_closing ...

The clone then plays the held-out plans without the truth; where it maps as the planner does, the network can
take the planner's choices from what it sees, and what the RL agents lack is a reward or a budget that leads
them there; where it maps as the agents do, what the observation shows is the limit.
"""

from __future__ import annotations

import argparse
from pathlib import Path

import _arguments as arguments
from target_lookahead import Lookahead, add_planner_arguments

from emmi_gym.env.seeds import DEMONSTRATION_SEED
from emmi_gym.tools.training.config import load_agent_config
from emmi_gym.tools.training.imitation import check_cloneable, collect_demonstrations


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0],
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--config", type=Path, default=Path("agents/ppo_plans_scratch.yaml"),
                        help="the agent configuration whose training env is played (default "
                             "agents/ppo_plans_scratch.yaml)")
    parser.add_argument("--episodes", type=arguments.EPISODES, default=160,
                        help="demonstration episodes (default 160)")
    parser.add_argument("--seed", type=arguments.SEED, default=DEMONSTRATION_SEED,
                        help=f"the first episode's seed (default {DEMONSTRATION_SEED}, as emmi-gym clone's)")
    add_planner_arguments(parser)
    parser.add_argument("--out", type=Path, required=True, help="the demonstrations file (.npz) to write")
    arguments.add_workers(parser)
    return arguments.run_command(parser, run, argv)


def run(args) -> int:
    config = load_agent_config(args.config)
    check_cloneable(config)  # before any episode is played
    if args.out.suffix != ".npz":
        raise ValueError(f"--out: a demonstrations file ends in .npz, got {args.out}")
    planner = Lookahead(args.objective, noise=args.noise)
    demonstrations = collect_demonstrations(config, planner, args.episodes, args.seed, workers=args.workers)
    args.out.parent.mkdir(parents=True, exist_ok=True)
    demonstrations.save(args.out)
    print(f"{len(demonstrations)} decisions of {planner.name} in {demonstrations.episodes} episodes of "
          f"{config.env_id} (seeds {args.seed}-{args.seed + args.episodes - 1}); wrote {args.out}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
