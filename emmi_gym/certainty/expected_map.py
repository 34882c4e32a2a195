"""The expected map (eq. 6), its mean information EMMI (eq. 11), and the particles' map entropies."""

from __future__ import annotations

import numpy as np

from ..concurrency.threads import MIN_CELLS_PER_THREAD, run_in_chunks
from . import _kernels
from .grids import ParticleGrids, cell_rows
from .information import DEFAULT_OBSERVED_TOL, cell_information, information_and_observed, observed_cells
from .weights import normalize_weights


def expected_map(grids, weights, *, logodds: bool = False, lut=None, log_weights: bool = False) -> np.ndarray:
    """Expected map, eq. (6): ``EM_xy = sum_i w_i p(m_xy^[i])``, in probability space.

    ``grids`` is (M, H, W) (or (M, N)) of occupancy probabilities, log-odds with
    ``logodds=True`` (converted per particle before averaging: averaging log-odds
    would not be eq. 6), or integer codes with a probability table ``lut`` (see
    :mod:`emmi_gym.certainty.grids`). ``weights`` are normalised here;
    ``log_weights=True`` takes log-weights. Returns a float64 grid of shape (H, W).
    """
    pg = ParticleGrids.from_arrays(grids, weights, logodds=logodds, lut=lut, log_weights=log_weights)
    return pg.expected_map_flat().reshape(pg.shape)


def emmi(grids, weights, *, logodds: bool = False, lut=None, log_weights: bool = False,
         observed_tol: float = DEFAULT_OBSERVED_TOL) -> float:
    """EMMI, eq. (11): the mean information (eq. 10) of the expected map (eq. 6), in bits/cell.

    Two numba passes: each particle's grid is streamed once into the EM, then the
    EM's information is summed, skipping the cells that are surely unobserved
    without a logarithm. Same arguments as :func:`expected_map` and
    :func:`~emmi_gym.certainty.mean_information`.
    """
    pg = ParticleGrids.from_arrays(grids, weights, logodds=logodds, lut=lut, log_weights=log_weights)
    info, n_obs = information_and_observed(pg.expected_map_flat(), observed_tol)
    return info / n_obs if n_obs else 0.0


def expected_map_of_cells(cell_codes, weights, *, lut, log_weights: bool = False) -> np.ndarray:
    """Eq. (6) at N cells given by their integer codes in the M particles' grids, ``cell_codes`` (N, M)
    (a row per cell), with the probability table ``lut``: float64 (N,). Split among the kernel threads."""
    return _expected_at_rows(*cell_rows(cell_codes, weights, lut=lut, log_weights=log_weights))


def _expected_at_rows(rows, weights, lut, offset) -> np.ndarray:
    """Eq. (6) of each row of codes, through the table of every particle's weighted probabilities
    ``w_i lut[c]``: over the 256 codes of 8-bit grids, over the codes the rows hold for wider ones."""
    if lut.size > 256 and rows.size:
        lo, hi = int(rows.min()) + offset, int(rows.max()) + offset + 1
    else:
        lo, hi = 0, lut.size
    weighted = np.ascontiguousarray(weights[:, None] * lut[None, lo:hi])
    out = np.empty(rows.shape[0])
    run_in_chunks(_kernels.expected_at, rows.shape[0], rows, weighted, offset - lo, out,
                  min_chunk=MIN_CELLS_PER_THREAD)
    return out


def emmi_of_parts(cell_codes, weights, agreed_counts, *, lut, log_weights: bool = False,
                  observed_tol: float = DEFAULT_OBSERVED_TOL) -> float:
    """EMMI, eq. (11), of integer-coded grids whose particles agree everywhere but on N cells, given by
    their codes in the M grids, ``cell_codes`` (N, M) (a row per cell, as
    :meth:`~emmi_gym.slam.ParticleMaps.disputed_codes` keeps them): an agreed cell's expected map
    (eq. 6) is its own probability whatever the weights, so those cells enter only through
    ``agreed_counts`` (how many agreed cells hold each code, indexed like ``lut``), and only the
    disputed ones are averaged with the weights. Equal to :func:`emmi` of the whole grids, at the
    cost of the disputed cells, split among the kernel threads (the same result on any number of them).
    """
    info, n_obs = expected_map_information_of_parts(cell_codes, weights, agreed_counts, lut=lut,
                                                    log_weights=log_weights, observed_tol=observed_tol)
    return info / n_obs if n_obs else 0.0


def expected_map_information_of_parts(cell_codes, weights, agreed_counts, *, lut, log_weights: bool = False,
                                      observed_tol: float = DEFAULT_OBSERVED_TOL) -> tuple[float, int]:
    """The information of the expected map, eq. (9) summed over its observed cells, in bits, and how
    many cells are observed (EMMI's numerator and denominator, eq. 10-11), from the same parts as
    :func:`emmi_of_parts`."""
    rows, w, table, offset = cell_rows(cell_codes, weights, lut=lut, log_weights=log_weights)
    info, n_obs = information_and_observed(_expected_at_rows(rows, w, table, offset), observed_tol)
    counts = np.asarray(agreed_counts)
    observed = (counts > 0) & observed_cells(table, observed_tol)
    info += float(counts[observed] @ cell_information(table[observed]))
    n_obs += int(counts[observed].sum())
    return info, n_obs


def weighted_map_entropy(grids, weights, *, logodds: bool = False, lut=None, log_weights: bool = False) -> float:
    """``sum_i w_i H(m_i)`` in bits: the map term of the joint entropy, eq. (12), with eq. (8)."""
    pg = ParticleGrids.from_arrays(grids, weights, logodds=logodds, lut=lut, log_weights=log_weights)
    return float(np.dot(pg.weights, pg.entropies_bits()))


def joint_entropy_of_parts(path_entropy_nats: float, map_entropies_bits, weights, *,
                           log_weights: bool = False) -> float:
    """Eq. (12) from its parts: the path entropy (nats) plus ``sum_i w_i H(m_i)`` (given in bits), in nats."""
    w = normalize_weights(weights, log=log_weights)
    h = np.asarray(map_entropies_bits, dtype=np.float64)
    if h.shape != w.shape:
        raise ValueError(f"{h.size} map entropies but {w.size} weights")
    return float(path_entropy_nats + np.dot(w, h) * np.log(2.0))
