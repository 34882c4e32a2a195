"""Paths on the expected map: cost-distance with obstacle inflation (Dijkstra's search, A* to a goal), and the
check that tells the robot to replan when the map it learns on the way blocks its path."""

from __future__ import annotations

import math
from dataclasses import dataclass

import numba as nb
import numpy as np

from ..certainty import observed_cells
from ..geometry.grid import GridGeometry
from . import _search

OCCUPIED_P = 0.65   # expected-map probability above which a cell is surely an obstacle
BLOCKING_P = 0.55   # ... above which the planner keeps out: a wall blurred by disagreeing particles still blocks
# ... above which it keeps out when nothing can be reached at BLOCKING_P (a recovery, as move_base
# clears its costmap): a ghost wall of particles that disagree can shut the robot in a slot of
# its own map; walls that most particles agree on, and the scan's obstacle layer, still block
RECOVERY_BLOCKING_P = 0.8
FREE_P = 0.47       # ... below which it is known free (observed in the sense of eq. 10: |p - 0.5| > 0.0224)
UNKNOWN_COST = 2.0  # unknown cells may be crossed (optimistic planning), at twice the cost
PREFERRED_CLEARANCE = 0.8  # m from an obstacle beyond which a cell costs no extra
CLEARANCE_COST = 8.0       # extra cost per cell at the impassable limit
KEEP_OUT_MARGIN = 0.05     # m beyond the robot's radius that a path must keep from obstacles
PLANNING_MARGIN = 2.0      # m of unknown round the observed area within which paths are planned


@dataclass
class CostMap:
    """Travel costs from the robot over an expected map, within a window of it.

    ``geometry`` is the whole map's; the costs were computed over the window of cells whose
    (row, col) is ``corner`` plus the window's own indices: ``cumulative`` (inf where
    unreachable), and the search's ``traceback`` and ``offsets`` (for each cell, the index
    of the step that reached it; -1 at the start), kept as plain arrays so the env can be
    pickled. ``start`` is the whole map's (row, col) the costs are measured
    from. Cells outside the window are unreachable."""

    geometry: GridGeometry
    cumulative: np.ndarray
    traceback: np.ndarray
    offsets: np.ndarray
    start: tuple[int, int]
    corner: tuple[int, int] = (0, 0)

    @property
    def window(self) -> tuple[slice, slice]:
        """The window, as slices of the whole map's arrays."""
        (r0, c0), (rows, cols) = self.corner, self.cumulative.shape
        return slice(r0, r0 + rows), slice(c0, c0 + cols)

    def costs_at(self, rows, cols) -> np.ndarray:
        """Travel cost in metres to the whole map's cells (rows, cols); inf where unreachable."""
        r, c = np.asarray(rows) - self.corner[0], np.asarray(cols) - self.corner[1]
        inside = (r >= 0) & (r < self.cumulative.shape[0]) & (c >= 0) & (c < self.cumulative.shape[1])
        costs = np.full(np.shape(r), np.inf)
        costs[inside] = self.cumulative[r[inside], c[inside]] * self.geometry.resolution
        return costs

    def cost_to(self, x: float, y: float) -> float:
        return float(self.costs_at(*self.geometry.cell_of(x, y)))

    def path_to(self, x: float, y: float, spacing: float = 0.5) -> list[tuple[float, float]]:
        """Waypoints (x, y) every ``spacing`` metres along the cheapest path, ending at the target cell."""
        cells = np.array(self._cells_to(*_clipped_cell(self.geometry, (x, y))))
        xs, ys = self.geometry.centre_of(cells[:, 0], cells[:, 1])
        step = max(1, int(round(spacing / self.geometry.resolution)))
        keep = list(range(step, len(cells), step))
        if not keep or keep[-1] != len(cells) - 1:
            keep.append(len(cells) - 1)
        return [(float(xs[k]), float(ys[k])) for k in keep]

    def route_lengths(self, xy: np.ndarray) -> np.ndarray:
        """Length in metres of the cheapest route to each point (n, 2); inf where unreachable.

        The cost weighs unknown cells and closeness to walls; this is the distance driven,
        summed along the traceback (:func:`_traceback_lengths`).
        """
        xy = np.asarray(xy, dtype=np.float64).reshape(-1, 2)
        rows, cols = self.geometry.cell_of(xy[:, 0], xy[:, 1])
        lengths = np.full(len(xy), np.inf)
        reachable = np.flatnonzero(np.isfinite(self.costs_at(rows, cols)))
        step_lengths = np.hypot(*self.offsets.T.astype(np.float64)) * self.geometry.resolution
        lengths[reachable] = _traceback_lengths(self.traceback, self.offsets, step_lengths,
                                                rows[reachable] - self.corner[0], cols[reachable] - self.corner[1])
        return lengths

    def _cells_to(self, row: int, col: int) -> list[tuple[int, int]]:
        """The whole map's cells from the start to (row, col), walking the traceback back."""
        if not np.isfinite(self.costs_at(row, col)):
            raise ValueError(f"no path to cell ({row}, {col}): it is unreachable")
        r0, c0 = self.corner
        row, col = row - r0, col - c0  # the walk runs in the window's indices
        cells = [(row, col)]
        while (step := self.traceback[row, col]) >= 0:
            row, col = row - int(self.offsets[step, 0]), col - int(self.offsets[step, 1])
            cells.append((row, col))
        return [(r + r0, c + c0) for r, c in reversed(cells)]


@nb.njit(cache=True)
def _traceback_lengths(traceback, offsets, step_lengths, rows, cols):
    """For each cell (rows[k], cols[k]) of a window, the summed ``step_lengths`` of the search's steps that lead
    back from it to the start (``traceback``: the index into ``offsets`` of the step that reached each
    cell, -1 at the start)."""
    lengths = np.zeros(rows.size)
    for k in range(rows.size):
        r, c = rows[k], cols[k]
        step = traceback[r, c]
        while step >= 0:
            lengths[k] += step_lengths[step]
            r -= offsets[step, 0]
            c -= offsets[step, 1]
            step = traceback[r, c]
    return lengths


def travel_costs(expected_map: np.ndarray, geometry: GridGeometry, start_xy, robot_radius: float,
                 goal_xy=None, blocking_p: float = BLOCKING_P) -> CostMap:
    """Cost-distance from ``start_xy`` over the expected map (to every cell, or until ``goal_xy`` is reached).

    Obstacles (p > 0.55: more likely occupied than not, so a wall blurred by particles
    that disagree still blocks) are inflated as by a ROS costmap's inflation layer: cells
    closer than the robot's radius plus 5 cm are impassable, and the cost rises from 0 at
    ``PREFERRED_CLEARANCE`` to ``CLEARANCE_COST`` at that limit, so paths keep to the middle
    of corridors and round corners wide (the pose estimate may be decimetres off while the
    filter is uncertain). Known free cells cost 1 per metre, unknown ones 2 (they
    may be crossed: a loop-closing target behind a stretch not yet seen is reachable).
    The robot's own footprint is passable (at the inflated cost), so that a robot
    brushing a wall can still leave (:func:`~emmi_gym.navigation._search.cell_costs`).

    The costs are computed within :func:`planning_window` only (what the robot has observed,
    plus ``PLANNING_MARGIN`` of unknown round it), so that planning costs what has been
    explored, not the whole map's extent; with a goal, the search is A* and stops at the goal
    (:func:`~emmi_gym.navigation._search.cost_distance`), so only the costs of the cells it
    settled on the way are known (the others read inf).
    """
    res = geometry.resolution
    start = _clipped_cell(geometry, start_xy)
    goal = None if goal_xy is None else _clipped_cell(geometry, goal_xy)
    window = planning_window(expected_map, geometry, [start] + ([goal] if goal else []))
    corner = (window[0].start, window[1].start)
    expected_map = np.ascontiguousarray(expected_map[window])
    keep_out = robot_radius + KEEP_OUT_MARGIN
    row, col = start[0] - corner[0], start[1] - corner[1]
    start_gx = (start_xy[0] - geometry.origin_x) / res - corner[1]
    start_gy = (start_xy[1] - geometry.origin_y) / res - corner[0]
    costs = _search.cell_costs(expected_map, res, FREE_P, UNKNOWN_COST, keep_out,
                               max(PREFERRED_CLEARANCE, 2 * keep_out), CLEARANCE_COST, float(start_gx),
                               float(start_gy), row, col, (robot_radius + res) / res, blocking_p)
    goal_row, goal_col = (-1, -1) if goal is None else (goal[0] - corner[0], goal[1] - corner[1])
    cumulative, traceback = _search.cost_distance(costs, row, col, goal_row, goal_col)
    return CostMap(geometry, cumulative, traceback, _search.OFFSETS, start, corner)


def planning_window(expected_map: np.ndarray, geometry: GridGeometry, cells) -> tuple[slice, slice]:
    """The part of the map worth planning over: the bounding box of the observed cells (eq. 10's
    sense) and of ``cells`` (the start, a goal), grown by ``PLANNING_MARGIN`` metres of unknown.
    Obstacles are observed, so every obstacle lies inside it; a path could leave it only to
    cross more than that much space never seen, which no target asks for."""
    observed = observed_cells(expected_map)
    rows, cols = np.flatnonzero(observed.any(axis=1)), np.flatnonzero(observed.any(axis=0))
    rows = np.concatenate([rows[[0, -1]] if rows.size else [], [r for r, _ in cells]])
    cols = np.concatenate([cols[[0, -1]] if cols.size else [], [c for _, c in cells]])
    margin = int(math.ceil(PLANNING_MARGIN / geometry.resolution))
    return (slice(max(0, int(rows.min()) - margin), min(geometry.rows, int(rows.max()) + margin + 1)),
            slice(max(0, int(cols.min()) - margin), min(geometry.cols, int(cols.max()) + margin + 1)))


def _clipped_cell(geometry: GridGeometry, xy) -> tuple[int, int]:
    row, col = geometry.cell_of(*xy)
    return int(np.clip(row, 0, geometry.rows - 1)), int(np.clip(col, 0, geometry.cols - 1))


def path_obstructed(expected_map: np.ndarray, geometry: GridGeometry, polyline, robot_radius: float,
                    skip: float = 0.0, horizon: float = math.inf, blocking_p: float = BLOCKING_P,
                    layer=None) -> bool:
    """Whether an obstacle (p > ``blocking_p``) now lies closer than the planner's keep-out distance
    to the polyline of (x, y) points, between ``skip`` metres along it (where the robot is) and
    ``skip + horizon`` (what the sensor can have changed, as a local costmap's window).
    ``layer`` (rows, columns, p): cells read as at least p, as if laid over the map (the scan's
    obstacle layer), without copying the map to lay them.

    The path is sampled every half cell (:func:`~emmi_gym.navigation._search.path_blocked`), only
    where it passes within the keep-out distance of the map: outside its extent the map holds
    nothing, so the cost is bounded by the map's size, however far the path runs (a wildly wrong
    pose estimate can make it kilometres), and no memory grows with it."""
    points = np.ascontiguousarray(polyline, dtype=np.float64).reshape(-1, 2)
    if len(points) < 2:
        return False
    keep_out = robot_radius + KEEP_OUT_MARGIN
    blocks = layer is not None and layer[2] > blocking_p
    layer_cells = np.zeros(0, dtype=np.int64)
    if blocks:
        layer_cells = np.unique(np.asarray(layer[0], dtype=np.int64) * geometry.cols + np.asarray(layer[1]))
    return _search.path_blocked(np.ascontiguousarray(expected_map), geometry.origin_x, geometry.origin_y,
                                geometry.resolution, points, float(skip), float(min(horizon, 1e300)), keep_out,
                                blocking_p, layer_cells)
