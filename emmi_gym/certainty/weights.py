"""Particle weights: normalisation (linear or log space), their entropy and Neff."""

from __future__ import annotations

import numpy as np


def normalize_weights(weights, *, log: bool = False) -> np.ndarray:
    """Return float64 weights that sum to one.

    ``log=True`` takes log-weights (any real numbers, e.g. accumulated scan
    log-likelihoods) and normalises them the log-sum-exp way, shifting by the maximum
    before exponentiating, so that values such as -1e9 neither overflow nor turn into
    NaN. Linear weights must be finite,
    non-negative and not all zero.
    """
    w = np.asarray(weights, dtype=np.float64)
    if w.ndim != 1 or w.size == 0:
        raise ValueError(f"weights must be a non-empty 1-D array, got shape {w.shape}")
    if log:
        if np.isnan(w).any() or np.isposinf(w).any():
            raise ValueError("log-weights must not be NaN or +inf")
        if np.isneginf(w).all():
            raise ValueError("all log-weights are -inf: no particle has any weight")
        relative = np.exp(w - w.max())  # the largest is exactly 1: no overflow, sum >= 1
        return relative / relative.sum()
    if not np.isfinite(w).all() or (w < 0).any():
        raise ValueError("linear weights must be finite and non-negative (pass log=True for log-weights)")
    total = w.sum()
    if total <= 0:
        raise ValueError("weights sum to zero: no particle has any weight")
    return w / total


def weight_entropy(weights, *, log: bool = False) -> float:
    """Entropy of the particle weights, ``-sum w ln w`` in nats (0 ln 0 = 0).

    Reported beside the pose entropy: it is ``ln M`` for uniform weights and 0 when
    one particle holds all the weight.
    """
    w = normalize_weights(weights, log=log)
    nz = w[w > 0]
    return float(-(nz * np.log(nz)).sum())


def effective_sample_size(weights, *, log: bool = False) -> float:
    """Neff = 1 / sum(w^2) of the normalised weights (Liu 1996; GMapping's resampling test)."""
    w = normalize_weights(weights, log=log)
    return float(1.0 / np.dot(w, w))
