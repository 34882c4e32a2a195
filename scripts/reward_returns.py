"""What each reward pays the scripted policies on LoopCorridor-v0, discounted per decision and per robot time.

Runs whole episodes of close_loop_first (the paper's A), explore_first (B) and frontier from
the decision point, keeps every step's reward components and duration, and prints for each
reward variant, time cost and discounting the mean discounted return of each policy and on
how many seeds A earns more than the others. A learning agent comes to prefer what earns
most here, so this is the check that a reward and discount make closing the loop first worth
learning (see emmi_gym/training/semi_markov.py for why the discount follows robot time).

    python scripts/reward_returns.py --seeds 12 --time-costs 0.002   # about 1 min on two cores
    python scripts/reward_returns.py --seeds 12 --env-kwargs '{laser: default, odometry_noise: typical}'

``--env-kwargs`` (a YAML mapping of ``gym.make`` keywords) asks the same of other settings of
the corridor (the second line: the 360-degree laser and typical odometry it had before): which
make the loop's closure worth going back for.
"""

from __future__ import annotations

import argparse

import numpy as np
import yaml

POLICIES = ("close_loop_first", "explore_first", "frontier")
VARIANTS = ("emmi", "pose_entropy", "joint_entropy", "coverage")


def episode_steps(job) -> tuple[str, int, list[dict]]:
    """One episode of a scripted policy: each step's reward components and duration (simulator steps)."""
    import gymnasium as gym

    import emmi_gym  # noqa: F401  (registers the ids in a worker process)
    from emmi_gym.policies import make_policy

    policy_name, seed, env_kwargs = job
    env = gym.make("emmi_gym/LoopCorridor-v0", **env_kwargs)
    policy = make_policy(policy_name)
    policy.reset(seed)
    env.reset(seed=seed)
    steps, done = [], False
    while not done:
        _, _, terminated, truncated, info = env.step(policy(env))
        steps.append({**info["reward_components"], "duration": info["sim_steps_this_step"]})
        done = terminated or truncated
    env.close()
    return policy_name, seed, steps


def discounted_return(steps: list[dict], variant: str, time_cost: float, gamma: float, unit: int | None) -> float:
    """Sum of the rewards discounted by ``gamma`` per decision (``unit`` None) or per ``unit`` simulator steps."""
    total, elapsed = 0.0, 0
    for k, step in enumerate(steps):
        reward = step[variant] - time_cost * step["duration"] + step["collision"]
        total += (gamma ** k if unit is None else gamma ** (elapsed / unit)) * reward
        elapsed += step["duration"]
    return total


def main() -> None:
    from emmi_gym.concurrency.parallel import run_in_processes
    from emmi_gym.env.config import EnvConfig

    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seeds", type=int, default=8)
    parser.add_argument("--time-costs", type=float, nargs="+", default=[EnvConfig.time_cost, 0.0005])
    parser.add_argument("--workers", type=int, default=None)
    parser.add_argument("--env-kwargs", type=yaml.safe_load, default={},
                        help="gym.make keywords of LoopCorridor-v0, as a YAML mapping")
    args = parser.parse_args()
    if not isinstance(args.env_kwargs, dict):
        parser.error(f"--env-kwargs: expected a YAML mapping of gym.make keywords, got {args.env_kwargs!r}")
    import gymnasium as gym

    import emmi_gym  # noqa: F401  (registers the ids)

    try:  # checked once here, before any worker starts (option errors are ValueErrors naming the field)
        gym.make("emmi_gym/LoopCorridor-v0", **args.env_kwargs).close()
    except ValueError as error:
        parser.error(f"--env-kwargs: {error}")
    jobs = [(policy, seed, args.env_kwargs) for seed in range(args.seeds) for policy in POLICIES]
    episodes = {(p, s): steps for p, s, steps in run_in_processes(episode_steps, jobs, workers=args.workers,
                                                                  desc="episodes")}
    for policy in POLICIES:
        lengths = [len(episodes[policy, s]) for s in range(args.seeds)]
        durations = [sum(step["duration"] for step in episodes[policy, s]) for s in range(args.seeds)]
        print(f"{policy:17s} decisions median {np.median(lengths):.0f}, "
              f"simulator steps median {np.median(durations):.0f}")
    discountings = [("per decision", 0.95, None), ("per 100 sim steps", 0.9, 100), ("per 100 sim steps", 0.95, 100)]
    for variant in VARIANTS:
        print(f"\nreward {variant}")
        for time_cost in args.time_costs:
            for label, gamma, unit in discountings:
                returns = {p: np.array([discounted_return(episodes[p, s], variant, time_cost, gamma, unit)
                                        for s in range(args.seeds)]) for p in POLICIES}
                a, b, f = (returns[p] for p in POLICIES)
                print(f"  time cost {time_cost:<7g} gamma {gamma} {label:18s} A {a.mean():+6.2f}  B {b.mean():+6.2f}  "
                      f"frontier {f.mean():+6.2f}   A > B on {np.sum(a > b)}/{args.seeds}, "
                      f"A > frontier on {np.sum(a > f)}/{args.seeds}")


if __name__ == "__main__":
    main()
