"""Cell geometry of occupancy grids: resolution, origin, shape, world <-> cell transforms.

Convention (DESIGN.md): ``array[row, col]``, row = y index, col = x index; the
origin is the lower-left corner of cell (0, 0), so cell (r, c) covers
``[x0 + c*res, x0 + (c+1)*res) x [y0 + r*res, y0 + (r+1)*res)``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True)
class GridGeometry:
    """Where a (rows, cols) grid of square cells of side ``resolution`` lies in the world."""

    resolution: float
    origin_x: float
    origin_y: float
    rows: int
    cols: int

    def __post_init__(self):
        if not (self.resolution > 0 and math.isfinite(self.resolution)):
            raise ValueError(f"resolution must be a positive number of metres, got {self.resolution!r}")
        if self.rows <= 0 or self.cols <= 0:
            raise ValueError(f"a grid needs at least one row and one column, got {self.rows} x {self.cols}")

    @classmethod
    def covering(cls, xmin: float, ymin: float, xmax: float, ymax: float, resolution: float,
                 margin: float = 0.0) -> GridGeometry:
        """The smallest grid of ``resolution`` cells covering the box grown by ``margin`` (the box may be
        flat, as a path along an axis, if the margin gives it an area)."""
        if not all(math.isfinite(v) for v in (xmin, ymin, xmax, ymax, margin)):
            raise ValueError(f"box ({xmin}, {ymin}) - ({xmax}, {ymax}) with margin {margin}: expected finite numbers")
        if not (xmax + margin > xmin - margin and ymax + margin > ymin - margin):
            raise ValueError(f"empty box ({xmin}, {ymin}) - ({xmax}, {ymax}) with margin {margin}")
        if not resolution > 0:
            raise ValueError(f"resolution must be positive, got {resolution!r}")
        x0, y0 = xmin - margin, ymin - margin
        cols, rows = (xmax + margin - x0) / resolution - 1e-9, (ymax + margin - y0) / resolution - 1e-9
        if not (math.isfinite(cols) and math.isfinite(rows)):
            raise ValueError(f"box ({xmin:g}, {ymin:g}) - ({xmax:g}, {ymax:g}) with margin {margin:g}: more cells of "
                             f"{resolution:g} m than a number can count")
        cols, rows = int(math.ceil(cols)), int(math.ceil(rows))
        return cls(float(resolution), float(x0), float(y0), rows, cols)

    @property
    def shape(self) -> tuple[int, int]:
        return (self.rows, self.cols)

    @property
    def extent(self) -> tuple[float, float, float, float]:
        """(xmin, xmax, ymin, ymax), for matplotlib's ``imshow(..., origin="lower", extent=...)``."""
        return (self.origin_x, self.origin_x + self.cols * self.resolution,
                self.origin_y, self.origin_y + self.rows * self.resolution)

    def cell_of(self, x, y) -> tuple[np.ndarray, np.ndarray]:
        """(row, col) integer indices of the cells holding the points (may lie outside the grid)."""
        col = np.floor((np.asarray(x, dtype=np.float64) - self.origin_x) / self.resolution).astype(np.int64)
        row = np.floor((np.asarray(y, dtype=np.float64) - self.origin_y) / self.resolution).astype(np.int64)
        return row, col

    def centre_of(self, row, col) -> tuple[np.ndarray, np.ndarray]:
        """World (x, y) of the centres of cells (row, col)."""
        x = self.origin_x + (np.asarray(col, dtype=np.float64) + 0.5) * self.resolution
        y = self.origin_y + (np.asarray(row, dtype=np.float64) + 0.5) * self.resolution
        return x, y

    def inside(self, row, col) -> np.ndarray:
        row, col = np.asarray(row), np.asarray(col)
        return (row >= 0) & (row < self.rows) & (col >= 0) & (col < self.cols)

    def cell_centres(self) -> tuple[np.ndarray, np.ndarray]:
        """(X, Y) arrays of shape (rows, cols) with every cell's centre."""
        r, c = np.meshgrid(np.arange(self.rows), np.arange(self.cols), indexing="ij")
        return self.centre_of(r, c)
