"""Numba kernels of the planner: the cost grid of a window of the expected map, the search over it, and
the check of the path ahead.

The search is Dijkstra's algorithm on the 8-connected grid with a bucket queue (Dial 1969: costs in
whole units, a ring of buckets, constant time per step), with scikit-image ``MCP_Geometric``'s step
costs: a step between neighbours a and b costs ``(c_a + c_b) / 2`` times its length (1 or sqrt 2
cells), and a cell of infinite cost is never entered. Given a goal it is A* (Hart, Nilsson and
Raphael 1968) with the octile distance as heuristic, admissible and consistent because no cell costs
less than 1 per cell crossed, and it stops when the goal is settled: a replan costs the part of the
map between the robot and its target, not the whole window. Each kernel has a plain-Python twin in
``tests/navigation/test_search.py``.
"""

from __future__ import annotations

import math

import numba as nb
import numpy as np

from ..geometry.clipping import clip_segment

#: The eight steps (d_row, d_col); ``traceback`` holds, for each cell, the index of the step that reached it.
OFFSETS = np.array([[-1, -1], [-1, 0], [-1, 1], [0, -1], [0, 1], [1, -1], [1, 0], [1, 1]], dtype=np.int64)
_SQRT2 = math.sqrt(2.0)


@nb.njit(cache=True)
def clearance(expected, obstacle_p, limit):
    """Cells from each cell's centre to the nearest obstacle's (p > ``obstacle_p``), exact up to ``limit``
    cells (farther cells read ``limit``): each obstacle cell beside a free one marks the cells within
    ``limit`` round it (a cell's nearest obstacle is always such a one), so the cost follows the
    walls' length, not the window's area (scipy's ``distance_transform_edt`` within the limit)."""
    h, w = expected.shape
    reach = int(math.ceil(limit))
    d2 = np.full((h, w), limit * limit)
    for r in range(h):
        for c in range(w):
            if not expected[r, c] > obstacle_p:
                continue
            edge = False
            for dr, dc in ((-1, 0), (1, 0), (0, -1), (0, 1)):
                rr, cc = r + dr, c + dc
                if 0 <= rr < h and 0 <= cc < w and not expected[rr, cc] > obstacle_p:
                    edge = True
            d2[r, c] = 0.0
            if not edge:
                continue
            for rr in range(max(r - reach, 0), min(r + reach + 1, h)):
                for cc in range(max(c - reach, 0), min(c + reach + 1, w)):
                    dist2 = float((rr - r) ** 2 + (cc - c) ** 2)
                    if dist2 < d2[rr, cc]:
                        d2[rr, cc] = dist2
    return np.sqrt(d2)


@nb.njit(cache=True)
def cell_costs(expected, resolution, free_p, unknown_cost, keep_out, soft, clearance_cost, start_gx, start_gy,
               start_row, start_col, footprint, obstacle_p):
    """The cost per cell of crossing each cell of ``expected`` (a window of the expected map, (H, W), cells
    of ``resolution`` metres): 1 if known free (p < ``free_p``), else ``unknown_cost``, plus
    ``clearance_cost * ((soft - clearance) / (soft - keep_out))^2`` within ``soft`` metres of an obstacle
    (p > ``obstacle_p``, :func:`clearance`); infinite closer than ``keep_out``, except in the robot's
    footprint (the cells whose centres lie within ``footprint`` cells of the robot at grid coordinates
    (``start_gx``, ``start_gy``) and that are not obstacles), so a robot brushing a wall can leave. The
    start cell (``start_row``, ``start_col``) costs at least 1 (5 if it would be infinite)."""
    h, w = expected.shape
    gaps = clearance(expected, obstacle_p, soft / resolution) * resolution
    costs = np.empty((h, w))
    reach = int(math.ceil(footprint)) + 1
    for r in range(h):
        for c in range(w):
            cost = 1.0 if expected[r, c] < free_p else unknown_cost
            gap = gaps[r, c]
            if gap < soft:
                fraction = min(1.0, (soft - gap) / (soft - keep_out))
                cost += clearance_cost * fraction * fraction
            if gap < keep_out:
                near = abs(r - start_row) <= reach and abs(c - start_col) <= reach and \
                    (c + 0.5 - start_gx) ** 2 + (r + 0.5 - start_gy) ** 2 <= footprint * footprint
                if not (near and expected[r, c] <= obstacle_p):
                    cost = np.inf
            costs[r, c] = cost
    start = costs[start_row, start_col]
    costs[start_row, start_col] = max(start, 1.0) if start < np.inf else 5.0
    return costs


#: The search's unit of cost: 1 / COST_QUANTUM of a cell crossed at cost 1 (so a path's cost is exact within
#: half a unit per step: a bucket queue, Dial's algorithm, orders the cells in constant time per step).
COST_QUANTUM = 32


@nb.njit(cache=True, inline="always")
def _unlink(cell, bucket, head, after, before):
    if before[cell] >= 0:
        after[before[cell]] = after[cell]
    else:
        head[bucket] = after[cell]
    if after[cell] >= 0:
        before[after[cell]] = before[cell]


@nb.njit(cache=True, inline="always")
def _link(cell, bucket, head, after, before):
    after[cell] = head[bucket]
    before[cell] = -1
    if head[bucket] >= 0:
        before[head[bucket]] = cell
    head[bucket] = cell


@nb.njit(cache=True, inline="always")
def _heuristic(row, col, goal_row, goal_col):
    """A*'s estimate of the cost left, in units: the octile distance to the goal (no cell costs less than 1)."""
    dr, dc = abs(row - goal_row), abs(col - goal_col)
    return int((max(dr, dc) + (_SQRT2 - 1.0) * min(dr, dc)) * COST_QUANTUM)


@nb.njit(cache=True)
def cost_distance(costs, start_row, start_col, goal_row, goal_col):
    """Cheapest cumulative cost (in cells) from the start to every cell of ``costs`` (H, W), inf where
    unreachable, and the traceback (the index into :data:`OFFSETS` of the step that reached each cell; -1
    at the start and at cells not reached). With ``goal_row >= 0``: A* towards the goal, stopping once it
    is settled; the cells not settled by then read inf (their costs are not final).

    Costs add up in whole units of 1 / :data:`COST_QUANTUM` (each step's cost rounded), so the cells
    wait in a ring of buckets, one per unit (Dial's algorithm), each a doubly linked list of cells."""
    h, w = costs.shape
    n = h * w
    flat_costs = costs.reshape(n)
    finite = flat_costs[np.isfinite(flat_costs)]
    largest_step = int(math.ceil(_SQRT2 * (finite.max() if finite.size else 1.0) * COST_QUANTUM)) + 1
    ring = 1
    while ring <= 2 * largest_step + 2:  # the keys queued span at most two steps (one more with A*)
        ring *= 2
    mask = ring - 1
    distance = np.full(n, np.iinfo(np.int64).max)
    traceback = np.full(n, -1, dtype=np.int8)
    key_of = np.empty(n, dtype=np.int64)
    state = np.zeros(n, dtype=np.int8)  # 0 never queued, 1 queued, 2 settled
    head = np.full(ring, -1, dtype=np.int64)
    after = np.empty(n, dtype=np.int64)
    before = np.empty(n, dtype=np.int64)
    step_units = np.empty(8)
    for k in range(8):
        step_units[k] = (_SQRT2 if OFFSETS[k, 0] != 0 and OFFSETS[k, 1] != 0 else 1.0) * COST_QUANTUM
    goal = goal_row * w + goal_col if goal_row >= 0 else -1
    start = start_row * w + start_col
    distance[start] = 0
    current = _heuristic(start_row, start_col, goal_row, goal_col) if goal >= 0 else 0
    key_of[start] = current
    state[start] = 1
    _link(start, current & mask, head, after, before)
    queued = 1
    while queued > 0:
        while head[current & mask] < 0:
            current += 1
        cell = head[current & mask]
        _unlink(cell, current & mask, head, after, before)
        queued -= 1
        state[cell] = 2
        if cell == goal:
            break
        row, col = cell // w, cell % w
        here = distance[cell]
        half = 0.5 * flat_costs[cell]
        for k in range(8):
            r, c = row + OFFSETS[k, 0], col + OFFSETS[k, 1]
            if r < 0 or r >= h or c < 0 or c >= w:
                continue
            other = r * w + c
            if state[other] == 2 or flat_costs[other] == np.inf:
                continue
            candidate = here + int(round((half + 0.5 * flat_costs[other]) * step_units[k]))
            if candidate < distance[other]:
                distance[other] = candidate
                traceback[other] = k
                key = candidate
                if goal >= 0:
                    # the heuristic's rounding may undercut the bucket being emptied by a unit
                    key = max(key + _heuristic(r, c, goal_row, goal_col), current)
                if state[other] == 1:
                    _unlink(other, key_of[other] & mask, head, after, before)
                else:
                    state[other] = 1
                    queued += 1
                key_of[other] = key
                _link(other, key & mask, head, after, before)
    cumulative = np.full(n, np.inf)
    for cell in range(n):
        if state[cell] == 2:
            cumulative[cell] = distance[cell] / COST_QUANTUM
        elif state[cell] == 1:  # still queued when A* stopped: not final
            traceback[cell] = -1
    return cumulative.reshape(h, w), traceback.reshape(h, w)


@nb.njit(cache=True)
def path_blocked(expected, origin_x, origin_y, resolution, points, skip, horizon, keep_out, blocking_p, layer_cells):
    """Whether a cell of ``expected`` above ``blocking_p`` (or listed in ``layer_cells``, sorted flat indices)
    has its centre closer than ``keep_out`` metres to a point sampled every half cell along the polyline
    ``points`` (n, 2), from ``skip`` to ``skip + horizon`` metres along it (the planner's
    ``path_obstructed``). Cells outside the grid hold nothing: each segment is sampled only over the part
    of it that passes within ``keep_out`` plus a cell of the grid (Liang and Barsky's clipping), so the
    work is bounded by the grid, whatever the path's length."""
    h, w = expected.shape
    step = resolution / 2.0
    reach = int(math.ceil(keep_out / resolution))
    limit2 = keep_out * keep_out
    margin = keep_out + resolution
    lo_x, hi_x = origin_x - margin, origin_x + w * resolution + margin
    lo_y, hi_y = origin_y - margin, origin_y + h * resolution + margin
    end = skip + horizon
    along = 0.0
    for k in range(points.shape[0] - 1):
        ax, ay = points[k, 0], points[k, 1]
        dx, dy = points[k + 1, 0] - ax, points[k + 1, 1] - ay
        length = math.hypot(dx, dy)
        start_s, stop_s = max(along, skip), min(along + length, end)
        along += length
        if length == 0.0 or start_s >= stop_s:
            continue
        t0, t1 = (start_s - (along - length)) / length, (stop_s - (along - length)) / length
        t0, t1 = clip_segment(ax, ay, dx, dy, t0, t1, lo_x, hi_x, lo_y, hi_y)
        if t0 > t1:
            continue
        segment_start = along - length
        first = int(math.ceil((segment_start + t0 * length - skip) / step))
        last = int(math.floor((segment_start + t1 * length - skip) / step))
        for j in range(max(first, 0), last + 1):
            s = skip + j * step
            if s >= stop_s:
                break
            t = (s - segment_start) / length
            x, y = ax + t * dx, ay + t * dy
            gx, gy = (x - origin_x) / resolution, (y - origin_y) / resolution
            col, row = int(math.floor(gx)), int(math.floor(gy))
            for r in range(max(row - reach, 0), min(row + reach + 1, h)):
                for c in range(max(col - reach, 0), min(col + reach + 1, w)):
                    if ((c + 0.5 - gx) ** 2 + (r + 0.5 - gy) ** 2) * resolution * resolution >= limit2:
                        continue
                    if expected[r, c] > blocking_p:
                        return True
                    if layer_cells.size:
                        i = np.searchsorted(layer_cells, r * w + c)
                        if i < layer_cells.size and layer_cells[i] == r * w + c:
                            return True
    return False
