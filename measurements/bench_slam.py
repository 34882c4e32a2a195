"""Time RBPF updates: the median per update and its split, and how the cost grows with M and beams.

    python measurements/bench_slam.py [--particles 15] [--table] [--extents]

Data: the loop_corridor loop (start -> decision -> start) recorded once with the
default laser (360 deg, 180 beams, 8 m); the filter runs on a fixed 25 m x 20 m grid
of 0.1 m cells covering the loop, its kernels on one thread per core (``emmi_gym.concurrency.threads``).
Every update includes the expected map and EMMI and the other metrics. The first 10
updates (numba loading) are not timed. ``--table`` adds M in {5, 15, 30, 60} and beams in
{90, 180, 360}; ``--extents`` runs the same loop on square grids of 30, 50 and 100 m: the
metrics and the resampling should cost the same whatever the grid's extent.
"""

from __future__ import annotations

import argparse
import time

import _arguments as arguments
import numpy as np

from emmi_gym.geometry.grid import GridGeometry
from emmi_gym.slam import RBPF, RBPFConfig
from emmi_gym.world import LaserConfig, Simulator, drive_route, load_world


def record(n_beams: int):
    world = load_world("loop_corridor")
    sim = Simulator(world, laser=LaserConfig(n_beams=n_beams))
    route = world.route("to_decision") + world.route("close_loop")[1:]
    return drive_route(sim, route, np.random.default_rng(0)), sim.laser.config.angles


def run(particles: int, n_beams: int, recorded=None, side: float | None = None):
    """Median ms per update and the median of each phase, over one pass of the recording; the grid is
    25 m x 20 m round the loop, or a square of ``side`` metres centred on it."""
    rec, angles = recorded or record(n_beams)
    geometry = GridGeometry.covering(-0.5, -2.0, 24.5, 18.0, 0.1)  # 25 m x 20 m
    if side is not None:
        geometry = GridGeometry.covering(12.0 - side / 2, 8.0 - side / 2, 12.0 + side / 2, 8.0 + side / 2, 0.1)
    slam = RBPF(RBPFConfig(particles=particles), max_range=8.0, geometry=geometry)
    slam.reset(rec.odometry_poses[0], np.random.default_rng(1))
    rows = []
    t0 = time.perf_counter()
    for pose, ranges in zip(rec.odometry_poses, rec.scans, strict=True):
        metrics = slam.process(pose, ranges, angles)
        if metrics is not None:
            rows.append(metrics)
    wall = time.perf_counter() - t0
    timed = rows[10:]
    phases = {k: float(np.median([r.phase_ms[k] for r in timed])) for k in timed[0].phase_ms}
    phases["longest resampling"] = max(r.phase_ms["resampling"] for r in rows)
    return float(np.median([r.update_ms for r in timed])), phases, len(rows), wall


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--particles", type=arguments.integer(1), default=15)
    parser.add_argument("--table", action="store_true")
    parser.add_argument("--extents", action="store_true")
    args = parser.parse_args()
    recorded = record(180)
    run(args.particles, 180, recorded)  # compile or load the kernels
    median, phases, n, wall = run(args.particles, 180, recorded)
    print(f"RBPF, {args.particles} particles, 180 beams, 0.1 m cells, 25 m x 20 m grid ({n} updates, "
          f"{wall:.1f} s for the 74 m loop)")
    print(f"median update: {median:.2f} ms, of which (medians) " +
          ", ".join(f"{k} {v:.2f}" for k, v in phases.items()))
    if args.extents:
        print("\n| grid | median ms / update | metrics (median) | longest resampling (ms) |")
        print("| --- | --- | --- | --- |")
        for side in (30.0, 50.0, 100.0):
            med, ph, _, _ = run(args.particles, 180, recorded, side)
            print(f"| {side:.0f} m x {side:.0f} m | {med:.2f} | {ph['metrics']:.2f} | {ph['longest resampling']:.2f} |")
    if args.table:
        print("\n| particles | beams | median ms / update | scan matching | insertion | metrics |")
        print("| --- | --- | --- | --- | --- | --- |")
        for beams in (180,):
            for m in (5, 15, 30, 60):
                med, ph, _, _ = run(m, beams, recorded)
                print(f"| {m} | {beams} | {med:.2f} | {ph['scan_matching']:.2f} | {ph['insertion']:.2f} | "
                      f"{ph['metrics']:.2f} |")
        for beams in (90, 360):
            med, ph, _, _ = run(15, beams)
            print(f"| 15 | {beams} | {med:.2f} | {ph['scan_matching']:.2f} | {ph['insertion']:.2f} | "
                  f"{ph['metrics']:.2f} |")


if __name__ == "__main__":
    main()
