"""A reactive safety layer on the live laser scan (the local planner of a navigation stack).

The global path is planned on the expected map, which lags behind what the robot sees
and may be shifted by the filter's pose error; a robot following it blindly brushes
walls at corners. Before each command the robot checks it against the current scan, as
the dynamic-window approach does (Fox, Burgard and Thrun 1997): among a small set of
commands near the desired one, it takes the closest whose 1 s arc keeps the robot's
radius plus a margin from every scan point.
"""

from __future__ import annotations

import math

import numba as nb
import numpy as np

HORIZON = 1.0        # s of motion checked ahead
SUBSTEPS = 5         # poses checked along each arc
MARGIN = 0.05        # m kept between the robot's body and any scan point
SPEED_SCALES = np.array([1.0, 0.6, 0.3, 0.0])
TURN_OFFSETS = np.array([0.0, -0.5, 0.5, -1.0, 1.0, -1.5, 1.5])  # rad/s added to the desired turn rate
BACK_UP = -0.3       # fraction of the top speed for backing away when nothing forward is safe


def scan_points(ranges: np.ndarray, angles: np.ndarray, max_range: float, within: float) -> np.ndarray:
    """(P, 2) scan end points in the robot frame (x forward) that are echoes closer than ``within`` metres."""
    keep = (ranges < max_range) & (ranges < within)
    r, a = ranges[keep], angles[keep]
    return np.column_stack([r * np.cos(a), r * np.sin(a)])


_ARC_TIMES = np.linspace(HORIZON / SUBSTEPS, HORIZON, SUBSTEPS)


def safe_command(v: float, omega: float, points: np.ndarray, radius: float, max_speed: float,
                 max_turn_rate: float) -> tuple[float, float]:
    """The command nearest (v, omega) whose arc keeps ``radius + MARGIN`` from every point of ``points``.

    Nearest by DWA-style cost: the change of turn rate (as a fraction of the limit) plus
    the fraction of speed given up. Turning on the spot is always safe for the round
    robot; when it already touches something it backs away instead, if that opens a gap. When
    the robot should drive on but no arc forward is clear, it turns away from the nearest point
    (:func:`_turn_away`).
    """
    clearance = radius + MARGIN
    if points.size == 0:
        return v, omega
    now = float(np.min(np.hypot(points[:, 0], points[:, 1])))
    if (now > abs(v) * HORIZON + clearance
            or _closest_approach(np.array([v]), np.array([omega]), points)[0] >= clearance):
        return v, omega  # the desired command is safe (and costs nothing): the usual case
    scales = np.repeat(SPEED_SCALES, TURN_OFFSETS.size)
    speeds = v * scales
    turns = np.clip(omega + np.tile(TURN_OFFSETS, SPEED_SCALES.size), -max_turn_rate, max_turn_rate)
    lowest = _closest_approach(speeds, turns, points)
    ok = (lowest >= clearance) | ((speeds == 0.0) & (now >= clearance))
    if ok.any():
        cost = np.abs(turns - omega) / max_turn_rate + (1.0 - scales)
        k = int(np.argmin(np.where(ok, cost, np.inf)))
        if speeds[k] != 0.0 or v <= 0.0:
            return float(speeds[k]), float(turns[k])
    elif _closest_approach(np.array([BACK_UP * max_speed]), np.array([omega]), points)[0] > now:
        return BACK_UP * max_speed, omega
    return 0.0, _turn_away(points, max_turn_rate) if v > 0.0 else omega


def _turn_away(points: np.ndarray, max_turn_rate: float) -> float:
    """The turn rate that rotates the robot in place away from the nearest point (safe for a round robot).

    When no arc forward is clear, standing still with the desired turn rate (the cheapest
    command by the cost above) is a deadlock: the path follower asks for the same command
    at every step, as by a door jamb just inside the margin at the robot's front corner.
    Turning away brings a clear arc into reach, and the robot slides past the obstacle
    (the escape rotation of a navigation stack's local planner).
    """
    nearest = points[np.argmin(np.hypot(points[:, 0], points[:, 1]))]
    return -max_turn_rate if nearest[1] > 0.0 else max_turn_rate


def _closest_approach(speeds: np.ndarray, turns: np.ndarray, points: np.ndarray) -> np.ndarray:
    """For each command, the smallest distance from the robot's centre to any point along its arc."""
    return _closest_approach_kernel(np.asarray(speeds, dtype=np.float64), np.asarray(turns, dtype=np.float64),
                                    np.ascontiguousarray(points, dtype=np.float64), _ARC_TIMES)


@nb.njit(cache=True)
def _closest_approach_kernel(speeds, turns, points, times):
    """:func:`_closest_approach` over the poses at ``times`` along each arc (in the robot frame, after driving
    (v, omega) for t: (v / omega sin(omega t), v / omega (1 - cos(omega t))), or (v t, 0) when not turning)."""
    lowest = np.full(speeds.size, np.inf)
    for k in range(speeds.size):
        v, omega = speeds[k], turns[k]
        turning = abs(omega) > 1e-6
        for t in times:
            x = v / omega * math.sin(omega * t) if turning else v * t
            y = v / omega * (1.0 - math.cos(omega * t)) if turning else 0.0
            for p in range(points.shape[0]):
                gap = math.hypot(x - points[p, 0], y - points[p, 1])
                if gap < lowest[k]:
                    lowest[k] = gap
    return lowest
