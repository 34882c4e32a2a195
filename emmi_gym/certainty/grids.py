"""How a stack of particle grids is given: probabilities, log-odds, or integer codes + table.

Every certainty function takes grids in any of the three forms:

- probabilities of occupancy in [0, 1] (float32 or float64);
- log-odds of occupancy (``logodds=True``), converted with the logistic function;
- integer codes (int8, uint8, int16, uint16) with ``lut``, a table giving the
  probability of each code (index = code - the dtype's minimum): how MRPT and our
  RBPF store cells, so that the expected map is a table look-up per cell.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from . import _kernels
from .information import map_entropy_of_code_counts
from .weights import normalize_weights

_CODE_DTYPES = (np.int8, np.uint8, np.int16, np.uint16)


@dataclass(frozen=True)
class ParticleGrids:
    """Validated (M, N) grids with their weights and encoding."""

    flat: np.ndarray
    weights: np.ndarray
    shape: tuple[int, ...]
    logodds: bool
    lut: np.ndarray | None
    offset: int

    @classmethod
    def from_arrays(cls, grids, weights, *, logodds=False, lut=None, log_weights=False) -> ParticleGrids:
        g = np.asarray(grids)
        if g.ndim < 2:
            raise ValueError(f"grids must be (M, H, W) or (M, N), got shape {g.shape}")
        w = normalize_weights(weights, log=log_weights)
        if w.shape[0] != g.shape[0]:
            raise ValueError(f"{g.shape[0]} grids but {w.shape[0]} weights")
        offset = 0
        if lut is not None:
            lut, offset = code_table(g.dtype, lut)
        elif g.dtype not in (np.float32, np.float64):
            g = g.astype(np.float64)
        flat = np.ascontiguousarray(g.reshape(g.shape[0], -1))
        if lut is None:
            if np.isnan(flat).any():
                raise ValueError("grids must not contain NaN")
            if not logodds and flat.size and (flat.min() < 0.0 or flat.max() > 1.0):
                raise ValueError("occupancy probabilities must lie in [0, 1] (pass logodds=True for log-odds)")
        return cls(flat, w, g.shape[1:], bool(logodds), lut, offset)

    def expected_map_flat(self) -> np.ndarray:
        """Eq. (6) as a flat float64 array: sum_i w_i p_i, in probability space."""
        out = np.zeros(self.flat.shape[1], dtype=np.float64)
        if self.lut is not None:
            _kernels.expected_map_codes(self.flat, self.weights, self.lut, self.offset, out)
        elif not self.logodds:
            _kernels.expected_map_probabilities(self.flat, self.weights, out)
        else:  # NumPy's SIMD exp per particle, then a fused accumulate
            scratch = np.empty(self.flat.shape[1], dtype=self.flat.dtype)
            for wi, row in zip(self.weights, self.flat, strict=False):
                if wi == 0.0:
                    continue
                np.negative(row, out=scratch)
                with np.errstate(over="ignore"):
                    np.exp(scratch, out=scratch)
                _kernels.accumulate_odds(out, wi, scratch)
        return out

    def entropies_bits(self) -> np.ndarray:
        """H(m_i), eq. (8), of each particle's map, in bits."""
        if self.lut is not None:
            return map_entropy_of_code_counts(
                [_kernels.code_histogram(row, self.lut.size, self.offset) for row in self.flat], self.lut)
        if self.logodds:
            return np.array([_kernels.entropy_sum(logistic(row)) for row in self.flat])
        return np.array([_kernels.entropy_sum(row) for row in self.flat])


def code_table(dtype, lut) -> tuple[np.ndarray, int]:
    """``lut`` checked as the probability table of integer codes of ``dtype`` (one entry per code),
    as float64, with the offset from a code to its entry."""
    if np.dtype(dtype).type not in _CODE_DTYPES:
        raise ValueError(f"grids with a lut must be integer codes {[d.__name__ for d in _CODE_DTYPES]}, got {dtype}")
    lut = np.ascontiguousarray(lut, dtype=np.float64)
    info = np.iinfo(dtype)
    if lut.shape != (info.max - info.min + 1,):
        raise ValueError(f"a lut for {dtype} codes needs {info.max - info.min + 1} entries, got {lut.shape}")
    if not ((lut >= 0) & (lut <= 1)).all():
        raise ValueError("lut entries must be probabilities in [0, 1]")
    return lut, -int(info.min)


def cell_rows(cell_codes, weights, *, lut, log_weights: bool = False) -> tuple[np.ndarray, np.ndarray, np.ndarray, int]:
    """Checked (N, M) integer codes of N cells in M particles' grids (a row per cell), with the normalised
    weights, the probability table and its offset (see :func:`code_table`)."""
    rows = np.ascontiguousarray(cell_codes)
    if rows.ndim != 2:
        raise ValueError(f"cell codes must be (N cells, M particles), got shape {rows.shape}")
    w = normalize_weights(weights, log=log_weights)
    if w.shape[0] != rows.shape[1]:
        raise ValueError(f"codes of {rows.shape[1]} particles per cell but {w.shape[0]} weights")
    lut, offset = code_table(rows.dtype, lut)
    return rows, w, lut, offset


def logistic(logodds) -> np.ndarray:
    """Probability from log-odds, float64, without overflow warnings (exp -> inf gives 0)."""
    with np.errstate(over="ignore"):
        return 1.0 / (1.0 + np.exp(-np.asarray(logodds, dtype=np.float64)))
