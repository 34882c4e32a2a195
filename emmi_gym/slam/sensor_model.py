"""Occupancy codes: quantised log-odds in int8 with probability and entropy tables (MRPT's layout).

A cell's log-odds of occupancy (eq. 4 in log-odds form: ``l_new = l_old + l_sensor``)
is kept as an int8 code ``k`` meaning ``k * step``. The expected map (eq. 6) then
needs one table look-up per cell instead of an exponential.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .config import RBPFConfig


@dataclass(frozen=True)
class CellCodes:
    """The int8 code book of a configuration: increments, clamp and the probability table."""

    step: float
    occupied: int      # code increment of a hit
    free: int          # code increment of a pass (negative)
    clamp: int         # codes stay within [-clamp, clamp]
    probability: np.ndarray   # (256,) p(occupied) of code k at index k + 128

    @classmethod
    def from_config(cls, config: RBPFConfig) -> CellCodes:
        step = config.logodds_step
        occupied = max(1, round(config.logodds_occupied / step))
        free = min(-1, round(config.logodds_free / step))
        clamp = int(config.logodds_clamp // step)
        codes = np.arange(-128, 128)
        probability = 1.0 / (1.0 + np.exp(-codes * step))
        return cls(step, occupied, free, clamp, probability)

    def to_probability(self, codes: np.ndarray) -> np.ndarray:
        return self.probability[codes.astype(np.int16) + 128]

    def to_logodds(self, codes: np.ndarray) -> np.ndarray:
        return codes.astype(np.float64) * self.step
