"""Numba kernel: first hit of rays against capsules (pymunk segment shapes with a radius).

It gives what ``pymunk.Space.segment_query_first`` gives for a zero-radius query
against ``pymunk.Segment`` shapes, for all beams of a scan in one call (pymunk costs
~10 us of Python per query). ``tests/test_world.py`` checks it against pymunk.
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


@nb.njit(cache=True)
def cast_rays(ox, oy, angles, max_range, capsules, out):
    """out[k] = distance along the ray at ``angles[k]`` from (ox, oy) to the first capsule, or max_range.

    ``capsules`` is (K, 5): ax, ay, bx, by, radius. A capsule is the set of points
    within ``radius`` of segment ab: its two end circles and its two side lines.
    The capsules are first sorted by a lower bound of their distance from the origin
    (centre distance less half the length and the radius), dropping those beyond
    ``max_range``; a beam then stops at the first capsule whose bound exceeds its best hit,
    so a scan costs what lies near the robot, not the whole world's walls.
    """
    k_all = capsules.shape[0]
    bound = np.empty(k_all)
    for w in range(k_all):
        ax, ay, bx, by, r = capsules[w, 0], capsules[w, 1], capsules[w, 2], capsules[w, 3], capsules[w, 4]
        mx, my = 0.5 * (ax + bx) - ox, 0.5 * (ay + by) - oy
        bound[w] = math.sqrt(mx * mx + my * my) - 0.5 * math.sqrt((bx - ax) ** 2 + (by - ay) ** 2) - r
    order = np.argsort(bound)
    n_near = 0
    while n_near < k_all and bound[order[n_near]] <= max_range:
        n_near += 1
    for k in range(angles.size):
        dx = math.cos(angles[k])
        dy = math.sin(angles[k])
        best = max_range
        for i in range(n_near):
            w = order[i]
            if bound[w] > best:
                break
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
        out[k] = best
