"""What a benchmark's routes explain of its maps: within the same held-out worlds, how much of the
differences in final ATE and accuracy against the oracle map the order (whether the loop was closed
first), the revisits (the share of decisions that went back to a revisit target) and the robot time
explain, and what each policy gains beyond them.

Per score, a least-squares fit within worlds (each world's mean taken out of the score and of the
predictors: a world fixed effect)::

    score - world mean = b_order * closed_first + b_revisit * revisit_share + b_time * sim_steps / 1000

and each policy's mean residual: what it gains or loses beyond what its order, revisits and time
predict. Where no episode has an order (floor plans: no loop to close first), the fit has the revisits and the
time only. Episodes are those of ``emmi-gym benchmark`` (its ``benchmark_episodes.csv``: a world is an episode
seed, a reward's agents are pooled) or of ``emmi-gym evaluate`` (``episodes.csv``: a world is a world and seed).
Intervals are 95% from a bootstrap over worlds (whole worlds resampled, every policy's
episode on a world kept together, each drawn copy of a world its own fixed effect); they hold the
variation between worlds, not that between an agent's training seeds (the benchmark's summary has
that).
"""

from __future__ import annotations

import numpy as np

from ..evaluation.loop_order import LOOP_ORDER_KEY

PREDICTORS = {LOOP_ORDER_KEY: "closed the loop first", "revisit_share": "revisit share",
              "sim_steps": "robot time (1000 steps)"}
SCALE = {"sim_steps": 1e-3}
SCORES = {"ate": "ATE (m)", "oracle_accuracy": "accuracy against the oracle map"}


def _is_number(value) -> bool:
    return isinstance(value, (int, float, np.number)) and bool(np.isfinite(value))


def policy_name(row: dict) -> str:
    """An episode row's policy: in a benchmark's rows a reward's agents pooled (``emmi agents``) or the baseline's
    name; in an evaluation's, its policy."""
    if "variant" not in row:
        return row["policy"]
    return f"{row['variant']} agents" if row["kind"] == "agent" else row["variant"]


def world_of(row: dict):
    """An episode row's world, which every policy played: a benchmark's episode seed, an evaluation's world and
    seed."""
    return row["episode_seed"] if "episode_seed" in row else f"{row['world']} #{row['seed']}"


def measured_predictors(rows: list[dict]) -> list[str]:
    """The :data:`PREDICTORS` some episode has a number for (the order only on the loop worlds)."""
    return [key for key in PREDICTORS if any(_is_number(row.get(key)) for row in rows)]


def within_world(values: np.ndarray, worlds: np.ndarray) -> np.ndarray:
    """``values`` (rows x columns) less the mean of their world's rows (a world fixed effect)."""
    out = np.array(values, dtype=float)
    for world in np.unique(worlds):
        rows = worlds == world
        out[rows] -= out[rows].mean(axis=0)
    return out


def fit(score: np.ndarray, predictors: np.ndarray, worlds: np.ndarray, policies: np.ndarray, names):
    """The within-world coefficients, the share of the within-world variance they explain (R^2) and each
    policy's mean residual, as one vector: coefficients, R^2, then residuals in the order of ``names``."""
    y = within_world(score[:, None], worlds)[:, 0]
    x = within_world(predictors, worlds)
    coefficients, *_ = np.linalg.lstsq(x, y, rcond=None)
    residual = y - x @ coefficients
    r2 = 1.0 - residual.var() / y.var() if y.var() > 0 else np.nan
    means = [residual[policies == name].mean() if np.any(policies == name) else np.nan for name in names]
    return np.concatenate([coefficients, [r2], means])


def _on_shared_worlds(rows: list[dict]) -> list[dict]:
    """The ``rows`` on the worlds every policy played (a world one policy lacks compares nothing); a
    ``ValueError`` if there is none, as when evaluations made on different worlds or seeds are pooled."""
    played: dict = {}
    for row in rows:
        played.setdefault(world_of(row), set()).add(policy_name(row))
    everyone = {policy_name(row) for row in rows}
    shared = {world for world, policies in played.items() if policies == everyone}
    if not shared:
        examples = {name: next(world for world, policies in played.items() if name in policies)
                    for name in sorted(everyone)}
        raise ValueError("no world and seed was played by every policy, so none compares them: "
                         + "; ".join(f"{name} played e.g. {world}" for name, world in examples.items()))
    return [row for row in rows if world_of(row) in shared]


def attribution(rows: list[dict], score: str, bootstrap: int, seed: int = 0):
    """The estimate of :func:`fit` on the episode ``rows`` (``read_csv`` of a ``benchmark_episodes.csv``) on the
    worlds every policy played, its 95% interval from ``bootstrap`` resamplings of the worlds (drawn with
    ``seed``), the policies' names in the order of the residuals, the number of worlds and the predictors fitted
    (:func:`measured_predictors`), in the order of the coefficients."""
    predictors = measured_predictors(rows)
    usable = [row for row in rows if all(_is_number(row.get(key)) for key in (score, *predictors))]
    if not usable or not {"revisit_share", "sim_steps"} <= set(predictors):
        raise ValueError(f"no episode has a number in each of {score}, revisit_share and sim_steps (and "
                         f"{LOOP_ORDER_KEY} on the loop worlds): episode rows of 'emmi-gym benchmark' "
                         "(benchmark_episodes.csv) or of 'emmi-gym evaluate' (episodes.csv) are expected")
    usable = _on_shared_worlds(usable)
    worlds = np.array([world_of(row) for row in usable])
    policies = np.array([policy_name(row) for row in usable])
    names = sorted(set(policies), key=lambda name: (not name.endswith(" agents"), name))
    y = np.array([row[score] for row in usable], dtype=float)
    x = np.array([[row[key] * SCALE.get(key, 1.0) for key in predictors] for row in usable], dtype=float)
    estimate = fit(y, x, worlds, policies, names)
    rng = np.random.default_rng(seed)
    unique = np.unique(worlds)
    draws = []
    for _ in range(bootstrap):
        chosen = rng.choice(unique, size=unique.size, replace=True)
        index = np.concatenate([np.flatnonzero(worlds == world) for world in chosen])
        # each drawn copy of a world is a world of its own, so its rows are demeaned apart from the other copies
        copies = np.concatenate([np.full(np.count_nonzero(worlds == world), i) for i, world in enumerate(chosen)])
        draws.append(fit(y[index], x[index], copies, policies[index], names))
    low, high = np.nanpercentile(np.array(draws), [2.5, 97.5], axis=0)
    return estimate, low, high, names, len(unique), predictors


def markdown(rows: list[dict], bootstrap: int) -> str:
    """Per score of :data:`SCORES`, a table of the coefficients, R^2 and each policy's mean residual."""
    lines = []
    for score, label in SCORES.items():
        estimate, low, high, names, worlds, predictors = attribution(rows, score, bootstrap)
        k = len(predictors)
        lines += [f"**{label}**, within {worlds} held-out episodes (each a world and seed every policy played): "
                  f"the variance explained R^2 = {estimate[k]:.2f} "
                  f"[{low[k]:.2f}, {high[k]:.2f}]", "", "| term | estimate [95% interval] |", "| --- | --- |"]
        lines += [f"| {PREDICTORS[key]} | {estimate[i]:+.3f} [{low[i]:+.3f}, {high[i]:+.3f}] |"
                  for i, key in enumerate(predictors)]
        lines += [f"| residual of {name} | {estimate[k + 1 + i]:+.3f} [{low[k + 1 + i]:+.3f}, "
                  f"{high[k + 1 + i]:+.3f}] |" for i, name in enumerate(names)]
        lines.append("")
    return "\n".join(lines)
