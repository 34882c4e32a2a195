"""Reward alignment: does a reward pay more to the policy that ends with the better map?

A learner comes to prefer what earns most, so a reward can only teach mapping better where mapping
better pays. The scripted policies are played on the same (world, seed) episodes with every step's
reward components kept (:func:`~emmi_gym.tools.evaluation.comparison.compare_on`); each reward variant,
time cost and discount is then applied to the kept steps, and compared with the ground truth each
episode ended with:

- the mean discounted return of each policy;
- **agreement**: over every episode and every pair of policies whose final maps differ, the share
  of pairs where the policy with the better map (higher accuracy against the oracle map, lower
  ATE) also earned the higher return, with a 95% interval from a bootstrap that draws the plans with all their
  pairs (the pairs of one plan are not independent: it explains half the variance of the final map); beside
  another set of the same episodes (another filter: :func:`agreement_change`), the change, paired by plan;
- **disagreeing pairs**: what the pairs whose better map earned less have in common: the share whose better
  map took more robot time (a return that ranks episodes by length), and their median quality gap beside the
  agreeing pairs' in brackets (maps too close to tell);
- **within-episode correlation**: Pearson's r between return and final map quality after
  subtracting each episode's mean over the policies (what varies between policies on the same
  plan, not between easy and hard plans);
- **preferred**: the policy with the highest mean return: where on the front of map quality
  against robot time the reward points a learner;
- **paired against a policy** (:func:`paired_returns`): each policy's return minus that policy's on the
  same episodes, with its 95% interval: whether a mean return's lead is more than the episodes' spread.

Given what each reward reads (``reads``: the filter, or the ground truth for a privileged reward, as the
env's reward registry says), the tables say it beside each reward: a privileged reward's agreement is what
training with the truth as teacher could reach, a filter-side one's what a reward a real robot could compute.

A reward's scale and the time cost act only through their ratio, so varying the time cost covers
the scales too. Discounts follow :mod:`emmi_gym.tools.training.semi_markov`: ``gamma`` per decision or
per ``unit`` simulator steps of robot time.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass
from itertools import combinations

import numpy as np

from ..evaluation.intervals import PairedDifference, mean_interval, share_bootstrap

#: Final map qualities compared, each with the sign that makes higher better.
QUALITIES = {"oracle_accuracy": 1.0, "ate": -1.0}


@dataclass(frozen=True)
class Discount:
    """``gamma`` per decision (``unit`` None) or per ``unit`` simulator steps; gamma 1: undiscounted."""

    gamma: float = 1.0
    unit: int | None = None

    @classmethod
    def parse(cls, text: str) -> Discount:
        """``"none"``, ``"0.95"`` (per decision) or ``"0.9@100"`` (per 100 simulator steps)."""
        try:
            if text == "none":
                return cls()
            gamma, _, unit = text.partition("@")
            discount = cls(float(gamma), int(unit) if unit else None)
        except ValueError:
            raise ValueError(f"a discount is 'none', GAMMA or GAMMA@SIM_STEPS (e.g. 0.9@100), got {text!r}") from None
        if not (0.0 < discount.gamma <= 1.0) or (discount.unit is not None and discount.unit < 1):
            raise ValueError(f"a discount's gamma is in (0, 1] and its unit at least 1 step, got {text!r}")
        return discount

    @property
    def label(self) -> str:
        if self.gamma == 1.0:
            return "none"
        return f"{self.gamma:g} per decision" if self.unit is None else f"{self.gamma:g} per {self.unit} steps"

    def weights(self, durations: np.ndarray) -> np.ndarray:
        """The discount of each step, given every step's duration in simulator steps."""
        if self.unit is None:
            return self.gamma ** np.arange(len(durations), dtype=np.float64)
        elapsed = np.concatenate([[0.0], np.cumsum(durations, dtype=np.float64)[:-1]])
        return self.gamma ** (elapsed / self.unit)


def discounted_return(steps: list[dict], variant: str, time_cost: float, discount: Discount) -> float:
    """What ``variant`` (at its default scale), the time cost per simulator step and the collision cost
    paid over an episode's kept ``steps``, discounted."""
    if not steps:
        return 0.0
    durations = np.array([step["duration"] for step in steps], dtype=np.float64)
    rewards = np.array([step[variant] + step["collision"] for step in steps]) - time_cost * durations
    return float(np.dot(discount.weights(durations), rewards))


def _episodes(rows: list[dict]) -> dict[tuple, dict[str, dict]]:
    """Rows grouped by (world, seed), then by policy."""
    grouped: dict[tuple, dict[str, dict]] = {}
    for row in rows:
        grouped.setdefault((row["world"], row["seed"]), {})[row["policy"]] = row
    return grouped


def _returns(episodes, variant: str, time_cost: float, discount: Discount) -> dict[tuple, float]:
    """Every episode's discounted return under ``variant``, keyed ``((world, seed), policy)``."""
    return {(key, p): discounted_return(row["steps"], variant, time_cost, discount)
            for key, by_policy in episodes.items() for p, row in by_policy.items()}


def _units(episodes) -> dict:
    """The bootstrap's unit of each episode key (world, seed): its world (a plan, with all its seeds), or where every
    episode lies on one world, the episode itself (as :func:`~emmi_gym.tools.evaluation.intervals.plan_bootstrap`)."""
    one_world = len({world for world, _ in episodes}) == 1
    return {key: key if one_world else key[0] for key in episodes}


def _pairs(episodes, returns, quality: str):
    """Every pair of policies on one episode whose final maps differ: (episode key, the better map's row, the other's,
    whether the better map earned the higher return)."""
    sign = QUALITIES[quality]
    for key, by_policy in episodes.items():
        for p, q in combinations(sorted(by_policy), 2):
            better = sign * (by_policy[p][quality] - by_policy[q][quality])
            if not np.isfinite(better) or better == 0:
                continue
            good, bad = (p, q) if better > 0 else (q, p)
            yield key, by_policy[good], by_policy[bad], returns[key, good] > returns[key, bad]


def _agreement_by_unit(episodes, returns, quality: str) -> dict:
    """For each unit (:func:`_units`), [pairs where the better map earned more, pairs whose maps differ]."""
    units = _units(episodes)
    counts = {unit: [0, 0] for unit in units.values()}
    for key, _, _, agrees in _pairs(episodes, returns, quality):
        counts[units[key]][0] += int(agrees)
        counts[units[key]][1] += 1
    return counts


def _disagreements(episodes, returns, quality: str) -> str:
    """What the pairs whose better map earned less have in common: the share whose better map took more robot time,
    and their median quality gap beside that of the agreeing pairs (a return that pays by length, or maps too close
    for it to tell)."""
    longer, gaps = [], {True: [], False: []}
    for _, good, bad, agrees in _pairs(episodes, returns, quality):
        gaps[agrees].append(abs(good[quality] - bad[quality]))
        if not agrees:
            longer.append(good["sim_steps"] > bad["sim_steps"])
    if not longer:
        return "-"
    agreeing = f"{np.median(gaps[True]):.3g}" if gaps[True] else "-"
    return f"{np.mean(longer):.0%} longer, gap {np.median(gaps[False]):.3g} ({agreeing})"


def _bootstrapped_share(counts: dict, baseline: dict | None = None) -> PairedDifference:
    """The share of agreeing pairs of :func:`_agreement_by_unit`'s ``counts``, its interval bootstrapped over the units
    (:func:`~emmi_gym.tools.evaluation.intervals.share_bootstrap`); with ``baseline`` (the counts of the same episodes
    played otherwise), the share minus the baseline's on the units both hold, paired by unit."""
    units = list(counts) if baseline is None else [u for u in counts if u in baseline]
    return share_bootstrap([counts[u][0] for u in units], [counts[u][1] for u in units], units,
                           None if baseline is None else ([baseline[u][0] for u in units],
                                                          [baseline[u][1] for u in units]))


def _share(agreement: PairedDifference) -> str:
    return "-" if math.isnan(agreement.mean) else \
        f"{agreement.mean:.0%} [{agreement.low:.0%}, {agreement.high:.0%}]"


def _within_correlation(episodes, returns, quality: str) -> float:
    """Pearson's r of return and quality, each centred on its episode's mean over the policies."""
    xs, ys = [], []
    for key, by_policy in episodes.items():
        if len(by_policy) < 2:
            continue
        r = np.array([returns[key, p] for p in by_policy])
        q = QUALITIES[quality] * np.array([by_policy[p][quality] for p in by_policy], dtype=np.float64)
        if not np.all(np.isfinite(q)):
            continue
        xs.extend(r - r.mean())
        ys.extend(q - q.mean())
    x, y = np.array(xs), np.array(ys)
    if x.size < 3 or x.std() == 0 or y.std() == 0:
        return math.nan
    return float(np.corrcoef(x, y)[0, 1])


def alignment(rows: list[dict], variants, time_costs, discounts, qualities=tuple(QUALITIES),
              reads: Mapping[str, str] | None = None) -> list[dict]:
    """One result per (variant, time cost, discount) over the episodes of ``rows`` (rows with ``steps``):
    each policy's mean return, the agreement and within-episode correlation for each quality, and
    the preferred policy; with ``reads`` (what each variant reads: ``"filter"``, ``"ground truth"``), a
    ``reads`` column beside the reward."""
    episodes = _episodes(rows)
    policies = list(dict.fromkeys(row["policy"] for row in rows))
    results = []
    for variant in variants:
        for time_cost in time_costs:
            for discount in discounts:
                returns = _returns(episodes, variant, time_cost, discount)
                means = {p: float(np.mean([v for (_, q), v in returns.items() if q == p])) for p in policies}
                result = {"reward": variant, **({"reads": reads.get(variant, "-")} if reads is not None else {}),
                          "time_cost": time_cost, "discount": discount.label,
                          **{f"return {p}": means[p] for p in policies},
                          "prefers": max(means, key=means.get)}
                for quality in qualities:
                    counts = _agreement_by_unit(episodes, returns, quality)
                    agree, pairs = (sum(count[i] for count in counts.values()) for i in (0, 1))
                    result[f"agree {quality}"] = f"{agree}/{pairs}"
                    result[f"agree {quality}, 95%"] = _share(_bootstrapped_share(counts))
                    result[f"disagreeing {quality}"] = _disagreements(episodes, returns, quality)
                    result[f"r {quality}"] = _within_correlation(episodes, returns, quality)
                results.append(result)
    return results


def agreement_change(rows: list[dict], baseline_rows: list[dict], variants, time_costs, discounts,
                     qualities=tuple(QUALITIES), baseline_reward: str | None = None) -> list[dict]:
    """For each (variant, time cost, discount, quality), the agreement of ``rows`` beside that of ``baseline_rows``
    (the same episodes played otherwise: another filter, another version) and the change, its interval a bootstrap
    that draws the units (plans, or one world's episodes) both hold, each with all its pairs in both: ``{"reward",
    "time_cost", "discount", "quality", "baseline", "agreement", "change", "low", "high", "units", "detectable"}``.
    With ``baseline_reward``, the baseline's agreement is that reward's (at the same time cost and discount), not
    the variant's own: two rewards on the same episodes when ``baseline_rows`` is ``rows``.
    A ``ValueError`` where the two share no unit."""
    episodes, baseline = _episodes(rows), _episodes(baseline_rows)
    shared = set(_units(episodes).values()) & set(_units(baseline).values())
    if not shared:
        raise ValueError(f"the two sets of episodes share no plan (or seed on one world): e.g. {next(iter(episodes))} "
                         f"against {next(iter(baseline))}")
    results = []
    for variant in variants:
        for time_cost in time_costs:
            for discount in discounts:
                returns = _returns(episodes, variant, time_cost, discount)
                baseline_returns = _returns(baseline, baseline_reward or variant, time_cost, discount)
                for quality in qualities:
                    after, before = (_agreement_by_unit(e, r, quality)
                                     for e, r in ((episodes, returns), (baseline, baseline_returns)))
                    after, before = ({u: c for u, c in counts.items() if u in shared} for counts in (after, before))
                    change = _bootstrapped_share(after, before)
                    results.append({"reward": variant, "time_cost": time_cost, "discount": discount.label,
                                    "quality": quality, "baseline": _share(_bootstrapped_share(before)),
                                    "agreement": _share(_bootstrapped_share(after)), "change": change.mean,
                                    "low": change.low, "high": change.high, "units": change.plans,
                                    "detectable": change.detectable})
    return results


def change_markdown(results: list[dict], baseline: str) -> str:
    """:func:`agreement_change` as a markdown table, the changes in percentage points."""
    lines = [f"Agreement with the better map beside {baseline}'s, on the plans both played; change in points, paired "
             "by plan, mean [95% interval] (detectable: the smallest change found with 80% power):", "",
             "| reward | time cost | discount | quality | plans | baseline | agreement | change | detectable |",
             "| --- | --- | --- | --- | --- | --- | --- | --- | --- |"]
    lines += [f"| {r['reward']} | {r['time_cost']:g} | {r['discount']} | {r['quality']} | {r['units']} | "
              f"{r['baseline']} | {r['agreement']} | {100 * r['change']:+.0f} [{100 * r['low']:+.0f}, "
              f"{100 * r['high']:+.0f}] | {100 * r['detectable']:.0f} |" for r in results]
    return "\n".join(lines)


def _first_world(episodes, policy: str) -> str:
    world, seed = next(key for key, by_policy in episodes.items() if policy in by_policy)
    return f"{world} #{seed}"


def paired_returns(rows: list[dict], variants, time_costs, discounts, against: str) -> list[dict]:
    """For each (variant, time cost, discount), each policy's discounted return minus ``against``'s on the
    episodes (world, seed) both played: ``{"reward", "time_cost", "discount", "policy", "difference", "low",
    "high", "episodes"}`` (mean and Student-t 95% interval); a ``ValueError`` for a policy that shares no episode
    with ``against``."""
    episodes = _episodes(rows)
    policies = [p for p in dict.fromkeys(row["policy"] for row in rows) if p != against]
    results = []
    for variant in variants:
        for time_cost in time_costs:
            for discount in discounts:
                returns = _returns(episodes, variant, time_cost, discount)
                for policy in policies:
                    differences = [returns[key, policy] - returns[key, against] for key, by_policy in episodes.items()
                                   if policy in by_policy and against in by_policy]
                    if not differences:
                        raise ValueError(f"{policy} played no episode (world and seed) that {against} played, so "
                                         f"none pairs them: e.g. {_first_world(episodes, policy)} against "
                                         f"{_first_world(episodes, against)}")
                    mean, low, high, n = mean_interval(differences)
                    results.append({"reward": variant, "time_cost": time_cost, "discount": discount.label,
                                    "policy": policy, "difference": mean, "low": low, "high": high, "episodes": n})
    return results


def paired_markdown(results: list[dict], against: str, privileged=()) -> str:
    """:func:`paired_returns` as a markdown table: a row per policy, a column per return (reward, time cost,
    discount; a reward of ``privileged`` marked so), each cell the mean difference and its interval, as a page
    compares many policies."""
    returns = list(dict.fromkeys((r["reward"], r["time_cost"], r["discount"]) for r in results))
    cells = {(r["policy"], (r["reward"], r["time_cost"], r["discount"])):
             f"{_format(r['difference'])} [{_format(r['low'])}, {_format(r['high'])}]" for r in results}
    lines = [f"Return minus {against}'s on the same episodes, mean [95% interval]:", "",
             "| policy | episodes | " + " | ".join(
                 f"{reward}{' (privileged)' if reward in privileged else ''}, {time_cost:g}, {discount}"
                 for reward, time_cost, discount in returns) + " |",
             "| --- | --- |" + " --- |" * len(returns)]
    for policy in dict.fromkeys(r["policy"] for r in results):
        episodes = max(r["episodes"] for r in results if r["policy"] == policy)
        lines.append(f"| {policy} | {episodes} | " + " | ".join(cells.get((policy, key), "-") for key in returns)
                     + " |")
    return "\n".join(lines)


def policy_front(rows: list[dict], qualities=tuple(QUALITIES)) -> list[dict]:
    """Each policy's mean final map quality and robot time (simulator steps): the front the rewards choose on."""
    policies = list(dict.fromkeys(row["policy"] for row in rows))
    return [{"policy": p, **{q: float(np.nanmean([r[q] for r in rows if r["policy"] == p])) for q in qualities},
             "sim_steps": float(np.mean([r["sim_steps"] for r in rows if r["policy"] == p]))} for p in policies]


def markdown(results: list[dict], front: list[dict], title: str) -> str:
    """The front and the alignment results as markdown tables."""
    lines = [title, "", "| policy | " + " | ".join(k for k in front[0] if k != "policy") + " |",
             "| --- |" + " --- |" * (len(front[0]) - 1)]
    lines += ["| " + " | ".join([row["policy"]] + [f"{v:.3f}" if k != "sim_steps" else f"{v:.0f}"
                                                   for k, v in row.items() if k != "policy"]) + " |" for row in front]
    columns = list(results[0])
    lines += ["", "| " + " | ".join(columns) + " |", "|" + " --- |" * len(columns)]
    lines += ["| " + " | ".join(f"{row[c]:g}" if c == "time_cost" else _format(row[c]) for c in columns) + " |"
              for row in results]
    return "\n".join(lines)


def _format(value) -> str:
    if isinstance(value, float):
        return "-" if value != value else f"{value:+.3f}" if abs(value) < 100 else f"{value:+.0f}"
    return str(value)
