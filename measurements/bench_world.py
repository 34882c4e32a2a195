"""Time loading worlds, the simulated laser and one simulator control step, per kind of world.

    python measurements/bench_world.py [--repeats 500]

Prints medians: loading a 640 x 480 DungeonMaps plan (image -> walls), then for each
world (the hand-made loop_corridor, a generated lattice world, a DungeonMaps plan, the
Intel building from its log) its wall count, a 180-beam scan with the numba kernel and
with pymunk segment queries (``Space.segment_query_first``, one Python call per beam),
and a control step of the pymunk world (5 physics substeps + odometry), on poses spread
over the world's free space.
"""

from __future__ import annotations

import argparse
import math
from importlib import resources
from pathlib import Path

import _arguments as arguments
import numpy as np
import pymunk
from _timing import median_seconds

from emmi_gym.world import GeneratorConfig, Simulator, generate_world, load_world, rasterise

PLAN = Path(str(resources.files("emmi_gym.worlds_data"))) / "dungeon_maps" / "test" / "img_10011.png"


def free_poses(world, n: int, rng) -> np.ndarray:
    """``n`` poses in the world's reachable free space, at least 0.3 m from the walls."""
    truth = rasterise(world, 0.1)
    rows, cols = np.nonzero(truth.reachable)
    poses = []
    while len(poses) < n:
        k = rng.integers(rows.size)
        x, y = truth.geometry.centre_of(rows[k], cols[k])
        if world.clearance(x, y) > 0.3:
            poses.append((float(x), float(y), rng.uniform(-math.pi, math.pi)))
    return np.array(poses)


def time_world(world, repeats: int, rng) -> tuple[float, float, float]:
    """Medians (us) on ``world``: a scan with the numba kernel, a scan with pymunk segment queries, a control step."""
    sim = Simulator(world)
    sim.reset(np.random.default_rng(0))
    config = sim.laser.config
    only_walls = pymunk.ShapeFilter(mask=pymunk.ShapeFilter.ALL_MASKS() ^ 1)
    sim.shape.filter = pymunk.ShapeFilter(categories=1)
    poses = free_poses(world, 64, rng)
    cycle = iter(range(10**9))

    def next_pose():
        return poses[next(cycle) % len(poses)]

    def pymunk_scan():
        x, y, theta = next_pose()
        for a in config.angles + theta:
            sim.space.segment_query_first((x, y), (x + config.max_range * math.cos(a),
                                                   y + config.max_range * math.sin(a)), 0.0, only_walls)

    kernel = 1e6 * median_seconds(lambda: sim.laser.true_ranges(next_pose()), repeats)
    queries = 1e6 * median_seconds(pymunk_scan, max(1, repeats // 5))
    step = 1e6 * median_seconds(lambda: sim.step(0.3, 0.2 * rng.standard_normal()), repeats)
    return kernel, queries, step


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeats", type=arguments.integer(1), default=500)
    args = parser.parse_args()
    rng = np.random.default_rng(1)
    load = 1e3 * median_seconds(lambda: load_world(PLAN), 20)
    print(f"loading a 640 x 480 DungeonMaps plan ({PLAN.name}): {load:.1f} ms (median of 20)\n")
    worlds = {"loop_corridor": load_world("loop_corridor"),
              "generated lattice": generate_world(np.random.default_rng(0), GeneratorConfig()),
              "DungeonMaps plan": load_world(PLAN), "intel (from its log)": load_world("intel")}
    print(f"median of {args.repeats}, 180 beams, 8 m")
    print("| world | walls | scan, kernel (us) | scan, pymunk queries (us) | control step (us) |")
    print("| --- | --- | --- | --- | --- |")
    for name, world in worlds.items():
        kernel, queries, step = time_world(world, args.repeats, rng)
        print(f"| {name} | {len(world.walls)} | {kernel:.1f} | {queries:.1f} | {step:.1f} |")


if __name__ == "__main__":
    main()
