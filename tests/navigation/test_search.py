"""The planner's kernels (emmi_gym.navigation._search) against plain-Python twins."""

from __future__ import annotations

import heapq
import math
import tracemalloc

import numpy as np
import pytest
from scipy import ndimage

from emmi_gym.geometry.grid import GridGeometry
from emmi_gym.navigation import _search
from emmi_gym.navigation.planner import path_obstructed, travel_costs


def dijkstra_twin(costs: np.ndarray, start: tuple[int, int]) -> np.ndarray:
    """Exact cost-distance with MCP_Geometric's step costs ((c_a + c_b) / 2 times the step's length)."""
    h, w = costs.shape
    best = np.full((h, w), np.inf)
    best[start] = 0.0
    queue = [(0.0, start)]
    while queue:
        d, (r, c) = heapq.heappop(queue)
        if d > best[r, c]:
            continue
        for dr, dc in _search.OFFSETS:
            rr, cc = r + dr, c + dc
            if 0 <= rr < h and 0 <= cc < w and np.isfinite(costs[rr, cc]):
                candidate = d + (costs[r, c] + costs[rr, cc]) / 2 * math.hypot(dr, dc)
                if candidate < best[rr, cc]:
                    best[rr, cc] = candidate
                    heapq.heappush(queue, (candidate, (rr, cc)))
    return best


def random_costs(rng, shape, walls=0.2, top=10.0):
    costs = rng.uniform(1.0, top, shape)
    costs[rng.random(shape) < walls] = np.inf
    return costs


@pytest.mark.parametrize("seed", range(12))
def test_cost_distance_is_dijkstra_within_the_cost_unit(seed):
    rng = np.random.default_rng(seed)
    costs = random_costs(rng, tuple(rng.integers(3, 40, 2)))
    start = tuple(int(v) for v in rng.integers(0, costs.shape))
    costs[start] = 1.0
    exact = dijkstra_twin(costs, start)
    cumulative, traceback = _search.cost_distance(costs, *start, -1, -1)
    assert np.array_equal(np.isfinite(cumulative), np.isfinite(exact))
    reached = np.isfinite(exact)
    # each step's cost is rounded to the nearest 1 / COST_QUANTUM and costs at least 1, so a path of cost C has
    # at most C steps and is off by at most C / (2 COST_QUANTUM); the bound checked is twice that
    assert np.all(np.abs(cumulative[reached] - exact[reached]) <= exact[reached] / _search.COST_QUANTUM + 1e-9)
    # the traceback leads back to the start from every reached cell, along steps whose costs add up
    for row, col in zip(*np.nonzero(reached), strict=True):
        total, r, c = 0.0, row, col
        while traceback[r, c] >= 0:
            dr, dc = _search.OFFSETS[traceback[r, c]]
            total += (costs[r, c] + costs[r - dr, c - dc]) / 2 * math.hypot(dr, dc)
            r, c = r - dr, c - dc
        assert (r, c) == start
        assert total == pytest.approx(exact[row, col], rel=1 / _search.COST_QUANTUM, abs=1e-9)


@pytest.mark.parametrize("seed", range(12))
def test_a_star_to_a_goal_finds_the_same_cost_and_settles_less(seed):
    rng = np.random.default_rng(100 + seed)
    costs = random_costs(rng, (40, 50), walls=0.15, top=3.0)
    start, goal = (2, 3), (35, 44)
    costs[start] = costs[goal] = 1.0
    full, _ = _search.cost_distance(costs, *start, -1, -1)
    to_goal, traceback = _search.cost_distance(costs, *start, *goal)
    if not np.isfinite(full[goal]):
        assert not np.isfinite(to_goal[goal])
        return
    assert to_goal[goal] == pytest.approx(full[goal], abs=2 / _search.COST_QUANTUM)
    assert np.count_nonzero(np.isfinite(to_goal)) < np.count_nonzero(np.isfinite(full))
    settled = np.isfinite(to_goal)
    assert np.all(traceback[~settled] == -1)


@pytest.mark.parametrize("seed", range(8))
def test_clearance_is_the_euclidean_distance_transform_up_to_its_limit(seed):
    rng = np.random.default_rng(seed)
    expected = ndimage.uniform_filter(rng.uniform(0.0, 1.0, tuple(rng.integers(4, 60, 2))), 3)
    limit = 6.5
    obstacle = expected > 0.55
    mine = _search.clearance(expected, 0.55, limit)
    if not obstacle.any():
        assert np.all(mine == limit)
        return
    exact = ndimage.distance_transform_edt(~obstacle)
    assert np.allclose(mine, np.minimum(exact, limit))


def path_obstructed_twin(expected, geometry, points, radius, skip=0.0, horizon=math.inf, blocking_p=0.55):
    """Every half cell along the polyline: any cell above ``blocking_p`` whose centre is within the keep-out
    distance of the point (cells outside the grid hold nothing)."""
    points = np.asarray(points, dtype=float)
    along = np.concatenate([[0.0], np.cumsum(np.hypot(*np.diff(points, axis=0).T))])
    keep_out = radius + 0.05
    res = geometry.resolution
    for s in np.arange(skip, min(along[-1], skip + horizon), res / 2):
        x, y = np.interp(s, along, points[:, 0]), np.interp(s, along, points[:, 1])
        for r in range(geometry.rows):
            for c in range(geometry.cols):
                cx, cy = geometry.origin_x + (c + 0.5) * res, geometry.origin_y + (r + 0.5) * res
                if math.hypot(cx - x, cy - y) < keep_out and expected[r, c] > blocking_p:
                    return True
    return False


@pytest.mark.parametrize("seed", range(10))
def test_path_obstructed_matches_its_twin(seed):
    rng = np.random.default_rng(seed)
    geometry = GridGeometry(0.1, -1.0, 2.0, 30, 40)
    expected = np.full(geometry.shape, 0.3)
    expected[rng.integers(0, 30, 4), rng.integers(0, 40, 4)] = 0.9
    xmin, xmax, ymin, ymax = geometry.extent
    points = np.column_stack([rng.uniform(xmin - 1, xmax + 1, 4), rng.uniform(ymin - 1, ymax + 1, 4)])
    skip, horizon = float(rng.uniform(0, 1)), float(rng.uniform(1, 6))
    assert path_obstructed(expected, geometry, points, 0.2, skip=skip, horizon=horizon) == \
        path_obstructed_twin(expected, geometry, points, 0.2, skip=skip, horizon=horizon)


def _peak_bytes(function) -> int:
    """The most memory ``function()`` held at once beyond what it started with (NumPy's arrays included)."""
    tracemalloc.start()
    try:
        function()
        return tracemalloc.get_traced_memory()[1]
    finally:
        tracemalloc.stop()


def test_a_path_a_thousand_kilometres_long_costs_what_the_map_holds():
    geometry = GridGeometry(0.1, 0.0, 0.0, 20, 200)
    expected = np.full(geometry.shape, 0.2)
    expected[:, 150] = 0.9
    peaks = []
    for end in (30.0, 1e6):  # the same question; the second path runs off the map for 1000 km
        def ask(end=end):
            assert path_obstructed(expected, geometry, [(0.5, 1.0), (19.5, 1.0), (19.5, end)], 0.2)
            assert not path_obstructed(expected, geometry, [(0.5, 1.0), (10.0, 1.0), (10.0, end)], 0.2)

        ask()  # compiled, so that only the question is measured
        peaks.append(_peak_bytes(ask))
    assert peaks[1] <= peaks[0] + 4096, peaks  # a few bytes of Python objects, no samples of the 1000 km


def test_drawing_a_path_a_thousand_kilometres_long_costs_what_the_panel_holds():
    from emmi_gym.env.rendering import Canvas

    peaks = []
    for end in (30.0, 1e6):
        canvas = Canvas((0.0, 0.0, 20.0, 20.0))
        path = np.array([(0.5, 1.0), (19.5, 1.0), (19.5, end)])
        canvas.polyline(path, (255, 0, 0))
        peaks.append(_peak_bytes(lambda canvas=canvas, path=path: canvas.polyline(path, (255, 0, 0))))
        assert canvas.image[-17, 16:300, 0].all() and canvas.image[:, 312, 0].sum() > 0  # both legs drawn
    assert peaks[1] <= 2 * peaks[0], peaks


def test_travel_costs_plan_round_a_wall_and_keep_clear_of_it():
    geometry = GridGeometry(0.1, 0.0, 0.0, 60, 60)
    expected = np.full(geometry.shape, 0.2)
    expected[10:50, 30] = 0.95  # a wall with a way round at either end
    costs = travel_costs(expected, geometry, (1.5, 3.0), 0.2)
    path = np.array(costs.path_to(4.5, 3.0, spacing=0.1))
    assert np.all(np.hypot(path[:, 0] - 3.05, np.clip(path[:, 1], 1.0, 5.0) - path[:, 1]) >= 0.25 - 1e-9)
    assert costs.route_lengths(np.array([[4.5, 3.0]]))[0] > 3.0  # round the wall, not through it
    goal = travel_costs(expected, geometry, (1.5, 3.0), 0.2, goal_xy=(4.5, 3.0))
    assert goal.cost_to(4.5, 3.0) == pytest.approx(costs.cost_to(4.5, 3.0), abs=0.01)
