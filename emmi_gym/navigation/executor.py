"""Macro-actions: plan to a target on the robot's own map, follow the path, replan, guard every command.

The executor knows nothing of Gymnasium: it drives a :class:`Robot`, whatever provides the
estimated pose, the live scan, the expected map and one control step (the env; a test double).
Planning is as a ROS navigation stack's: a global plan on the expected map plus the scan's
obstacle layer, replanned when the map learnt on the way blocks it (move_base), an
oscillation timeout, and a safety layer on the live scan before every command (a small
dynamic window).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Protocol

import numpy as np

from ..geometry.grid import GridGeometry
from . import safety
from .candidates import Target, candidate_slots
from .follower import WaypointFollower
from .planner import BLOCKING_P, KEEP_OUT_MARGIN, RECOVERY_BLOCKING_P, CostMap, path_obstructed, travel_costs

#: Consecutive steps driving into a wall, or held back by the safety layer, after which a
#: macro-action replans (with the scan's obstacles), and after which it counts as blocked.
REPLAN_STALLED_STEPS = 5
BLOCKED_STEPS = 15
#: Steps (30 s) in which the path left to a target must shrink by PROGRESS_M, else the target
#: counts as blocked: replanning round a passage that the scan shows shut only when near can
#: swing between two routes for ever (move_base's oscillation timeout).
NO_PROGRESS_STEPS = 300
PROGRESS_M = 0.5
#: Scan echoes closer than this (m) are obstacles for planning, with this occupancy probability.
SCAN_LAYER_RANGE = 3.0
SCAN_LAYER_P = 0.9


class Robot(Protocol):
    """What the executor drives."""

    filter_step: int           # changes whenever the filter updated (the map may have changed)

    def pose_estimate(self) -> np.ndarray: ...
    def scan(self) -> np.ndarray: ...
    def expected_map(self) -> np.ndarray: ...  # may be read-only: the executor copies what it changes
    def step(self, v: float, omega: float) -> bool: ...  # one control step; True if it collided
    def out_of_time(self) -> bool: ...


@dataclass(frozen=True)
class Limits:
    """The robot's and its laser's: radius (m), speed (m/s), turn rate (rad/s), beam angles, range."""

    radius: float
    max_speed: float
    max_turn_rate: float
    beam_angles: np.ndarray
    max_range: float


class MacroActionExecutor:
    """Targets to choose from, and going to one of them (:meth:`follow`)."""

    def __init__(self, geometry: GridGeometry, limits: Limits, timeout_steps: int):
        self.geometry, self.limits, self.timeout_steps = geometry, limits, timeout_steps
        self.blocking_p = BLOCKING_P
        self.costs: CostMap | None = None

    def targets(self, robot: Robot, expected: np.ndarray, best_path: np.ndarray, n_frontiers: int, n_revisits: int,
                blocked, keep_revisit=None) -> list[Target | None]:
        """The action slots, planned on ``expected`` plus the scan's obstacle layer (a wall the particles
        blur but the laser sees hides no frontier behind it), without targets near the ``blocked`` points
        where earlier attempts ended, and without the revisit targets ``keep_revisit`` (if given) turns
        down (:func:`~emmi_gym.navigation.candidates.candidate_slots`). Recoveries when no target is
        left, as move_base clears its costmap when stuck: again with only cells of p >
        ``RECOVERY_BLOCKING_P`` as obstacles (a ghost wall of particles that disagree can shut the
        robot in a slot of its map), then both again with the blocked points forgotten (the one
        frontier left can lie by a point where an attempt ended blocked before the map showed the
        way; without it the robot would stand still to the end of the episode)."""
        pose = robot.pose_estimate()
        planning_map = with_scan_layer(expected.copy(), self.scan_layer(robot, pose))
        for avoided in (blocked, ()):
            for self.blocking_p in (BLOCKING_P, RECOVERY_BLOCKING_P):
                self.costs = travel_costs(planning_map, self.geometry, pose[:2], self.limits.radius,
                                          blocking_p=self.blocking_p)
                slots = candidate_slots(planning_map, best_path, self.costs, n_frontiers, n_revisits, avoided,
                                        keep_revisit)
                if any(slot is not None for slot in slots):
                    return slots
            if not blocked:
                break
        return slots

    def follow(self, robot: Robot, target: Target) -> str:
        """Follow the planned path to ``target`` with the estimated pose.

        After every filter update the rest of the path, as far ahead as the laser reaches, is
        checked against the new expected map and replanned if a wall now lies on it; every
        command passes the safety layer on the live scan first. Returns "stayed" if not a
        single step was taken, "blocked" if for ``BLOCKED_STEPS`` steps it drove into a wall
        or the safety layer would not let it drive on, the target became unreachable, or the
        path left to it did not shrink by ``PROGRESS_M`` in ``NO_PROGRESS_STEPS`` steps,
        else "moved".
        """
        follower = self._follower(self.costs.path_to(target.x, target.y))
        planned_at = robot.filter_step
        colliding = taken = since_progress = 0
        shortest = math.inf
        for _ in range(self.timeout_steps):
            pose = robot.pose_estimate()
            if robot.filter_step != planned_at or colliding == REPLAN_STALLED_STEPS:
                planned_at = robot.filter_step
                follower = self._replanned(robot, follower, pose, target)
                if follower is None:
                    return "blocked"
            left = follower.remaining_length(pose)
            if left < shortest - PROGRESS_M:
                shortest, since_progress = left, 0
            elif since_progress >= NO_PROGRESS_STEPS:
                return "blocked"
            since_progress += 1
            v, omega = follower.command(pose)
            if follower.done or robot.out_of_time():
                break
            safe_v, safe_omega = self.guarded(robot, v, omega)
            collided = robot.step(safe_v, safe_omega)
            taken += 1
            stalled = collided or (v > 0.0 and safe_v <= 0.0)
            colliding = colliding + 1 if stalled else 0
            if colliding >= BLOCKED_STEPS:
                return "blocked"
        return "moved" if taken else "stayed"

    def guarded(self, robot: Robot, v: float, omega: float) -> tuple[float, float]:
        """(v, omega) made safe against the live scan (:mod:`emmi_gym.navigation.safety`)."""
        lim = self.limits
        points = safety.scan_points(robot.scan(), lim.beam_angles, lim.max_range,
                                    within=lim.max_speed * safety.HORIZON + 1.0)
        return safety.safe_command(v, omega, points, lim.radius, lim.max_speed, lim.max_turn_rate)

    def scan_layer(self, robot: Robot, pose) -> tuple[np.ndarray, np.ndarray]:
        """The cells (rows, columns) of the live scan's echoes within ``SCAN_LAYER_RANGE`` at ``pose``: a
        costmap's obstacle layer, laid over the map with :func:`with_scan_layer`."""
        points = safety.scan_points(robot.scan(), self.limits.beam_angles, self.limits.max_range, SCAN_LAYER_RANGE)
        cos, sin = np.cos(pose[2]), np.sin(pose[2])
        rows, cols = self.geometry.cell_of(pose[0] + cos * points[:, 0] - sin * points[:, 1],
                                           pose[1] + sin * points[:, 0] + cos * points[:, 1])
        inside = self.geometry.inside(rows, cols)
        return rows[inside], cols[inside]

    def _follower(self, waypoints) -> WaypointFollower:
        return WaypointFollower(waypoints, self.limits.max_speed, self.limits.max_turn_rate, tolerance=0.3)

    def _replanned(self, robot: Robot, follower: WaypointFollower, pose, target: Target) -> WaypointFollower | None:
        """``follower`` if the rest of its path is still clear, else one on a new path to ``target`` (None
        if it cannot be reached any more), on the expected map plus the scan's obstacle layer."""
        expected, layer = robot.expected_map(), self.scan_layer(robot, pose)  # the map read, not copied
        radius = self.limits.radius
        if not path_obstructed(expected, self.geometry, [tuple(pose[:2])] + follower.remaining, radius,
                               skip=radius + KEEP_OUT_MARGIN, horizon=self.limits.max_range,
                               blocking_p=self.blocking_p, layer=(*layer, SCAN_LAYER_P)):
            return follower
        costs = travel_costs(with_scan_layer(expected.copy(), layer), self.geometry, pose[:2], radius,
                             goal_xy=(target.x, target.y), blocking_p=self.blocking_p)
        if not np.isfinite(costs.cost_to(target.x, target.y)):
            return None
        return self._follower(costs.path_to(target.x, target.y))


def with_scan_layer(expected: np.ndarray, layer: tuple[np.ndarray, np.ndarray]) -> np.ndarray:
    """``expected`` (changed in place) with the cells of ``layer`` (rows, columns; see
    :meth:`MacroActionExecutor.scan_layer`) at least ``SCAN_LAYER_P``: the obstacle layer over the map."""
    rows, cols = layer
    expected[rows, cols] = np.maximum(expected[rows, cols], SCAN_LAYER_P)
    return expected
