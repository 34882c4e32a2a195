"""Selective resampling (Doucet; GMapping): resample only when Neff / M drops below a threshold."""

from __future__ import annotations

import numpy as np


def systematic_resample(weights: np.ndarray, rng: np.random.Generator) -> np.ndarray:
    """Low-variance (systematic) resampling: M evenly spaced pointers with one random offset.

    Returns the index each new particle copies; a particle of weight w gets floor(M w)
    or ceil(M w) copies.
    """
    m = weights.size
    positions = (rng.random() + np.arange(m)) / m
    cumulative = np.cumsum(weights)
    cumulative[-1] = 1.0  # guard against round-off
    return np.searchsorted(cumulative, positions, side="right").astype(np.int64)
