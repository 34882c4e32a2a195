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


def survivors_in_place(parents: np.ndarray) -> np.ndarray:
    """The same draw (the same number of copies of each parent), arranged so that every particle
    that survives keeps its own slot and its extra copies fill the slots of those that died.

    Then only the dead slots are overwritten, each from a slot that does not change, so the
    maps need no temporary copy and resampling costs the dead particles only (as MRPT's and
    GMapping's in-place resampling).
    """
    parents = np.asarray(parents, dtype=np.int64)
    arranged = np.full(parents.size, -1, dtype=np.int64)
    drawn = np.sort(parents)
    first = np.ones(drawn.size, dtype=bool)
    first[1:] = drawn[1:] != drawn[:-1]
    arranged[drawn[first]] = drawn[first]
    arranged[arranged < 0] = drawn[~first]
    return arranged
