"""Numba kernels of the RBPF's maps: scan rays and their insertion (matching: ``_matching``).

Hot loops only; each has a plain-Python twin in ``tests/slam/test_slam_kernels.py``.
Grid coordinates: ``g = (world - origin) / resolution``; cell (row, col) = (floor(gy), floor(gx)).
Maps are int8 codes of log-odds (see ``sensor_model``): > 0 occupied, < 0 free, 0 unknown.
Beside them, ``hits`` (M, H, W, 3) int8 keeps for each cell the mean position of the beam
end points that fell in it (x and y offsets from the cell centre in 1/254 of a cell)
and how many (capped), as GMapping's point accumulators do: the scan matcher measures
distances to these means, not to cell centres, so its accuracy is not that of the grid.
And ``coarse`` (M, ceil(H / block), ceil(W / block)) counts the occupied cells (code > 0)
of each block of ``block x block`` cells, for the matcher's coarse stage.
"""


from __future__ import annotations

import math

import numba as nb
import numpy as np

from ._memory import copy_rows, prefetch_row

#: Cells remember the mean of their last this-many hits (a running mean with a capped count).
HIT_COUNT_CAP = 32
OFFSET_SCALE = 254.0


@nb.njit(cache=True, inline="always")
def _add_clamped(grid, counts, coarse, block, row, col, increment, clamp):
    """grid[row, col] += increment within +-clamp, keeping the grid's code histogram ``counts`` and
    its count of occupied cells per block ``coarse`` current."""
    old = np.int16(grid[row, col])
    v = old + increment
    if v > clamp:
        v = clamp
    elif v < -clamp:
        v = -clamp
    grid[row, col] = v
    counts[old + 128] -= 1
    counts[v + 128] += 1
    if (old > 0) != (v > 0):
        coarse[row // block, col // block] += 1 if v > 0 else -1


#: Kinds of insertion rays: a beam's hit (end cell occupied), a ray that frees its whole
#: length (max-range reading), a ray that frees up to but not its end cell (a sub-ray).
RAY_HIT, RAY_FREE, RAY_BOUNDED = 0, 1, 2


@nb.njit(cache=True)
def scan_rays(ranges, angles, gaps, max_range, free_lengths, resolution):
    """The rays that insert one scan as its polygon: each beam, plus sub-rays across the gap to the next.

    A gap of ``gaps[b]`` radians after beam b (0 for a last beam without neighbour) gets
    sub-rays no more than one cell apart at the far end (at most 16), so that every cell
    of the scanned area is crossed whatever the resolution (MRPT's widened beams). A
    sub-ray reaches as far as the nearer of the two beams (each beam's own length: its
    range, or ``free_lengths[b]`` for one that hits nothing within ``max_range``), and only
    frees cells, up to but not its end cell: only real end points claim occupancy, and a
    sub-ray never enters a shadow. A length interpolated between the two beams, as on a
    continuous surface, would reach past a far wall seen at a slant wherever the range noise
    put it a cell further, and free that wall's cells between end points (which get no hit
    from the same scan) more often than they are hit.

    A sub-ray starts only where it is needed: where the rays already there, between which it
    lies, are a cell apart. The sub-rays of a gap bisect it in turn (first the one halfway
    between the beams, then those halfway between it and each beam, ...); the rays either
    side of a sub-ray k/c of the way across are (hi - lo) / c * gap apart, and cross every
    cell between them up to the distance ``resolution * c / ((hi - lo) * gap)`` (a cell at
    distance r spans more than ``resolution / r`` radians as seen from the laser), where the
    sub-ray starts. It starts at most two cells before its end, so that it still crosses the
    cells next to the end cells of its neighbours, which are not freed. The same cells are
    freed as by sub-rays from the laser (the insertion's tests compare with those), without
    walking the cells near the laser again on long beams.
    Returns (angle offsets, lengths, kinds, start distances) of all rays, relative to the
    laser heading; kinds are RAY_HIT, RAY_FREE or RAY_BOUNDED; a beam starts at 0.
    """
    n = ranges.size
    total = 0
    counts = np.ones(n, dtype=np.int64)
    lengths = np.empty(n)
    for b in range(n):
        lengths[b] = ranges[b] if 0.0 < ranges[b] < max_range else (free_lengths[b] if ranges[b] > 0.0 else 0.0)
    for b in range(n):
        if gaps[b] > 0.0:
            far = max(lengths[b], lengths[(b + 1) % n])
            counts[b] = min(16, max(1, int(math.ceil(far * gaps[b] / resolution))))
        total += counts[b]
    ray_angles = np.empty(total)
    ray_lengths = np.empty(total)
    ray_kinds = np.empty(total, dtype=np.int64)
    ray_starts = np.zeros(total)
    k = 0
    for b in range(n):
        hit = 0.0 < ranges[b] < max_range
        nearer = min(lengths[b], lengths[(b + 1) % n])
        for j in range(counts[b]):
            ray_angles[k] = angles[b] + j / counts[b] * gaps[b]
            if j == 0:
                ray_lengths[k] = lengths[b]
                ray_kinds[k] = RAY_HIT if hit else RAY_FREE
            else:
                ray_lengths[k] = nearer
                ray_kinds[k] = RAY_BOUNDED
                ray_starts[k] = max(0.0, min(_bisection_start(j, counts[b], gaps[b], resolution),
                                             nearer - 2.0 * resolution))
            k += 1
    return ray_angles, ray_lengths, ray_kinds, ray_starts


@nb.njit(cache=True, inline="always")
def _bisection_start(j, count, gap, resolution):
    """Where sub-ray ``j`` of a gap split in ``count`` is needed (see :func:`scan_rays`): the distance at
    which the two rays it bisects, ``lo`` and ``hi`` of the count, are one cell apart."""
    lo, hi = 0, count
    mid = (lo + hi) // 2
    while mid != j:
        if j < mid:
            hi = mid
        else:
            lo = mid
        mid = (lo + hi) // 2
    return resolution * count / ((hi - lo) * gap)


@nb.njit(cache=True, inline="always")
def _accumulate_hit(cell, gx, gy, col, row):
    """Fold an end point at grid coordinates (gx, gy) into its cell's running mean."""
    n = np.int32(cell[2]) + 1
    if n > HIT_COUNT_CAP:
        n = HIT_COUNT_CAP
    for axis in range(2):
        offset = (gx - col - 0.5) if axis == 0 else (gy - row - 0.5)
        old = np.float64(cell[axis]) / OFFSET_SCALE
        new = old + (offset - old) / n
        cell[axis] = np.int8(round(max(-0.5, min(0.5, new)) * OFFSET_SCALE))
    cell[2] = n


@nb.njit(cache=True, nogil=True)
def insert_scans(start, stop, codes, hits, ever_hit, counts, coarse, block, poses, ray_angles, ray_lengths, ray_kinds,
                 ray_starts, inc_occupied, inc_free, clamp, origin_x, origin_y, resolution, stamp, serial, touched):
    """Insert one scan, given as rays (see :func:`scan_rays`), into the grid of each particle in
    [start, stop) at its pose.

    Eq. (4) in log-odds with the paper's peaked model (Fig. 2): per particle and scan a
    cell is updated at most once, ``inc_occupied`` if some hit ray ends in it, else
    ``inc_free`` if some ray crosses it before its end (exact cell traversal, Amanatides
    & Woo, from the ray's start distance; a RAY_FREE ray frees its end cell too). Hit end points
    also update their cell's mean hit position and set its flag in ``ever_hit`` (H, W), shared by
    all grids (threads may set one flag at once: the same value; a flag is never cleared, so a cell
    without one has no mean hit point in any grid), and ``counts`` (M, 256), how many cells of each
    grid hold each code (index code + 128), and ``coarse``, the occupied cells per block, follow
    every change.

    The flat indices of the cells the scan **changed** in some grid of the chunk (an end point's
    cell, or a crossed cell whose code moved) go to ``touched`` (size H * W), each once, and their
    number is returned with the new ``serial``: a crossed cell that every grid already held at the
    free clamp keeps its code and its agreement, so the caller need not look at it again (in a
    mapped area, most of the cells a scan crosses).
    ``stamp`` (H, W) int64 remembers which cells this scan already updated, and whether they are
    listed: ``serial`` grows by 3 per particle, whose ids are serial + 1 (an end point's cell,
    listed), serial + 2 (a crossed cell, not listed) and serial + 3 (a crossed cell, listed); a
    stamp at or below the call's first serial was left by an earlier scan (:func:`_listed`). Chunks
    of particles may run on parallel threads, each with its own ``stamp`` and ``touched`` (see
    :func:`merge_touched`).
    """
    h, w = codes.shape[1], codes.shape[2]
    n_rays = ray_angles.size
    first = serial  # stamps at or below this were left by earlier scans
    n_touched = 0
    for i in range(start, stop):
        grid = codes[i]
        hit_id = serial + 1
        free_id = serial + 2  # + 1 once listed
        serial += 3
        gx0 = (poses[i, 0] - origin_x) / resolution
        gy0 = (poses[i, 1] - origin_y) / resolution
        for b in range(n_rays):  # end points first: they win over crossings
            if ray_kinds[b] != RAY_HIT:
                continue
            a = poses[i, 2] + ray_angles[b]
            gx = gx0 + ray_lengths[b] * math.cos(a) / resolution
            gy = gy0 + ray_lengths[b] * math.sin(a) / resolution
            col, row = int(math.floor(gx)), int(math.floor(gy))
            if not (0 <= row < h and 0 <= col < w):
                continue
            _accumulate_hit(hits[i, row, col], gx, gy, col, row)
            if not ever_hit[row, col]:  # written once: threads that write a shared line take turns for it
                ever_hit[row, col] = True
            if stamp[row, col] != hit_id:
                if not _listed(stamp[row, col], first):
                    touched[n_touched] = row * w + col
                    n_touched += 1
                stamp[row, col] = hit_id
                _add_clamped(grid, counts[i], coarse[i], block, row, col, inc_occupied, clamp)
        if not (0.0 <= gx0 < w and 0.0 <= gy0 < h):
            continue  # a laser off the grid frees nothing: its rays stop at once (a late start may not)
        for b in range(n_rays):
            length = ray_lengths[b]
            if length <= 0.0 or ray_starts[b] >= length:
                continue
            keep_end = ray_kinds[b] != RAY_FREE
            a = poses[i, 2] + ray_angles[b]
            c, s = math.cos(a), math.sin(a)
            ex = gx0 + length * c / resolution
            ey = gy0 + length * s / resolution
            sx = gx0 + ray_starts[b] * c / resolution
            sy = gy0 + ray_starts[b] * s / resolution
            cx, cy = int(math.floor(sx)), int(math.floor(sy))
            end_x, end_y = int(math.floor(ex)), int(math.floor(ey))
            dx, dy = ex - gx0, ey - gy0
            step_x = 1 if dx > 0 else -1
            step_y = 1 if dy > 0 else -1
            t_dx = abs(1.0 / dx) if dx != 0.0 else np.inf
            t_dy = abs(1.0 / dy) if dy != 0.0 else np.inf
            t_x = ((cx + 1 - sx) if dx > 0 else (sx - cx)) * t_dx if dx != 0.0 else np.inf
            t_y = ((cy + 1 - sy) if dy > 0 else (sy - cy)) * t_dy if dy != 0.0 else np.inf
            n_steps = abs(end_x - cx) + abs(end_y - cy)
            for k in range(n_steps + 1):
                if k == n_steps and keep_end:
                    break
                if not (0 <= cy < h and 0 <= cx < w):
                    break
                if stamp[cy, cx] < hit_id:
                    listed = _listed(stamp[cy, cx], first)
                    # inc_free < 0 moves the code unless it sits at the clamp, as most cells a scan crosses
                    # in a mapped area do: those keep their code, histogram and block count untouched
                    changed = grid[cy, cx] > -clamp
                    if changed:
                        _add_clamped(grid, counts[i], coarse[i], block, cy, cx, inc_free, clamp)
                        if not listed:
                            touched[n_touched] = cy * w + cx
                            n_touched += 1
                    stamp[cy, cx] = free_id + 1 if listed or changed else free_id
                if t_x < t_y:
                    cx += step_x
                    t_x += t_dx
                else:
                    cy += step_y
                    t_y += t_dy
    return serial, n_touched


@nb.njit(cache=True, inline="always")
def _listed(stamp, first):
    """Whether a cell stamped ``stamp`` by :func:`insert_scans` (``first``: the call's first serial) is in
    its ``touched`` list: stamped in this call with an end point's id (first + 3j + 1) or a listed
    crossing's (first + 3j + 3), or appended by :func:`merge_touched` (first + 1)."""
    return stamp > first and (stamp - first) % 3 != 2


@nb.njit(cache=True)
def merge_touched(touched, n_touched, stamp, first, other, n_other):
    """Append to ``touched[:n_touched]`` the cells of ``other[:n_other]`` it lacks; whether a cell is listed
    there is told by ``stamp`` of the chunk that filled ``touched`` (:func:`_listed`), and a cell appended
    is stamped listed. Returns the new length."""
    w = stamp.shape[1]
    mark = first + 1
    for k in range(n_other):
        cell = other[k]
        row = cell // w
        col = cell - row * w
        if not _listed(stamp[row, col], first):
            stamp[row, col] = mark
            touched[n_touched] = cell
            n_touched += 1
    return n_touched


#: ``status`` of a cell on which the particles' grids differ (agreeing cells hold their common code).
DISPUTED = 1000
#: Flagged cells ahead whose mean hit points :func:`agreement_of_hits` asks the caches for
#: (``prefetch_row``): far enough for the cache misses to overlap, near enough to stay cached.
PREFETCH_AHEAD = 32


@nb.njit(cache=True, inline="always")
def _same_hit(hits, i, first, cell):
    """Whether grids ``i`` and ``first`` hold the same mean hit point at ``cell``."""
    return hits[i, cell, 0] == hits[first, cell, 0] and hits[i, cell, 1] == hits[first, cell, 1] and \
        hits[i, cell, 2] == hits[first, cell, 2]


@nb.njit(cache=True, inline="always")
def _agrees(codes, hits, ever_hit, particles, cell):
    """Whether the grids of ``particles`` hold the same code and the same mean hit point at ``cell`` (the
    mean hit points are compared only where ``ever_hit``: elsewhere they are all zero)."""
    first = particles[0]
    c0 = codes[first, cell]
    hit = ever_hit[cell]
    for j in range(1, particles.size):
        i = particles[j]
        if codes[i, cell] != c0 or (hit and not _same_hit(hits, i, first, cell)):
            return False
    return True


@nb.njit(cache=True, nogil=True)
def agreement_of_cells(start, stop, codes, hits, ever_hit, particles, cells, out, rows):
    """``out[k]``, for k in [start, stop): the code the grids of ``particles`` share at ``cells[k]`` (with
    the same mean hit point), or DISPUTED; for a disputed cell ``rows[k]`` takes its code in every grid.
    The grids come as flat views, ``codes`` (M, N) and ``hits`` (M, N, 3), with the flat ``ever_hit``
    (N) of :func:`insert_scans`; chunks of cells may run on parallel threads."""
    for k in range(start, stop):
        cell = cells[k]
        if _agrees(codes, hits, ever_hit, particles, cell):
            out[k] = codes[particles[0], cell]
        else:
            out[k] = DISPUTED
            for i in range(codes.shape[0]):
                rows[k, i] = codes[i, cell]


@nb.njit(cache=True, nogil=True)
def agreement_of_hits(start, stop, codes, hits, ever_hit, particles, cells, out):
    """As :func:`agreement_of_cells` for cells whose codes are known to agree in every grid (after a
    resampling, from the disputed cells' table): only the mean hit points are compared, and only where
    ``ever_hit`` (most cells that come to agree lie in open space, where no scan ever ended). The
    flagged cells are listed first, without a branch (a cell is written at the next free place, which
    moves on only for a flagged one), then compared: a branch on the flag per cell would be a coin
    toss to the branch predictor."""
    first = particles[0]
    flagged = np.empty(stop - start, dtype=np.int32)
    n = 0
    for k in range(start, stop):
        cell = cells[k]
        out[k] = codes[first, cell]
        flagged[n] = k
        n += ever_hit[cell]
    for f in range(n):
        if f + PREFETCH_AHEAD < n:
            for j in range(particles.size):
                prefetch_row(hits[particles[j]], cells[flagged[f + PREFETCH_AHEAD]])
        k = flagged[f]
        cell = cells[k]
        for j in range(1, particles.size):
            if not _same_hit(hits, particles[j], first, cell):
                out[k] = DISPUTED
                break


@nb.njit(cache=True, inline="always")
def _unlist(cell, disputed, table, n_disputed, position):
    """Take listed ``cell`` out of the disputed list and the table: the last entry takes its place.
    Returns the new length of the list."""
    p = position[cell]
    n_disputed -= 1
    last = disputed[n_disputed]
    disputed[p] = last
    if p != n_disputed:  # memcpy's regions must not overlap
        copy_rows(table[p], table[n_disputed], 0, table.shape[1])
    position[last] = p
    position[cell] = -1
    return n_disputed


@nb.njit(cache=True)
def record_agreement(cells, agreement, rows, status, agreed_counts, disputed, table, n_disputed, position):
    """Store the agreement of ``cells`` (flat indices, no repeats; ``agreement`` and ``rows`` from
    :func:`agreement_of_cells`) in the flat ``status``, keeping its bookkeeping current.

    ``status`` holds an agreed cell's code, or DISPUTED; ``agreed_counts`` (256) how many
    agreed cells hold each code (index code + 128); ``disputed[:n_disputed]`` lists the
    disputed cells (flat indices, in the order they were listed and unlisted: a function of
    the calls, whatever the number of threads), ``table[k]`` the codes of cell ``disputed[k]``
    in every grid, and ``position`` each cell's place in that list (-1: not listed). Returns
    the new length of the list.
    """
    for k in range(cells.size):
        cell = cells[k]
        old, code = status[cell], agreement[k]
        if old != DISPUTED:
            agreed_counts[old + 128] -= 1
        status[cell] = code
        p = position[cell]
        if code != DISPUTED:
            agreed_counts[code + 128] += 1
            if p >= 0:
                n_disputed = _unlist(cell, disputed, table, n_disputed, position)
        else:
            if p < 0:
                p = n_disputed
                disputed[p] = cell
                position[cell] = p
                n_disputed += 1
            copy_rows(table[p], rows[k], 0, table.shape[1])
    return n_disputed


@nb.njit(cache=True, nogil=True)
def unlist_agreed(cells, agreement, status, agreed_counts, disputed, table, n_disputed, position):
    """After a resampling: record the agreed ones among ``cells`` (all listed as disputed; ``agreement``
    from :func:`agreement_of_hits`) as :func:`record_agreement` would, and drop them from the list
    and the table: each hole filled from the list's end when few go, or, when many go (as at a
    loop's closure), in one pass that reads the list front to back. Returns the new length. It
    touches no grid, so it may run on a thread beside :func:`resample_cells`."""
    agreed = 0
    for k in range(cells.size):
        code = agreement[k]
        if code != DISPUTED:
            status[cells[k]] = code
            agreed_counts[code + 128] += 1
            agreed += 1
    if 2 * agreed < n_disputed:
        for k in range(cells.size):
            if agreement[k] != DISPUTED:
                n_disputed = _unlist(cells[k], disputed, table, n_disputed, position)
        return n_disputed
    kept = 0
    for k in range(n_disputed):
        cell = disputed[k]
        if status[cell] == DISPUTED:
            if kept != k:
                disputed[kept] = cell
                copy_rows(table[kept], table[k], 0, table.shape[1])
                position[cell] = kept
            kept += 1
        else:
            position[cell] = -1
    return kept


@nb.njit(cache=True)
def sorted_cells(cells):
    """``cells`` (non-negative int32 flat indices) in increasing order: an LSD radix sort, 11 bits a
    pass (far faster than a comparison sort on hundreds of thousands of cells)."""
    out, spare = cells.copy(), np.empty_like(cells)
    top = out.max() if out.size else 0
    shift = 0
    while shift < 32 and (shift == 0 or (top >> shift) > 0):
        starts = np.zeros(2049, dtype=np.int64)
        for c in out:
            starts[((c >> shift) & 2047) + 1] += 1
        for d in range(2048):
            starts[d + 1] += starts[d]
        for c in out:
            d = (c >> shift) & 2047
            spare[starts[d]] = c
            starts[d] += 1
        out, spare = spare, out
        shift += 11
    return out


@nb.njit(cache=True, nogil=True)
def resample_rows(start, stop, table, parents, cells, candidates):
    """Rows ``table[start:stop]`` (the codes of the disputed cells ``cells[k]`` in every grid) after
    particle i took the grid of ``parents[i]`` (survivors keep their own: ``parents[parents] ==
    parents``). The cells whose codes now agree in every grid go to ``candidates[start:]`` (their
    mean hit points may still differ); returns how many. The others stay disputed without
    reading a grid. Chunks of rows may run on parallel threads. Unsigned column indices (no
    wraparound test, see ``certainty._kernels.expected_at``) and no branch on whether a row agrees
    (every cell is written at the next free place)."""
    m = table.shape[1]
    n = start
    for k in range(start, stop):
        first = table[k, np.uint64(parents[0])]
        same = True
        for i in range(m):  # parents[i] survives: its column is written only with its own code
            code = table[k, np.uint64(parents[i])]
            table[k, i] = code
            same &= code == first
        candidates[n] = cells[k]
        n += same
    return n - start


#: Disputed cells of one row at most this many cells apart are copied as one span at resampling (the
#: agreed cells between hold the same values in every grid, so copying them changes nothing): shorter
#: gaps make more ``memcpy`` calls, longer ones copy more cells.
SPAN_GAP = 64


@nb.njit(cache=True)
def copy_spans(cells, width, block, max_gap):
    """(S, 4) spans covering ``cells`` (flat indices, increasing) in grids of rows of ``width`` cells: per
    span, flat cells ``[start, stop)`` within one row (cells of a row at most ``max_gap`` apart join one
    span), and the flat indices ``[start, stop)`` of the blocks of ``block x block`` cells that they
    reach in the grid of blocks (``coarse``, rows of ``ceil(width / block)`` blocks)."""
    n, row_end, last = 0, 0, 0
    for k in range(cells.size):  # count the spans first: a buffer of one span per cell is fresh memory
        cell = cells[k]
        if not (cell < row_end and cell - last < max_gap):
            row_end = (cell // width + 1) * width
            n += 1
        last = cell + 1
    spans = np.empty((n, 4), dtype=np.int64)
    n, row_end, blocks_per_row = 0, 0, -(-width // block)
    for k in range(cells.size):
        cell = cells[k]
        if cell < row_end and cell - spans[n - 1, 1] < max_gap:
            spans[n - 1, 1] = cell + 1
        else:
            spans[n, 0], spans[n, 1] = cell, cell + 1
            row_end = (cell // width + 1) * width
            n += 1
    for s in range(n):
        row = spans[s, 0] // width
        first_block = (row // block) * blocks_per_row
        spans[s, 2] = first_block + (spans[s, 0] - row * width) // block
        spans[s, 3] = first_block + (spans[s, 1] - 1 - row * width) // block + 1
    return spans[:n]


@nb.njit(cache=True, nogil=True)
def resample_cells(start, stop, codes, hits, coarse, spans, dead, parents):
    """Each particle i of ``dead[start:stop]`` takes particle ``parents[i]``'s codes, mean hit points and
    occupied-cell counts per block on the ``spans`` (:func:`copy_spans` of the disputed cells).

    The grids come as flat views: ``codes`` (M, N), ``hits`` (M, N, 3), ``coarse`` (M, blocks).
    Outside the spans every grid already holds the same values, so afterwards grid i equals
    its parent's everywhere, and so do the counts of every block a span reaches (the other
    blocks hold agreed cells only). ``parents`` keeps survivors in place
    (``parents[parents[i]] == parents[i]``), so a source is never overwritten, and chunks of
    the dead particles (split among them, not among all particles: the dead are not spread
    evenly) may run on parallel threads.
    """
    for i in dead[start:stop]:
        p = parents[i]
        for s in range(spans.shape[0]):
            copy_rows(codes[i], codes[p], spans[s, 0], spans[s, 1])
            copy_rows(hits[i], hits[p], spans[s, 0], spans[s, 1])
            copy_rows(coarse[i], coarse[p], spans[s, 2], spans[s, 3])
