"""What each registered reward pays for standing still, spinning in place and exploring.

    python measurements/reward_farming.py [--seeds 5] [--steps 300] [--decisions 40]

Velocity mode (one simulator step per action) on the hard configuration's worlds and
sensors (ExplorePlans-v1's DungeonMaps plans, SICK LMS200 at 8 m, poor odometry): standing
still, spinning in place at full turn rate, and driving straight ahead (until a wall), each
for ``--steps`` steps; waypoint mode (``ExplorePlans-v1``): the frontier and active
loop-closing policies for ``--decisions`` decisions. Prints per variant the mean return
(the variant's reward at its default scale plus the time and collision costs, undiscounted)
per policy, and the same per 100 simulator steps, over ``--seeds`` plans and seeds.
"""

from __future__ import annotations

import argparse

import _arguments as arguments
import gymnasium as gym
import numpy as np

import emmi_gym  # noqa: F401 (registers the ids)
from emmi_gym.env import ENV_IDS, REWARDS
from emmi_gym.tools.policies import make_policy

HARD = {k: v for k, v in ENV_IDS["ExplorePlans-v1"].items() if k not in ("action_mode", "max_decisions")}
VELOCITY_POLICIES = {"stand still": (0.0, 0.0), "spin in place": (0.0, 1.0), "drive ahead": (1.0, 0.0)}


def returns(steps: list[dict]) -> dict[str, float]:
    """The undiscounted return of every variant over an episode's steps, and its length in simulator steps."""
    costs = sum(s["time"] + s["collision"] for s in steps)
    row = {v: sum(s[v] for s in steps) + costs for v in REWARDS}
    row["sim_steps"] = sum(s["duration"] for s in steps)
    return row


def velocity_episode(command, seed: int, n_steps: int) -> dict:
    env = gym.make("emmi_gym/ExplorePlans-v1", **dict(HARD, action_mode="velocity", max_sim_steps=n_steps),
                   info_rewards="all")
    env.reset(seed=seed)
    steps, done = [], False
    while not done:
        _, _, terminated, truncated, info = env.step(np.array(command, dtype=np.float32))
        steps.append({**info["reward_components"], "duration": 1})
        done = terminated or truncated
    return returns(steps)


def waypoint_steps(policy_name: str, seed: int, n_decisions: int, env_id: str = "emmi_gym/ExplorePlans-v1") -> list:
    """Every decision's reward components (every registered reward's) and duration, of one episode of the policy."""
    env = gym.make(env_id, max_decisions=n_decisions, info_rewards="all")
    policy = make_policy(policy_name)
    env.reset(seed=seed)
    policy.reset(seed)
    steps, done = [], False
    while not done:
        _, _, terminated, truncated, info = env.step(policy(env))
        steps.append({**info["reward_components"], "duration": info["sim_steps_this_step"]})
        done = terminated or truncated
    env.close()
    return steps


def waypoint_episode(policy_name: str, seed: int, n_decisions: int) -> dict:
    return returns(waypoint_steps(policy_name, seed, n_decisions))


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    arguments.add_seed_range(parser, 5)
    parser.add_argument("--steps", type=arguments.integer(1), default=300)
    parser.add_argument("--decisions", type=arguments.integer(1), default=40)
    args = parser.parse_args()
    results = {}
    for name, command in VELOCITY_POLICIES.items():
        results[f"{name} ({args.steps} steps)"] = [velocity_episode(command, s, args.steps)
                                                   for s in arguments.seed_range(args)]
    for name in ("frontier", "active_loop_closing"):
        results[f"{name} (at most {args.decisions} decisions)"] = [
            waypoint_episode(name, s, args.decisions) for s in arguments.seed_range(args)]
    print(f"mean undiscounted return over {args.seeds} seeds (plans of dungeon_maps/train), time and collision "
          "costs included; in brackets: per 100 simulator steps")
    print("| policy | " + " | ".join(REWARDS) + " |")
    print("| --- |" + " --- |" * len(REWARDS))
    for name, rows in results.items():
        cells = []
        for variant in REWARDS:
            total = np.mean([r[variant] for r in rows])
            rate = np.mean([100 * r[variant] / r["sim_steps"] for r in rows])
            cells.append(f"{total:+.2f} ({rate:+.2f})")
        print(f"| {name} | " + " | ".join(cells) + " |")


if __name__ == "__main__":
    main()
