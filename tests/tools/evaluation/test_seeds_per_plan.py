"""Several seeds per plan: the episodes of each plan, paired per plan and seed across policies, the intervals over
plans (a paired bootstrap that keeps each plan's seeds together) and the smallest difference they detect."""

import numpy as np
import pytest

from emmi_gym.tools.evaluation.comparison import ComparisonSettings, compare_on, episodes_on, markdown_table
from emmi_gym.tools.evaluation.intervals import mean_interval, plan_bootstrap, share_bootstrap
from emmi_gym.world.map_sets import map_set_files


def test_each_plan_is_played_with_its_seeds_and_the_set_wraps_with_fresh_ones():
    files = [str(f) for f in map_set_files("dungeon_maps/test")]
    pairs = episodes_on("dungeon_maps/test", 3, 100, seeds_per_plan=2)
    assert list(pairs) == [(files[0], 100), (files[0], 101), (files[1], 100), (files[1], 101), (files[2], 100),
                           (files[2], 101)]
    assert list(episodes_on("dungeon_maps/test", 2, 100)) == [(files[0], 100), (files[1], 100)]  # one seed a plan
    wrapped = episodes_on("dungeon_maps/test", len(files) + 1, 7, seeds_per_plan=3)
    assert len(wrapped) == 3 * (len(files) + 1) and wrapped[-3:] == [(files[0], 10), (files[0], 11), (files[0], 12)]
    assert len(set(wrapped)) == len(wrapped)
    assert list(episodes_on("loop_corridor", 3, 5)) == [("loop_corridor", 5), ("loop_corridor", 6),
                                                        ("loop_corridor", 7)]


@pytest.mark.parametrize("world", ["loop_corridor", None])
def test_several_seeds_per_plan_need_a_map_set(world):
    with pytest.raises(ValueError, match="2 seeds per plan need a map set to draw the plans from"):
        episodes_on(world, 3, 0, seeds_per_plan=2)
    with pytest.raises(ValueError, match="expected an integer of at least 1, got 0"):
        episodes_on("dungeon_maps/test", 3, 0, seeds_per_plan=0)


def seeded_differences(plans: int, seeds: int, plan_spread: float, seed_spread: float, effect: float = 0.01):
    rng = np.random.default_rng(3)
    per_plan = effect + rng.normal(0.0, plan_spread, plans)
    values = (per_plan[:, None] + rng.normal(0.0, seed_spread, (plans, seeds))).ravel()
    return values, np.repeat([f"plan{k}" for k in range(plans)], seeds)


def test_the_interval_counts_plans_not_seeds_as_the_units():
    """Where the plan explains much of the variance, the seeds of one plan are not independent draws: the naive
    t-interval over all episodes is too narrow; the bootstrap over plans is as wide as the t-interval of the plans'
    means."""
    values, plans = seeded_differences(40, 4, plan_spread=0.03, seed_spread=0.01)
    estimate = plan_bootstrap(values, plans, "oracle_accuracy")
    _, naive_low, naive_high, _ = mean_interval(values)
    means = values.reshape(40, 4).mean(axis=1)
    _, low, high, _ = mean_interval(means)
    assert estimate.plans == 40 and estimate.mean == pytest.approx(values.mean())
    assert estimate.high - estimate.low > 1.5 * (naive_high - naive_low)
    assert estimate.high - estimate.low == pytest.approx(high - low, rel=0.15)
    assert estimate == plan_bootstrap(values, plans, "oracle_accuracy")  # seeded: a table is made the same each time


def test_the_smallest_detectable_difference_falls_with_more_seeds_where_the_seeds_are_the_noise():
    one = plan_bootstrap(*seeded_differences(30, 1, plan_spread=0.002, seed_spread=0.03), "oracle_accuracy")
    four = plan_bootstrap(*seeded_differences(30, 4, plan_spread=0.002, seed_spread=0.03), "oracle_accuracy")
    assert four.detectable < 0.6 * one.detectable
    # 2.8 standard errors: (z_0.975 + z_0.80) x the bootstrap's spread, near the analytic one of the plans' means
    values, plans = seeded_differences(30, 4, plan_spread=0.002, seed_spread=0.03)
    standard_error = values.reshape(30, 4).mean(axis=1).std(ddof=1) / np.sqrt(30)
    assert four.detectable == pytest.approx(2.8 * standard_error, rel=0.15)


def test_agents_are_drawn_with_the_plans_and_one_plan_makes_its_episodes_the_units():
    values, plans = seeded_differences(20, 2, plan_spread=0.01, seed_spread=0.01)
    apart = np.concatenate([values - 0.02, values + 0.02])  # two agents far apart: the agents' spread counts
    agents = np.repeat([0, 1], len(values))
    together = plan_bootstrap(apart, np.concatenate([plans, plans]), "oracle_accuracy")
    crossed = plan_bootstrap(apart, np.concatenate([plans, plans]), "oracle_accuracy", agents=agents)
    assert crossed.high - crossed.low > 2 * (together.high - together.low)
    single = plan_bootstrap([0.1, 0.2, 0.3], ["w", "w", "w"], "ate")
    assert single.plans == 3 and single.low < 0.2 < single.high
    assert plan_bootstrap([0.1], ["w"], "ate").plans == 1 and np.isnan(plan_bootstrap([0.1], ["w"], "ate").detectable)
    assert plan_bootstrap([np.nan], ["w"], "ate").plans == 0
    with pytest.raises(ValueError, match="2 differences, 1 plans, 2 agents and 2 episodes"):
        plan_bootstrap([0.1, 0.2], ["w"], "ate")


def test_a_comparison_with_seeds_per_plan_pairs_per_plan_and_seed_and_reports_over_plans():
    pairs = episodes_on("dungeon_maps/test", 2, 0, seeds_per_plan=2)
    rows = compare_on(pairs, ["frontier", "random"], ComparisonSettings(env_options={"max_decisions": 2}),
                      workers=1, progress=False)
    assert sorted((r["plan"], r["seed"]) for r in rows if r["policy"] == "random") == \
        sorted((r["plan"], r["seed"]) for r in rows if r["policy"] == "frontier")
    assert len({r["plan"] for r in rows}) == 2 and {r["seed"] for r in rows} == {0, 1}
    table = markdown_table(rows, "random", "frontier", "random - frontier")
    assert "4 pairs (world, seed) on 2 plans" in table and "| detectable |" in table
    row = next(line for line in table.splitlines() if line.startswith("| building accuracy"))
    assert row.count("[") == 3  # each policy's mean and the difference, with their intervals


def test_the_commands_refuse_seeds_per_plan_on_a_world_that_is_not_a_map_set(capsys):
    pytest.importorskip("stable_baselines3")
    from emmi_gym.tools.cli import main

    with pytest.raises(SystemExit) as exit_:
        main(["evaluate", "--pretrained", "loop_corridor_emmi", "--seeds-per-plan", "2", "--quiet"])
    err = capsys.readouterr().err
    assert exit_.value.code == 2 and "--seeds-per-plan: 2 seeds per plan need a map set" in err
    assert "'loop_corridor'" in err and "Traceback" not in err
    with pytest.raises(SystemExit):
        main(["benchmark", "--seeds-per-plan", "0"])
    assert "--seeds-per-plan" in capsys.readouterr().err


def test_a_share_over_plans_resamples_plans_with_all_their_pairs_and_pairs_a_baseline_by_plan():
    rng = np.random.default_rng(3)
    trials = rng.integers(2, 12, size=40)
    successes = rng.binomial(trials, 0.7)
    plans = [f"plan{k}" for k in range(40)]
    share = share_bootstrap(successes, trials, plans)
    assert share.mean == pytest.approx(successes.sum() / trials.sum()) and share.plans == 40
    assert share.low < share.mean < share.high and share.high - share.low < 0.2
    # one plan's pairs all agreeing, the other's none: the plans, not the pairs, are what the interval counts
    lumped = share_bootstrap([30, 0], [30, 30], ["a", "b"])
    assert lumped.mean == 0.5 and lumped.low == 0.0 and lumped.high == 1.0
    same = share_bootstrap(successes, trials, plans, baseline=(successes, trials))
    assert (same.mean, same.low, same.high) == (0.0, 0.0, 0.0)
    # a baseline that agrees one pair less on every plan: the change is what it lost, plan by plan
    fewer = share_bootstrap(successes, trials, plans, baseline=(np.maximum(successes - 1, 0), trials))
    lost = (successes - np.maximum(successes - 1, 0)).sum() / trials.sum()
    assert fewer.mean == pytest.approx(lost) and 0 < fewer.low <= lost <= fewer.high
    assert share == share_bootstrap(successes, trials, plans)   # seeded
    with pytest.raises(ValueError, match="one each a unit"):
        share_bootstrap([1, 2], [3], ["a", "b"])
    with pytest.raises(ValueError, match="named twice"):
        share_bootstrap([1, 2], [3, 3], ["a", "a"])
    assert np.isnan(share_bootstrap([0], [0], ["a"]).mean)
