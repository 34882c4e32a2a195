"""Time the simulated laser and one simulator control step.

    python scripts/bench_world.py [--repeats 500]

Prints medians: a 180-beam scan with the numba kernel vs the same beams as pymunk
segment queries (``Space.segment_query_first``, one Python call per beam), and a
control step of the pymunk world (5 physics substeps + odometry), in loop_corridor.
"""

from __future__ import annotations

import argparse
import math

import numpy as np
import pymunk
from _timing import median_seconds

from emmi_gym.world.loader import load_world
from emmi_gym.world.simulator import Simulator


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeats", type=int, default=500)
    args = parser.parse_args()
    world = load_world("loop_corridor")
    sim = Simulator(world)
    sim.reset(np.random.default_rng(0))
    config = sim.laser.config
    only_walls = pymunk.ShapeFilter(mask=pymunk.ShapeFilter.ALL_MASKS() ^ 1)
    sim.shape.filter = pymunk.ShapeFilter(categories=1)

    def pymunk_scan():
        x, y, theta = sim.true_pose
        for a in config.angles + theta:
            sim.space.segment_query_first((x, y), (x + config.max_range * math.cos(a),
                                                   y + config.max_range * math.sin(a)), 0.0, only_walls)

    rng = np.random.default_rng(1)
    print(f"loop_corridor ({len(world.walls)} wall segments), {config.n_beams} beams, median of {args.repeats}")
    kernel = 1e6 * median_seconds(lambda: sim.laser.true_ranges(sim.true_pose), args.repeats)
    noisy = 1e6 * median_seconds(sim.scan, args.repeats)
    queries = 1e6 * median_seconds(pymunk_scan, args.repeats // 5)
    step = 1e6 * median_seconds(lambda: sim.step(0.3, 0.2 * rng.standard_normal()), args.repeats)
    print(f"scan, numba kernel (no noise):  {kernel:8.1f} us")
    print(f"scan, with noise and drops:      {noisy:8.1f} us")
    print(f"scan, pymunk segment queries:    {queries:8.1f} us  ({queries / kernel:.0f}x the kernel)")
    print(f"control step (physics + odometry): {step:6.1f} us")


if __name__ == "__main__":
    main()
