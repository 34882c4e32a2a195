"""Cell and map information, map entropy and mean information (paper eqs. 7-10).

All in bits, as the paper: the entropy of a cell uses base-2 logs, so an unknown
cell (p = 0.5) carries 0 bits of information and a certain one (p in {0, 1}) 1 bit.
"""

from __future__ import annotations

import functools
import math

import numpy as np

from . import _kernels

#: Default observed-cell rule of eq. (10), from the authors' reference implementation
#: (MRPT's ``COccupancyGridMap2D::computeEntropy``): a cell counts as observed when
#: its entropy is more than 0.001 nats below ln 2, i.e. |p - 0.5| > ~0.0224.
DEFAULT_OBSERVED_TOL = 1e-3


def as_probability(grid, *, logodds: bool = False, lut=None) -> np.ndarray:
    """Occupancy probabilities (float64) from probabilities, log-odds, or integer codes + ``lut``.

    See :mod:`emmi_gym.certainty.grids` for the three encodings.
    """
    if lut is not None:
        codes = np.asarray(grid)
        if codes.dtype.kind not in "iu":
            raise ValueError(f"grids with a lut must hold integer codes, got {codes.dtype}")
        return np.asarray(lut, dtype=np.float64)[codes.astype(np.int64) - np.iinfo(codes.dtype).min]
    a = np.asarray(grid, dtype=np.float64)
    if logodds:
        return 0.5 * (1.0 + np.tanh(0.5 * a))  # the logistic function, overflow-free
    if a.size and (np.nanmin(a) < 0.0 or np.nanmax(a) > 1.0 or np.isnan(a).any()):
        raise ValueError("occupancy probabilities must lie in [0, 1] (pass logodds=True for log-odds)")
    return a


def cell_entropy(p) -> np.ndarray:
    """Entropy of each cell in bits, eq. (7) with base-2 logs; 0 at p in {0, 1}."""
    p = np.asarray(p, dtype=np.float64)
    q = 1.0 - p
    with np.errstate(divide="ignore", invalid="ignore"):
        h = -(np.where(p > 0, p * np.log2(np.where(p > 0, p, 1.0)), 0.0)
              + np.where(q > 0, q * np.log2(np.where(q > 0, q, 1.0)), 0.0))
    return h


def cell_information(p) -> np.ndarray:
    """Information of each cell, ``I = 1 - H(p)`` in bits (eq. 9)."""
    return 1.0 - cell_entropy(p)


def map_information(p) -> float:
    """Map information ``I(m) = sum_xy (1 - H(p_xy))`` in bits (eq. 9)."""
    return float(cell_information(p).sum())


def map_entropy(p, *, logodds: bool = False, lut=None) -> float:
    """Map entropy ``H(m) = sum_xy H(p_xy)`` in bits (eq. 8).

    Unlike the information it depends on the grid's extent and resolution: every
    unknown cell adds a full bit.
    """
    return float(cell_entropy(as_probability(p, logodds=logodds, lut=lut)).sum())


def max_entropy_bits(observed_tol: float = DEFAULT_OBSERVED_TOL) -> float:
    """Entropy (bits) a cell must stay below to count as observed in eq. (10).

    ``observed_tol`` is in nats: observed when ``H_nats(p) < ln 2 - observed_tol``.
    """
    if not (0.0 <= observed_tol < math.log(2.0)):
        raise ValueError(f"observed_tol must be in [0, ln 2), got {observed_tol!r}")
    return 1.0 - observed_tol / math.log(2.0)


@functools.lru_cache(maxsize=32)
def observed_halfwidth(max_bits: float) -> float:
    """The |p - 0.5| at which H2(p) = ``max_bits``: the entropy is symmetric about 0.5 and falls with
    |p - 0.5|, so a cell is observed (eq. 10) about when it lies farther than this from 0.5."""
    if max_bits >= 1.0:
        return 0.0
    from scipy.optimize import brentq  # here, not at the top: scipy.optimize takes 0.6 s to import

    return brentq(lambda d: float(cell_entropy(0.5 + d)) - max_bits, 0.0, 0.5, xtol=1e-15)


def unobserved_halfwidth(max_bits: float) -> float:
    """A half-width around p = 0.5 inside which every cell is surely unobserved: 90% of
    :func:`observed_halfwidth`, so the kernels can skip those cells without a logarithm and still
    decide every other cell exactly."""
    return 0.9 * observed_halfwidth(max_bits)


#: Cells per block of :func:`information_and_observed` (its buffers stay in cache).
INFORMATION_BLOCK = 16384


def information_and_observed(p_flat: np.ndarray, observed_tol: float) -> tuple[float, int]:
    """(Information over observed cells in bits, eq. 9, number of observed cells, eq. 10) of a flat float
    grid, block by block: the cells within :func:`unobserved_halfwidth` of 0.5 are set aside without a
    logarithm (most of a map is unknown), the others' logarithms come from NumPy's vectorised ``log``
    (several cells per instruction, where a scalar ``log`` per cell would dominate the pass)."""
    max_bits = max_entropy_bits(observed_tol)
    halfwidth = unobserved_halfwidth(max_bits)
    p_flat = np.ascontiguousarray(p_flat).ravel()
    p, q = np.empty(min(p_flat.size, INFORMATION_BLOCK)), np.empty(min(p_flat.size, INFORMATION_BLOCK))
    log_p, log_q = np.empty_like(p), np.empty_like(q)
    info, n_obs = 0.0, 0
    for start in range(0, p_flat.size, INFORMATION_BLOCK):
        n = _kernels.beyond_band(p_flat[start:start + INFORMATION_BLOCK], halfwidth, p, q)
        # log(0) is -inf and a probability a rounding error beyond [0, 1] gives NaN: information_sum reads
        # the logarithms of cells with 0 < p < 1 only
        with np.errstate(divide="ignore", invalid="ignore"):
            np.log(p[:n], out=log_p[:n])
            np.log(q[:n], out=log_q[:n])
        block_info, block_obs = _kernels.information_sum(p[:n], q[:n], log_p[:n], log_q[:n], max_bits)
        info += block_info
        n_obs += block_obs
    return info, n_obs


def observed_cells(p, observed_tol: float = DEFAULT_OBSERVED_TOL) -> np.ndarray:
    """Boolean mask of the cells that count as observed in eq. (10): ``H2(p) < max_entropy_bits``
    (see :func:`observation_labels`)."""
    return observation_labels(p, observed_tol) >= 0


def observation_labels(p, observed_tol: float = DEFAULT_OBSERVED_TOL) -> np.ndarray:
    """Per cell, int8: -1 if unobserved in the sense of eq. (10) (``H2(p) >= max_entropy_bits``), else 1 if
    p > 0.5 (occupied), 0 if not (free).

    One pass of a kernel decides every cell by |p - 0.5| outside a band of +-10% round
    :func:`observed_halfwidth`; the entropy itself decides the few inside it (and NaN)."""
    p = np.ascontiguousarray(p, dtype=np.float64)
    max_bits = max_entropy_bits(observed_tol)
    halfwidth = observed_halfwidth(max_bits)
    labels = np.empty(p.shape, dtype=np.int8)
    flat_p, flat_labels = p.reshape(-1), labels.reshape(-1)
    band = np.empty(flat_p.size, dtype=np.int64)
    n = _kernels.label_cells(flat_p, 1.1 * halfwidth, 0.9 * halfwidth, flat_labels, band)
    if n:
        cells = band[:n]
        values = flat_p[cells]
        flat_labels[cells] = np.where(cell_entropy(values) < max_bits, (values > 0.5).astype(np.int8), np.int8(-1))
    return labels


def mean_information(p, *, logodds: bool = False, lut=None, observed_tol: float = DEFAULT_OBSERVED_TOL) -> float:
    """Mean information (MI) of a map, eq. (10): ``I(m) / N_obs`` bits per cell, 0 if N_obs = 0.

    ``I(m)`` sums eq. (9) over the observed cells only (an unobserved cell carries
    ~0 bits anyway; the tolerance keeps cells that are a hair from 0.5 out of both
    the sum and the count). The result lies in [0, 1]; see ``DEFAULT_OBSERVED_TOL``.
    """
    if lut is not None:  # integer codes: count them, then weigh the table's entries
        codes = np.ascontiguousarray(p).ravel()
        table = np.asarray(lut, dtype=np.float64)
        if codes.dtype.kind not in "iu" or table.shape != (np.iinfo(codes.dtype).max - np.iinfo(codes.dtype).min + 1,):
            raise ValueError(f"a lut for {codes.dtype} codes needs one probability per code value")
        counts = _kernels.code_histogram(codes, table.size, -int(np.iinfo(codes.dtype).min))
        return mean_information_of_code_counts(counts, table, observed_tol)
    prob = np.ascontiguousarray(as_probability(p, logodds=logodds)).ravel()
    info, n_obs = information_and_observed(prob, observed_tol)
    return info / n_obs if n_obs else 0.0


def mean_information_of_code_counts(counts, lut, observed_tol: float = DEFAULT_OBSERVED_TOL) -> float:
    """Eq. (10) of an integer-coded map given only how many cells hold each code.

    ``counts[k]`` cells hold the code of probability ``lut[k]``; a map whose histogram
    is kept up to date as cells change needs no pass over its cells.
    """
    counts, table = np.asarray(counts), np.asarray(lut, dtype=np.float64)
    observed = (counts > 0) & observed_cells(table, observed_tol)
    n_obs = int(counts[observed].sum())
    return float(counts[observed] @ cell_information(table[observed])) / n_obs if n_obs else 0.0


def map_entropy_of_code_counts(counts, lut) -> np.ndarray:
    """Eq. (8), bits, of integer-coded maps given their code histograms (..., K)."""
    return np.asarray(counts) @ cell_entropy(np.asarray(lut, dtype=np.float64))
