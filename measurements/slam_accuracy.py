"""Accuracy of the RBPF round the loop_corridor loop, over seeds (the full version of tests/slam/test_slam.py).

    python measurements/slam_accuracy.py [--seeds 20] [--particles 15] [--slam '{"logodds_free": -0.7}']
        [--laser '{"preset": "sick_lms200", "max_range": 8.0}'] [--odometry poor]

The sensors default to the simulator's own (a 360-degree 8 m laser, typical odometry);
``--laser`` and ``--odometry`` take the environments' presets (``LoopCorridor-v1``
registers the SICK LMS200 at 8 m and poor odometry).

For each seed: record start -> decision -> start (74 m), run the filter, and report
the best particle's ATE (unaligned: the filter starts at the true start pose, as
dead reckoning does; and aligned), dead reckoning's ATE, the best map's accuracy
against the ground truth (raw and registered by the path's alignment), and whether
the loop closure shows in the metrics (EMMI higher 4 updates after the closure - the first
scan that sees again what the first leg saw, ``loop_closure_update`` - than just before;
Neff < 0.8 M or a resampling within 3 before to 7 after; EMMI's largest rise of the second
half of the loop, from the left corridor on, within 5 updates of it; the first scans raise
EMMI more than anything), and how many resamplings came before it.
"""

from __future__ import annotations

import argparse

import _arguments as arguments
import numpy as np
from _options import checked, preset_or_fields, rbpf_config

from emmi_gym.geometry.grid import GridGeometry
from emmi_gym.scoring.scores import absolute_trajectory_error, loop_closure_update, map_accuracy, trajectory_alignment
from emmi_gym.slam import RBPF
from emmi_gym.world import LaserConfig, OdometryNoise, Simulator, drive_route, load_world, rasterise
from emmi_gym.world.presets import laser_config, odometry_config


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    arguments.add_seed_range(parser, 20)
    parser.add_argument("--particles", type=arguments.integer(1), default=15)
    parser.add_argument("--slam", default="{}", help="RBPFConfig overrides as JSON")
    parser.add_argument("--laser", default=None, help="a laser preset name, or JSON fields with an optional preset")
    parser.add_argument("--odometry", default=None, help="an odometry preset name, or JSON fields")
    args = parser.parse_args()
    config = rbpf_config(parser, args.slam, particles=args.particles)
    world = load_world("loop_corridor")
    laser = (checked(parser, laser_config, preset_or_fields(parser, "--laser", args.laser), "", "--laser")
             if args.laser else LaserConfig())
    noise = (checked(parser, odometry_config, preset_or_fields(parser, "--odometry", args.odometry), "",
                     "--odometry") if args.odometry else OdometryNoise())
    sim = Simulator(world, laser=laser, odometry=noise)
    angles = sim.laser.config.angles
    geometry = GridGeometry.covering(*world.bounds, 0.1)
    truth_grid = rasterise(world, 0.1, geometry).grid
    route = world.route("to_decision") + world.route("close_loop")[1:]
    rows = []
    for seed in arguments.seed_range(args):
        rec = drive_route(sim, route, np.random.default_rng(seed))
        slam = RBPF(config, max_range=laser.max_range, geometry=geometry)
        slam.reset(rec.odometry_poses[0], np.random.default_rng(1000 + seed))
        metrics, steps = [], []
        for k, (pose, ranges) in enumerate(zip(rec.odometry_poses, rec.scans, strict=True)):
            m = slam.process(pose, ranges, angles)
            if m is not None:
                metrics.append(m)
                steps.append(k)
        truth, best, odometry = rec.true_poses[steps], slam.paths[slam.best], rec.odometry_poses[steps]
        xy = truth[:, :2]
        left = np.flatnonzero((xy[:, 0] < 2.0) & (xy[:, 1] < 12.0))[0]
        # the loop closes when a scan sees again what the bottom corridor's first leg saw
        first_leg = int(np.flatnonzero(xy[:, 1] > 2.0)[0])
        close = loop_closure_update(truth, [rec.scans[k] for k in steps], angles, laser.max_range, geometry,
                                    first_leg, left + 1)
        if close is None:
            raise SystemExit(f"seed {seed}: no scan after the left corridor saw the first leg again "
                             "(the loop never closed)")
        emmi = [m.emmi for m in metrics]
        window = metrics[max(close - 3, 0):close + 8]
        rows.append((
            absolute_trajectory_error(best, truth, align=False),
            absolute_trajectory_error(odometry, truth, align=False),
            absolute_trajectory_error(best, truth),
            map_accuracy(slam.best_map(), truth_grid),
            map_accuracy(slam.best_map(), truth_grid, geometry=geometry, transform=trajectory_alignment(best, truth)),
            emmi[min(close + 4, len(emmi) - 1)] > emmi[close - 1],
            any(m.resampled or m.neff < 0.8 * args.particles for m in window),
            sum(m.resampled for m in metrics[:max(close - 3, 0)]),
            abs(left + 1 + int(np.argmax(np.diff(emmi[left:]))) - close) <= 5))
        print(f"seed {seed:2d}: ATE {rows[-1][0]:.3f} m (dead reckoning {rows[-1][1]:.2f} m), "
              f"map accuracy {rows[-1][3]:.3f} (registered {rows[-1][4]:.3f}); "
              f"closure at update {close} of {len(steps)}, "
              f"{int(rows[-1][7])} resamplings before it", flush=True)
    r = np.array(rows, dtype=float)
    n = args.seeds
    print(f"\n{n} seeds, {args.particles} particles; laser {np.degrees(laser.fov):.0f} deg, {laser.n_beams} beams, "
          f"{laser.max_range:g} m; "
          f"odometry alphas {noise.alphas}, drift {noise.heading_drift:g} rad/m")
    print(f"ATE of the best path: median {np.median(r[:, 0]):.3f} m, max {r[:, 0].max():.3f} m (aligned: median "
          f"{np.median(r[:, 2]):.3f} m); dead reckoning median {np.median(r[:, 1]):.2f} m; "
          f"worst ratio best / dead reckoning {(r[:, 0] / r[:, 1]).max():.2f}")
    print(f"map accuracy: median {np.median(r[:, 3]):.3f} (min {r[:, 3].min():.3f}); registered median "
          f"{np.median(r[:, 4]):.3f} (min {r[:, 4].min():.3f}), >= 0.90 on {int(np.sum(r[:, 4] >= 0.9))} of {n}")
    print(f"loop closure: EMMI up on {int(r[:, 5].sum())} of {n}; "
          f"Neff drop or resampling on {int(r[:, 6].sum())} of {n}; "
          f"EMMI's largest rise (second half) within 5 updates of it on {int(r[:, 8].sum())} of {n}")
    print(f"resamplings before the closure: none on {int(np.sum(r[:, 7] == 0))} of {n} "
          f"(median {np.median(r[:, 7]):.0f})")


if __name__ == "__main__":
    main()
