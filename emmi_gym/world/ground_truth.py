"""Ground-truth occupancy grids of a world, for map accuracy and coverage.

``FREE`` cells are the free space reachable from the start (4-connected), ``OCCUPIED``
cells lie within a wall, everything else (outside the building, closed-off pockets)
is ``UNKNOWN``: no laser could ever see it from where the robot can go.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy import ndimage

from ..geometry.grid import GridGeometry
from .spec import WorldSpec, point_segment_distance

UNKNOWN, FREE, OCCUPIED = -1, 0, 1


@dataclass(frozen=True)
class GroundTruth:
    """A world rasterised at one resolution: ``grid`` holds UNKNOWN / FREE / OCCUPIED (int8)."""

    geometry: GridGeometry
    grid: np.ndarray

    @property
    def reachable(self) -> np.ndarray:
        """Boolean mask of the free space reachable from the start."""
        return self.grid == FREE


def wall_mask(world: WorldSpec, geometry: GridGeometry) -> np.ndarray:
    """Cells that a wall overlaps: centre closer than half the thickness plus half a cell to its centre line.

    The inequality is strict (less 1e-6 of a cell), so a cell that only touches a wall's
    face is free, as it is for the laser; the half cell makes every wall at least one
    cell thick, so no 4-connected path of free cells leaks through a thin wall.
    """
    mask = np.zeros(geometry.shape, dtype=bool)
    res = geometry.resolution
    for wall in world.walls:
        ax, ay, bx, by, t = wall
        reach = t / 2 + res / 2 - 1e-6 * res
        r0, c0 = geometry.cell_of(min(ax, bx) - reach, min(ay, by) - reach)
        r1, c1 = geometry.cell_of(max(ax, bx) + reach, max(ay, by) + reach)
        r0, c0 = max(int(r0), 0), max(int(c0), 0)
        r1, c1 = min(int(r1), geometry.rows - 1), min(int(c1), geometry.cols - 1)
        if r1 < r0 or c1 < c0:
            continue
        rows, cols = np.mgrid[r0:r1 + 1, c0:c1 + 1]
        x, y = geometry.centre_of(rows, cols)
        d = point_segment_distance(x.ravel(), y.ravel(), wall[None, :])[:, 0].reshape(x.shape)
        mask[r0:r1 + 1, c0:c1 + 1] |= d < reach
    return mask


def rasterise(world: WorldSpec, resolution: float, geometry: GridGeometry | None = None) -> GroundTruth:
    """Rasterise ``world`` on ``geometry`` (default: a grid of ``resolution`` covering its bounds)."""
    if geometry is None:
        xmin, ymin, xmax, ymax = world.bounds
        geometry = GridGeometry.covering(xmin, ymin, xmax, ymax, resolution)
    walls = wall_mask(world, geometry)
    labels, _ = ndimage.label(~walls)  # 4-connected components of the non-wall cells
    row, col = geometry.cell_of(world.start.x, world.start.y)
    if not geometry.inside(row, col) or walls[row, col]:
        raise ValueError(f"world '{world.name}': the start cell lies outside the grid or in a wall at "
                         f"resolution {geometry.resolution} m")
    grid = np.full(geometry.shape, UNKNOWN, dtype=np.int8)
    grid[labels == labels[row, col]] = FREE
    grid[walls] = OCCUPIED
    return GroundTruth(geometry, grid)


def is_reachable(truth: GroundTruth, x: float, y: float) -> bool:
    """Whether the point (x, y) lies in the free space reachable from the start."""
    row, col = truth.geometry.cell_of(x, y)
    return bool(truth.geometry.inside(row, col) and truth.grid[row, col] == FREE)
