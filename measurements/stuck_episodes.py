"""Episodes that run out of targets: how often a waypoint env leaves the robot nothing to go to.

    python measurements/stuck_episodes.py [--env-id emmi_gym/Explore-v1] [--policy random] [--episodes 100]
                                          [--options '{"particles": 8}']

Plays ``--episodes`` episodes (seeds 0, 1, ...) with a scripted policy (``emmi_gym.tools.policies``; the
random one draws among the valid slots, seeded with the episode's seed) and counts the decisions
whose slot was empty (``info["target_kind"] == "none"``: with no target at all, slot 0 stays valid
and the robot turns in place), the episodes that had at least three such decisions and ended below
the coverage target (stuck), and the coverage reached. ``--options`` makes the env with further ``gym.make``
options.
"""

from __future__ import annotations

import argparse

import _arguments as arguments
import gymnasium as gym
import numpy as np
from _options import checked, json_object

import emmi_gym
from emmi_gym.tools.policies import make_policy

gym.register_envs(emmi_gym)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--env-id", default="emmi_gym/Explore-v1")
    parser.add_argument("--policy", default="random", help="frontier, random, active_loop_closing, ...")
    parser.add_argument("--episodes", type=arguments.EPISODES, default=100)
    parser.add_argument("--options", default="{}", help="JSON of further gym.make options")
    args = parser.parse_args()
    policy = make_policy(args.policy)
    env = checked(parser, gym.make, args.env_id, **json_object(parser, "--options", args.options))
    target = env.unwrapped.config.coverage_target
    coverages, empty, stuck = [], 0, []
    for seed in range(args.episodes):
        _, info = env.reset(seed=seed)
        policy.reset(seed)
        terminated = truncated = False
        standing = 0
        while not (terminated or truncated):
            _, _, terminated, truncated, info = env.step(policy(env))
            standing += info["target_kind"] == "none"
        empty += standing
        coverages.append(info["coverage"])
        if standing >= 3 and info["coverage"] < target:
            stuck.append(seed)
    print(f"{args.env_id}, {args.policy} policy, {args.episodes} episodes: {len(stuck)} stuck (seeds {stuck}), "
          f"{empty} decisions with no target; coverage mean {np.mean(coverages):.3f}, "
          f"median {np.median(coverages):.3f}")


if __name__ == "__main__":
    main()
