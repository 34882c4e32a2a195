"""The rewards' measurements of measurements/ on a few short episodes: every registered reward gets its row or
column, and the returns obey what a return is (a cost lowers it, the paired difference is the difference of the
means, the episodes kept give the same tables again)."""

import json

import pytest
from helpers import MEASUREMENTS, markdown_rows, run_script

from emmi_gym.env import REWARDS
from emmi_gym.env.reward_registry import privileged_rewards


def test_reward_farming_pays_a_robot_standing_still_nothing_but_the_costs():
    done = run_script(MEASUREMENTS / "reward_farming.py", "--seeds", "1", "--steps", "5", "--decisions", "2")
    assert done.code == 0, done.err
    header = next(line for line in done.out.splitlines() if line.startswith("| policy |"))
    assert header == "| policy | " + " | ".join(REWARDS) + " |"
    rows = {row[0]: row[1:] for row in markdown_rows(done.out)}
    assert list(rows) == ["stand still (5 steps)", "spin in place (5 steps)", "drive ahead (5 steps)",
                          "frontier (at most 2 decisions)", "active_loop_closing (at most 2 decisions)"]
    assert len(set(rows["stand still (5 steps)"])) == 1  # the time cost alone, whatever the reward
    assert float(rows["stand still (5 steps)"][0].split()[0]) < 0


def test_reward_scales_gives_every_reward_its_scale_and_what_it_reads():
    done = run_script(MEASUREMENTS / "reward_scales.py", "--env-id", "emmi_gym/Explore-v1", "--seeds", "1",
                      "--policies", "frontier", "--decisions", "2")
    assert done.code == 0, done.err
    assert done.out.startswith("emmi_gym/Explore-v1: 2 decisions of frontier on seeds from 0")
    rows = {row[0].strip("`"): row[1:] for row in markdown_rows(done.out)}
    privileged = privileged_rewards()
    assert list(rows) == list(REWARDS)
    for name, (reads, median, high, scale, _, moved) in rows.items():
        assert reads == ("ground truth" if name in privileged else "filter")
        assert float(scale) == REWARDS[name].scale and 0 <= float(median) <= float(high)
        assert moved.endswith("%") and 0 <= int(moved[:-1]) <= 100


@pytest.fixture(scope="module")
def alignment(tmp_path_factory):
    out = tmp_path_factory.mktemp("alignment")
    done = run_script(MEASUREMENTS / "reward_returns.py", "--env-id", "emmi_gym/Explore-v1", "--worlds",
                      "loop_corridor", "--seeds", "2", "--policies", "frontier", "random", "--options",
                      '{"particles": 3, "max_decisions": 2}', "--rewards", "emmi", "coverage", "--discounts", "none",
                      "0.9@100", "--workers", "1", "--paired-with", "random", "--out", out)
    assert done.code == 0, done.err
    return done, out


def test_reward_returns_weighs_every_reward_cost_and_discount_and_pairs_the_returns(alignment):
    done, out = alignment
    rows = [row for row in markdown_rows(done.out) if row[0] in ("emmi", "coverage")]
    assert [(row[0], row[2], row[3]) for row in rows] == [
        (reward, cost, discount) for reward in ("emmi", "coverage") for cost in ("0", "0.002")
        for discount in ("none", "0.9 per 100 steps")]
    returns = {(row[0], row[2], row[3]): (float(row[4]), float(row[5])) for row in rows}
    for (reward, cost, discount), (frontier, random) in returns.items():
        if cost == "0":  # the time cost takes from every return
            costly = returns[(reward, "0.002", discount)]
            assert costly[0] < frontier and costly[1] < random
    [paired] = [row for row in markdown_rows(done.out) if row[0] == "frontier" and row[1] == "2"]
    frontier, random = returns[("emmi", "0", "none")]
    assert float(paired[2].split()[0]) == pytest.approx(frontier - random, abs=2e-3)
    episodes = json.loads((out / "episodes.json").read_text())
    assert sorted((row["policy"], row["seed"]) for row in episodes) == [
        ("frontier", 0), ("frontier", 1), ("random", 0), ("random", 1)]
    assert (out / "summary.md").read_text().strip() in done.out
    scores = run_script(MEASUREMENTS / "versions_paired.py", out / "episodes.csv", out / "episodes.csv", "--scores",
                        "oracle_accuracy", "sim_steps")
    assert scores.code == 0, scores.err
    assert [row[:3] + row[5:] for row in markdown_rows(scores.out)] == [
        [policy, score, "2", "+0 [+0, +0]" + (" = +0.0% [+0.0%, +0.0%]" if score == "sim_steps" else "")]
        for policy in ("frontier", "random") for score in ("oracle_accuracy", "sim_steps")]


def test_reward_returns_reads_the_episodes_it_kept_to_the_same_tables(alignment, tmp_path):
    done, out = alignment
    again = run_script(MEASUREMENTS / "reward_returns.py", "--episodes-from", out / "episodes.json", "--rewards",
                       "emmi", "coverage", "--discounts", "none", "0.9@100", "--paired-with", "random")
    assert again.code == 0, again.err
    assert markdown_rows(again.out) == markdown_rows(done.out)
    episodes = json.loads((out / "episodes.json").read_text())
    for row in episodes:
        row["steps"] = [{k: v for k, v in step.items() if k != "coverage"} for step in row["steps"]]
    (tmp_path / "episodes.json").write_text(json.dumps(episodes))
    missing = run_script(MEASUREMENTS / "reward_returns.py", "--episodes-from", tmp_path / "episodes.json",
                         "--rewards", "coverage")
    assert missing.code == 2 and "--rewards: the steps of --episodes-from do not hold ['coverage']" in missing.err
    against = run_script(MEASUREMENTS / "reward_returns.py", "--episodes-from", out / "episodes.json", "--rewards",
                         "emmi", "coverage", "--discounts", "none", "--against-episodes", tmp_path / "episodes.json")
    assert against.code == 2 and "--against-episodes: their steps do not hold ['coverage']" in against.err


def test_reward_returns_sets_the_agreement_beside_that_of_the_same_episodes_played_otherwise(alignment, tmp_path):
    done, out = alignment
    itself = run_script(MEASUREMENTS / "reward_returns.py", "--episodes-from", out / "episodes.json", "--rewards",
                        "emmi", "--discounts", "none", "--against-episodes", out / "episodes.json")
    assert itself.code == 0, itself.err
    changes = [row for row in markdown_rows(itself.out) if row[0] == "emmi" and len(row) == 9]
    assert [(row[1], row[3]) for row in changes] == [
        (cost, quality) for cost in ("0", "0.002") for quality in ("oracle_accuracy", "ate")]
    assert all(row[5] == row[6] and row[7] == "+0 [+0, +0]" for row in changes)
    (tmp_path / "broken.json").write_text("{")
    broken = run_script(MEASUREMENTS / "reward_returns.py", "--episodes-from", out / "episodes.json",
                        "--against-episodes", tmp_path / "broken.json")
    assert broken.code == 2 and f"--against-episodes: {tmp_path / 'broken.json'}: not an episodes.json" in broken.err


def test_reward_returns_sets_each_reward_beside_another_on_the_same_episodes(alignment):
    done, out = alignment
    beside = run_script(MEASUREMENTS / "reward_returns.py", "--episodes-from", out / "episodes.json", "--rewards",
                        "emmi", "coverage", "--discounts", "none", "--against-reward", "coverage")
    assert beside.code == 0, beside.err
    assert "beside the reward coverage's" in beside.out
    changes = [row for row in markdown_rows(beside.out) if len(row) == 9 and row[0] in ("emmi", "coverage")]
    assert {row[0] for row in changes} == {"emmi"}  # the baseline is not set beside itself
    header = next(line for line in done.out.splitlines() if line.startswith("| reward | reads |"))
    columns = [cell.strip() for cell in header.strip("|").split("|")]
    coverage = {(row[columns.index("time_cost")], quality): row[columns.index(f"agree {quality}, 95%")]
                for row in markdown_rows(done.out) if row[0] == "coverage" and len(row) == len(columns)
                and row[columns.index("discount")] == "none" for quality in ("oracle_accuracy", "ate")}
    assert sorted((row[1], row[3]) for row in changes) == sorted(coverage)
    for row in changes:  # the baseline is the coverage reward's own agreement on the same episodes, undiscounted
        assert row[2] == "none" and row[5] == coverage[row[1], row[3]]
    unknown = run_script(MEASUREMENTS / "reward_returns.py", "--episodes-from", out / "episodes.json", "--rewards",
                         "emmi", "--against-reward", "coverage")
    assert unknown.code == 2 and "--against-reward: 'coverage' is not one of --rewards ['emmi']" in unknown.err
