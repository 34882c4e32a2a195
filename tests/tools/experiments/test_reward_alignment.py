"""Reward alignment: returns recomputed from kept steps, and how they rank the policies' final maps."""

import math

import numpy as np
import pytest

from emmi_gym.tools.evaluation.comparison import ComparisonSettings, compare_on
from emmi_gym.tools.experiments.reward_alignment import (
    Discount,
    agreement_change,
    alignment,
    change_markdown,
    discounted_return,
    markdown,
    paired_markdown,
    paired_returns,
    policy_front,
)


def step(emmi=0.0, coverage=0.0, duration=100, collision=0.0):
    return {"emmi": emmi, "coverage": coverage, "collision": collision, "duration": duration}


def test_discounts_follow_decisions_or_robot_time():
    steps = [step(emmi=1.0, duration=50), step(emmi=1.0, duration=150), step(emmi=1.0, duration=10)]
    assert discounted_return(steps, "emmi", 0.0, Discount()) == 3.0
    assert discounted_return(steps, "emmi", 0.0, Discount(0.5)) == 1.0 + 0.5 + 0.25
    assert discounted_return(steps, "emmi", 0.0, Discount(0.5, 100)) == pytest.approx(1 + 0.5 ** 0.5 + 0.5 ** 2)
    assert discounted_return(steps, "emmi", 0.01, Discount()) == pytest.approx(3.0 - 0.01 * 210)
    assert Discount.parse("0.9@100") == Discount(0.9, 100) and Discount.parse("none") == Discount()
    for bad in ("fast", "1.5", "0.9@0"):
        with pytest.raises(ValueError, match="discount"):
            Discount.parse(bad)


def episode(world, policy, quality, ate, steps):
    return {"world": world, "seed": 0, "policy": policy, "oracle_accuracy": quality, "ate": ate,
            "sim_steps": sum(s["duration"] for s in steps), "steps": steps}


def test_agreement_and_correlation_rank_the_better_map_against_the_higher_return():
    # "slow" maps better on both plans; coverage pays it more, EMMI pays "fast" more on plan b
    rows = [episode("a", "fast", 0.80, 0.4, [step(emmi=0.5, coverage=0.5)]),
            episode("a", "slow", 0.90, 0.2, [step(emmi=0.6, coverage=0.6, duration=300)]),
            episode("b", "fast", 0.70, 0.5, [step(emmi=0.9, coverage=0.2)]),
            episode("b", "slow", 0.75, 0.3, [step(emmi=0.1, coverage=0.4, duration=300)])]
    results = {(r["reward"], r["time_cost"]): r for r in alignment(rows, ["emmi", "coverage"], [0.0, 0.01],
                                                                   [Discount()])}
    assert results["coverage", 0.0]["agree oracle_accuracy"] == "2/2" and results["coverage", 0.0]["prefers"] == "slow"
    assert results["coverage", 0.0]["agree oracle_accuracy, 95%"] == "100% [100%, 100%]"
    assert results["emmi", 0.0]["agree oracle_accuracy, 95%"] == "50% [0%, 100%]"   # plan a agrees, b not
    # plan b's better map ("slow") took longer and earned less; its maps are closer than plan a's
    assert results["emmi", 0.0]["disagreeing oracle_accuracy"] == "100% longer, gap 0.05 (0.1)"
    assert results["coverage", 0.0]["disagreeing oracle_accuracy"] == "-"
    centred_returns, centred_quality = [-0.05, 0.05, -0.1, 0.1], [-0.05, 0.05, -0.025, 0.025]
    assert results["coverage", 0.0]["r oracle_accuracy"] == pytest.approx(np.corrcoef(centred_returns,
                                                                                      centred_quality)[0, 1])
    assert results["emmi", 0.0]["agree oracle_accuracy"] == "1/2" and results["emmi", 0.0]["agree ate"] == "1/2"
    assert results["coverage", 0.01]["prefers"] == "fast"   # robot time costs more than the better map earns
    assert results["coverage", 0.01]["agree ate"] == "0/2"
    front = {row["policy"]: row for row in policy_front(rows)}
    assert front["slow"]["sim_steps"] == 300 and front["fast"]["oracle_accuracy"] == pytest.approx(0.75)
    assert "| coverage | 0.01 | none |" in markdown(list(results.values()), policy_front(rows), "t")


def test_the_tables_say_what_each_reward_reads():
    rows = [episode(w, p, q, 0.3, [dict(step(emmi=e), ate=a)]) for w, p, q, e, a in
            (("a", "base", 0.80, 1.0, 0.1), ("a", "agent", 0.90, 0.5, 0.3), ("b", "base", 0.70, 2.0, 0.0),
             ("b", "agent", 0.75, 2.5, 0.2))]
    reads = {"emmi": "filter", "ate": "ground truth"}
    results = alignment(rows, ["emmi", "ate"], [0.0], [Discount()], reads=reads)
    assert [(r["reward"], r["reads"]) for r in results] == [("emmi", "filter"), ("ate", "ground truth")]
    assert "| ate | ground truth | 0 | none |" in markdown(results, policy_front(rows), "t")
    assert "reads" not in alignment(rows, ["emmi"], [0.0], [Discount()])[0]
    paired = paired_returns(rows, ["emmi", "ate"], [0.0], [Discount()], "base")
    assert "| policy | episodes | emmi, 0, none | ate (privileged), 0, none |" in \
        paired_markdown(paired, "base", privileged=("ate",))


def test_returns_paired_with_a_policy_give_the_difference_on_each_episode_and_its_interval():
    rows = [episode(w, p, 0.9, 0.2, [step(emmi=e)]) for w, p, e in
            (("a", "base", 1.0), ("a", "agent", 1.5), ("b", "base", 2.0), ("b", "agent", 2.1), ("c", "base", 0.0),
             ("c", "agent", 0.4), ("d", "agent", 9.0))]   # no "base" on d: not paired
    (result,) = paired_returns(rows, ["emmi"], [0.0], [Discount()], "base")
    assert result["policy"] == "agent" and result["episodes"] == 3
    assert result["difference"] == pytest.approx(1.0 / 3.0)
    half_width = 4.302653 * np.std([0.5, 0.1, 0.4], ddof=1) / np.sqrt(3)   # Student's t, 2 degrees of freedom
    assert (result["low"], result["high"]) == pytest.approx((1 / 3 - half_width, 1 / 3 + half_width), rel=1e-5)
    with pytest.raises(ValueError, match="stranger played no episode .* that base played"):
        paired_returns([*rows, episode("z", "stranger", 0.9, 0.2, [step(emmi=1.0)])], ["emmi"], [0.0], [Discount()],
                       "base")
    table = paired_markdown([result], "base").splitlines()
    assert table[2] == "| policy | episodes | emmi, 0, none |" and table[4].startswith("| agent | 3 | +0.333 [")


def test_kept_steps_add_up_to_the_return_the_env_paid():
    settings = ComparisonSettings("emmi_gym/Explore-v1", {"particles": 3, "max_decisions": 3,
                                                          "generator": {"nx": 2, "ny": 2, "n_loops": 1}})
    rows = compare_on([(None, 4)], ["frontier", "random"], settings, workers=1, progress=False, keep_steps=True)
    time_cost = settings.env_on(None).unwrapped.config.time_cost
    for row in rows:
        assert len(row["steps"]) == row["decisions"] >= 1
        assert math.isclose(discounted_return(row["steps"], "emmi", time_cost, Discount()), row["return"],
                            rel_tol=1e-9, abs_tol=1e-12)


def test_a_change_of_agreement_pairs_the_same_plans_played_otherwise():
    # on plans a-d "slow" maps better; the old filter's EMMI paid "fast" more on a and b, the new one pays "slow"
    def played(emmi_slow):
        return [row for world, paid in zip("abcd", emmi_slow, strict=True) for row in (
            episode(world, "fast", 0.80, 0.4, [step(emmi=0.5)]),
            episode(world, "slow", 0.90, 0.2, [step(emmi=paid)]))]
    before, after = played([0.1, 0.1, 0.9, 0.9]), played([0.9, 0.9, 0.9, 0.9])
    results = {r["quality"]: r for r in agreement_change(after[:6], before, ["emmi"], [0.0], [Discount()])}
    change = results["oracle_accuracy"]
    assert change["units"] == 3   # plan d only in the baseline: left out of both
    assert change["baseline"] == "33% [0%, 100%]" and change["agreement"] == "100% [100%, 100%]"
    assert change["change"] == pytest.approx(2 / 3) and 0 <= change["low"] <= 2 / 3 <= change["high"] <= 1
    table = change_markdown(list(results.values()), "old")
    assert "| emmi | 0 | none | oracle_accuracy | 3 | 33% [0%, 100%] | 100% [100%, 100%] | +67 [" in table
    with pytest.raises(ValueError, match="share no plan"):
        agreement_change(after[:2], before[2:4], ["emmi"], [0.0], [Discount()])


def test_two_rewards_agreement_on_the_same_episodes_paired_by_plan():
    # on plans a-c "slow" maps better; EMMI pays it more on all three, the coverage on none
    rows = [row for world in "abc" for row in (
        episode(world, "fast", 0.80, 0.4, [step(emmi=0.1, coverage=0.9)]),
        episode(world, "slow", 0.90, 0.2, [step(emmi=0.9, coverage=0.1)]))]
    results = {r["quality"]: r for r in agreement_change(rows, rows, ["emmi"], [0.0], [Discount()],
                                                         baseline_reward="coverage")}
    change = results["oracle_accuracy"]
    assert change["reward"] == "emmi" and change["units"] == 3
    assert change["baseline"] == "0% [0%, 0%]" and change["agreement"] == "100% [100%, 100%]"
    assert change["change"] == pytest.approx(1.0)
