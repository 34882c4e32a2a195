"""Following a list of waypoints with a differential-drive robot (turn towards, then drive)."""

from __future__ import annotations

import math

import numpy as np


class WaypointFollower:
    """Pure-pursuit style: steer towards the current waypoint, slow down while the heading error is large.

    ``command(pose)`` returns (v, omega); ``done`` turns true once the last waypoint
    is within ``tolerance`` metres.
    """

    def __init__(self, waypoints, max_speed: float, max_turn_rate: float, tolerance: float = 0.25,
                 heading_gain: float = 2.0):
        self.waypoints = [tuple(map(float, w)) for w in waypoints]
        if not self.waypoints:
            raise ValueError("WaypointFollower needs at least one waypoint")
        self.max_speed, self.max_turn_rate = max_speed, max_turn_rate
        self.tolerance, self.heading_gain = tolerance, heading_gain
        self.index = 0
        # the path's length from each waypoint to the last, so that the length left costs the same at every step
        legs = np.hypot(*np.diff(np.array(self.waypoints), axis=0).T) if len(self.waypoints) > 1 else np.zeros(0)
        self._length_after = np.concatenate([np.cumsum(legs[::-1])[::-1], [0.0]]).tolist()

    @property
    def done(self) -> bool:
        return self.index >= len(self.waypoints)

    @property
    def remaining(self) -> list[tuple[float, float]]:
        """The waypoints not reached yet."""
        return self.waypoints[self.index:]

    def remaining_length(self, pose) -> float:
        """Length (m) of the rest of the path from ``pose``: to the next waypoint, then along the others."""
        if self.done:
            return 0.0
        x, y = self.waypoints[self.index]
        return math.hypot(x - float(pose[0]), y - float(pose[1])) + self._length_after[self.index]

    def command(self, pose) -> tuple[float, float]:
        x, y, theta = pose
        while not self.done:
            tx, ty = self.waypoints[self.index]
            if math.hypot(tx - x, ty - y) > self.tolerance:
                break
            self.index += 1
        if self.done:
            return 0.0, 0.0
        error = (math.atan2(ty - y, tx - x) - theta + math.pi) % (2 * math.pi) - math.pi
        omega = min(self.max_turn_rate, max(-self.max_turn_rate, self.heading_gain * error))
        v = self.max_speed * max(0.0, math.cos(error)) ** 4
        return v, omega
