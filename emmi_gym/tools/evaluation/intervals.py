"""Confidence intervals over seeds or episodes that respect what a measure can be.

A Student-t interval of a handful of values in [0, 1] easily reaches past 1 (three seeds at
0.8, 1.0 and 1.0 give [0.64, 1.22]); a proportion of successes has no spread at all when every
run succeeded. So: proportions (values 0 or 1) get the Wilson score interval (Wilson 1927, the
usual choice for small n: it never leaves [0, 1] and is not empty at 0 or n successes); other
measures with a known range get the t-interval clipped to it; paired differences of bounded
measures are clipped to plus or minus the range's width.

Two policies played on the same plans with several seeds each are compared by a paired bootstrap that
resamples plans (:func:`plan_bootstrap`): the seeds of one plan are not independent draws (the plan
explains about half the variance of the final map), so the plans are the units; it also states the
smallest difference the protocol can detect from the noise it measured.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from scipy import stats

CONFIDENCE = 0.95

#: Ranges of the measures the A/B summary and the benchmark report (absent: unbounded).
PROPORTIONS = ("completed", "reached_target", "closed_loop_first", "loop_closed")
RANGES = {
    **{name: (0.0, 1.0) for name in PROPORTIONS},
    "map_accuracy": (0.0, 1.0), "oracle_accuracy": (0.0, 1.0), "wall_consistency": (0.0, 1.0),
    "new_area_accuracy": (0.0, 1.0), "new_area_accuracy_on_arrival": (0.0, 1.0),
    "coverage": (0.0, 1.0), "building_accuracy": (0.0, 1.0), "revisit_share": (0.0, 1.0), "ate": (0.0, math.inf),
    "loop_ate": (0.0, math.inf),
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


#: Resamples of :func:`plan_bootstrap` (seeded: a table is the same each time it is made).
RESAMPLES = 10_000
#: The power at which :func:`plan_bootstrap` states the smallest difference it detects.
POWER = 0.8


@dataclass(frozen=True)
class PairedDifference:
    """The paired difference of two policies over plans (:func:`plan_bootstrap`): ``mean`` [``low``, ``high``],
    from ``plans`` plans (the units; on one world, its episodes), and ``detectable``, the smallest true difference
    the protocol finds (its interval excluding zero) with :data:`POWER`."""

    mean: float
    low: float
    high: float
    plans: int
    detectable: float


def plan_bootstrap(differences, plans, measure: str, agents=None, episodes=None, confidence: float = CONFIDENCE,
                   resamples: int = RESAMPLES, seed: int = 0) -> PairedDifference:
    """The mean of paired ``differences`` of ``measure`` (one per episode pair) and its interval by a paired
    bootstrap over plans: each resample draws the plans with replacement, each plan with all its episodes (its
    seeds, and every agent's on it), so the interval counts the plans' spread, not the seeds' as if they were
    independent. ``plans[k]`` names the plan of ``differences[k]``; where all lie on one plan (a single world),
    the episodes are the units: ``episodes[k]`` names the pair's episode (its seed, which several agents played
    alike; without them each pair is a unit of its own). With ``agents`` (the trained agent of each pair, e.g. its
    training seed) naming more than one, the agents are drawn with replacement too (plans and agents crossed;
    conservative).
    Each plan (and agent) weighs the same: the mean is that of the per-(agent, plan) means. Percentile interval,
    clipped to +-(the measure's range width).

    ``detectable`` is the minimum detectable effect of a two-sided test at ``1 - confidence`` with
    :data:`POWER`: ``(z_(1 - alpha/2) + z_power)`` bootstrap standard errors of the mean, 2.80 at 95% and 80%
    (NaN below two units)."""
    values = np.asarray(differences, dtype=float)
    plans = np.asarray(plans, dtype=object)
    agents = np.zeros(len(values), dtype=int) if agents is None else np.asarray(agents, dtype=object)
    episodes = np.arange(len(values)) if episodes is None else np.asarray(episodes, dtype=object)
    if not len(values) == len(plans) == len(agents) == len(episodes):
        raise ValueError(f"{len(values)} differences, {len(plans)} plans, {len(agents)} agents and {len(episodes)} "
                         "episodes: one each a pair")
    keep = np.isfinite(values)
    values, plans, agents, episodes = values[keep], plans[keep], agents[keep], episodes[keep]
    if values.size == 0:
        return PairedDifference(math.nan, math.nan, math.nan, 0, math.nan)
    if len(set(plans)) == 1:
        plans = episodes
    plan_index = np.unique(plans.astype(str), return_inverse=True)[1]
    agent_index = np.unique(agents.astype(str), return_inverse=True)[1]
    sums = np.zeros((agent_index.max() + 1, plan_index.max() + 1))
    counts = np.zeros_like(sums)
    np.add.at(sums, (agent_index, plan_index), values)
    np.add.at(counts, (agent_index, plan_index), 1.0)
    cells = np.where(counts > 0, sums / np.maximum(counts, 1.0), np.nan)  # each (agent, plan)'s mean
    n_agents, n_plans = cells.shape
    mean = float(np.nanmean(cells))
    if n_plans < 2:
        return PairedDifference(mean, mean, mean, n_plans, math.nan)
    rng = np.random.default_rng(seed)
    drawn_plans = rng.integers(n_plans, size=(resamples, 1, n_plans))
    drawn_agents = rng.integers(n_agents, size=(resamples, n_agents, 1)) if n_agents > 1 else \
        np.zeros((resamples, 1, 1), dtype=int)
    drawn = cells[drawn_agents, drawn_plans]
    present = np.isfinite(drawn)
    means = np.where(present, drawn, 0.0).sum(axis=(1, 2)) / np.maximum(present.sum(axis=(1, 2)), 1)
    low, high = np.quantile(means, [(1 - confidence) / 2, (1 + confidence) / 2])
    lo, hi = RANGES.get(measure, (-math.inf, math.inf))
    width = hi - lo
    detectable = float((stats.norm.ppf((1 + confidence) / 2) + stats.norm.ppf(POWER)) * np.std(means, ddof=1))
    return PairedDifference(mean, float(max(low, -width)), float(min(high, width)), n_plans, detectable)


def share_bootstrap(successes, trials, units, baseline=None, confidence: float = CONFIDENCE,
                    resamples: int = RESAMPLES, seed: int = 0) -> PairedDifference:
    """The share ``sum(successes) / sum(trials)`` over ``units`` (e.g. plans, each holding many pairs of episodes)
    and its percentile interval by a bootstrap that draws the units with replacement, each with all its trials:
    the pairs of one plan are not independent draws. ``successes[k]`` and ``trials[k]`` are unit ``units[k]``'s.

    With ``baseline`` (``(successes, trials)`` of the same units under another condition: another filter, another
    version), the share minus the baseline's, both taken on each resample's units (paired by unit). ``detectable``
    as :func:`plan_bootstrap` states it; a resample without trials is left out."""
    s, t = np.asarray(successes, dtype=float), np.asarray(trials, dtype=float)
    if not len(s) == len(t) == len(units):
        raise ValueError(f"{len(s)} successes, {len(t)} trials and {len(units)} units: one each a unit")
    if baseline is not None:
        b_s, b_t = np.asarray(baseline[0], dtype=float), np.asarray(baseline[1], dtype=float)
        if not len(b_s) == len(b_t) == len(s):
            raise ValueError(f"{len(b_s)} successes and {len(b_t)} trials of the baseline for {len(s)} units: one "
                             "each a unit")
    if len(set(units)) != len(units):
        raise ValueError("a unit is named twice: give each unit's successes and trials summed")

    def shares(drawn):
        with np.errstate(invalid="ignore", divide="ignore"):
            share = s[drawn].sum(axis=-1) / t[drawn].sum(axis=-1)
            return share if baseline is None else share - b_s[drawn].sum(axis=-1) / b_t[drawn].sum(axis=-1)

    n = len(s)
    if n == 0 or t.sum() == 0 or (baseline is not None and b_t.sum() == 0):
        return PairedDifference(math.nan, math.nan, math.nan, n, math.nan)
    mean = float(shares(np.arange(n)))
    if n < 2:
        return PairedDifference(mean, mean, mean, n, math.nan)
    drawn = shares(np.random.default_rng(seed).integers(n, size=(resamples, n)))
    drawn = drawn[np.isfinite(drawn)]
    low, high = np.quantile(drawn, [(1 - confidence) / 2, (1 + confidence) / 2])
    detectable = float((stats.norm.ppf((1 + confidence) / 2) + stats.norm.ppf(POWER)) * np.std(drawn, ddof=1))
    return PairedDifference(mean, float(low), float(high), n, detectable)
