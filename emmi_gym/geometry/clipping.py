"""Clipping a segment to a box (Liang and Barsky, "A new concept and method for line clipping", ACM
Transactions on Graphics 3(1), 1984): what samples a path, a ray or a drawn line visits only the part
that lies over the map, so its cost is bounded by the map, never by the coordinates it is given (a
lost pose estimate can put a path a thousand kilometres off)."""

from __future__ import annotations

import numba as nb


@nb.njit(cache=True)
def clip_segment(ax, ay, dx, dy, t0, t1, lo_x, hi_x, lo_y, hi_y):
    """The part ``[t0, t1]`` of the segment ``(ax, ay) + t (dx, dy)``, ``t`` in the given ``[t0, t1]``, that
    lies in the box ``[lo_x, hi_x] x [lo_y, hi_y]``; ``t0 > t1`` where none does."""
    for delta, low, high, origin in ((dx, lo_x, hi_x, ax), (dy, lo_y, hi_y, ay)):
        if delta == 0.0:
            if origin < low or origin > high:
                t1 = -1.0
        else:
            a, b = (low - origin) / delta, (high - origin) / delta
            t0, t1 = max(t0, min(a, b)), min(t1, max(a, b))
    return t0, t1
