"""The expected map (eq. 6), its mean information EMMI (eq. 11), and the particles' map entropies."""

from __future__ import annotations

import numpy as np

from ..threads import MIN_CELLS_PER_THREAD, run_in_chunks
from . import _kernels
from .grids import ParticleGrids
from .information import (DEFAULT_OBSERVED_TOL, cell_information, information_and_observed, max_entropy_bits,
                          observed_cells, unobserved_halfwidth)
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


def emmi_of_parts(grids, disputed, weights, agreed_counts, *, lut, log_weights: bool = False,
                  observed_tol: float = DEFAULT_OBSERVED_TOL) -> float:
    """EMMI, eq. (11), of integer-coded grids (M, H, W) whose particles agree everywhere but on the
    cells ``disputed`` (flat indices): an agreed cell's expected map (eq. 6) is its own
    probability whatever the weights, so those cells enter only through ``agreed_counts``
    (how many agreed cells hold each code, indexed like ``lut``), and only the disputed ones
    are averaged with the weights. Equal to :func:`emmi` of the whole grids, at the cost of
    the disputed cells, split among the kernel threads (the same result on any number of them).
    """
    pg = ParticleGrids.from_arrays(grids, weights, lut=lut, log_weights=log_weights)
    cells = np.asarray(disputed)
    information, observed = np.empty(cells.size), np.empty(cells.size, dtype=np.bool_)
    max_bits = max_entropy_bits(observed_tol)
    run_in_chunks(_kernels.information_at, cells.size, pg.flat, cells, pg.weights, pg.lut, pg.offset, max_bits,
                  unobserved_halfwidth(max_bits), information, observed, min_chunk=MIN_CELLS_PER_THREAD)
    info, n_obs = float(information.sum()), int(np.count_nonzero(observed))
    counts, table = np.asarray(agreed_counts), pg.lut
    observed = (counts > 0) & observed_cells(table, observed_tol)
    info += float(counts[observed] @ cell_information(table[observed]))
    n_obs += int(counts[observed].sum())
    return info / n_obs if n_obs else 0.0


def weighted_map_entropy(grids, weights, *, logodds: bool = False, lut=None, log_weights: bool = False) -> float:
    """``sum_i w_i H(m_i)`` in bits: the map term of the joint entropy, eq. (12), with eq. (8)."""
    pg = ParticleGrids.from_arrays(grids, weights, logodds=logodds, lut=lut, log_weights=log_weights)
    return float(np.dot(pg.weights, pg.entropies_bits()))


def joint_entropy_of_parts(path_entropy_nats: float, map_entropies_bits, weights, *, log_weights: bool = False) -> float:
    """Eq. (12) from its parts: the path entropy (nats) plus ``sum_i w_i H(m_i)`` (given in bits), in nats."""
    w = normalize_weights(weights, log=log_weights)
    h = np.asarray(map_entropies_bits, dtype=np.float64)
    if h.shape != w.shape:
        raise ValueError(f"{h.size} map entropies but {w.size} weights")
    return float(path_entropy_nats + np.dot(w, h) * np.log(2.0))
