"""Dead-reckoning drift of the default odometry noise around the loop_corridor loop.

    python scripts/odometry_drift.py [--seeds 30]

Drives start -> decision point -> back to the start (74 m) on each seed and prints
the final odometry position and heading errors: median, 10th/90th percentiles and
the fraction of seeds more than 1 m off. The suite runs a fast version (8 seeds).
"""

from __future__ import annotations

import argparse

import numpy as np

from emmi_gym.world.laser import LaserConfig
from emmi_gym.world.loader import load_world
from emmi_gym.world.recording import drive_route
from emmi_gym.world.simulator import Simulator


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seeds", type=int, default=30)
    args = parser.parse_args()
    world = load_world("loop_corridor")
    sim = Simulator(world, laser=LaserConfig(n_beams=4))
    route = world.route("to_decision") + world.route("close_loop")[1:]
    position, heading = [], []
    for seed in range(args.seeds):
        rec = drive_route(sim, route, np.random.default_rng(seed))
        position.append(np.hypot(*(rec.true_poses[-1, :2] - rec.odometry_poses[-1, :2])))
        d = rec.true_poses[-1, 2] - rec.odometry_poses[-1, 2]
        heading.append(abs((d + np.pi) % (2 * np.pi) - np.pi))
    position, heading = np.array(position), np.array(heading)
    p10, p50, p90 = np.percentile(position, [10, 50, 90])
    print(f"{args.seeds} seeds, 74 m loop, default OdometryNoise")
    print(f"position error: median {p50:.2f} m (10%: {p10:.2f}, 90%: {p90:.2f}); "
          f"> 1 m on {np.sum(position > 1)} of {args.seeds} seeds")
    print(f"heading error: median {np.median(heading):.3f} rad")


if __name__ == "__main__":
    main()
