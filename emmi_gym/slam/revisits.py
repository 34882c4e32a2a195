"""Places seen again: which beams of a new scan end where the scans came back to after a gap.

A particle's map of the last few updates was built from that particle's own poses, so a new
scan fits it about equally well whatever the particle's path; the differences in that fit
are the map's discretisation noise, correlated from one update to the next (overlapping
scans meet the same map again), and weights computed on every beam re-count them update after
update until the particle set resamples along a plain corridor. Beams that end where the scans
came back to after many updates test each particle's whole path since: that is the evidence a
loop closure brings.
``RBPFConfig.revisit_exponent`` weighs those beams, ``likelihood_exponent`` the rest (the
proposal, the scan match, uses every beam).

One grid shared by the particles, in blocks of the maps' coarse stage: the update at which
a scan's end points (taken at the best particle's pose) last fell in each block or within
``reach`` blocks of it, and whether the block was ever reached again ``gap`` or more updates
after it last had been (seen again: it stays so, since the map there still holds what the
earlier visit saw). The same beams are tested for every particle, from the best particle's
predicted pose, so the weights compare like with like.

A laser that reaches across a building sees places again at almost every update (an 8 m
laser in ``loop_corridor``'s corridors, only where the loop closes): ``RBPFConfig.revisit_beams`` then bounds how
much they count, as if at most that many beams saw a place again (:func:`revisit_exponent`).
"""

from __future__ import annotations

import math

import numba as nb
import numpy as np

from ..geometry.grid import GridGeometry


def revisit_exponent(config, seen_again: int) -> float:
    """The exponent of this update's beams that see a place again, ``seen_again`` of them:
    ``config.revisit_exponent``, times ``revisit_beams / seen_again`` when more than
    ``config.revisit_beams`` do (their evidence is not independent: the total counts as that
    many beams' would), never below ``likelihood_exponent``."""
    bound = config.revisit_beams
    if bound is None or seen_again <= bound:
        return config.revisit_exponent
    return max(config.likelihood_exponent, config.revisit_exponent * bound / seen_again)


class RevisitGrid:
    """Per block: the update at which the scans last reached it (``last``, 0: never) and whether it was
    ever reached again after a gap (``again``)."""

    def __init__(self, geometry: GridGeometry, block: int, reach: float):
        self.block = int(block)
        self.side = geometry.resolution * self.block
        self.reach = max(0, int(math.ceil(reach / self.side)))
        self.origin = (geometry.origin_x, geometry.origin_y)
        self.last = np.zeros((-(-geometry.rows // self.block), -(-geometry.cols // self.block)), dtype=np.int32)
        self.again = np.zeros(self.last.shape, dtype=bool)

    def follow(self, geometry: GridGeometry) -> None:
        """Pad to the maps' grown geometry (they grow by whole blocks)."""
        left = int(round((self.origin[0] - geometry.origin_x) / self.side))
        down = int(round((self.origin[1] - geometry.origin_y) / self.side))
        rows, cols = -(-geometry.rows // self.block), -(-geometry.cols // self.block)
        if (left, down, rows, cols) == (0, 0) + self.last.shape:
            return
        window = (slice(down, down + self.last.shape[0]), slice(left, left + self.last.shape[1]))
        last, again = np.zeros((rows, cols), dtype=np.int32), np.zeros((rows, cols), dtype=bool)
        last[window], again[window] = self.last, self.again
        self.last, self.again, self.origin = last, again, (geometry.origin_x, geometry.origin_y)

    def _blocks(self, pose, ranges, angles, max_range) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(rows, cols) of the blocks of the beams' end points, and which beams have an echo inside the grid."""
        echo = (ranges > 0.0) & (ranges < max_range)
        a = pose[2] + angles
        col = np.floor((pose[0] + ranges * np.cos(a) - self.origin[0]) / self.side).astype(np.int64)
        row = np.floor((pose[1] + ranges * np.sin(a) - self.origin[1]) / self.side).astype(np.int64)
        h, w = self.last.shape
        return row, col, echo & (row >= 0) & (row < h) & (col >= 0) & (col < w)

    def stamp(self, pose, ranges, angles, max_range: float, update: int, gap: int) -> None:
        """Record that the scan taken at ``pose`` reached its end points' blocks (and ``reach`` around) at
        ``update``; a block reached again ``gap`` or more updates after it was last reached is revisited
        from then on."""
        row, col, inside = self._blocks(pose, ranges, angles, max_range)
        _stamp_blocks(self.last, self.again, row[inside], col[inside], self.reach, update, gap)

    def revisited(self, pose, ranges, angles, max_range: float, update: int, gap: int) -> np.ndarray:
        """Which beams, from ``pose``, end in a block seen again after a gap, or that this scan, as update
        ``update``, would see again."""
        row, col, inside = self._blocks(pose, ranges, angles, max_range)
        seen = np.zeros(ranges.shape, dtype=np.int64)
        seen[inside] = self.last[row[inside], col[inside]]
        again = np.zeros(ranges.shape, dtype=bool)
        again[inside] = self.again[row[inside], col[inside]]
        return inside & (again | ((seen > 0) & (update - seen >= gap)))


@nb.njit(cache=True)
def _stamp_blocks(last, again, rows, cols, reach, update, gap):
    """Stamp ``update`` on the blocks within ``reach`` of each (row, col); a block last stamped ``gap`` or
    more updates before is seen again (a block met twice in one call is stamped already the second time,
    so the order does not matter)."""
    h, w = last.shape
    for k in range(rows.size):
        for r in range(max(rows[k] - reach, 0), min(rows[k] + reach + 1, h)):
            for c in range(max(cols[k] - reach, 0), min(cols[k] + reach + 1, w)):
                if last[r, c] > 0 and update - last[r, c] >= gap:
                    again[r, c] = True
                last[r, c] = update
