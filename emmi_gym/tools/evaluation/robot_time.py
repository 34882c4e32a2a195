"""Map quality at equal robot time: two policies' episodes on the same (world, seed), both read at the robot time
the shorter of the two took.

Policies stop at different times (one reaches the coverage target sooner), and a final map made in more robot time
is not a fair win: an evaluation "at equal robot time" reads the longer episode at the moment the shorter one ended.
Each episode keeps a trace of its ground-truth scores after every decision (and at the reset); the score at a robot
time between two decisions is linear between them (a decision on a floor plan moves the robot for 100-200
simulator steps), and an episode read past its end gives its final score.

The accuracy against the oracle map and the ATE judge only what has been mapped and driven so far, so read early
they favour whoever has explored less; the coverage and the building accuracy (the share of the building mapped
correctly, unmapped cells counting as wrong: :func:`~emmi_gym.scoring.scores.building_accuracy`) are read beside
them, so that mapping less never reads as mapping better.
"""

from __future__ import annotations

import math

import numpy as np

#: The ground-truth scores a trace keeps, read at equal robot time (``info`` keys of the env).
TRACED = ("oracle_accuracy", "ate", "wall_consistency", "coverage", "building_accuracy")
#: The column of the robot time (simulator steps) in a trace and in an episode row.
TIME = "sim_steps"
#: The row key of an episode's trace: a list of :func:`trace_point` dicts.
TRACE = "trace"


def trace_point(info: dict) -> dict:
    """The robot time and the ground-truth scores of an env's ``info`` (at a reset or after a step)."""
    return {TIME: float(info[TIME]), **{k: float(info[k]) for k in TRACED}}


def score_at(trace: list[dict], column: str, robot_time: float) -> float:
    """``column`` of the episode whose ``trace`` is given, at ``robot_time`` simulator steps: linear between the
    decisions that bracket it; its first value before the first point, its last after the end. Points at the
    same time (a decision that moved no simulator step) count as the last of them."""
    times = np.array([point[TIME] for point in trace], dtype=np.float64)
    values = np.array([point[column] for point in trace], dtype=np.float64)
    last_of_each_time = np.append(times[1:] != times[:-1], True)
    return float(np.interp(robot_time, times[last_of_each_time], values[last_of_each_time]))


def read_together(mine: dict, theirs: dict) -> tuple[dict, dict]:
    """Two episodes of the same (world, seed), rows with a :data:`TRACE`, read at the robot time the shorter took:
    for each, ``sim_steps`` that time and the :data:`TRACED` scores at it."""
    robot_time = min(mine[TRACE][-1][TIME], theirs[TRACE][-1][TIME])
    return tuple({TIME: robot_time, **{column: score_at(row[TRACE], column, robot_time) for column in TRACED}}
                 for row in (mine, theirs))


def at_equal_robot_time(rows: list[dict], policy: str, baseline: str, keys=("world", "seed")) -> list[dict]:
    """For each (world, seed) both ``policy`` and ``baseline`` played (rows with a :data:`TRACE`, matched on
    ``keys``), a row of each read together (:func:`read_together`), with ``keys``, the ``plan`` where the row has
    one, and ``policy``: the paired tables of final scores read them as they are."""
    by_key = {(*(row[k] for k in keys), row["policy"]): row for row in rows if TRACE in row}
    read = []
    for (*where, name), mine in by_key.items():
        theirs = by_key.get((*where, baseline))
        if name != policy or theirs is None:
            continue
        for row, scores in zip((mine, theirs), read_together(mine, theirs), strict=True):
            read.append({**{k: row[k] for k in (*keys, "plan") if k in row}, "policy": row["policy"], **scores})
    return read


def trace_rows(rows: list[dict], keys=("world", "seed", "policy")) -> list[dict]:
    """The traces of episode ``rows`` in long form, a row per point (``keys``, then the point's columns), as a
    trace file holds them."""
    return [{**{k: row[k] for k in keys}, **point} for row in rows if TRACE in row for point in row[TRACE]]


def with_traces(rows: list[dict], points: list[dict], keys=("world", "seed", "policy")) -> list[dict]:
    """Episode ``rows`` given back their traces from ``points`` (rows of a trace file, :func:`trace_rows`),
    matched on ``keys``; a row that no point matches stays without a trace, a score a file does not hold (one
    written before the score was traced) is NaN."""
    traces: dict[tuple, list[dict]] = {}
    for point in points:
        traces.setdefault(tuple(point[k] for k in keys), []).append(
            {TIME: float(point[TIME]), **{column: float(point.get(column, math.nan)) for column in TRACED}})
    return [{**row, TRACE: traces[key]} if (key := tuple(row[k] for k in keys)) in traces else dict(row)
            for row in rows]


def without_traces(rows: list[dict]) -> list[dict]:
    """Episode ``rows`` without their traces, as an episodes file holds them."""
    return [{k: v for k, v in row.items() if k != TRACE} for row in rows]
