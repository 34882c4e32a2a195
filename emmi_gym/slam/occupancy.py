"""The particles' occupancy grids: one contiguous (M, H, W) int8 array of log-odds codes."""

from __future__ import annotations

import math
import time

import numpy as np

from .. import certainty
from ..concurrency.threads import MIN_CELLS_PER_THREAD, chunk_bounds, run_calls, run_in_chunks
from ..geometry.grid import GridGeometry
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


def open_space_beams(no_echo: np.ndarray, gaps: np.ndarray) -> np.ndarray:
    """The beams without echo that have a neighbour without echo too (neighbours as in :func:`beam_gaps`).

    Open space beyond the sensor's range leaves runs of beams without echo; a dropped echo is
    a lone one among echoes (a second one beside it has the drop probability squared). Only the
    former may free cells: freeing along a dropped echo would cut through the wall it missed.
    """
    joined = gaps > 0.0
    after = np.roll(no_echo, -1) & joined  # beam b + 1, where b and b + 1 are neighbours
    before = np.roll(no_echo & joined, 1)  # beam b - 1, where b - 1 and b are
    return no_echo & (after | before)


#: The most memory the particles' maps may take (a pose far off in a log, or a huge world, would
#: otherwise ask for terabytes).
MAX_MAP_BYTES = 4 * 2**30


class MapTooLarge(ValueError):
    """The maps asked for would exceed :data:`MAX_MAP_BYTES`."""


def _amount(value, spec: str) -> str:
    """``value`` formatted by ``spec``, or in three significant digits when that would be unreadably long."""
    if abs(value) < 1e9:
        return format(value, spec)
    return f"{float(value):.3g}" if math.isfinite(value) else "more than 1e308"


class ParticleMaps:
    """M occupancy grids on one :class:`GridGeometry`, updated by scans and copied by index.

    ``codes`` (M, H, W) int8 holds the log-odds codes; ``hits`` (M, H, W, 3) int8 the
    mean end-point position of each cell, for the scan matcher (see ``_kernels``), and
    ``ever_hit`` (H, W) the cells where a scan ever ended in some grid (elsewhere every
    grid's mean hit point is zero, so comparing grids there needs only their codes);
    ``counts`` (M, 256) how many cells of each grid hold each code (index code + 128),
    and ``coarse`` (M, ceil(H / block), ceil(W / block)) how many cells of each block of
    ``block x block`` cells are occupied (the scan matcher's coarse level), both kept
    current by the insertion, so that a map's entropy and mean information need
    no pass over its cells.

    The maps also know where the particles **agree** (every grid holds the same code and
    mean hit point): ``status`` (H, W) holds an agreed cell's code or ``DISPUTED``,
    ``agreed_counts`` the code histogram of the agreed cells, and a list the disputed
    cells with their codes in every grid side by side (a table of M bytes per cell), all
    re-derived after each scan for the cells it touched. An agreed cell's expected map is
    its own probability whatever the weights, so EMMI and the expected map need a pass
    over the disputed cells' table only (contiguous, not M gathers from grids far apart in
    memory), and resampling copies only those cells:
    an update costs what the particles disagree on, not the grids' extent. The extent
    can grow in chunks (for logs whose size is not known in advance); growing keeps
    cells aligned.
    """

    #: Bytes a cell takes: per particle its code, mean hit, share of a coarse count and (when every
    #: cell is disputed) its row in the disputed cells' table; shared, its agreement status, list
    #: positions, expected map and ever-hit flag; per insertion thread, its stamp and touched list.
    BYTES_PER_CELL_PARTICLE = 6
    BYTES_PER_CELL = 19
    BYTES_PER_CELL_THREAD = 12
    #: Rows the disputed cells' table starts with.
    TABLE_ROWS = 4096

    @classmethod
    def bytes_per_cell(cls, n_particles: int) -> int:
        """What maps of ``n_particles`` grids take per cell (see the constants above)."""
        return (cls.BYTES_PER_CELL_PARTICLE * n_particles + cls.BYTES_PER_CELL +
                cls.BYTES_PER_CELL_THREAD * len(chunk_bounds(n_particles)))

    @classmethod
    def check_memory(cls, rows: int, cols: int, n_particles: int, resolution: float) -> None:
        """Raise :class:`MapTooLarge` if maps of this shape would take more than :data:`MAX_MAP_BYTES` (counted
        in floating point: a pose far off asks for more cells than an integer division can express in GiB)."""
        needed = float(rows) * float(cols) * cls.bytes_per_cell(n_particles)
        if needed > MAX_MAP_BYTES:
            raise MapTooLarge(f"maps of {_amount(rows, 'd')} x {_amount(cols, 'd')} cells of {resolution:g} m "
                              f"({_amount(cols * resolution, '.0f')} x {_amount(rows * resolution, '.0f')} m) for "
                              f"{n_particles} particles would take {_amount(needed / 2**30, '.1f')} GiB, above the "
                              f"bound of {MAX_MAP_BYTES / 2**30:.0f} GiB: use coarser cells, fewer particles or a "
                              "smaller area")

    def __init__(self, geometry: GridGeometry, n_particles: int, codes: CellCodes, block: int = 1):
        self.check_memory(geometry.rows, geometry.cols, n_particles, geometry.resolution)
        self.geometry = geometry
        self.cell_codes = codes
        self.block = int(block)
        self.codes = np.zeros((n_particles, *geometry.shape), dtype=np.int8)
        self.hits = np.zeros((n_particles, *geometry.shape, 3), dtype=np.int8)
        self.ever_hit = np.zeros(geometry.shape, dtype=np.bool_)
        self.coarse = np.zeros((n_particles, -(-geometry.rows // self.block), -(-geometry.cols // self.block)),
                               dtype=np.int32)
        self.counts = np.zeros((n_particles, 256), dtype=np.int64)
        self.counts[:, 128] = geometry.rows * geometry.cols
        self.status = np.zeros(geometry.shape, dtype=np.int16)
        self.agreed_counts = self.counts[0].copy()
        self._position = np.full(geometry.shape, -1, dtype=np.int32)
        self._disputed = np.empty(geometry.rows * geometry.cols, dtype=np.int32)
        self._table = np.empty((min(self.TABLE_ROWS, geometry.rows * geometry.cols), n_particles), dtype=np.int8)
        self._n_disputed = 0
        self._scratch: list[_InsertionScratch] = []
        self._gaps: tuple[np.ndarray, np.ndarray] | None = None  # (beam angles, their beam_gaps) of the last scan
        #: The last resampling's phases (ms): ordering the disputed cells, moving the table's columns,
        #: comparing mean hit points where codes now agree, copying the dead particles' cells beside
        #: unlisting those that agree.
        self.resample_ms: dict[str, float] = {}
        self._expected: np.ndarray | None = None  # the expected map as of the last expected_map() call
        self._changed: list[np.ndarray] = []  # cells whose agreement may have changed since that call
        self._n_changed = 0

    @property
    def n_particles(self) -> int:
        return self.codes.shape[0]

    @property
    def disputed_cells(self) -> np.ndarray:
        """Flat indices of the cells on which the particles' grids differ (a view; the order is that of
        :meth:`disputed_codes`, the same whatever the number of threads, not increasing)."""
        return self._disputed[:self._n_disputed]

    def disputed_codes(self) -> np.ndarray:
        """(N, M) codes of the disputed cells, row k those of ``disputed_cells[k]`` in every grid (a view)."""
        return self._table[:self._n_disputed]

    def insert(self, poses: np.ndarray, ranges: np.ndarray, angles: np.ndarray, max_range: float,
               free_range: float, insertion_range: float | None = None) -> None:
        """Insert one scan, as its polygon, into every particle's grid at that particle's pose.

        ``angles`` must increase; a scan that closes the circle has its last beam joined
        to its first. Readings of ``max_range`` (no echo) free ``free_range`` metres where a
        neighbouring beam has no echo either (:func:`open_space_beams`; a lone one is a dropped
        echo and frees nothing); with ``insertion_range`` below ``max_range``, echoes beyond it
        only free the cells up to it (GMapping's maxUrange). See ``_kernels.scan_rays`` and
        ``_kernels.insert_scans``.
        """
        g, c = self.geometry, self.cell_codes
        hit_range = max_range if insertion_range is None else min(max_range, insertion_range)
        gaps = self._beam_gaps(angles)
        no_echo = ranges >= max_range
        free = min(free_range, hit_range)
        if free > 0.0:  # off by default: the real logs' updates skip it
            no_echo_lengths = np.where(open_space_beams(no_echo, gaps), free, 0.0)
        else:
            no_echo_lengths = 0.0
        free_lengths = np.where(no_echo, no_echo_lengths, hit_range)
        rays = _kernels.scan_rays(ranges, angles, gaps, hit_range, free_lengths, g.resolution)
        chunks = chunk_bounds(self.n_particles)
        while len(self._scratch) < len(chunks):
            self._scratch.append(_InsertionScratch(g.shape))
        scratch = self._scratch[:len(chunks)]
        first = scratch[0].serial
        results = run_calls([(_kernels.insert_scans, start, stop, self.codes, self.hits, self.ever_hit, self.counts,
                              self.coarse, self.block, poses, *rays, c.occupied, c.free, c.clamp, g.origin_x,
                              g.origin_y, g.resolution, part.stamp, part.serial, part.touched)
                             for (start, stop), part in zip(chunks, scratch, strict=False)])
        for part, (serial, n_touched) in zip(scratch, results, strict=False):
            part.serial, part.n_touched = serial, n_touched
        touched = scratch[0].touched
        for part in scratch[1:]:  # the cells other chunks touched that the first did not
            scratch[0].n_touched = _kernels.merge_touched(touched, scratch[0].n_touched, scratch[0].stamp, first,
                                                          part.touched, part.n_touched)
        self._refresh(touched[:scratch[0].n_touched], np.arange(self.n_particles))

    def _beam_gaps(self, angles: np.ndarray) -> np.ndarray:
        """:func:`beam_gaps` of ``angles``, kept from scan to scan while the beam angles stay the same."""
        if self._gaps is None or not np.array_equal(self._gaps[0], angles):
            self._gaps = (np.array(angles, dtype=np.float64), beam_gaps(angles))
        return self._gaps[1]

    def _refresh(self, cells: np.ndarray, particles: np.ndarray) -> None:
        """Re-derive the agreement of ``cells`` among the grids of ``particles`` (on the kernel threads),
        and the table's rows of those that are disputed."""
        agreement = np.empty(cells.size, dtype=np.int16)
        rows = np.empty((cells.size, self.n_particles), dtype=np.int8)
        run_in_chunks(_kernels.agreement_of_cells, cells.size, *self._flat_grids(), _flat(self.ever_hit), particles,
                      cells, agreement, rows, min_chunk=MIN_CELLS_PER_THREAD)
        self._reserve(self._n_disputed + cells.size)
        self._n_disputed = _kernels.record_agreement(cells, agreement, rows, _flat(self.status), self.agreed_counts,
                                                     self._disputed, self._table, self._n_disputed,
                                                     _flat(self._position))
        self._note_changed(cells)

    def _note_changed(self, cells: np.ndarray) -> None:
        """Remember ``cells`` (flat indices) as ones whose agreement may have changed, for the kept expected
        map; past a grid's worth of them, drop that map instead (the next call makes it whole)."""
        if self._expected is None:
            return
        self._n_changed += cells.size
        if self._n_changed > self.status.size:
            self._forget_expected_map()
        else:
            self._changed.append(cells.copy())  # a view of scratch memory that the next scan reuses

    def _forget_expected_map(self) -> None:
        self._expected, self._changed, self._n_changed = None, [], 0

    def _reserve(self, n_rows: int) -> None:
        """Room for ``n_rows`` rows in the disputed cells' table (at most one per cell): doubled as needed."""
        capacity, n_rows = self._table.shape[0], min(n_rows, self.status.size)
        if n_rows > capacity:
            grown = np.empty((min(max(n_rows, 2 * capacity), self.status.size), self.n_particles), dtype=np.int8)
            grown[:self._n_disputed] = self._table[:self._n_disputed]
            self._table = grown

    def _flat_grids(self) -> tuple[np.ndarray, np.ndarray]:
        """``codes`` as (M, H * W) and ``hits`` as (M, H * W, 3): views, for kernels that index cells flat."""
        return _flat(self.codes, self.n_particles), _flat(self.hits, self.n_particles, 3)

    def resample(self, parents: np.ndarray) -> None:
        """Particle i takes the grid of particle ``parents[i]``, an arrangement that keeps survivors in
        place (:func:`~emmi_gym.slam.resampling.survivors_in_place`): only the dead particles'
        disputed cells are copied (elsewhere all grids already hold the same values), in spans
        of a row (``_kernels.copy_spans``: the agreed cells between come along, unchanged), the
        disputed cells' table takes the same copies, and the agreement is re-derived among the
        survivors for the cells whose codes now agree (the others stay disputed). The grids' copies
        and unlisting the cells that now agree touch different arrays: they share the kernel
        threads. How long each phase took is left in :attr:`resample_ms`."""
        parents = np.ascontiguousarray(parents, dtype=np.int64)
        if parents.shape != (self.n_particles,) or not np.all((parents >= 0) & (parents < self.n_particles)):
            raise ValueError(f"parents must be {self.n_particles} particle indices, got {parents!r:.200}")
        if not np.array_equal(parents[parents], parents):
            raise ValueError("parents must keep every survivor in its own slot (parents[parents] == parents); "
                             "arrange a draw with resampling.survivors_in_place")
        clock = _PhaseClock()
        spans = _kernels.copy_spans(_kernels.sorted_cells(self.disputed_cells), self.geometry.cols, self.block,
                                    _kernels.SPAN_GAP)
        clock.lap("order")
        candidates = np.empty(self._n_disputed, dtype=np.int32)
        chunks = chunk_bounds(self._n_disputed, MIN_CELLS_PER_THREAD)
        found = run_calls([(_kernels.resample_rows, start, stop, self._table, parents, self._disputed, candidates)
                           for start, stop in chunks])
        clock.lap("table")
        cells = _kernels.sorted_cells(np.concatenate([candidates[start:start + n]
                                                      for (start, _), n in zip(chunks, found, strict=False)]))
        agreement = np.empty(cells.size, dtype=np.int16)
        run_in_chunks(_kernels.agreement_of_hits, cells.size, *self._flat_grids(), _flat(self.ever_hit),
                      np.unique(parents), cells, agreement, min_chunk=MIN_CELLS_PER_THREAD)
        clock.lap("agreement")
        dead = np.flatnonzero(parents != np.arange(self.n_particles))
        grids = (*self._flat_grids(), _flat(self.coarse, self.n_particles))
        self._n_disputed, *_ = run_calls(
            [(_kernels.unlist_agreed, cells, agreement, _flat(self.status), self.agreed_counts, self._disputed,
              self._table, self._n_disputed, _flat(self._position))] +
            [(_kernels.resample_cells, k, k + 1, *grids, spans, dead, parents) for k in range(dead.size)])
        self.counts = self.counts[parents]
        self._note_changed(cells)
        clock.lap("copies and unlisting")
        self.resample_ms = clock.laps

    def expected_map(self, weights: np.ndarray) -> np.ndarray:
        """EM, eq. (6), (H, W) float64, for normalised ``weights``: an agreed cell's own probability, the
        weighted average over the disputed cells.

        The map is kept from call to call: a call brings up to date the cells whose agreement changed
        since the last one and the disputed cells, so its cost follows what the scans touched, not the
        grid's extent. What it returns is a read-only view of that map, which the next call changes:
        copy it to keep or to modify it.
        """
        table = self.cell_codes.probability
        if self._expected is None:
            self._expected = table[np.where(self.status == _kernels.DISPUTED, 0, self.status).astype(np.int64) + 128]
        else:
            em, status = self._expected.reshape(-1), _flat(self.status)
            for cells in self._changed:
                codes = status[cells]
                agreed = codes != _kernels.DISPUTED
                em[cells[agreed]] = table[codes[agreed] + 128]
        self._changed, self._n_changed = [], 0
        if self._n_disputed:
            self._expected.reshape(-1)[self.disputed_cells] = certainty.expected_map_of_cells(
                self.disputed_codes(), weights, lut=table)
        view = self._expected.view()
        view.flags.writeable = False
        return view

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
        self.check_memory(g.rows + (down + up) * cells, g.cols + (left + right) * cells, self.n_particles,
                          g.resolution)
        pad = ((0, 0), (down * cells, up * cells), (left * cells, right * cells))
        self.codes = np.pad(self.codes, pad)
        self.hits = np.pad(self.hits, pad + ((0, 0),))
        self.ever_hit = np.pad(self.ever_hit, pad[1:])
        self.coarse = np.pad(self.coarse, ((0, 0),) + tuple((a // self.block, b // self.block) for a, b in pad[1:]))
        added = self.codes.shape[1] * self.codes.shape[2] - g.rows * g.cols
        self.counts[:, 128] += added
        self.agreed_counts[128] += added
        rows, cols = np.divmod(self.disputed_cells.astype(np.int64), g.cols)
        self.status = np.pad(self.status, pad[1:])
        self._forget_expected_map()
        self._position = np.pad(self._position, pad[1:], constant_values=-1)
        for part in self._scratch:
            part.grow(pad[1:])
        self.geometry = GridGeometry(g.resolution, g.origin_x - left * cells * g.resolution,
                                     g.origin_y - down * cells * g.resolution, self.codes.shape[1],
                                     self.codes.shape[2])
        n = self._n_disputed
        self._disputed = np.empty(self.geometry.rows * self.geometry.cols, dtype=np.int32)
        self._disputed[:n] = (rows + down * cells) * self.geometry.cols + cols + left * cells
        return True


def _flat(array: np.ndarray, *shape: int) -> np.ndarray:
    """A view of ``array`` with its two grid axes (after the leading ``shape[:1]``) joined; never a copy
    (writes through it must reach ``array``: a layout that would need one raises)."""
    view = array.view()
    view.shape = (*shape[:1], -1, *shape[1:])
    return view


class _InsertionScratch:
    """One insertion thread's working memory: which cells its particles' rays updated in this scan
    (``stamp``, see ``_kernels.insert_scans``), the flat indices of those cells and its serial."""

    def __init__(self, shape: tuple[int, int]):
        self.stamp = np.zeros(shape, dtype=np.int64)
        self.touched = np.empty(shape[0] * shape[1], dtype=np.int32)
        self.serial = 0
        self.n_touched = 0

    def grow(self, pad) -> None:
        self.stamp = np.pad(self.stamp, pad)
        self.touched = np.empty(self.stamp.size, dtype=np.int32)


class _PhaseClock:
    """Wall time of consecutive phases, in milliseconds."""

    def __init__(self):
        self.laps: dict[str, float] = {}
        self._last = time.perf_counter()

    def lap(self, name: str) -> None:
        now = time.perf_counter()
        self.laps[name] = 1e3 * (now - self._last)
        self._last = now
