"""Time the RBPF on a long-range laser over a building-sized area: 361 beams, 180 degrees, 30 m.

    python measurements/bench_large_map.py [--particles 15] [--resolution 0.05] [--metres 323]
                                      [--data ../shared/datasets/carmen] [--out aces_tour.log] [--threads N]
                                      [--slam '{"revisit_beams": 30}'] [--filter-seeds 1 2 3 4 5 6]

Data: the ACES building world (``load_world("aces")``, 57 m x 57 m) driven by the
simulator along the corrected ACES trajectory (its keyframe poses, from
``aces-corrected.log.gz``, as waypoints; ``--metres`` of it), with a SICK-like laser
(361 beams over 180 degrees, readings to 30 m) and the simulator's noisy odometry.
``--out`` also writes the drive as a CARMEN log (``emmi-gym replay`` reads it). The
filter then runs over the drive on a 60 m x 60 m grid round the building, its kernels on
one thread per core (``--threads`` sets how many). It prints the median update (wall
time) with its phases and the median CPU time of an update over all threads (the first
10 updates, numba loading, are not timed, and a short warm-up run loads the resampling's
kernels), the longest and median resampling (and the longest one's phases), and the ATE of
the best particle's path against the truth (unaligned: the filter starts at the true start
pose). ``--slam`` overrides ``RBPFConfig`` fields; with several ``--filter-seeds`` (the filter's
own random draws; the timings are the first one's) it also prints each seed's ATE and
resamplings and their median: one run says little about a change to the weights.
"""

from __future__ import annotations

import argparse
import itertools
import math
import time
from dataclasses import replace
from pathlib import Path

import _arguments as arguments
import numpy as np
from _data import require_files
from _options import rbpf_config

from emmi_gym.concurrency.threads import set_kernel_threads
from emmi_gym.formats import carmen
from emmi_gym.geometry.grid import GridGeometry
from emmi_gym.scoring.scores import absolute_trajectory_error
from emmi_gym.slam import RBPF, RBPFConfig
from emmi_gym.tools.experiments.replay import laser_stream
from emmi_gym.world import LaserConfig, Simulator, drive_route, load_world, write_carmen

LASER = LaserConfig(fov=math.pi, n_beams=361, max_range=30.0)


def tour(data: Path, metres: float, spacing: float = 1.0) -> list[tuple[float, float]]:
    """Waypoints ``spacing`` metres apart along the first ``metres`` of the corrected ACES path."""
    log = carmen.read_log(data / "aces-corrected.log.gz")
    xy = np.array([pose[:2] for _, pose, _ in laser_stream(log) if pose is not None])
    travelled = np.concatenate([[0.0], np.cumsum(np.hypot(*np.diff(xy, axis=0).T))])
    keep = travelled <= metres
    xy, travelled = xy[keep], travelled[keep]
    marks = np.searchsorted(travelled, np.arange(0.0, travelled[-1], spacing))
    return [tuple(p) for p in xy[np.unique(np.append(marks, xy.shape[0] - 1))]]


def run(rec, angles, config: RBPFConfig, geometry: GridGeometry, scans: int | None = None, seed: int = 1):
    """The filter (random draws from ``seed``) over the first ``scans`` of the drive: its updates' metrics,
    the ATE of its best path, and each resampling's phases (``ParticleMaps.resample_ms``)."""
    slam = RBPF(config, max_range=LASER.max_range, geometry=geometry)
    slam.reset(rec.odometry_poses[0], np.random.default_rng(seed))
    rows, truth, resamplings = [], [], []
    for pose, true_pose, ranges in itertools.islice(zip(rec.odometry_poses, rec.true_poses, rec.scans, strict=True),
                                                    scans):
        metrics = slam.process(pose, ranges, angles)
        if metrics is not None:
            if metrics.resampled:
                resamplings.append(dict(slam.maps.resample_ms, total=metrics.phase_ms["resampling"]))
            rows.append(metrics)
            truth.append(true_pose)
    return rows, absolute_trajectory_error(slam.paths[slam.best], truth, align=False), resamplings


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--particles", type=arguments.integer(1), default=15)
    parser.add_argument("--resolution", type=arguments.number(0.0, unit="m"), default=0.05)
    parser.add_argument("--metres", type=arguments.number(0.0, unit="m"), default=323.0,
                        help="how much of the ACES path to drive")
    parser.add_argument("--data", type=Path,
                        default=Path(__file__).resolve().parents[2] / "shared" / "datasets" / "carmen")
    parser.add_argument("--out", type=Path, default=None, help="also write the drive as a CARMEN log")
    parser.add_argument("--threads", type=arguments.integer(1), default=None,
                        help="kernel threads (default: one per core)")
    parser.add_argument("--slam", default="{}", help="RBPFConfig overrides as JSON")
    parser.add_argument("--filter-seeds", nargs="+", type=arguments.SEED, default=[1], help="the filter's random seeds")
    args = parser.parse_args()
    require_files(parser, args.data, ["aces-corrected.log.gz"], "carmen")
    config = rbpf_config(parser, args.slam, particles=args.particles, resolution=args.resolution)
    if args.threads is not None:
        set_kernel_threads(args.threads)
    world = load_world("aces")
    sim = Simulator(world, laser=LASER)
    t0 = time.perf_counter()
    rec = drive_route(sim, tour(args.data, args.metres), np.random.default_rng(0), max_steps=100000)
    print(f"drove {np.hypot(*np.diff(rec.true_poses[:, :2], axis=0).T).sum():.0f} m of the ACES path in "
          f"{rec.times[-1]:.0f} s simulated ({time.perf_counter() - t0:.0f} s wall, {len(rec.times)} scans, "
          f"{'reached its end' if rec.reached else 'stopped before its end'})")
    if args.out:
        write_carmen(rec, sim, args.out)
        print(f"wrote {args.out}")
    xmin, ymin, xmax, ymax = world.bounds
    cx, cy = (xmin + xmax) / 2, (ymin + ymax) / 2
    geometry = GridGeometry.covering(cx - 30.0, cy - 30.0, cx + 30.0, cy + 30.0, args.resolution)
    run(rec, LASER.angles, replace(config, resample_threshold=1.0), geometry, scans=100)  # load kernels
    t0 = time.perf_counter()
    rows, ate, phases_of_resamplings = run(rec, LASER.angles, config, geometry, seed=args.filter_seeds[0])
    wall = time.perf_counter() - t0
    timed = rows[10:]
    if not timed:
        raise SystemExit(f"the drive gave {len(rows)} filter updates, all among the first 10, which are not timed: "
                         "drive farther (--metres) or update more often (--slam '{\"linear_update\": 0.1}')")
    phases = {k: float(np.median([r.phase_ms[k] for r in timed])) for k in timed[0].phase_ms}
    resamplings = [laps["total"] for laps in phases_of_resamplings]
    longest = max(phases_of_resamplings, key=lambda laps: laps["total"], default=None)
    print(f"RBPF, {args.particles} particles, {LASER.n_beams} beams over 180 deg to {LASER.max_range:g} m, "
          f"{args.resolution:g} m cells, 60 m x 60 m grid, overrides {args.slam}: {len(rows)} updates in "
          f"{wall:.1f} s")
    print(f"median update {np.median([r.update_ms for r in timed]):.2f} ms (max "
          f"{max(r.update_ms for r in timed):.1f}), of which (medians) " +
          ", ".join(f"{k} {v:.2f}" for k, v in phases.items()))
    print(f"CPU time per update (all threads) median {np.median([r.cpu_ms for r in timed]):.2f} ms")
    print(f"resamplings {len(resamplings)}, longest {max(resamplings, default=0.0):.2f} ms, median "
          f"{np.median(resamplings) if resamplings else 0.0:.2f} ms; ATE of the best path {ate:.3f} m "
          f"(filter seed {args.filter_seeds[0]})")
    if longest is not None:
        print("the longest resampling's phases (ms): " +
              ", ".join(f"{k} {v:.2f}" for k, v in longest.items() if k != "total"))
    if len(args.filter_seeds) > 1:
        runs = [(ate, len(resamplings))]
        for seed in args.filter_seeds[1:]:
            seed_rows, seed_ate, _ = run(rec, LASER.angles, config, geometry, seed=seed)
            runs.append((seed_ate, sum(r.resampled for r in seed_rows)))
        print("filter seeds " + ", ".join(f"{s}: ATE {a:.3f} m ({n} resamplings)"
                                          for s, (a, n) in zip(args.filter_seeds, runs, strict=True)))
        print(f"median ATE over {len(runs)} filter seeds {np.median([a for a, _ in runs]):.3f} m")


if __name__ == "__main__":
    main()
