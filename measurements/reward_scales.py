"""How much each registered reward's value moves over one decision, and what its default scale makes of it.

    python measurements/reward_scales.py [--env-id emmi_gym/ExplorePlans-v1] [--seeds 3]
                                         [--policies frontier active_loop_closing random] [--decisions 60]

Plays each policy on ``--seeds`` seeded episodes of the id (at most ``--decisions`` decisions each; every
registered reward in ``info``: ``info_rewards="all"``) and prints, per reward, the median and the 90th
percentile over decisions of its unscaled value's magnitude, both scaled by the default scale, and the share
of decisions on which it moved at all. A scale is what turns the typical change into O(0.1-1)
(docs/rewards.md): then a reward is comparable with the others and with the time cost.
"""

from __future__ import annotations

import argparse

import _arguments as arguments
import numpy as np
from reward_farming import waypoint_steps

import emmi_gym  # noqa: F401 (registers the ids)
from emmi_gym.env import REWARDS


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--env-id", default="emmi_gym/ExplorePlans-v1")
    arguments.add_seed_range(parser, 3)
    parser.add_argument("--policies", nargs="+", default=["frontier", "active_loop_closing", "random"])
    parser.add_argument("--decisions", type=arguments.integer(1), default=60, help="decisions per episode at most")
    args = parser.parse_args()
    steps = [step for name in args.policies for seed in arguments.seed_range(args)
             for step in waypoint_steps(name, seed, args.decisions, args.env_id)]
    print(f"{args.env_id}: {len(steps)} decisions of {', '.join(args.policies)} on seeds from {args.first_seed} "
          f"({args.seeds} each, at most {args.decisions} decisions)")
    print("| reward | reads | median change | 90th percentile | default scale | scaled: median, 90th pct. | moved |")
    print("| --- | --- | --- | --- | --- | --- | --- |")
    for name, reward in REWARDS.items():
        values = np.abs([step[name] / reward.scale for step in steps])
        reads = "ground truth" if reward.privileged else "filter"
        median, high = np.median(values), np.percentile(values, 90)
        print(f"| `{name}` | {reads} | {median:.3g} | {high:.3g} | {reward.scale:g} | {reward.scale * median:.2f}, "
              f"{reward.scale * high:.2f} | {np.mean(values > 0):.0%} |")


if __name__ == "__main__":
    main()
