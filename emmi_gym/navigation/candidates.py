"""Where to go next: frontier targets (explore) and revisit targets that would close a loop.

Slots are deterministic: the first ``n_frontiers`` hold frontier targets, nearest
(by travel cost) first; the next ``n_revisits`` hold revisit targets, strongest loop
first. Empty slots are masked.
"""

from __future__ import annotations

from dataclasses import dataclass
from itertools import islice

import numpy as np
from scipy import ndimage

from ..certainty import DEFAULT_OBSERVED_TOL, observed_cells
from .planner import FREE_P, CostMap

MIN_FRONTIER_CELLS = 4        # frontiers shorter than this (cells) are noise
MIN_TRAVEL = 1.0              # m: a frontier target nearer than this (straight line) is where the robot already is
LOOP_MIN_PATH = 12.0          # m of path between a past pose and the robot for a revisit to close a loop
LOOP_RATIO = 1.5              # ... and at least this ratio of path length to the route there (metres)
REVISIT_SPACING = 3.0         # m between two revisit targets
BLOCKED_RADIUS = 1.0          # m round a target whose attempt ended blocked: no target there any more


@dataclass(frozen=True)
class Target:
    """A candidate goal (x, y) in the map frame, of kind 'frontier' or 'revisit'."""

    kind: str
    x: float
    y: float
    travel_cost: float
    gain: float  # frontier: its length in cells; revisit: path length closed / length of the route there
    path_index: int | None = None  # revisit: the update index of the estimated path it revisits

    @property
    def xy(self) -> tuple[float, float]:
        return (self.x, self.y)


def frontier_targets(expected_map: np.ndarray, costs: CostMap,
                     observed_tol: float = DEFAULT_OBSERVED_TOL) -> list[Target]:
    """Clusters of known-free cells next to open unknown space, each represented by its cell nearest its centroid.

    Unknown means not observed in the sense of eq. (10) (:func:`~emmi_gym.certainty.observed_cells`,
    ``observed_tol`` in nats). Unknown cells within two cells of an observed cell that leans
    occupied (p > 0.5) do not count: they are the never-seen inside of a wall, not
    unexplored space. Leaning, not surely occupied: a wall seen only at glancing angles
    is a broken line of cells just above 0.5, mixed with free ones where beams passed in
    front of it, and the unknown behind it gave rows of frontiers that vanished as the
    robot drove near (seen on the real buildings, where they ended many macro-actions blocked).
    """
    geometry, window = costs.geometry, costs.window
    expected_map = expected_map[window]  # frontiers next to unknown space lie well inside the planning window
    free = expected_map < FREE_P
    observed = observed_cells(expected_map, observed_tol)
    near_obstacle = ndimage.binary_dilation(observed & (expected_map > 0.5), iterations=2)
    unknown = ~observed & ~near_obstacle
    frontier = free & ndimage.binary_dilation(unknown, structure=ndimage.generate_binary_structure(2, 1))
    labels, n = ndimage.label(frontier, structure=np.ones((3, 3)))
    targets = []
    for index, cluster in enumerate(ndimage.find_objects(labels), start=1):
        rows, cols = np.nonzero(labels[cluster] == index)
        if rows.size < MIN_FRONTIER_CELLS:
            continue
        rows, cols = rows + cluster[0].start + window[0].start, cols + cluster[1].start + window[1].start
        cell_costs = costs.costs_at(rows, cols)
        away = np.hypot(rows - costs.start[0], cols - costs.start[1]) * geometry.resolution
        eligible = (away >= MIN_TRAVEL) & np.isfinite(cell_costs)
        if not eligible.any():
            continue
        # the eligible cell nearest the centroid (a frontier through the robot, as behind a 180-degree
        # scanner at the start, has its centroid where the robot already is)
        distance2 = (rows - rows.mean()) ** 2 + (cols - cols.mean()) ** 2
        k = int(np.argmin(np.where(eligible, distance2, np.inf)))
        x, y = geometry.centre_of(rows[k], cols[k])
        targets.append(Target("frontier", float(x), float(y), float(cell_costs[k]), float(rows.size)))
    targets.sort(key=lambda t: (t.travel_cost, t.x, t.y))
    return targets


def revisit_targets(path: np.ndarray, costs: CostMap) -> list[Target]:
    """Past poses of the estimated path that would close a loop if revisited.

    A pose qualifies when at least ``LOOP_MIN_PATH`` metres of path lie between it and
    the robot, the planned route there is at most 1/``LOOP_RATIO`` of that long, and the
    recent path (those last metres) never came within ``REVISIT_SPACING`` of it: an area
    just revisited closes nothing more. The route is measured in metres, not in the
    planner's cost, which doubles across unknown cells: a route that closes a loop
    through a stretch not yet seen would otherwise count as twice its length.
    """
    if len(path) < 2:
        return []
    steps = np.hypot(*np.diff(path[:, :2], axis=0).T)
    along = np.concatenate([[0.0], np.cumsum(steps)])
    behind = along[-1] - along  # path length from each past pose to the robot
    recent = path[behind < LOOP_MIN_PATH, :2]
    older = np.flatnonzero(behind >= LOOP_MIN_PATH)
    nearest = np.hypot(path[older, None, 0] - recent[None, :, 0], path[older, None, 1] - recent[None, :, 1]).min(
        axis=1, initial=np.inf)
    older = older[nearest >= REVISIT_SPACING]
    travel = costs.costs_at(*costs.geometry.cell_of(path[older, 0], path[older, 1]))
    reachable = (MIN_TRAVEL <= travel) & (travel < np.inf)
    older, travel = older[reachable], travel[reachable]
    lengths = costs.route_lengths(path[older, :2])
    candidates = [Target("revisit", float(path[k, 0]), float(path[k, 1]), float(cost), behind[k] / max(length, 0.5),
                      int(k))
                  for k, cost, length in zip(older, travel, lengths, strict=False) if behind[k] >= LOOP_RATIO * length]
    candidates.sort(key=lambda t: (-t.gain, t.travel_cost))
    chosen: list[Target] = []
    for t in candidates:
        if all(np.hypot(t.x - c.x, t.y - c.y) >= REVISIT_SPACING for c in chosen):
            chosen.append(t)
    return chosen


def candidate_slots(expected_map: np.ndarray, path: np.ndarray, costs: CostMap, n_frontiers: int,
                    n_revisits: int, blocked=(), keep_revisit=None) -> list[Target | None]:
    """The action slots: frontiers then revisits, None where a slot is empty.

    Targets within ``BLOCKED_RADIUS`` of a ``blocked`` point (where an earlier attempt
    ended against a wall) are left out, so the robot is not sent into the same wall again;
    so are revisit targets for which ``keep_revisit`` (if given) is false.
    """
    def open_(t: Target) -> bool:
        return all(np.hypot(t.x - bx, t.y - by) > BLOCKED_RADIUS for bx, by in blocked)

    frontiers = [t for t in frontier_targets(expected_map, costs) if open_(t)][:n_frontiers]
    revisits = list(islice((t for t in revisit_targets(path, costs)
                            if open_(t) and (keep_revisit is None or keep_revisit(t))), n_revisits))
    return (frontiers + [None] * (n_frontiers - len(frontiers))
            + revisits + [None] * (n_revisits - len(revisits)))
