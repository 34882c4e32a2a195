"""Paths on the expected map: cost-distance with obstacle inflation (scikit-image's MCP)."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy import ndimage
from skimage.graph import MCP_Geometric

from ..grid import GridGeometry

OCCUPIED_P = 0.65   # expected-map probability above which a cell is surely an obstacle
BLOCKING_P = 0.55   # ... above which the planner keeps out: a wall blurred by disagreeing particles still blocks
FREE_P = 0.47       # ... below which it is known free (observed in the sense of eq. 10: |p - 0.5| > 0.0224)
UNKNOWN_COST = 2.0  # unknown cells may be crossed (optimistic planning), at twice the cost


@dataclass
class CostMap:
    """Travel costs from the robot over an expected map; ``cumulative`` is inf where unreachable."""

    geometry: GridGeometry
    cumulative: np.ndarray
    _mcp: MCP_Geometric

    def cost_to(self, x: float, y: float) -> float:
        row, col = self.geometry.cell_of(x, y)
        if not self.geometry.inside(row, col):
            return float("inf")
        return float(self.cumulative[row, col]) * self.geometry.resolution

    def path_to(self, x: float, y: float, spacing: float = 0.5) -> list[tuple[float, float]]:
        """Waypoints (x, y) every ``spacing`` metres along the cheapest path, ending at the target cell."""
        row, col = self.geometry.cell_of(x, y)
        cells = np.array(self._mcp.traceback((int(row), int(col))))
        xs, ys = self.geometry.centre_of(cells[:, 0], cells[:, 1])
        step = max(1, int(round(spacing / self.geometry.resolution)))
        keep = list(range(step, len(cells), step))
        if not keep or keep[-1] != len(cells) - 1:
            keep.append(len(cells) - 1)
        return [(float(xs[k]), float(ys[k])) for k in keep]


def travel_costs(expected_map: np.ndarray, geometry: GridGeometry, start_xy, robot_radius: float) -> CostMap:
    """Cost-distance from ``start_xy`` over the expected map.

    Obstacles (p > 0.55: more likely occupied than not, so a wall blurred by particles
    that disagree still blocks) are inflated: cells closer than the robot's radius plus 5 cm
    are impassable, and the cost rises within twice that distance, so paths keep to
    the middle of corridors. Known free cells cost 1 per metre, unknown ones 2 (they
    may be crossed: a loop-closing target behind a stretch not yet seen is reachable).
    The robot's own footprint is passable (at the inflated cost), so that a robot
    brushing a wall can still leave.
    """
    res = geometry.resolution
    obstacle = expected_map > BLOCKING_P
    clearance = ndimage.distance_transform_edt(~obstacle) * res
    costs = np.where(expected_map < FREE_P, 1.0, UNKNOWN_COST)
    keep_out = robot_radius + 0.05
    costs = costs + 4.0 * np.clip((2 * keep_out - clearance) / keep_out, 0.0, 1.0)
    x, y = geometry.cell_centres()
    footprint = np.hypot(x - start_xy[0], y - start_xy[1]) <= robot_radius + res
    costs[(clearance < keep_out) & ~(footprint & ~obstacle)] = np.inf
    row, col = geometry.cell_of(*start_xy)
    row, col = int(np.clip(row, 0, geometry.rows - 1)), int(np.clip(col, 0, geometry.cols - 1))
    costs[row, col] = max(float(costs[row, col]), 1.0) if np.isfinite(costs[row, col]) else 5.0
    mcp = MCP_Geometric(costs)
    cumulative, _ = mcp.find_costs([(row, col)])
    return CostMap(geometry, cumulative, mcp)
