"""Numba kernels: first hit of rays against capsules (pymunk segment shapes with a radius).

They give what ``pymunk.Space.segment_query_first`` gives for a zero-radius query
against ``pymunk.Segment`` shapes, for all beams of a scan in one call (pymunk costs
~10 us of Python per query). ``tests/world/test_world.py`` checks them against pymunk.

The capsules are bucketed once in a uniform grid (:func:`capsule_grid`); each beam walks
the grid's cells in the order it crosses them (Amanatides and Woo, "A fast voxel
traversal algorithm for ray tracing", 1987) and stops once its nearest hit lies inside
the cells already walked, so a scan costs what lies along the beams, not the number of
walls in the world (a building traced from a real log has thousands of segments).
"""

from __future__ import annotations

import math

import numba as nb
import numpy as np


@nb.njit(cache=True, inline="always")
def _ray_circle(ox, oy, dx, dy, cx, cy, r):
    """Smallest t >= 0 with |o + t d - c| = r (d unit), or inf."""
    fx, fy = ox - cx, oy - cy
    b = fx * dx + fy * dy
    c = fx * fx + fy * fy - r * r
    if c <= 0.0:
        return 0.0  # the origin is inside the circle
    disc = b * b - c
    if disc < 0.0:
        return np.inf
    t = -b - math.sqrt(disc)
    return t if t >= 0.0 else np.inf


#: Side of the buckets (m), unless the world is so large that they would exceed MAX_BUCKETS.
BUCKET_SIZE = 0.5
MAX_BUCKETS = 1_000_000


@nb.njit(cache=True, inline="always")
def _capsule_hit(ox, oy, dx, dy, capsules, w, best):
    """The nearer of ``best`` and the distance along the ray to capsule ``w`` (its two end circles and two sides)."""
    ax, ay, bx, by, r = capsules[w, 0], capsules[w, 1], capsules[w, 2], capsules[w, 3], capsules[w, 4]
    ex, ey = bx - ax, by - ay
    length = math.sqrt(ex * ex + ey * ey)
    t = _ray_circle(ox, oy, dx, dy, ax, ay, r)
    if t < best:
        best = t
    t = _ray_circle(ox, oy, dx, dy, bx, by, r)
    if t < best:
        best = t
    nx, ny = -ey / length, ex / length
    denom = dx * nx + dy * ny
    if abs(denom) > 1e-12:
        dist0 = (ox - ax) * nx + (oy - ay) * ny  # signed distance of the origin to the centre line
        for side in (-1.0, 1.0):
            t = (side * r - dist0) / denom
            if 0.0 <= t < best:
                px, py = ox + t * dx - ax, oy + t * dy - ay
                u = (px * ex + py * ey) / (length * length)
                if 0.0 <= u <= 1.0:
                    best = t
    return best


@nb.njit(cache=True)
def _bucket_capsules(capsules, x0, y0, size, rows, cols, fill, starts, items):
    """Count (``fill`` False) or list (True) the capsules of each bucket: those whose distance to the bucket's
    centre is at most their radius plus half the bucket's diagonal (a conservative test)."""
    half_diagonal = size * math.sqrt(0.5)
    for w in range(capsules.shape[0]):
        ax, ay, bx, by, r = capsules[w, 0], capsules[w, 1], capsules[w, 2], capsules[w, 3], capsules[w, 4]
        reach = r + half_diagonal
        c0 = max(int(math.floor((min(ax, bx) - reach - x0) / size)), 0)
        c1 = min(int(math.floor((max(ax, bx) + reach - x0) / size)), cols - 1)
        r0 = max(int(math.floor((min(ay, by) - reach - y0) / size)), 0)
        r1 = min(int(math.floor((max(ay, by) + reach - y0) / size)), rows - 1)
        ex, ey = bx - ax, by - ay
        length2 = max(ex * ex + ey * ey, 1e-300)
        for row in range(r0, r1 + 1):
            cy = y0 + (row + 0.5) * size
            for col in range(c0, c1 + 1):
                cx = x0 + (col + 0.5) * size
                u = min(max(((cx - ax) * ex + (cy - ay) * ey) / length2, 0.0), 1.0)
                if math.hypot(cx - ax - u * ex, cy - ay - u * ey) <= reach:
                    cell = row * cols + col
                    if fill:
                        items[starts[cell]] = w
                    starts[cell + 1 if not fill else cell] += 1


def capsule_grid(capsules: np.ndarray, bounds) -> tuple:
    """The buckets of :func:`cast_rays`: (x0, y0, size, rows, cols, starts, items) covering ``bounds`` and the
    capsules; bucket ``row * cols + col`` lists ``items[starts[cell]:starts[cell + 1]]``."""
    ends = np.vstack([capsules[:, 0:2], capsules[:, 2:4], np.reshape(bounds, (2, 2))])
    pad = (float(capsules[:, 4].max()) if len(capsules) else 0.0) + 1.0
    lo, hi = ends.min(axis=0) - pad, ends.max(axis=0) + pad
    size = max(BUCKET_SIZE, math.sqrt(float(np.prod(hi - lo)) / MAX_BUCKETS))
    cols, rows = (int(math.ceil(v / size)) for v in hi - lo)
    counts = np.zeros(rows * cols + 1, dtype=np.int64)
    _bucket_capsules(capsules, lo[0], lo[1], size, rows, cols, False, counts, np.zeros(0, dtype=np.int64))
    starts = np.cumsum(counts)  # counts[c + 1] held bucket c's count: starts[c] is where its list begins
    items = np.empty(int(starts[-1]), dtype=np.int64)
    cursor = starts.copy()
    _bucket_capsules(capsules, lo[0], lo[1], size, rows, cols, True, cursor, items)
    return float(lo[0]), float(lo[1]), float(size), rows, cols, starts, items


@nb.njit(cache=True)
def cast_rays(ox, oy, angles, max_range, capsules, x0, y0, size, rows, cols, starts, items, out):
    """out[k] = distance along the ray at ``angles[k]`` from (ox, oy) to the first capsule, or max_range.

    ``capsules`` is (K, 5): ax, ay, bx, by, radius; the rest is their :func:`capsule_grid`.
    A capsule is the set of points within ``radius`` of segment ab. An origin outside the
    grid tests every capsule.
    """
    seen = np.zeros(capsules.shape[0], dtype=np.int64)  # the last beam that tested each capsule
    col0, row0 = int(math.floor((ox - x0) / size)), int(math.floor((oy - y0) / size))
    inside = 0 <= col0 < cols and 0 <= row0 < rows
    for k in range(angles.size):
        dx = math.cos(angles[k])
        dy = math.sin(angles[k])
        best = max_range
        if not inside:
            for w in range(capsules.shape[0]):
                best = _capsule_hit(ox, oy, dx, dy, capsules, w, best)
            out[k] = best
            continue
        col, row = col0, row0
        step_col = 1 if dx > 0 else -1
        step_row = 1 if dy > 0 else -1
        next_col = (x0 + (col + (1 if dx > 0 else 0)) * size - ox) / dx if dx != 0.0 else np.inf
        next_row = (y0 + (row + (1 if dy > 0 else 0)) * size - oy) / dy if dy != 0.0 else np.inf
        delta_col = size / abs(dx) if dx != 0.0 else np.inf
        delta_row = size / abs(dy) if dy != 0.0 else np.inf
        while True:
            cell = row * cols + col
            for j in range(starts[cell], starts[cell + 1]):
                w = items[j]
                if seen[w] != k + 1:
                    seen[w] = k + 1
                    best = _capsule_hit(ox, oy, dx, dy, capsules, w, best)
            leave = min(next_col, next_row)
            if best <= leave or leave >= max_range:
                break
            if next_col < next_row:
                col += step_col
                next_col += delta_col
            else:
                row += step_row
                next_row += delta_row
            if not (0 <= col < cols and 0 <= row < rows):
                break
        out[k] = best
