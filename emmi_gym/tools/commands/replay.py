"""``emmi-gym replay``: the RBPF and every certainty metric on a CARMEN log or a ROS bag
(:mod:`emmi_gym.tools.experiments.replay`, :mod:`emmi_gym.formats.ros_bags`)."""

from __future__ import annotations

import argparse
import sys

from . import arguments


def add_parser(subparsers) -> None:
    rep = subparsers.add_parser("replay", help="run the RBPF and the certainty metrics on a CARMEN log or a ROS bag")
    rep.add_argument("log", help="CARMEN log, plain or .gz (ODOM, FLASER, RAWLASER1, ROBOTLASER1, TRUEPOS lines), "
                                 "or a ROS bag: ROS 1 .bag, ROS 2 folder, .db3 or .mcap (needs the 'ros' extra)")
    rep.add_argument("--particles", type=arguments.integer(1), default=15, help="particles of the filter (default 15)")
    rep.add_argument("--resolution", type=arguments.number(0.0, unit="m"), default=0.1,
                     help="cell size in metres (default 0.1)")
    rep.add_argument("--max-range", type=arguments.number(0.0, unit="m"), default=None,
                     help="laser range limit, metres (default: from the log or the scans' range_max; FLASER logs "
                          "need it)")
    rep.add_argument("--seed", type=arguments.SEED, default=0, help="seed of the filter's sampling (default 0)")
    rep.add_argument("--skip-bad-lines", action="store_true", help="skip and count malformed lines")
    rep.add_argument("--every-scan", action="store_true",
                     help="make every scan an update (logs of keyframes; default: after 0.5 m or 0.3 rad)")
    rep.add_argument("--flaser-fov", type=arguments.number(0.0, 360.0, "degrees"), default=180.0,
                     help="field of view of FLASER lines in degrees (default 180)")
    rep.add_argument("--preset", default=None,
                     help="RBPF settings for a known kind of log (radish-noisy: the classic CARMEN logs with "
                          "shared/datasets' odometry noise); default: the simulator's")
    rep.add_argument("--insertion-range", type=arguments.number(0.0, unit="m"), default=None,
                     help="echoes beyond this only free cells up to it (default: the sensor's range)")
    rep.add_argument("--matching-range", type=arguments.number(0.0, unit="m"), default=None,
                     help="beams beyond this are left out of matching and weights (default: the sensor's range)")
    bag = rep.add_argument_group("ROS bags")
    bag.add_argument("--scan", default=None, metavar="TOPIC",
                     help="the sensor_msgs/LaserScan topic (default: the bag's only one)")
    bag.add_argument("--odom", default=None, metavar="TOPIC",
                     help="a nav_msgs/Odometry topic (default: /tf's --odom-frame -> --base-frame transforms)")
    bag.add_argument("--odom-frame", default="odom", help="odometry frame of /tf (default odom)")
    bag.add_argument("--base-frame", default="base_link", help="robot frame of /tf (default base_link)")
    bag.add_argument("--truth", default=None, metavar="TOPIC",
                     help="ground-truth poses (Odometry, PoseStamped or PoseWithCovarianceStamped), for the ATE")
    rep.add_argument("--out", default="replay_out",
                     help="folder for metrics.csv, the PNGs, map.yaml/.pgm, expected_information.yaml/.pgm and "
                          "best_path.csv (default replay_out)")
    rep.add_argument("--overwrite", action="store_true",
                     help="write into an --out folder that is not empty, replacing an earlier replay's files there "
                          "(without it such a folder is refused)")
    rep.add_argument("--bag-out", default=None, metavar="FOLDER",
                     help="also write /map, /expected_information (OccupancyGrid) and /path (Path) as a ROS 2 bag "
                          "(sqlite3) in this new folder")
    arguments.add_quiet(rep)
    rep.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    import math

    import numpy as np

    from ...formats.carmen import read_log
    from ...formats.ros_bags import BagTopics, is_bag, read_bag
    from ...formats.ros_writers import check_new_bag
    from ...inputs.user_paths import output_folder
    from ...slam import RBPFConfig
    from ..experiments.map_outputs import REPLAY_FILES, write_map_files, write_replay_bag
    from ..experiments.replay import replay, tum_problem, tum_warning, write_outputs
    from ..training.run_folders import RunFolder

    folder = RunFolder(args.out, REPLAY_FILES)  # the rule of train and clone: a folder in use is refused
    folder.check_new(args.overwrite, resumable=False, inputs={"the log": args.log})
    output_folder(args.out)  # before the run, which would otherwise be lost at its end
    if args.bag_out is not None:
        check_new_bag(args.bag_out)
    options = dict(particles=args.particles, resolution=args.resolution, insertion_range=args.insertion_range,
                   matching_range=args.matching_range)
    config = RBPFConfig(**options) if args.preset is None else RBPFConfig.preset(args.preset, **options)
    topics = BagTopics(args.scan, args.odom, args.odom_frame, args.base_frame, args.truth)
    if is_bag(args.log):
        log = read_bag(args.log, topics, progress=not args.quiet)
    else:
        given = [f"--{name.replace('_', '-')}" for name, value in vars(topics).items()
                 if value != getattr(BagTopics(), name)]
        if given:
            raise ValueError(f"{' '.join(given)}: options of ROS bags, and {args.log} is not one (a .bag, .db3 or "
                             ".mcap file, or a ROS 2 bag's folder)")
        log = read_log(args.log, skip_bad_lines=args.skip_bad_lines, flaser_fov=math.radians(args.flaser_fov),
                       progress=not args.quiet)
    for sentence in log.timing + log.warnings:  # now, not after a run of minutes
        print(f"{args.log}: warning: {sentence}", file=sys.stderr)
    try:
        result = replay(log, config, max_range=args.max_range, seed=args.seed, progress=not args.quiet,
                        every_scan=args.every_scan)
    except ValueError as exc:  # what the log lacks (lasers, odometry, a maximum range) or asks (maps too large)
        raise ValueError(f"{args.log}: {exc}") from None
    if not result.rows:
        raise ValueError(f"{args.log}: no scan could be used (none had odometry)")
    if args.overwrite:  # once the log is read and replayed
        folder.clear()
    files = write_outputs(result, args.out) | write_map_files(result, args.out)
    if args.bag_out is not None:
        files["bag"] = write_replay_bag(result, args.bag_out)
    last = result.rows[-1]
    print(f"{args.log}: {result.scans_used} scans, {len(result.rows)} RBPF updates "
          f"({args.particles} particles, {args.resolution} m cells)")
    for sentence in log.report():
        print(sentence)
    if tum_problem(result) is not None:
        print(f"no best_trajectory.tum: {tum_problem(result)}")
    elif tum_warning(result) is not None:
        print(f"best_trajectory.tum: {tum_warning(result)}")
    if result.scans_without_odometry:
        print(f"skipped {result.scans_without_odometry} scans without odometry at their time")
    times = [r.update_ms for r in result.rows[1:]] or [last.update_ms]
    print(f"median update {np.median(times):.2f} ms; final EMMI {last.emmi:.3f} bits/cell, "
          f"pose entropy {last.pose_entropy:.2f} nats, Neff {last.neff:.1f}, "
          f"{sum(r.resampled for r in result.rows)} resamplings")
    ate = result.ate()
    if ate is not None:
        print(f"ATE of the best particle against {args.truth or 'TRUEPOS'}: {ate:.3f} m "
              f"(dead reckoning {result.dead_reckoning_ate():.3f} m)")
    for path in files.values():
        print(f"wrote {path}")
    return 0

