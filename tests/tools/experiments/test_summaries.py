"""Every summary table says which side of each measure is better, and its comparison column counts the
pairs on that side ("A better"), never merely "A higher"; numbers are written alike in every table."""

import math

from emmi_gym.tools.evaluation.comparison import format_table, markdown_table
from emmi_gym.tools.evaluation.directions import BETTER, HIGHER, better_side
from emmi_gym.tools.experiments.report import SUMMARY_COLUMNS, markdown_summary
from emmi_gym.tools.training.reward_benchmark import markdown


def _row_cells(table: str, label: str) -> list[str]:
    line = next(line for line in table.splitlines() if line.startswith(f"| {label}"))
    return [cell.strip() for cell in line.strip("|").split("|")]


def _ab_rows(seeds=4) -> list[dict]:
    """A better than B by one unit on every measure with a better side; the others A higher."""
    rows = []
    for seed in range(seeds):
        for arm, sign in (("A", 1.0), ("B", 0.0)):
            row = {"seed": seed, "arm": arm, "completed": 1.0, "first_goal_update": 3}
            for column in SUMMARY_COLUMNS:
                base = 0.2 + 0.01 * seed
                row[column] = base + sign * 0.5 * BETTER.get(column, HIGHER) if column not in (
                    "completed", "loop_closed") else (sign if BETTER.get(column, HIGHER) > 0 else 1 - sign)
            rows.append(row)
    return rows


def test_the_ab_summary_counts_a_better_on_each_measures_better_side():
    table = markdown_summary(_ab_rows(), "test")
    assert "| measure | better | A | B | A - B (paired) | A better |" in table
    for column, label in SUMMARY_COLUMNS.items():
        cells = _row_cells(table, label)
        assert cells[1] == better_side(column), column
        assert cells[-1] == ("-" if column not in BETTER else "4/4"), (column, cells)
    # lower is better: A's ATE is below B's, so the difference is negative and A did better
    ate = _row_cells(table, SUMMARY_COLUMNS["ate"])
    assert ate[1] == "lower" and ate[4].startswith("-0.500") and ate[-1] == "4/4"
    assert "(*)" in _row_cells(table, SUMMARY_COLUMNS["closure_error"])[0]


def test_the_comparison_counts_the_policy_better_on_each_side():
    rows = []
    for seed in range(3):
        rows.append({"world": "w", "seed": seed, "policy": "frontier", "ate": 0.5, "oracle_accuracy": 0.80,
                     "coverage": 0.9, "sim_steps": 969.0})
        rows.append({"world": "w", "seed": seed, "policy": "agent", "ate": 0.3 + 0.3 * (seed == 2),
                     "oracle_accuracy": 0.85, "coverage": 0.9, "sim_steps": 1118.0})
    table = markdown_table(rows, "agent", "frontier", "t")
    assert "| score | better | frontier | agent | agent - frontier | detectable | agent better |" in table
    assert _row_cells(table, "ATE (m)")[1] == "lower" and _row_cells(table, "ATE (m)")[-1] == "2/3"
    assert _row_cells(table, "accuracy against the oracle map")[-1] == "3/3"
    assert _row_cells(table, "coverage")[-1] == "0/3 (3 tied)"  # ties are neither better nor worse
    steps = _row_cells(table, "simulator steps")
    assert steps[1] == "-" and steps[-1] == "-" and steps[2].startswith("969 [") and steps[4].startswith("+149 [")


def test_the_benchmark_headings_name_the_better_side():
    rows = [{"kind": kind, "variant": variant, "seed": seed, "episode_seed": episode, "ate": ate,
             "oracle_accuracy": 0.8, "sim_steps": 1000.0 + episode}
            for kind, variant, seeds, ate in (("agent", "emmi", (0, 1), 0.3), ("baseline", "frontier", (0,), 0.5))
            for seed in seeds for episode in range(3)]
    table = markdown(rows, "header")
    assert "ATE (m) (lower is better)" in table and "accuracy against the oracle map (higher is better)" in table
    assert "| robot time (simulator steps) |" in table  # no better side: no word on it
    assert "| 1001 [1001, 1001] (n=2) |" in table  # a count, without decimals


def test_evaluate_tables_write_counts_without_decimals_and_name_the_sides():
    text = format_table([{"policy": "a", "sim_steps": 969.0, "ate": 0.25, "decisions": 12.0},
                         {"policy": "b", "sim_steps": 1118.0, "ate": math.nan, "decisions": 9.0}])
    lines = text.splitlines()
    assert lines[1].split() == ["a", "969", "0.250", "12"] and lines[2].split() == ["b", "1118", "-", "9"]
    assert lines[-1] == "better: lower ate"
