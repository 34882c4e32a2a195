"""The particles' occupancy grids: one contiguous (M, H, W) int8 array of log-odds codes."""

from __future__ import annotations

import math

import numpy as np

from ..grid import GridGeometry
from . import _kernels
from .sensor_model import CellCodes


def beam_gaps(angles: np.ndarray) -> np.ndarray:
    """Angular gap from each beam to the next (radians); the last beam's gap joins it to the first
    when the scan closes the circle, else it is 0."""
    angles = np.asarray(angles, dtype=np.float64)
    gaps = np.zeros(angles.size)
    if angles.size < 2:
        return gaps
    gaps[:-1] = np.diff(angles)
    if np.any(gaps[:-1] <= 0):
        raise ValueError("beam angles must increase")
    closing = angles[0] + 2.0 * math.pi - angles[-1]
    if closing <= 1.5 * float(np.median(gaps[:-1])):
        gaps[-1] = closing
    return gaps


class ParticleMaps:
    """M occupancy grids on one :class:`GridGeometry`, updated by scans and copied by index.

    ``codes`` (M, H, W) int8 holds the log-odds codes; ``hits`` (M, H, W, 3) int8 the
    mean end-point position of each cell, for the scan matcher (see ``_kernels``);
    ``counts`` (M, 256) how many cells of each grid hold each code (index code + 128),
    kept current by the insertion, so that a map's entropy and mean information need
    no pass over its cells; ``touched`` the box (row0, row1, col0, col1) of the cells
    any scan may have reached: outside it every grid is unknown.
    Resampling copies the chosen particles into spare arrays with ``np.take`` and swaps
    them in (one pass over memory, no allocation). The extent can grow in chunks (for
    logs whose size is not known in advance); growing keeps cells aligned.
    """

    def __init__(self, geometry: GridGeometry, n_particles: int, codes: CellCodes):
        self.geometry = geometry
        self.cell_codes = codes
        self.codes = np.zeros((n_particles, *geometry.shape), dtype=np.int8)
        self.hits = np.zeros((n_particles, *geometry.shape, 3), dtype=np.int8)
        self.counts = np.zeros((n_particles, 256), dtype=np.int64)
        self.counts[:, 128] = geometry.rows * geometry.cols
        self.touched: tuple[int, int, int, int] | None = None
        self._spare_codes = np.empty_like(self.codes)
        self._spare_hits = np.empty_like(self.hits)
        self._stamp = np.zeros(geometry.shape, dtype=np.int64)
        self._serial = 0

    @property
    def n_particles(self) -> int:
        return self.codes.shape[0]

    def insert(self, poses: np.ndarray, ranges: np.ndarray, angles: np.ndarray, max_range: float,
               free_range: float, depth_jump: float = 0.3) -> None:
        """Insert one scan, as its polygon, into every particle's grid at that particle's pose.

        ``angles`` must increase; a scan that closes the circle has its last beam joined
        to its first. See ``_kernels.scan_rays`` and ``_kernels.insert_scans``.
        """
        g, c = self.geometry, self.cell_codes
        rays = _kernels.scan_rays(ranges, angles, beam_gaps(angles), max_range, free_range, g.resolution,
                                  depth_jump)
        self._serial = _kernels.insert_scans(self.codes, self.hits, self.counts, poses, *rays, c.occupied, c.free,
                                             c.clamp, g.origin_x, g.origin_y, g.resolution, self._stamp,
                                             self._serial)
        reach = float(rays[1].max(initial=0.0)) + g.resolution
        rows, cols = g.cell_of(np.concatenate([poses[:, 0] - reach, poses[:, 0] + reach]),
                               np.concatenate([poses[:, 1] - reach, poses[:, 1] + reach]))
        box = (max(int(rows.min()), 0), min(int(rows.max()) + 1, g.rows),
               max(int(cols.min()), 0), min(int(cols.max()) + 1, g.cols))
        if self.touched is not None:
            box = (min(box[0], self.touched[0]), max(box[1], self.touched[1]),
                   min(box[2], self.touched[2]), max(box[3], self.touched[3]))
        self.touched = box

    def touched_codes(self) -> np.ndarray:
        """The (M, h, w) view of the codes inside the touched box (everything, before any scan)."""
        if self.touched is None:
            return self.codes
        r0, r1, c0, c1 = self.touched
        return self.codes[:, r0:r1, c0:c1]

    def resample(self, indices: np.ndarray) -> None:
        """Particle i takes the grid of particle ``indices[i]``."""
        np.take(self.codes, indices, axis=0, out=self._spare_codes)
        np.take(self.hits, indices, axis=0, out=self._spare_hits)
        self.counts = self.counts[indices]
        self.codes, self._spare_codes = self._spare_codes, self.codes
        self.hits, self._spare_hits = self._spare_hits, self.hits

    def probabilities(self, particle: int) -> np.ndarray:
        """Occupancy probabilities (H, W) of one particle's grid."""
        return self.cell_codes.to_probability(self.codes[particle])

    def grow_to_contain(self, xmin: float, ymin: float, xmax: float, ymax: float, chunk: float) -> bool:
        """Enlarge the grids (by whole chunks of ``chunk`` metres) so the box fits; True if they grew."""
        g = self.geometry
        gx0, gx1, gy0, gy1 = g.extent
        cells = max(1, int(round(chunk / g.resolution)))

        def chunks_needed(missing: float) -> int:
            return int(math.ceil(missing / (cells * g.resolution))) if missing > 0 else 0

        left, right = chunks_needed(gx0 - xmin), chunks_needed(xmax - gx1)
        down, up = chunks_needed(gy0 - ymin), chunks_needed(ymax - gy1)
        if not (left or right or down or up):
            return False
        pad = ((0, 0), (down * cells, up * cells), (left * cells, right * cells))
        self.codes = np.pad(self.codes, pad)
        self.hits = np.pad(self.hits, pad + ((0, 0),))
        self.counts[:, 128] += self.codes.shape[1] * self.codes.shape[2] - g.rows * g.cols
        if self.touched is not None:
            r0, r1, c0, c1 = self.touched
            self.touched = (r0 + down * cells, r1 + down * cells, c0 + left * cells, c1 + left * cells)
        self._spare_codes = np.empty_like(self.codes)
        self._spare_hits = np.empty_like(self.hits)
        self._stamp = np.pad(self._stamp, pad[1:])
        self.geometry = GridGeometry(g.resolution, g.origin_x - left * cells * g.resolution,
                                     g.origin_y - down * cells * g.resolution, self.codes.shape[1],
                                     self.codes.shape[2])
        return True
