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
    and ``coarse`` (M, ceil(H / block), ceil(W / block)) how many cells of each block of
    ``block x block`` cells are occupied (the scan matcher's coarse level), both kept
    current by the insertion, so that a map's entropy and mean information need
    no pass over its cells; ``touched`` the box (row0, row1, col0, col1) of the cells
    any scan may have reached: outside it every grid is unknown.
    Resampling copies the chosen particles into spare arrays with ``np.take`` and swaps
    them in (one pass over memory, no allocation). The extent can grow in chunks (for
    logs whose size is not known in advance); growing keeps cells aligned.
    """

    def __init__(self, geometry: GridGeometry, n_particles: int, codes: CellCodes, block: int = 1):
        self.geometry = geometry
        self.cell_codes = codes
        self.block = int(block)
        self.codes = np.zeros((n_particles, *geometry.shape), dtype=np.int8)
        self.hits = np.zeros((n_particles, *geometry.shape, 3), dtype=np.int8)
        self.coarse = np.zeros((n_particles, -(-geometry.rows // self.block), -(-geometry.cols // self.block)),
                               dtype=np.int32)
        self.counts = np.zeros((n_particles, 256), dtype=np.int64)
        self.counts[:, 128] = geometry.rows * geometry.cols
        self.touched: tuple[int, int, int, int] | None = None
        self._spare_codes = np.zeros_like(self.codes)  # unknown outside the touched box, as the grids
        self._spare_hits = np.zeros_like(self.hits)
        self._stamp = np.zeros(geometry.shape, dtype=np.int64)
        self._serial = 0

    @property
    def n_particles(self) -> int:
        return self.codes.shape[0]

    def insert(self, poses: np.ndarray, ranges: np.ndarray, angles: np.ndarray, max_range: float,
               free_range: float, insertion_range: float | None = None, depth_jump: float = 0.3) -> None:
        """Insert one scan, as its polygon, into every particle's grid at that particle's pose.

        ``angles`` must increase; a scan that closes the circle has its last beam joined
        to its first. Readings of ``max_range`` (no echo) free ``free_range`` metres; with
        ``insertion_range`` below ``max_range``, echoes beyond it only free the cells up to
        it (GMapping's maxUrange). See ``_kernels.scan_rays`` and ``_kernels.insert_scans``.
        """
        g, c = self.geometry, self.cell_codes
        hit_range = max_range if insertion_range is None else min(max_range, insertion_range)
        free_lengths = np.where(ranges >= max_range, min(free_range, hit_range), hit_range)
        rays = _kernels.scan_rays(ranges, angles, beam_gaps(angles), hit_range, free_lengths, g.resolution,
                                  depth_jump)
        self._serial = _kernels.insert_scans(self.codes, self.hits, self.counts, self.coarse, self.block, poses,
                                             *rays, c.occupied, c.free, c.clamp, g.origin_x, g.origin_y,
                                             g.resolution, self._stamp, self._serial)
        # every ray is a segment from a pose to its end point: their box holds every cell touched
        heading = poses[:, 2:3] + rays[0][None, :]
        xs = np.concatenate([poses[:, 0], (poses[:, 0:1] + rays[1] * np.cos(heading)).ravel()])
        ys = np.concatenate([poses[:, 1], (poses[:, 1:2] + rays[1] * np.sin(heading)).ravel()])
        rows, cols = g.cell_of(np.array([xs.min(), xs.max()]), np.array([ys.min(), ys.max()]))
        box = (max(int(rows[0]) - 1, 0), min(int(rows[1]) + 2, g.rows),
               max(int(cols[0]) - 1, 0), min(int(cols[1]) + 2, g.cols))
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
        """Particle i takes the grid of particle ``indices[i]``.

        Only the touched box is copied: outside it every grid (and the spare arrays) is
        still unknown, so the copy costs the explored area, not the grids' extent.
        """
        r0, r1, c0, c1 = self.touched or (0, self.geometry.rows, 0, self.geometry.cols)
        np.take(self.codes[:, r0:r1, c0:c1], indices, axis=0, out=self._spare_codes[:, r0:r1, c0:c1])
        np.take(self.hits[:, r0:r1, c0:c1], indices, axis=0, out=self._spare_hits[:, r0:r1, c0:c1])
        self.counts = self.counts[indices]
        self.coarse = self.coarse[indices]
        self.codes, self._spare_codes = self._spare_codes, self.codes
        self.hits, self._spare_hits = self._spare_hits, self.hits

    def probabilities(self, particle: int) -> np.ndarray:
        """Occupancy probabilities (H, W) of one particle's grid."""
        return self.cell_codes.to_probability(self.codes[particle])

    def grow_to_contain(self, xmin: float, ymin: float, xmax: float, ymax: float, chunk: float) -> bool:
        """Enlarge the grids (by whole chunks of about ``chunk`` metres, a whole number of coarse blocks)
        so the box fits; True if they grew."""
        g = self.geometry
        gx0, gx1, gy0, gy1 = g.extent
        cells = self.block * max(1, int(round(chunk / (g.resolution * self.block))))

        def chunks_needed(missing: float) -> int:
            return int(math.ceil(missing / (cells * g.resolution))) if missing > 0 else 0

        left, right = chunks_needed(gx0 - xmin), chunks_needed(xmax - gx1)
        down, up = chunks_needed(gy0 - ymin), chunks_needed(ymax - gy1)
        if not (left or right or down or up):
            return False
        pad = ((0, 0), (down * cells, up * cells), (left * cells, right * cells))
        self.codes = np.pad(self.codes, pad)
        self.hits = np.pad(self.hits, pad + ((0, 0),))
        self.coarse = np.pad(self.coarse, ((0, 0),) + tuple((a // self.block, b // self.block) for a, b in pad[1:]))
        self.counts[:, 128] += self.codes.shape[1] * self.codes.shape[2] - g.rows * g.cols
        if self.touched is not None:
            r0, r1, c0, c1 = self.touched
            self.touched = (r0 + down * cells, r1 + down * cells, c0 + left * cells, c1 + left * cells)
        self._spare_codes = np.zeros_like(self.codes)
        self._spare_hits = np.zeros_like(self.hits)
        self._stamp = np.pad(self._stamp, pad[1:])
        self.geometry = GridGeometry(g.resolution, g.origin_x - left * cells * g.resolution,
                                     g.origin_y - down * cells * g.resolution, self.codes.shape[1],
                                     self.codes.shape[2])
        return True
