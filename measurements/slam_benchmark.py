"""The RBPF on real laser logs: the radish-noisy set (Intel, ACES, CSAIL, Freiburg 079 x 3 odometry seeds).

    python measurements/slam_benchmark.py [--data ../shared/datasets/radish-noisy] [--logs intel aces]
        [--log-seeds 0 1 2] [--particles 15] [--resolution 0.05] [--max-range 30] [--preset radish-noisy]
        [--slam '{"insertion_range": 8}'] [--filter-seeds 0 1 2] [--out slam_benchmark] [--jobs 1]
        [--threads N] [--flaser-fov 180]

Every keyframe is an update (linear_update = angular_update = 0, as GMapping's
``-linearUpdate 0 -angularUpdate 0``). For each log and seed it prints the best
particle's ATE (aligned, against the TRUEPOS lines), dead reckoning's ATE, the median
and maximum milliseconds per update (wall time; whole update, and of it the matching, the
insertion and the certainty metrics), the median CPU time per update of all the process's
threads (the kernels run on one thread per core: compare this with GMapping's, which has one),
the resamplings, and writes the best particle's map as PNG beside the corrected
map's picture, and its trajectory in the TUM format. Run with ``--jobs 1`` (in this process) for
the timings (parallel runs share the cores). With several ``--filter-seeds`` (the filter's own
random draws) each log and seed runs once per filter seed, and a last table gives each
log's median ATE over all its runs: one run says little about a change to the filter.
"""

from __future__ import annotations

import argparse
import json
import math
import shutil
import time
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path

import _arguments as arguments
import numpy as np
from _data import require_files
from _options import rbpf_config

from emmi_gym.concurrency.threads import set_kernel_threads
from emmi_gym.formats.carmen import read_log
from emmi_gym.slam import RBPFConfig
from emmi_gym.tools.experiments.replay import replay, write_map_png, write_tum

LOGS = ("intel", "aces", "csail", "freiburg-079")



def run_one(path: Path, config: RBPFConfig, max_range: float, out: Path, filter_seed: int,
            threads: int | None, flaser_fov: float) -> dict:
    if threads is not None:
        set_kernel_threads(threads)
    log = read_log(path, flaser_fov=math.radians(flaser_fov))
    t0 = time.perf_counter()
    result = replay(log, config, max_range=max_range, seed=filter_seed)
    wall = time.perf_counter() - t0
    rows = result.rows[1:]
    name = path.name.removesuffix(".gz").removesuffix(".log")
    if filter_seed:
        name += f"-filter{filter_seed}"
    write_map_png(result, out / f"{name}-best_map.png", title=f"{name}: best particle's map")
    write_tum(result, out / f"{name}-best.tum")
    return dict(log=name, updates=len(result.rows), ate=result.ate(),
                dead_reckoning=result.dead_reckoning_ate(),
                median_ms=float(np.median([r.update_ms for r in rows])),
                max_ms=float(np.max([r.update_ms for r in rows])),
                metrics_ms=float(np.median([r.phase_ms["metrics"] for r in rows])),
                matching_ms=float(np.median([r.phase_ms["scan_matching"] for r in rows])),
                insertion_ms=float(np.median([r.phase_ms["insertion"] for r in rows])),
                resampling_max_ms=float(np.max([r.phase_ms["resampling"] for r in rows])),
                resamplings=sum(r.resampled for r in rows), wall_s=wall,
                cpu_ms=float(np.median([r.cpu_ms for r in rows])))


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--data", default=str(Path(__file__).resolve().parents[2] / "shared/datasets/radish-noisy"))
    parser.add_argument("--logs", nargs="+", default=list(LOGS), choices=LOGS)
    parser.add_argument("--log-seeds", nargs="+", type=arguments.integer(0), default=[0, 1, 2],
                        help="which odometry-noise versions of each log (the N of NAME-seedN.log.gz)")
    parser.add_argument("--particles", type=arguments.integer(1), default=15)
    parser.add_argument("--resolution", type=arguments.number(0.0, unit="m"), default=0.05)
    parser.add_argument("--max-range", type=arguments.number(0.0, unit="m"), default=30.0,
                        help="readings at or beyond it are no echo (the logs mark them 81.83 m or 50 m)")
    parser.add_argument("--preset", default="radish-noisy", help="RBPFConfig preset ('none': the defaults)")
    parser.add_argument("--slam", default="{}", help="further RBPFConfig fields as JSON")
    parser.add_argument("--filter-seeds", nargs="+", type=arguments.SEED, default=[0], help="the filter's random seeds")
    parser.add_argument("--out", default="slam_benchmark")
    parser.add_argument("--jobs", type=arguments.integer(1), default=1, help="replays at a time (1: in this process)")
    parser.add_argument("--threads", type=arguments.integer(1), default=None,
                        help="kernel threads per run (default: one per core)")
    parser.add_argument("--flaser-fov", type=arguments.number(0.0, 360.0, "degrees"), default=180.0,
                        help="field of view of the FLASER lines, degrees "
                             "(the first beam at -fov/2, the last at +fov/2)")
    args = parser.parse_args()
    config = rbpf_config(parser, args.slam, None if args.preset == "none" else args.preset,
                         particles=args.particles, resolution=args.resolution, linear_update=0.0,
                         angular_update=0.0)  # every keyframe an update
    data, out = Path(args.data), Path(args.out)
    runs = [(data / f"{name}-seed{seed}.log.gz", f) for name in args.logs for seed in args.log_seeds
            for f in args.filter_seeds]
    require_files(parser, data, [p.name for p, _ in runs], "radish-noisy")
    out.mkdir(parents=True, exist_ok=True)
    corrected = data.parent / "carmen"
    for name in args.logs:
        picture = corrected / f"{name}-corrected.png"
        if picture.exists():
            shutil.copy(picture, out / picture.name)
    jobs = [(path, config, args.max_range, out, filter_seed, args.threads, args.flaser_fov)
            for path, filter_seed in runs]
    if args.jobs == 1:
        results = [run_one(*job) for job in jobs]
    else:
        with ProcessPoolExecutor(args.jobs) as pool:
            results = list(pool.map(run_one, *zip(*jobs, strict=True)))
    print(f"{args.particles} particles, {args.resolution} m cells, every keyframe an update, max range "
          f"{args.max_range} m, FLASER field of view {args.flaser_fov:g} deg, preset {args.preset}, "
          f"overrides {args.slam}")
    print("| log | updates | dead reckoning ATE (m) | RBPF ATE (m) | median ms/update | max ms | "
          "of which matching / insertion / metrics (medians) | CPU ms/update | resamplings | "
          "longest resampling (ms) |")
    print("| --- | --- | --- | --- | --- | --- | --- | --- | --- | --- |")
    for r in results:
        print(f"| {r['log']} | {r['updates']} | {r['dead_reckoning']:.2f} | {r['ate']:.3f} | {r['median_ms']:.1f} | "
              f"{r['max_ms']:.1f} | {r['matching_ms']:.1f} / {r['insertion_ms']:.1f} / {r['metrics_ms']:.1f} | "
              f"{r['cpu_ms']:.1f} | "
              f"{r['resamplings']} | {r['resampling_max_ms']:.1f} |")
    if len(args.filter_seeds) > 1:
        print("\n| log | runs | median ATE (m) | min - max |\n| --- | --- | --- | --- |")
        for name in args.logs:
            ates = [r["ate"] for r in results if r["log"].startswith(f"{name}-seed")]
            print(f"| {name} | {len(ates)} | {np.median(ates):.3f} | {min(ates):.3f} - {max(ates):.3f} |")
    (out / "results.json").write_text(json.dumps(results, indent=1))


if __name__ == "__main__":
    main()
