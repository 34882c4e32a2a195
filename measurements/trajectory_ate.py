"""ATE of a trajectory file against a CARMEN log's TRUEPOS lines (matched by timestamp), e.g. GMapping's.

    python measurements/trajectory_ate.py LOG TRAJECTORY [--timing gfs_timing.txt]

TRAJECTORY: rows of ``timestamp x y theta`` (GMapping's ``best_traj.txt`` from the bench
patch of ``shared/anchors/gmapping``) or the TUM format ``timestamp x y z qx qy qz qw``
(what ``emmi-gym replay`` writes); ``#`` lines are comments. Prints the aligned ATE and,
with ``--timing``, the median and maximum of GMapping's per-update thread CPU time.
"""

from __future__ import annotations

import argparse

import numpy as np

from emmi_gym.formats.carmen import read_log
from emmi_gym.scoring.scores import absolute_trajectory_error
from emmi_gym.tools.experiments.replay import laser_stream, true_pose_at


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("log")
    parser.add_argument("trajectory")
    parser.add_argument("--timing", help="gfs_timing.txt of the GMapping bench patch")
    args = parser.parse_args()
    table = np.atleast_2d(np.loadtxt(args.trajectory, comments="#"))
    if table.shape[1] not in (4, 8):
        raise SystemExit(f"{args.trajectory}: expected 4 columns (t x y theta) or 8 (TUM), got {table.shape[1]}")
    log = read_log(args.log)
    truth_at = true_pose_at(log)
    if truth_at is None:
        raise SystemExit(f"{args.log}: no TRUEPOS lines")
    # one pose per scan (every keyframe an update): the k-th pose belongs to the k-th scan, whose
    # odometry settles ties of rounded timestamps; otherwise the first TRUEPOS of that time
    scans = [(position, pose) for position, pose, _ in laser_stream(log)]
    in_order = len(scans) == len(table)
    pairs = [(row[1:3], truth_at(row[0], *(scans[k][::-1] if in_order else ((np.inf, np.inf), 0))))
             for k, row in enumerate(table)]
    pairs = [(estimate, truth) for estimate, truth in pairs if truth is not None]
    if not pairs:
        raise SystemExit(f"{args.trajectory}: no pose has a TRUEPOS within 0.05 s")
    estimate = np.array([e for e, _ in pairs])
    truth = np.array([t[:2] for _, t in pairs])
    print(f"poses {len(pairs)} of {len(table)}; ATE (aligned) {absolute_trajectory_error(estimate, truth):.3f} m")
    if args.timing:
        timing = np.loadtxt(args.timing, comments="#")
        cpu = timing[:, -1] if timing.ndim == 2 else timing
        print(f"updates {cpu.size}; CPU ms per update median {np.median(cpu):.1f}, max {np.max(cpu):.1f}")


if __name__ == "__main__":
    main()
