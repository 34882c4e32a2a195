"""Dead-reckoning drift of the odometry presets around the loop_corridor loop.

    python measurements/odometry_drift.py [--seeds 30] [--preset typical|good|poor|all]

Drives the loop (start -> decision point -> back to the start, 74 m) twice on each seed
and prints the odometry's position and heading errors once the robot has travelled 74 m
(one loop) and 100 m: median, 10th/90th percentiles and the share of seeds more than 1 m
off. ``typical`` is the default OdometryNoise. The suite runs a fast version (8 seeds).
"""

from __future__ import annotations

import argparse

import _arguments as arguments
import numpy as np

from emmi_gym.world import LaserConfig, Simulator, drive_route, load_world
from emmi_gym.world.presets import ODOMETRY_PRESETS, odometry_config

DISTANCES = (74.0, 100.0)


def errors_after(recording, distance: float) -> tuple[float, float]:
    """Position (m) and heading (rad) error of dead reckoning once the robot has travelled ``distance``."""
    travelled = np.concatenate([[0.0], np.cumsum(np.hypot(*np.diff(recording.true_poses[:, :2], axis=0).T))])
    i = int(np.searchsorted(travelled, distance))
    if i >= len(travelled):
        raise RuntimeError(f"the route is {travelled[-1]:.1f} m, shorter than {distance} m")
    d = recording.true_poses[i, 2] - recording.odometry_poses[i, 2]
    return (float(np.hypot(*(recording.true_poses[i, :2] - recording.odometry_poses[i, :2]))),
            abs((d + np.pi) % (2 * np.pi) - np.pi))


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    arguments.add_seed_range(parser, 30)
    parser.add_argument("--preset", default="typical", choices=[*ODOMETRY_PRESETS, "all"])
    args = parser.parse_args()
    world = load_world("loop_corridor")
    loop = world.route("to_decision") + world.route("close_loop")[1:]
    route = loop + loop[1:]
    print(f"{args.seeds} seeds round the loop_corridor loop (74 m); median (10% - 90%), share > 1 m")
    print("| preset | position error after 74 m | after 100 m | heading error after 100 m |")
    print("| --- | --- | --- | --- |")
    for preset in (ODOMETRY_PRESETS if args.preset == "all" else [args.preset]):
        sim = Simulator(world, laser=LaserConfig(n_beams=4), odometry=odometry_config(preset))
        results = {d: [] for d in DISTANCES}
        for seed in arguments.seed_range(args):
            rec = drive_route(sim, route, np.random.default_rng(seed))
            for d in DISTANCES:
                results[d].append(errors_after(rec, d))
        cells = []
        for d in DISTANCES:
            position = np.array([p for p, _ in results[d]])
            p10, p50, p90 = np.percentile(position, [10, 50, 90])
            cells.append(f"{p50:.2f} m ({p10:.2f} - {p90:.2f}), {np.mean(position > 1):.0%}")
        heading = np.median([h for _, h in results[DISTANCES[-1]]])
        print(f"| {preset} | {cells[0]} | {cells[1]} | {heading:.3f} rad |")


if __name__ == "__main__":
    main()
