"""The replay of ROS bags against the CARMEN logs they were made from: the same ATE, the same EMMI curve.

    python measurements/ros_bags.py [--data ../shared/datasets/radish-noisy] [--logs intel aces freiburg-079]
        [--log-seed 0] [--filter-seeds 0 1 2] [--bag-seeds 0] [--particles 15] [--out ros_bags] [--jobs 1]

Converts each ``radish-noisy`` log (``NAME-seedN.log.gz``) with the ``rosbags`` writer
(:func:`emmi_gym.formats.ros_writers.write_log_bag`) to a ROS 1 bag and to ROS 2 bags of the sqlite3 and
MCAP storages (``/scan``, ``/odom``, ``/tf``, ``/tf_static``, ``/truth``), then replays the log and each
bag as ``emmi-gym replay --preset radish-noisy --resolution 0.05 --every-scan`` does (``--particles``, 15 by
default; the log with ``--max-range 30``, the bags with their ``range_max`` of 30 m and ``--truth /truth``;
``--jobs`` replays at a time, 1: in this process). The log
replays under each of ``--filter-seeds`` (the run-to-run spread), every bag under ``--bag-seeds``, and
the MCAP bag under all the filter seeds. It prints per log the final ATE of every run, whether the three
bags decode to the same scans and poses, and the EMMI curves' largest difference from the log's at the
same seed beside the largest between two seeds of the log; ``results.json`` keeps every curve.
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

from emmi_gym.formats.carmen import LaserRecord, read_log
from emmi_gym.formats.ros_bags import BagTopics, read_bag
from emmi_gym.formats.ros_writers import STORAGES, write_log_bag
from emmi_gym.slam import RBPFConfig
from emmi_gym.tools.experiments.replay import replay

LOGS = ("intel", "aces", "csail", "freiburg-079")
MAX_RANGE = 30.0
BAG_NAMES = {"ros1": "bag.bag", "sqlite3": "bag-sqlite3", "mcap": "bag-mcap"}


def convert(log_path: Path, out: Path) -> dict[str, Path]:
    """The log as a bag of each storage in ``out`` (made anew)."""
    log = read_log(log_path)
    out.mkdir(parents=True, exist_ok=True)
    bags = {}
    for storage in STORAGES:
        path = out / BAG_NAMES[storage]
        if path.exists():
            shutil.rmtree(path) if path.is_dir() else path.unlink()
        bags[storage] = write_log_bag(log, path, storage, max_range=MAX_RANGE)
    return bags


def same_inputs(bags: dict[str, Path]) -> bool:
    """Whether every bag decodes to the same scans, poses and times."""
    logs = [read_bag(path, BagTopics(truth="/truth")).of_type(LaserRecord) for path in bags.values()]
    first = logs[0]
    return all(len(other) == len(first) and all(
        np.array_equal(a.ranges, b.ranges) and np.array_equal(a.odometry_pose, b.odometry_pose)
        and a.timestamp == b.timestamp and a.start_angle == b.start_angle for a, b in zip(first, other, strict=True))
        for other in logs[1:])


def run_one(source: str, path: str, seed: int, particles: int = 15) -> dict:
    config = RBPFConfig.preset("radish-noisy", particles=particles, resolution=0.05)
    started = time.perf_counter()
    if source == "carmen":
        result = replay(read_log(path), config, max_range=MAX_RANGE, seed=seed, every_scan=True)
    else:
        result = replay(read_bag(path, BagTopics(truth="/truth")), config, seed=seed, every_scan=True)
    return dict(source=source, seed=seed, ate=result.ate(), updates=len(result.rows),
                emmi=[r.emmi for r in result.rows], seconds=time.perf_counter() - started)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--data", default=str(Path(__file__).resolve().parents[2] / "shared/datasets/radish-noisy"))
    parser.add_argument("--logs", nargs="+", default=["intel", "aces", "freiburg-079"], choices=LOGS)
    parser.add_argument("--log-seed", type=arguments.integer(0), default=0,
                        help="which odometry-noise version of each log (the N of NAME-seedN.log.gz)")
    parser.add_argument("--filter-seeds", nargs="+", type=arguments.SEED, default=[0, 1, 2])
    parser.add_argument("--bag-seeds", nargs="+", type=arguments.SEED, default=[0],
                        help="the filter seeds every bag format replays under")
    parser.add_argument("--particles", type=arguments.integer(1), default=15, help="the filter's particles")
    parser.add_argument("--out", default="ros_bags")
    parser.add_argument("--jobs", type=arguments.integer(1), default=1, help="replays at a time (1: in this process)")
    args = parser.parse_args()
    data, out = Path(args.data), Path(args.out)
    names = {name: f"{name}-seed{args.log_seed}.log.gz" for name in args.logs}
    require_files(parser, data, names.values(), "radish-noisy")
    runs, identical = [], {}
    for name, file in names.items():
        bags = convert(data / file, out / name)
        identical[name] = same_inputs(bags)
        runs += [(name, "carmen", str(data / file), seed) for seed in args.filter_seeds]
        runs += [(name, storage, str(bags[storage]), seed) for storage in STORAGES for seed in args.bag_seeds]
        runs += [(name, "mcap", str(bags["mcap"]), seed) for seed in args.filter_seeds if seed not in args.bag_seeds]
    jobs = [(*run[1:], args.particles) for run in runs]
    if args.jobs == 1:
        results = [run_one(*job) for job in jobs]
    else:
        with ProcessPoolExecutor(args.jobs) as pool:
            results = list(pool.map(run_one, *zip(*jobs, strict=True)))
    for run, result in zip(runs, results, strict=True):
        result["log"] = run[0]
    print("| log | CARMEN ATE (m), filter seeds | ROS 1 / sqlite3 / MCAP ATE (m), seed "
          f"{args.bag_seeds[0]} | MCAP, filter seeds | bags decode alike | EMMI: bag - log, same seed | "
          "EMMI: log seed - seed |")
    print("| --- | --- | --- | --- | --- | --- | --- |")
    for name in names:
        mine = [r for r in results if r["log"] == name]
        carmen = {r["seed"]: r for r in mine if r["source"] == "carmen"}
        seed = args.bag_seeds[0]
        bag_ates = " / ".join(f"{next(r for r in mine if r['source'] == s and r['seed'] == seed)['ate']:.3f}"
                              for s in STORAGES)
        mcap = {r["seed"]: r for r in mine if r["source"] == "mcap"}
        same_seed = max(_gap(mcap[s]["emmi"], carmen[s]["emmi"]) for s in mcap if s in carmen)
        seeds = sorted(carmen)
        between = max((_gap(carmen[a]["emmi"], carmen[b]["emmi"]) for a in seeds for b in seeds if a < b),
                      default=math.nan)
        log_ates = " / ".join(f"{carmen[s]['ate']:.3f}" for s in seeds)
        mcap_ates = " / ".join(f"{mcap[s]['ate']:.3f}" for s in sorted(mcap))
        print(f"| {name} | {log_ates} | {bag_ates} | {mcap_ates} | {'yes' if identical[name] else 'NO'} | "
              f"{same_seed:.4f} | {between:.4f} |")
    print("seconds per replay: " + ", ".join(f"{r['log']} {r['source']} {r['seed']}: {r['seconds']:.0f}"
                                             for r in results))
    (out / "results.json").write_text(json.dumps(results))


def _gap(a: list[float], b: list[float]) -> float:
    """The largest difference of two EMMI curves (bits/cell) over their common updates."""
    n = min(len(a), len(b))
    return float(np.max(np.abs(np.asarray(a[:n]) - np.asarray(b[:n])))) if n else math.nan


if __name__ == "__main__":
    main()
