"""Drive a scripted route through a world and record it, optionally as a CARMEN log."""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ..formats import carmen
from ..navigation.follower import WaypointFollower
from .simulator import Simulator


@dataclass
class Recording:
    """Per control step: time, true pose, odometry pose, (v, omega) commanded, laser ranges, collisions."""

    times: np.ndarray
    true_poses: np.ndarray
    odometry_poses: np.ndarray
    commands: np.ndarray
    scans: np.ndarray
    collisions: np.ndarray
    reached: bool


def drive_route(sim: Simulator, waypoints, rng: np.random.Generator, *, max_steps: int = 20000,
                tolerance: float = 0.25) -> Recording:
    """Reset ``sim`` at the world's start with ``rng`` and follow ``waypoints`` using the *true* pose.

    One scan is taken at the start and one after every control period. Stops when the
    last waypoint is reached or after ``max_steps``.
    """
    sim.reset(rng)
    cfg = sim.robot_config
    follower = WaypointFollower(waypoints, cfg.max_speed, cfg.max_turn_rate, tolerance)
    times, true_poses, odom_poses, commands, scans, collisions = [0.0], [sim.true_pose], \
        [sim.odometry_pose.copy()], [(0.0, 0.0)], [sim.scan()], [False]
    for _ in range(max_steps):
        v, omega = follower.command(sim.true_pose)
        if follower.done:
            break
        result = sim.step(v, omega)
        times.append(sim.time)
        true_poses.append(result.true_pose)
        odom_poses.append(result.odometry_pose)
        commands.append((v, omega))
        scans.append(sim.scan())
        collisions.append(result.collided)
    return Recording(np.array(times), np.array(true_poses), np.array(odom_poses), np.array(commands),
                     np.array(scans), np.array(collisions), follower.done)


def write_carmen(recording: Recording, sim: Simulator, path) -> Path:
    """Write a recording as a CARMEN log: per step ODOM, TRUEPOS and ROBOTLASER1 lines."""
    path = Path(path)
    laser = sim.laser.config
    angles = laser.angles
    with path.open("w") as fh:
        fh.write(f"# emmi-gym recording of world '{sim.world.name}', control period "
                 f"{sim.robot_config.control_period} s\n")
        for t, true_pose, odom, (v, omega), ranges in zip(recording.times, recording.true_poses,
                                                          recording.odometry_poses, recording.commands,
                                                          recording.scans, strict=False):
            carmen.write_odometry(fh, odom, v, omega, t)
            carmen.write_truepos(fh, true_pose, odom, t)
            carmen.write_robotlaser(fh, ranges, angles[0], laser.fov, laser.angular_resolution, laser.max_range,
                                    odom, t, range_accuracy=laser.range_sigma)
    return path
