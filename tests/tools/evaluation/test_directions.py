"""Which side of each measure is better (emmi_gym.tools.evaluation.directions), as the paper says, and how its numbers
are written; the tables that use it: tools/experiments/test_summaries.py."""

import math

import pytest

from emmi_gym.tools.evaluation.directions import BETTER, HIGHER, LOWER, Tally, count_better, format_number


@pytest.mark.parametrize(("column", "side"), [("oracle_accuracy", HIGHER), ("ate", LOWER), ("emmi_change", HIGHER),
                                              ("pose_entropy_change", LOWER), ("joint_entropy_change", LOWER)])
def test_directions_follow_the_paper(column, side):
    assert BETTER[column] == side
    assert count_better([side * 0.1, -side * 0.1, 0.0, math.nan], column) == Tally(better=1, tied=1, worse=1)
    assert count_better([1.0], "sim_steps") is None
    assert format_number(3.14159, column) == "3.142" and format_number(-2.0, "decisions", signed=True) == "-2"


def test_a_tie_is_counted_as_a_tie_not_a_loss():
    assert str(count_better([0.0, 0.0, 0.0], "completed")) == "0/3 (3 tied)"
    assert str(count_better([0.2, -0.1], "oracle_accuracy")) == "1/2"
