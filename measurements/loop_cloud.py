"""Where the particles stand at the decision point of a loop, against the truth: what closing the loop can
choose from.

    python measurements/loop_cloud.py [--env-id emmi_gym/LoopOrder-v1] [--seeds 10] [--first-seed 0]
                                    [--odometry poor]

For each seed it resets the env (which drives the loop up to the decision point) and prints, averaged over
the seeds: the particles' spread (m, the norm of their x and y deviations), how far their mean lies from the
true pose, the error of the particle nearest the truth, and the ATE of the loop (the path so far) under the
best, the median and the nearest-to-the-truth particle, with the correlation over particles between the end
error and the loop's ATE. A loop closure selects particles by their end pose: it can gain what separates the
nearest particle's loop ATE from the median's, and depletion can only cost that.
"""

from __future__ import annotations

import argparse

import _arguments as arguments
import gymnasium as gym
import numpy as np

import emmi_gym  # noqa: F401
from emmi_gym.tools.experiments.ab import loop_ate


def cloud(env, seed: int) -> tuple[float, ...]:
    _, info = env.reset(seed=seed)
    core = env.unwrapped
    paths, poses, truth = core.slam.paths, core.slam.poses[:, :2], core.true_path
    period = core.robot_config.control_period
    ates = np.array([loop_ate(info["rbpf_updates"], path, truth, period) for path in paths])
    end_error = np.hypot(*(poses - truth[-1, :2]).T)
    return (float(np.hypot(*poses.std(axis=0))), float(np.hypot(*(poses.mean(axis=0) - truth[-1, :2]))),
            float(end_error.min()), float(ates.min()), float(np.median(ates)), float(ates[np.argmin(end_error)]),
            float(np.corrcoef(end_error, ates)[0, 1]))


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--env-id", default="emmi_gym/LoopOrder-v1")
    arguments.add_seed_range(parser, 10)
    parser.add_argument("--odometry", default=None, help="an odometry preset (default: the env's)")
    args = parser.parse_args()
    options = {"update_records": True} | ({"odometry_noise": args.odometry} if args.odometry else {})
    env = gym.make(args.env_id, **options)
    rows = np.array([cloud(env, seed) for seed in arguments.seed_range(args)])
    spread, offset, nearest, best, median, of_nearest, correlation = rows.mean(axis=0)
    print(f"{args.env_id}, seeds {args.first_seed}-{args.first_seed + args.seeds - 1}, odometry "
          f"{args.odometry or 'as registered'} (means over seeds):")
    print(f"  particles' spread {spread:.2f} m; their mean {offset:.2f} m from the truth; nearest particle "
          f"{nearest:.2f} m")
    print(f"  ATE of the loop: best particle {best:.2f} m, median {median:.2f} m, the particle nearest the truth "
          f"{of_nearest:.2f} m; correlation of end error and loop ATE {correlation:.2f}")


if __name__ == "__main__":
    main()
