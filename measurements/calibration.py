"""Whether the filter is as sure as it is right: the particles' belief against the truth at every update.

    python measurements/calibration.py env [--env-id emmi_gym/LoopOrder-v1] [--policy active_loop_closing]
        [--seeds 10] [--first-seed 1000000] [--options '{"world": "dungeon_maps/test"}'] [--slam '{...}']
        [--unweighted] [--workers 2] [--csv before.csv] [--label before]
    python measurements/calibration.py logs [--data ../shared/datasets/radish-noisy] [--logs intel aces]
        [--log-seeds 0 1 2] [--filter-seeds 0] [--preset radish-noisy] [--slam '{...}'] [--csv logs.csv]
    python measurements/calibration.py plot before.csv after.csv --out calibration.png
    python measurements/calibration.py honest [--particles 15 30 60] [--log-weight-sd 0 1 2] [--moments 4000]

``env`` plays episodes of a scripted policy and checks (``emmi_gym.tools.experiments.calibration``), at every
filter update, the weighted particle mean and covariance of the pose against the true pose, the motion over
the last 1, 10 and 50 updates against the true motion, and at every decision each revisit target's loop
spread against the true error of ``x_now - x_then``. ``logs`` replays the real logs (every keyframe an
update, as ``slam_benchmark.py``) and checks the relative motions against their reference trajectories. Each
prints, per family: the NEES in (x, y) (2 for an honest belief) and in (x, y, theta) (3), the share of
moments whose truth lies inside the 50, 90 and 95% ellipses, and the RMS spread against the RMS error (m).
``--csv`` keeps every moment's check; ``plot`` draws the calibration curves of such files (RMS error
against RMS predicted spread, moments binned by spread, the diagonal drawn). ``honest`` prints what a cloud
that is honest by construction scores with so many particles and weights so uneven
(:func:`emmi_gym.scoring.calibration.honest_cloud_summary`): the most a filter of that size can show.
"""

from __future__ import annotations

import argparse
import csv
import json
import math
from dataclasses import asdict
from functools import partial
from pathlib import Path

import _arguments as arguments
import numpy as np
from _data import require_files
from _options import json_object, rbpf_config

from emmi_gym.concurrency.parallel import run_in_processes
from emmi_gym.env.seeds import HELD_OUT_SEED
from emmi_gym.formats.carmen import read_log
from emmi_gym.scoring.calibration import PoseCheck, honest_cloud_summary
from emmi_gym.tools.experiments.calibration import (
    FAMILIES,
    CalibrationRecord,
    LogChecks,
    calibrate_env,
    spread_against_error,
    summary,
)
from emmi_gym.tools.experiments.replay import replay
from emmi_gym.tools.policies import POLICY_NAMES

LOGS = ("intel", "aces", "csail", "freiburg-079")


def env_job(job) -> CalibrationRecord:
    env_id, options, policy, seed, unweighted = job
    return calibrate_env(env_id, options, policy, [seed], unweighted)


def log_job(config, max_range: float, job) -> CalibrationRecord:
    path, filter_seed = job
    checks = LogChecks()
    result = replay(read_log(path, flaser_fov=math.pi), config, max_range=max_range, seed=filter_seed,
                    on_update=checks)
    return checks.record(result.true_poses)


def print_table(record: CalibrationRecord, title: str) -> None:
    print(title)
    print("| checks | moments | NEES x, y: mean | median | inside 50 / 90 / 95% | NEES x, y, theta: mean | inside 95% "
          "| RMS spread (m) | RMS error (m) | nearest particle (m) |")
    print("| --- | --- | --- | --- | --- | --- | --- | --- | --- | --- |")
    for family in FAMILIES:
        s = summary(record.checks[family])
        if not s["moments"]:
            continue
        print(f"| {family} | {s['moments']:.0f} | {s['xy_mean']:.2f} | {s['xy_median']:.2f} | "
              f"{s['xy_inside_50']:.0%} / {s['xy_inside_90']:.0%} / {s['xy_inside_95']:.0%} | {s['pose_mean']:.2f} | "
              f"{s['pose_inside_95']:.0%} | {s['rms_spread']:.3f} | {s['rms_error']:.3f} | {s['nearest']:.3f} |")


def write_checks(record: CalibrationRecord, path: Path, label: str) -> None:
    with open(path, "w", newline="") as f:
        writer = csv.DictWriter(f, fieldnames=["label", "family", *PoseCheck.__dataclass_fields__])
        writer.writeheader()
        for family, rows in record.checks.items():
            for check in rows:
                writer.writerow({"label": label, "family": family, **asdict(check)})


def read_checks(path: Path) -> tuple[str, CalibrationRecord]:
    record, label = CalibrationRecord(), path.stem
    with open(path, newline="") as f:
        for row in csv.DictReader(f):
            label = row["label"]
            record.checks[row["family"]].append(PoseCheck(*(float(row[k]) for k in PoseCheck.__dataclass_fields__)))
    return label, record


def plot(paths: list[Path], out: Path) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    runs = [read_checks(p) for p in paths]
    families = [f for f in FAMILIES if any(r.checks[f] for _, r in runs)]
    fig, axes = plt.subplots(1, len(families), figsize=(3.4 * len(families), 3.4), squeeze=False)
    for ax, family in zip(axes[0], families, strict=True):
        top = 0.0
        for label, record in runs:
            if record.checks[family]:
                spread, error, _ = spread_against_error(record.checks[family])
                ax.plot(spread, error, "o-", label=label, markersize=4)
                top = max(top, spread.max(), error.max())
        ax.plot([0, top], [0, top], "k--", linewidth=0.8, label="honest")
        ax.set(title=family, xlabel="predicted spread (RMS, m)", ylabel="actual error (RMS, m)")
        ax.legend(fontsize=7)
    fig.tight_layout()
    fig.savefig(out, dpi=110)
    print(f"wrote {out}")


def print_honest(particles: list[int], log_weight_sds: list[float], moments: int) -> None:
    print(f"honest clouds: truth and particles from one Gaussian, {moments} moments each")
    print("| particles | log-weight sd | median Neff | NEES x, y: mean | median | inside 50 / 90 / 95% |")
    print("| --- | --- | --- | --- | --- | --- |")
    for m in particles:
        for sd in log_weight_sds:
            s = honest_cloud_summary(m, sd, moments, np.random.default_rng(0))
            print(f"| {m} | {sd:g} | {s['neff']:.1f} | {s['mean']:.2f} | {s['median']:.2f} | "
                  f"{s['inside_50']:.0%} / {s['inside_90']:.0%} / {s['inside_95']:.0%} |")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    sub = parser.add_subparsers(dest="mode", required=True)
    env = sub.add_parser("env", help="episodes of an env under a scripted policy")
    env.add_argument("--env-id", default="emmi_gym/LoopOrder-v1")
    env.add_argument("--policy", default="active_loop_closing", choices=POLICY_NAMES)
    arguments.add_seed_range(env, 10, HELD_OUT_SEED)
    env.add_argument("--options", default="{}", help="env options as JSON")
    env.add_argument("--slam", default=None, help="RBPFConfig fields as JSON (merged into the options' slam)")
    env.add_argument("--unweighted", action="store_true",
                     help="check the particles with equal weights (a diagnosis: the weights or the cloud?)")
    logs = sub.add_parser("logs", help="the real logs against their reference trajectories")
    logs.add_argument("--data", default=str(Path(__file__).resolve().parents[2] / "shared/datasets/radish-noisy"))
    logs.add_argument("--logs", nargs="+", default=list(LOGS), choices=LOGS)
    logs.add_argument("--log-seeds", nargs="+", type=arguments.integer(0), default=[0])
    logs.add_argument("--filter-seeds", nargs="+", type=arguments.SEED, default=[0])
    logs.add_argument("--particles", type=arguments.integer(1), default=15)
    logs.add_argument("--resolution", type=arguments.number(0.0, unit="m"), default=0.05)
    logs.add_argument("--max-range", type=arguments.number(0.0, unit="m"), default=30.0)
    logs.add_argument("--preset", default="radish-noisy", help="RBPFConfig preset ('none': the defaults)")
    logs.add_argument("--slam", default="{}", help="further RBPFConfig fields as JSON")
    for p in (env, logs):
        p.add_argument("--workers", type=arguments.integer(1), default=None, help="processes (default: one per core)")
        p.add_argument("--csv", type=Path, default=None, help="write every moment's check here")
        p.add_argument("--label", default=None, help="the run's name in the CSV and the plot")
    drawing = sub.add_parser("plot", help="calibration curves of --csv files")
    drawing.add_argument("csvs", nargs="+", type=Path)
    drawing.add_argument("--out", type=Path, default=Path("calibration.png"))
    honest = sub.add_parser("honest", help="what honest clouds of a few particles score")
    honest.add_argument("--particles", nargs="+", type=arguments.integer(3), default=[15, 30, 60])
    honest.add_argument("--log-weight-sd", nargs="+", type=arguments.non_negative, default=[0.0, 1.0, 2.0])
    honest.add_argument("--moments", type=arguments.integer(1), default=4000)
    args = parser.parse_args()
    if args.mode == "honest":
        print_honest(args.particles, args.log_weight_sd, args.moments)
        return
    if args.mode == "plot":
        plot(args.csvs, args.out)
        return
    if args.mode == "env":
        options = json_object(parser, "--options", args.options)
        if args.slam is not None:
            options["slam"] = {**options.get("slam", {}), **json_object(parser, "--slam", args.slam)}
        jobs = [(args.env_id, options, args.policy, seed, args.unweighted) for seed in arguments.seed_range(args)]
        records = run_in_processes(env_job, jobs, workers=args.workers, desc="episodes")
        title = (f"{args.env_id} {json.dumps(options)}, {args.policy}, seeds {args.first_seed}-"
                 f"{args.first_seed + args.seeds - 1}{', unweighted' if args.unweighted else ''}")
    else:
        config = rbpf_config(parser, args.slam, None if args.preset == "none" else args.preset,
                             particles=args.particles, resolution=args.resolution, linear_update=0.0,
                             angular_update=0.0)
        data = Path(args.data)
        runs = [(data / f"{name}-seed{seed}.log.gz", f) for name in args.logs for seed in args.log_seeds
                for f in args.filter_seeds]
        require_files(parser, data, [p.name for p, _ in runs], "radish-noisy")
        records = run_in_processes(partial(log_job, config, args.max_range), runs, workers=args.workers, desc="logs")
        title = f"logs {args.logs} x odometry seeds {args.log_seeds} x filter seeds {args.filter_seeds}, {args.slam}"
    total = CalibrationRecord()
    for record in records:
        total.extend(record)
    print_table(total, title)
    if args.csv is not None:
        write_checks(total, args.csv, args.label or args.csv.stem)
        print(f"wrote {args.csv}")


if __name__ == "__main__":
    main()
