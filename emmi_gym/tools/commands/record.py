"""``emmi-gym record``: drive a world's named routes and write a CARMEN log (:mod:`emmi_gym.world`), the
world's map as a map_server map and the true path; a ROS 2 bag of the run if asked."""

from __future__ import annotations

import argparse

from . import arguments


def add_parser(subparsers) -> None:
    record = subparsers.add_parser("record", help="drive named routes through a world and write a CARMEN log")
    record.add_argument("world", help="built-in world name or a world .yaml file")
    record.add_argument("--route", nargs="+", default=["to_decision", "close_loop"],
                        help="route names of the world, driven one after the other (default: to_decision close_loop)")
    record.add_argument("--seed", type=arguments.SEED, default=0,
                        help="seed of the odometry and laser noise (default 0)")
    record.add_argument("--beams", type=arguments.integer(1), default=180,
                        help="laser beams per scan, over 360 degrees (default 180)")
    record.add_argument("--max-range", type=arguments.number(0.0, unit="m"), default=8.0,
                        help="the laser's maximum range in metres (default 8)")
    record.add_argument("--out", default="run.log",
                        help="the log file to write (default run.log); beside it <name>_map.yaml/.pgm (the world's "
                             "map, map_server) and <name>_path.csv (the true path)")
    record.add_argument("--map-resolution", type=arguments.number(0.0, unit="m"), default=0.05,
                        help="cell size of the map written, metres (default 0.05)")
    record.add_argument("--bag-out", default=None, metavar="FOLDER",
                        help="also write the run as a ROS 2 bag (sqlite3) in this new folder: /scan, /odom, /tf, "
                             "/tf_static, /truth ('ros' extra)")
    record.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    import numpy as np

    from ...formats.carmen import read_log
    from ...formats.map_server import write_map_server
    from ...formats.ros_writers import check_new_bag, write_log_bag
    from ...inputs.user_paths import check_outputs_apart, output_file
    from ...world import LaserConfig, Simulator, drive_route, load_world, write_carmen
    from ...world.ground_truth import FREE, OCCUPIED, rasterise
    from ...world.loader import world_files
    from ..experiments.map_outputs import write_path_csv

    out = output_file(args.out)
    if args.bag_out is not None:
        check_new_bag(args.bag_out)
    world = load_world(args.world)
    outputs = {"--out": out, "the map of --out": out.with_name(f"{out.stem}_map.yaml"),
               "the map image of --out": out.with_name(f"{out.stem}_map.pgm"),
               "the path of --out": out.with_name(f"{out.stem}_path.csv")}
    if args.bag_out is not None:
        outputs["--bag-out"] = args.bag_out
    check_outputs_apart(outputs, world_files(args.world))  # before the route is driven
    waypoints = []
    for name in args.route:
        route = world.route(name)
        waypoints.extend(route if not waypoints else route[1:])
    sim = Simulator(world, laser=LaserConfig(n_beams=args.beams, max_range=args.max_range))
    rec = drive_route(sim, waypoints, np.random.default_rng(args.seed))
    write_carmen(rec, sim, out)
    truth = rasterise(world, args.map_resolution)
    values = np.select([truth.grid == FREE, truth.grid == OCCUPIED], [0, 100], -1).astype(np.int8)
    files = [write_map_server(outputs["the map of --out"], values, truth.geometry),
             write_path_csv(outputs["the path of --out"], rec.times, rec.true_poses)]
    if args.bag_out is not None:
        files.append(write_log_bag(read_log(out), args.bag_out))
    drift = float(np.hypot(*(rec.true_poses[-1, :2] - rec.odometry_poses[-1, :2])))
    status = "reached the end of the route" if rec.reached else "stopped before the end of the route"
    print(f"wrote {args.out}: {len(rec.times)} scans over {rec.times[-1]:.1f} s in '{world.name}' ({status}); "
          f"dead reckoning ends {drift:.2f} m from the truth; {int(rec.collisions.sum())} collision steps")
    for path in files:
        print(f"wrote {path}")
    return 0 if rec.reached else 1
