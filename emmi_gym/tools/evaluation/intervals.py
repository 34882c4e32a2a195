"""Confidence intervals over seeds or episodes that respect what a measure can be.

A Student-t interval of a handful of values in [0, 1] easily reaches past 1 (three seeds at
0.8, 1.0 and 1.0 give [0.64, 1.22]); a proportion of successes has no spread at all when every
run succeeded. So: proportions (values 0 or 1) get the Wilson score interval (Wilson 1927, the
usual choice for small n: it never leaves [0, 1] and is not empty at 0 or n successes); other
measures with a known range get the t-interval clipped to it; paired differences of bounded
measures are clipped to plus or minus the range's width.
"""

from __future__ import annotations

import math

import numpy as np
from scipy import stats

CONFIDENCE = 0.95

#: Ranges of the measures the A/B summary and the benchmark report (absent: unbounded).
PROPORTIONS = ("completed", "reached_target", "closed_loop_first", "loop_closed")
RANGES = {
    **{name: (0.0, 1.0) for name in PROPORTIONS},
    "map_accuracy": (0.0, 1.0), "oracle_accuracy": (0.0, 1.0), "wall_consistency": (0.0, 1.0),
    "new_area_accuracy": (0.0, 1.0), "new_area_accuracy_on_arrival": (0.0, 1.0),
    "coverage": (0.0, 1.0), "revisit_share": (0.0, 1.0), "ate": (0.0, math.inf), "loop_ate": (0.0, math.inf),
    "closure_error": (0.0, math.inf), "loop_hypotheses": (1.0, math.inf), "resamplings": (0.0, math.inf),
    "sim_steps_to_target": (0.0, math.inf), "sim_steps": (0.0, math.inf), "decisions": (0.0, math.inf),
}


def mean_interval(values, confidence: float = CONFIDENCE,
                  bounds=(-math.inf, math.inf)) -> tuple[float, float, float, int]:
    """Mean and Student-t confidence interval of the finite values, clipped to ``bounds``: (mean, low, high, n)."""
    x = np.asarray(values, dtype=float)
    x = x[np.isfinite(x)]
    if x.size == 0:
        return math.nan, math.nan, math.nan, 0
    mean = float(x.mean())
    if x.size < 2 or np.all(x == x[0]):
        return mean, mean, mean, int(x.size)
    low, high = stats.t.interval(confidence, x.size - 1, loc=mean, scale=stats.sem(x))
    return mean, float(max(low, bounds[0])), float(min(high, bounds[1])), int(x.size)


def proportion_interval(values, confidence: float = CONFIDENCE) -> tuple[float, float, float, int]:
    """Share of successes (values 0 or 1) with the Wilson score interval: (share, low, high, n)."""
    x = np.asarray(values, dtype=float)
    x = x[np.isfinite(x)]
    if x.size == 0:
        return math.nan, math.nan, math.nan, 0
    successes = int(np.count_nonzero(x))
    ci = stats.binomtest(successes, int(x.size)).proportion_ci(confidence, method="wilson")
    return successes / x.size, float(ci.low), float(ci.high), int(x.size)


def measure_interval(values, measure: str, confidence: float = CONFIDENCE) -> tuple[float, float, float, int]:
    """The interval of ``measure`` over runs: Wilson for a proportion given as successes (every value 0 or
    1), else t clipped to :data:`RANGES` (a share per run, such as each agent's share of its episodes, is
    a mean like any other)."""
    x = np.asarray(values, dtype=float)
    if measure in PROPORTIONS and np.all((x == 0.0) | (x == 1.0) | ~np.isfinite(x)):
        return proportion_interval(values, confidence)
    return mean_interval(values, confidence, RANGES.get(measure, (-math.inf, math.inf)))


def difference_interval(differences, measure: str, confidence: float = CONFIDENCE) -> tuple[float, float, float, int]:
    """The t-interval of paired differences of ``measure``, clipped to +-(its range's width)."""
    lo, hi = RANGES.get(measure, (-math.inf, math.inf))
    width = hi - lo
    return mean_interval(differences, confidence, (-width, width))
