"""Scores against ground truth: trajectory error (ATE), map accuracy against the floor plan and against the oracle map,
and the building accuracy (the share of the whole building mapped correctly).

Neutral helpers: the SLAM replay, the tests and the environment's ``info`` use them;
they know arrays, not worlds or filters.
"""

from __future__ import annotations

import numba as nb
import numpy as np
from scipy import ndimage

from ..certainty import DEFAULT_OBSERVED_TOL, observation_labels
from ..geometry.grid import GridGeometry


def align_se2(estimated_xy: np.ndarray, true_xy: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Rotation R (2, 2) and translation t (2,) minimising sum |R e + t - g|^2 (Horn / Umeyama, no scale)."""
    mu_e, mu_g = estimated_xy.mean(axis=0), true_xy.mean(axis=0)
    cov = (true_xy - mu_g).T @ (estimated_xy - mu_e)
    u, _, vt = np.linalg.svd(cov)
    d = np.sign(np.linalg.det(u @ vt))
    rotation = u @ np.diag([1.0, d]) @ vt
    return rotation, mu_g - rotation @ mu_e


def absolute_trajectory_error(estimated, truth, *, align: bool = True) -> float:
    """ATE: RMS position error (m) between matching poses of two (T, >=2) trajectories.

    With ``align=True`` (the usual definition, Sturm et al. 2012) the estimate is first
    moved by the rigid 2-D transform that fits it best to the truth; without, the
    frames are taken to coincide (as when the filter starts at the true start pose).
    """
    e = np.asarray(estimated, dtype=np.float64)[:, :2]
    g = np.asarray(truth, dtype=np.float64)[:, :2]
    if e.shape != g.shape or e.shape[0] == 0:
        raise ValueError(f"trajectories must have the same number of poses (>0), got {e.shape} and {g.shape}")
    if align and e.shape[0] >= 2:
        rotation, translation = align_se2(e, g)
        e = e @ rotation.T + translation
    return float(np.sqrt(np.mean(np.sum((e - g) ** 2, axis=1))))


def trajectory_alignment(estimated, truth) -> tuple[np.ndarray, np.ndarray]:
    """The rigid transform (R, t) taking the estimated trajectory's frame onto the truth's."""
    return align_se2(np.asarray(estimated, dtype=np.float64)[:, :2], np.asarray(truth, dtype=np.float64)[:, :2])


def loop_closure_update(true_poses, scans, angles, max_range: float, geometry: GridGeometry, first_leg: int,
                        search_from: int, share: float = 0.1) -> int | None:
    """The update at which a loop closes: the first at or after ``search_from`` whose scan, at its true
    pose, puts at least ``share`` of its echoes within one cell of an echo of the first ``first_leg``
    updates (what the robot mapped as it set out). None if no scan does.

    Where that happens depends on the sensor, not only on where the robot is: a 360-degree
    laser sees the start area from the side and from behind, a 180-degree one only once it
    lies ahead within range. ``scans[k]`` are the ranges of update k; a range of
    ``max_range`` is no echo.
    """
    def echo_cells(k):
        x, y, theta = true_poses[k][:3]
        r = np.asarray(scans[k], dtype=np.float64)
        hit = r < max_range
        a = theta + np.asarray(angles)[hit]
        row, col = geometry.cell_of(x + r[hit] * np.cos(a), y + r[hit] * np.sin(a))
        inside = geometry.inside(row, col)
        return row[inside], col[inside]

    seen = np.zeros((geometry.rows, geometry.cols), dtype=bool)
    for k in range(first_leg):
        seen[echo_cells(k)] = True
    seen = ndimage.binary_dilation(seen, structure=np.ones((3, 3), dtype=bool))
    for k in range(search_from, len(scans)):
        row, col = echo_cells(k)
        if row.size and np.count_nonzero(seen[row, col]) >= share * row.size:
            return k
    return None


def labels_in_map_frame(truth_grid: np.ndarray, geometry: GridGeometry, transform, unknown: int = -1) -> np.ndarray:
    """The truth's label under each map cell's centre, moved by ``transform`` = (R, t) into the truth's frame.

    Both grids share ``geometry``; centres that land outside it are ``unknown``.
    """
    rotation, translation = transform
    x, y = geometry.cell_centres()
    wx = rotation[0, 0] * x + rotation[0, 1] * y + translation[0]
    wy = rotation[1, 0] * x + rotation[1, 1] * y + translation[1]
    row, col = geometry.cell_of(wx, wy)
    inside = geometry.inside(row, col)
    labels = np.full(truth_grid.shape, unknown, dtype=truth_grid.dtype)
    labels[inside] = truth_grid[row[inside], col[inside]]
    return labels


def map_accuracy(probabilities: np.ndarray, truth_grid: np.ndarray, *, geometry: GridGeometry | None = None,
                 transform=None, unknown: int = -1, occupied: int = 1,
                 observed_tol: float = DEFAULT_OBSERVED_TOL) -> float:
    """Share of the cells known to both the map and the truth on which they agree (occupied or free).

    A map cell is known when it is observed in the sense of eq. (10); it says occupied
    when p > 0.5. ``truth_grid`` holds ``unknown`` / free / ``occupied`` labels on the
    same grid. With ``transform`` (R, t), e.g. the :func:`trajectory_alignment` of the
    path that built the map, the map is first registered onto the truth (needs
    ``geometry``), as trajectories are aligned for the ATE. 0.0 when no cell is known to
    both (a map that holds nothing of the truth gets nothing right; a finite value keeps
    ``info`` and the means over episodes defined).
    """
    p = np.asarray(probabilities)
    if p.shape != truth_grid.shape:
        raise ValueError(f"map {p.shape} and truth {truth_grid.shape} must share one grid")
    if transform is not None:
        if geometry is None:
            raise ValueError("map_accuracy with a transform needs the grid's geometry")
        truth_grid = labels_in_map_frame(truth_grid, geometry, transform, unknown)
    return accuracy_of_labels(map_labels(p, observed_tol), truth_grid, unknown, occupied)


def accuracy_of_labels(labels: np.ndarray, truth_grid: np.ndarray, unknown: int = -1, occupied: int = 1) -> float:
    """:func:`map_accuracy` of a map already labelled by :func:`map_labels` (on the truth's grid)."""
    known = (labels >= 0) & (truth_grid != unknown)
    if not known.any():
        return 0.0
    return float(np.mean((labels[known] == 1) == (truth_grid[known] == occupied)))


def building_cells(truth_grid: np.ndarray, unknown: int = -1, occupied: int = 1) -> np.ndarray:
    """The cells of the building a laser could ever observe, as a boolean mask: the truth's free cells (the free
    space reachable from the start, all that :func:`~emmi_gym.world.rasterise` labels free) and its ``occupied``
    cells that touch one of them, side or corner (the walls' faces, where a beam from the free space ends).
    The inside of a thick wall, closed-off pockets and the outside are no laser's to see."""
    truth = np.asarray(truth_grid)
    free = (truth != unknown) & (truth != occupied)
    faces = ndimage.binary_dilation(free, structure=np.ones((3, 3), dtype=bool)) & (truth == occupied)
    return free | faces


def building_accuracy(probabilities: np.ndarray, truth_grid: np.ndarray, unknown: int = -1, occupied: int = 1,
                      observed_tol: float = DEFAULT_OBSERVED_TOL) -> float:
    """Share of the building's cells (:func:`building_cells`) that the map has observed (eq. 10) and labels as
    the floor plan does (occupied when p > 0.5, else free); an unobserved cell counts as wrong. So a complete,
    correct map scores 1.0 and an empty one 0.0, and mapping less never scores more: where
    :func:`map_accuracy` and :func:`oracle_accuracy` judge only what was mapped, this also counts what was
    not (a score to compare maps at equal robot time). Its ceiling is what the sensor model and the grid
    leave of the floor plan (the final :func:`map_accuracy` of a perfectly localised map)."""
    p = np.asarray(probabilities)
    if p.shape != np.shape(truth_grid):
        raise ValueError(f"map {p.shape} and truth {np.shape(truth_grid)} must share one grid")
    return building_accuracy_of_labels(map_labels(p, observed_tol), truth_grid,
                                       building_cells(truth_grid, unknown, occupied), occupied)


def building_accuracy_of_labels(labels: np.ndarray, truth_grid: np.ndarray, cells: np.ndarray,
                                occupied: int = 1) -> float:
    """:func:`building_accuracy` of a map already labelled by :func:`map_labels`, on the building's ``cells``
    (:func:`building_cells` of ``truth_grid``, computed once per world); 0.0 for a building of no cell."""
    total = np.count_nonzero(cells)
    if total == 0:
        return 0.0
    right = cells & (labels >= 0) & ((labels == 1) == (truth_grid == occupied))
    return np.count_nonzero(right) / total


#: How far (m) a map's wall cell may lie from the oracle map's nearest wall and still count as the same
#: wall in :func:`wall_consistency` (two cells at the default 0.1 m: blur and the laser's noise).
WALL_TOLERANCE = 0.2


def map_labels(probabilities: np.ndarray, observed_tol: float = DEFAULT_OBSERVED_TOL) -> np.ndarray:
    """-1 (unobserved, eq. 10), 0 (free: p <= 0.5) or 1 (occupied: p > 0.5) per cell, int8."""
    return observation_labels(probabilities, observed_tol)


def oracle_accuracy(probabilities: np.ndarray, oracle: np.ndarray, observed_tol: float = DEFAULT_OBSERVED_TOL) -> float:
    """Share of the cells observed in the map or the oracle map on which both say the same (unobserved,
    free or occupied): 1.0 when SLAM added no error to what the scans could show; lower for walls
    drawn in the wrong place, cells freed through walls, space mapped where the robot never saw.
    1.0 when neither map has observed anything (nothing to disagree on)."""
    _check_same_grid(probabilities, oracle)
    return _agreement(map_labels(probabilities, observed_tol), map_labels(oracle, observed_tol))


def wall_consistency(probabilities: np.ndarray, oracle: np.ndarray, resolution: float,
                     tolerance: float = WALL_TOLERANCE, observed_tol: float = DEFAULT_OBSERVED_TOL) -> float:
    """Share of the map's occupied cells that lie within ``tolerance`` metres of an occupied cell of the
    oracle map. A loop closed too late leaves a revisited wall drawn twice, the copy away from every
    true wall: this share drops where accuracy, dominated by free space, hardly moves. 1.0 for a map
    with no occupied cell."""
    _check_same_grid(probabilities, oracle)
    return _walls_near(map_labels(probabilities, observed_tol), map_labels(oracle, observed_tol), resolution,
                       tolerance)


def oracle_scores(probabilities: np.ndarray, oracle: np.ndarray, resolution: float,
                  tolerance: float = WALL_TOLERANCE, observed_tol: float = DEFAULT_OBSERVED_TOL) -> tuple[float, float]:
    """(:func:`oracle_accuracy`, :func:`wall_consistency`), labelling each map once."""
    return oracle_scores_of_labels(map_labels(probabilities, observed_tol), map_labels(oracle, observed_tol),
                                   resolution, tolerance)


def oracle_scores_of_labels(mine: np.ndarray, truth: np.ndarray, resolution: float,
                            tolerance: float = WALL_TOLERANCE) -> tuple[float, float]:
    """:func:`oracle_scores` of two maps already labelled by :func:`map_labels` (the environment labels
    each map once per filter update, for these and its coverage and accuracy)."""
    _check_same_grid(mine, truth)
    return _agreement(mine, truth), _walls_near(mine, truth, resolution, tolerance)


def _check_same_grid(probabilities, oracle) -> None:
    if np.shape(probabilities) != np.shape(oracle):
        raise ValueError(f"map {np.shape(probabilities)} and oracle {np.shape(oracle)} must share one grid")


def _agreement(mine: np.ndarray, truth: np.ndarray) -> float:
    seen = (mine >= 0) | (truth >= 0)
    if not seen.any():
        return 1.0
    return float(np.mean(mine[seen] == truth[seen]))


def _walls_near(mine: np.ndarray, truth: np.ndarray, resolution: float, tolerance: float) -> float:
    """Share of ``mine``'s wall cells with a wall cell of ``truth`` within ``tolerance`` metres (centre to
    centre; 1.0 when ``mine`` has none, 0.0 when only ``truth`` has none)."""
    reach = tolerance / resolution + 1e-9
    k = int(np.floor(reach))
    rows, cols = np.mgrid[-k:k + 1, -k:k + 1]
    within = rows ** 2 + cols ** 2 <= reach ** 2
    walls, near = _count_walls_near(mine, truth, np.column_stack([rows[within], cols[within]]))
    return 1.0 if walls == 0 else near / walls


@nb.njit(cache=True)
def _count_walls_near(mine, truth, offsets):
    """(wall cells of ``mine``, those of them with a wall cell of ``truth`` at one of ``offsets`` (row, column)
    from them): a pass over the grid, and a few reads per wall."""
    h, w = mine.shape
    walls = near = 0
    for row in range(h):
        for col in range(w):
            if mine[row, col] != 1:
                continue
            walls += 1
            for k in range(offsets.shape[0]):
                r, c = row + offsets[k, 0], col + offsets[k, 1]
                if 0 <= r < h and 0 <= c < w and truth[r, c] == 1:
                    near += 1
                    break
    return walls, near
