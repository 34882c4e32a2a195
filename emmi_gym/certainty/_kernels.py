"""Numba kernels behind the certainty functions (single thread, cached).

Each kernel has a plain NumPy twin in ``tests/certainty/test_certainty.py``. Grids arrive
flattened as (M, N).
"""

from __future__ import annotations

import math

import numba as nb
import numpy as np

_INV_LN2 = 1.0 / math.log(2.0)


@nb.njit(cache=True, inline="always")
def _entropy_bits(p):
    """Binary entropy H2(p) in bits, eq. (7) with base-2 logs; 0 at p in {0, 1}."""
    p = np.float64(p)  # float32 grids: do the logs in double precision
    if p <= 0.0 or p >= 1.0:
        return 0.0
    q = 1.0 - p
    return -(p * math.log(p) + q * math.log(q)) * _INV_LN2


@nb.njit(cache=True)
def expected_map_probabilities(grids, weights, out):
    """EM, eq. (6): out[j] = sum_i w_i p_ij, particle by particle (memory order, vectorised)."""
    m, n = grids.shape
    out[:] = 0.0
    for i in range(m):
        wi = weights[i]
        if wi == 0.0:
            continue
        row = grids[i]
        for j in range(n):
            out[j] += wi * np.float64(row[j])


@nb.njit(cache=True)
def accumulate_odds(out, weight, exp_minus_logodds):
    """out += weight * p with p = 1 / (1 + exp(-l)): eq. (6) from log-odds.

    The exponentials come from NumPy (vectorised); an overflow to inf gives p = 0.
    """
    for j in range(out.size):
        out[j] += weight / (1.0 + np.float64(exp_minus_logodds[j]))


@nb.njit(cache=True)
def expected_map_codes(grids, weights, lut, offset, out):
    """EM, eq. (6), of integer-coded grids: out[j] = sum_i w_i lut[code_ij + offset].

    The layout MRPT uses for occupancy grids (quantised log-odds + a table of
    probabilities): a gather from a table that stays in L1 cache instead of an
    exponential per cell and particle.
    """
    m, n = grids.shape
    out[:] = 0.0
    for i in range(m):
        wi = weights[i]
        if wi == 0.0:
            continue
        row = grids[i]
        for j in range(n):
            out[j] += wi * lut[np.uint64(np.int64(row[j]) + offset)]  # unsigned: see expected_at


@nb.njit(cache=True, nogil=True)
def expected_at(start, stop, table, weighted, offset, out):
    """Eq. (6) of the cells ``table[start:stop]`` (one row of M codes per cell) into ``out``:
    ``sum_i weighted[i, code_i + offset]``, with ``weighted[i, c]`` = w_i p(c) made beforehand (a few
    KB that stay in L1 cache: one load per code, no multiplication; the same sums, bit for bit, as
    ``sum_i w_i lut[code_i]`` in the same order). The index is made unsigned, so numba leaves out
    its test for a negative index (which wraps round) on every load."""
    for k in range(start, stop):
        p = 0.0
        for i in range(table.shape[1]):
            p += weighted[i, np.uint64(np.int64(table[k, i]) + offset)]  # unsigned: no wraparound test
        out[k] = p


@nb.njit(cache=True)
def beyond_band(p, unobserved_halfwidth, p_out, q_out):
    """Copy the cells of ``p`` farther than ``unobserved_halfwidth`` from 0.5 (the others are surely
    unobserved, eq. 10) into ``p_out``, with ``1 - p`` into ``q_out``; returns how many.

    Without a branch (every cell is written at the next free place, which moves on only for the
    cells kept; ``p_out`` and ``q_out`` hold at least ``p.size``): which cells are kept is a coin
    toss to the branch predictor."""
    n = 0
    for j in range(p.size):
        x = np.float64(p[j])
        p_out[n] = x
        q_out[n] = 1.0 - x
        n += abs(x - 0.5) >= unobserved_halfwidth
    return n


@nb.njit(cache=True)
def information_sum(p, q, log_p, log_q, max_entropy_bits):
    """Map information over the observed cells, eq. (9), and their count, eq. (10), from each cell's
    ``p``, ``q = 1 - p`` and their natural logarithms: a cell is observed when its entropy H2 is
    below ``max_entropy_bits`` (H2 = 0 at p in {0, 1}). Selections, not branches (see
    :func:`beyond_band`); adding 0.0 for a cell not observed leaves the sum as it was."""
    info = 0.0
    n_obs = 0
    for j in range(p.size):
        h = -(p[j] * log_p[j] + q[j] * log_q[j]) * _INV_LN2 if (p[j] > 0.0) & (q[j] > 0.0) else 0.0
        observed = h < max_entropy_bits
        info += (1.0 - h) if observed else 0.0
        n_obs += observed
    return info, n_obs


# Sums below use fastmath so LLVM may reorder the additions (vectorise the reduction);
# the inputs are validated (no NaN) before they get here.
@nb.njit(cache=True, fastmath=True)
def entropy_sum(p):
    """H(m) = sum of H2(p) in bits, eq. (8), of a flat probability grid."""
    h = 0.0
    for j in range(p.size):
        h += _entropy_bits(p[j])
    return h


@nb.njit(cache=True)
def code_histogram(codes, n_codes, offset):
    """How many cells hold each code (index = code + offset), with four interleaved tallies.

    Interleaving breaks the store-to-load chain of a map where most cells share one code.
    """
    tallies = np.zeros((4, n_codes), dtype=np.int64)
    n = codes.size
    j = 0
    while j + 4 <= n:
        tallies[0, np.int64(codes[j]) + offset] += 1
        tallies[1, np.int64(codes[j + 1]) + offset] += 1
        tallies[2, np.int64(codes[j + 2]) + offset] += 1
        tallies[3, np.int64(codes[j + 3]) + offset] += 1
        j += 4
    while j < n:
        tallies[0, np.int64(codes[j]) + offset] += 1
        j += 1
    return tallies.sum(axis=0)


@nb.njit(cache=True, inline="always")
def _wrapped(d):
    """(d + pi) % 2 pi - pi, the same number: for d + pi in [-2 pi, 4 pi) (two headings' difference) one add
    or subtract gives the remainder exactly as fmod does, without its call."""
    y = d + math.pi
    if y < 0.0:
        if y >= -2.0 * math.pi:
            y += 2.0 * math.pi
        else:
            y = y % (2.0 * math.pi)
    elif y >= 2.0 * math.pi:
        if y < 4.0 * math.pi:
            y -= 2.0 * math.pi
        else:
            y = y % (2.0 * math.pi)
    return y - math.pi


@nb.njit(cache=True)
def heading_sincos(headings, out):
    """``out[..., 0]``, ``out[..., 1]``: sin and cos of each heading (rad), with the kernels' own ``math.sin``
    and ``math.cos`` (NumPy's vectorised ones may differ in the last bit), for :func:`pose_entropies`."""
    flat, sincos = headings.reshape(-1), out.reshape(-1, 2)
    for k in range(flat.size):
        sincos[k, 0] = math.sin(flat[k])
        sincos[k, 1] = math.cos(flat[k])


@nb.njit(cache=True)
def pose_entropies(paths, sincos, weights, det_floor, log_2pie_3):
    """Gaussian differential entropy (nats) of the weighted poses at each step of (M, T, 3) paths.

    Per step: weighted mean of x, y; circular mean of theta (from ``sincos`` (M, T, 2), the headings'
    sines and cosines of :func:`heading_sincos`: a path's poses do not change, so a caller that keeps
    them computes each once, not at every call); the weighted covariance with theta wrapped about it;
    ``0.5 * (ln (2 pi e)^3 + ln max(det, det_floor))``.
    """
    m, t_steps = paths.shape[0], paths.shape[1]
    out = np.empty(t_steps)
    for t in range(t_steps):
        mx = my = s = c = 0.0
        for i in range(m):
            wi = weights[i]
            mx += wi * paths[i, t, 0]
            my += wi * paths[i, t, 1]
            s += wi * sincos[i, t, 0]
            c += wi * sincos[i, t, 1]
        mt = math.atan2(s, c)
        cxx = cxy = cxt = cyy = cyt = ctt = 0.0
        for i in range(m):
            wi = weights[i]
            dx = paths[i, t, 0] - mx
            dy = paths[i, t, 1] - my
            dt = _wrapped(paths[i, t, 2] - mt)
            cxx += wi * dx * dx
            cxy += wi * dx * dy
            cxt += wi * dx * dt
            cyy += wi * dy * dy
            cyt += wi * dy * dt
            ctt += wi * dt * dt
        det = cxx * (cyy * ctt - cyt * cyt) - cxy * (cxy * ctt - cyt * cxt) + cxt * (cxy * cyt - cyy * cxt)
        out[t] = 0.5 * (log_2pie_3 + math.log(max(det, det_floor)))
    return out


@nb.njit(cache=True)
def label_cells(p, observed_beyond, unobserved_within, labels, band):
    """``labels[k]``: 1 (occupied) or 0 (free) where |p - 0.5| > ``observed_beyond``, -1 (unobserved) where
    it is at most ``unobserved_within``; the cells between (and NaN) are left to the caller, listed in
    ``band``. Returns how many."""
    n = 0
    for k in range(p.size):
        distance = abs(p[k] - 0.5)
        if distance > observed_beyond:
            labels[k] = 1 if p[k] > 0.5 else 0
        elif distance <= unobserved_within:
            labels[k] = -1
        else:
            band[n] = k
            n += 1
    return n
