"""A world as data: walls (thick segments), bounds, start pose, named places and routes."""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from ..inputs.errors import FieldError

#: Radius of the simulated robot's round body, metres (a small indoor platform).
ROBOT_RADIUS = 0.2


class WorldFileError(FieldError):
    """A world file (or dict) is malformed; says which file, which field, what was expected."""


@dataclass(frozen=True)
class Place:
    """A named pose in the world; ``theta`` is None where the file gives no heading."""

    x: float
    y: float
    theta: float | None = None

    @property
    def xy(self) -> tuple[float, float]:
        return (self.x, self.y)


@dataclass(frozen=True)
class WorldSpec:
    """Everything the simulator and the ground truth need to know about a world.

    ``walls`` is a (K, 5) float64 array of thick segments ``ax, ay, bx, by, thickness``
    (polylines and rectangles of the file are expanded into segments). ``routes`` map
    a name to a list of (x, y) waypoints (place names resolved).
    """

    name: str
    bounds: tuple[float, float, float, float]  # xmin, ymin, xmax, ymax
    walls: np.ndarray
    start: Place
    places: dict[str, Place] = field(default_factory=dict)
    routes: dict[str, list[tuple[float, float]]] = field(default_factory=dict)
    description: str = ""
    source: str = "<dict>"

    @property
    def start_pose(self) -> np.ndarray:
        return np.array([self.start.x, self.start.y, self.start.theta or 0.0])

    def place(self, name: str) -> Place:
        if name not in self.places:
            raise KeyError(f"world '{self.name}' has no place '{name}'; it has {sorted(self.places)}")
        return self.places[name]

    def route(self, name: str) -> list[tuple[float, float]]:
        if name not in self.routes:
            raise KeyError(f"world '{self.name}' has no route '{name}'; it has {sorted(self.routes)}")
        return self.routes[name]

    def clearance(self, x: float, y: float) -> float:
        """Distance from (x, y) to the nearest wall surface (negative inside a wall)."""
        return float(np.min(point_segment_distance(np.array([x]), np.array([y]), self.walls)[0]
                            - self.walls[:, 4] / 2))


def point_segment_distance(px: np.ndarray, py: np.ndarray, walls: np.ndarray) -> np.ndarray:
    """Distances (P, K) from points (P,) to the centre lines of walls (K, 5)."""
    ax, ay, bx, by = (walls[:, i][None, :] for i in range(4))
    px, py = np.asarray(px, dtype=np.float64)[:, None], np.asarray(py, dtype=np.float64)[:, None]
    dx, dy = bx - ax, by - ay
    length2 = np.maximum(dx * dx + dy * dy, 1e-300)
    t = np.clip(((px - ax) * dx + (py - ay) * dy) / length2, 0.0, 1.0)
    return np.hypot(px - (ax + t * dx), py - (ay + t * dy))
