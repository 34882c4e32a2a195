"""Map quality at equal robot time: each episode's trace of scores after every decision, and two episodes of the
same world and seed read at the robot time the shorter took."""

import math

import pytest

from emmi_gym.tools.evaluation.comparison import ComparisonSettings, make_actor, markdown_table, play_on_world
from emmi_gym.tools.evaluation.episodes import info_options, play_episode
from emmi_gym.tools.evaluation.robot_time import (
    TRACE,
    TRACED,
    at_equal_robot_time,
    read_together,
    score_at,
    trace_rows,
    with_traces,
    without_traces,
)

#: A small generated world, four decisions an episode.
SMALL = ComparisonSettings("emmi_gym/Explore-v1", {"particles": 3, "generator": {"nx": 2, "ny": 2, "n_loops": 1},
                                                   "max_decisions": 4})


def point(time, accuracy, ate=0.0, coverage=0.5, building=0.45):
    return {"sim_steps": time, "oracle_accuracy": accuracy, "ate": ate, "wall_consistency": 1.0, "coverage": coverage,
            "building_accuracy": building}


def test_a_score_between_two_decisions_is_linear_between_them_and_past_the_end_the_final_one():
    trace = [point(0, 1.0), point(100, 0.9), point(100, 0.8), point(300, 0.6)]
    assert score_at(trace, "oracle_accuracy", 50) == pytest.approx(0.9)  # from 1.0 at 0 to 0.8 at 100
    assert score_at(trace, "oracle_accuracy", 100) == pytest.approx(0.8)  # the last decision of that time
    assert score_at(trace, "oracle_accuracy", 200) == pytest.approx(0.7)
    assert score_at(trace, "oracle_accuracy", 10_000) == 0.6 and score_at(trace, "oracle_accuracy", -5) == 1.0


def test_two_episodes_are_read_at_the_shorter_ones_end():
    short = {"world": "w", "seed": 1, "policy": "agent", TRACE: [point(0, 1.0, 0.0), point(200, 0.9, 0.2)]}
    long = {"world": "w", "seed": 1, "policy": "closer", TRACE: [point(0, 1.0, 0.0), point(100, 0.8, 0.4),
                                                                 point(400, 0.95, 0.1)]}
    mine, theirs = read_together(short, long)
    assert mine == {"sim_steps": 200, "oracle_accuracy": 0.9, "ate": 0.2, "wall_consistency": 1.0, "coverage": 0.5,
                    "building_accuracy": 0.45}
    assert theirs["sim_steps"] == 200 and theirs["oracle_accuracy"] == pytest.approx(0.85)
    assert theirs["ate"] == pytest.approx(0.3)
    other_seed = {**long, "seed": 2}
    read = at_equal_robot_time([short, long, other_seed], "agent", "closer")
    assert [(r["policy"], r["seed"]) for r in read] == [("agent", 1), ("closer", 1)]  # seed 2 has no pair
    table = markdown_table(read, "agent", "closer", "agent - closer")
    assert "1 pairs" in table and "| accuracy against the oracle map | higher | 0.850" in table


def test_at_equal_robot_time_mapping_less_is_not_read_as_mapping_better():
    """An agent that stops early having explored little keeps a high oracle accuracy and a low ATE on the little it
    mapped; read at its end, the planner that explored more looks worse on those, and the coverage and the building
    accuracy (unmapped cells counting as wrong) in the same table say what the agent left out."""
    rows = []
    for plan in ("a", "b", "c"):
        rows += [{"world": plan, "plan": plan, "seed": 1, "policy": "agent",
                  TRACE: [point(0, 1.0), point(1000, 0.95, 0.1, coverage=0.6, building=0.55)]},
                 {"world": plan, "plan": plan, "seed": 1, "policy": "planner",
                  TRACE: [point(0, 1.0), point(1000, 0.9, 0.3, coverage=0.8, building=0.7),
                          point(2000, 0.9, 0.3, coverage=0.95, building=0.85)]}]
    read = at_equal_robot_time(rows, "agent", "planner")
    assert {r["plan"] for r in read} == {"a", "b", "c"}  # the plans stay with the rows read
    table = markdown_table(read, "agent", "planner", "agent - planner at equal robot time")
    lines = {line.split(" | ")[0].strip("| "): line for line in table.splitlines() if line.startswith("| ")}
    assert "+0.050" in lines["accuracy against the oracle map"] and "-0.200" in lines["ATE (m)"]
    assert "-0.200" in lines["coverage"] and "-0.150" in lines["building accuracy (unmapped counts as wrong)"]
    assert "3 pairs (world, seed) on 3 plans" in table


def test_a_trace_file_without_a_score_gives_it_as_nan():
    points = [{"world": "w", "seed": 1, "policy": "agent", **{k: v for k, v in point(t, 0.9).items()
                                                              if k != "building_accuracy"}} for t in (0, 100)]
    (row,) = with_traces([{"world": "w", "seed": 1, "policy": "agent"}], points)
    assert row[TRACE][1]["oracle_accuracy"] == 0.9 and math.isnan(row[TRACE][1]["building_accuracy"])


def test_an_episodes_trace_starts_at_the_reset_and_ends_at_its_final_scores():
    rows = [play_on_world(None, 8, policy, SMALL, keep_trace=True) for policy in ("frontier", "random")]
    for row in rows:
        trace = row[TRACE]
        assert trace[0]["sim_steps"] == 0 and len(trace) == row["decisions"] + 1
        assert all(trace[-1][column] == row[column] for column in (*TRACED, "sim_steps"))
        assert [p["sim_steps"] for p in trace] == sorted(p["sim_steps"] for p in trace)
    assert play_on_world(None, 8, "frontier", SMALL)["ate"] == rows[0]["ate"]  # keeping it changes nothing
    assert TRACE not in play_on_world(None, 8, "frontier", SMALL)
    long_form = trace_rows(rows)
    assert len(long_form) == sum(len(row[TRACE]) for row in rows)
    assert set(long_form[0]) == {"world", "seed", "policy", "sim_steps", *TRACED}
    assert all(TRACE not in row for row in without_traces(rows)) and TRACE in rows[0]
    # a trace file's points give each episode its trace back, matched on world, seed and policy
    assert with_traces(without_traces(rows), long_form) == rows
    assert TRACE not in with_traces(without_traces([{**rows[0], "seed": 9}]), long_form)[0]


def test_a_trace_needs_the_scores_after_every_step_which_the_env_gives_when_asked():
    """The env measures the ground-truth scores for the episode's last info alone unless asked: a trace asks, and
    a trace from an env that was not asked is refused at the reset rather than read from figures that are not
    there."""
    env = SMALL.env_on(None)
    with pytest.raises(ValueError, match="make the env with info_scores='always'"):
        play_episode(env, make_actor("frontier"), 8, keep_trace=True)
    assert info_options(keep_trace=True) == {"info_scores": "always"}
    assert info_options(keep_steps=True) == {"info_rewards": "all"}
    assert "oracle_accuracy" in SMALL.env_on(None, keep_trace=True).reset(seed=8)[1]
