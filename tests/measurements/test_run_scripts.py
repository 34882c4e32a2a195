"""The measurements of measurements/ that read trained runs and their evaluations, on a run of 16 decisions
(``small_corridor_run`` in tests/conftest.py) and its evaluation beside the frontier policy: every table row
counts what the run holds."""

import shutil

import pytest
from helpers import MEASUREMENTS, markdown_rows, run_script

pytestmark = pytest.mark.slow  # they share a trained run, and play its agent


def test_policy_churn_compares_the_runs_checkpoint_with_its_final_model(small_corridor_run):
    done = run_script(MEASUREMENTS / "policy_churn.py", small_corridor_run, "--episodes", "1", "--seed", "7")
    assert done.code == 0, done.err
    [(run, final, checkpoint, decisions, same, share)] = markdown_rows(done.out)
    assert (run, final, checkpoint) == (small_corridor_run.name, "16", "8")
    assert 1 <= int(decisions) <= 3 and 0 <= int(same) <= int(decisions)  # one episode of at most 3 decisions
    assert float(share) == pytest.approx(int(same) / int(decisions), abs=0.005)
    missing = run_script(MEASUREMENTS / "policy_churn.py", small_corridor_run, "--checkpoints", "5")
    assert missing.code == 2 and "no whole checkpoint at [5] decisions; its checkpoints are at [8, 16]" in missing.err


def test_lost_updates_finds_every_update_of_a_run_that_was_not_stopped(small_corridor_run):
    done = run_script(MEASUREMENTS / "lost_updates.py", small_corridor_run / "model.zip")
    assert done.code == 0, done.err
    assert markdown_rows(done.out) == [[str(small_corridor_run / "model.zip"), "1 of 1", "16", "8", "2", "2", "0"]]
    earlier = run_script(MEASUREMENTS / "lost_updates.py", small_corridor_run / "model.zip", "--earlier", "8:1:8:8:1")
    # the two stages alike: only the count of the optimizer's steps tells that each made its update
    assert [row[1:] for row in markdown_rows(earlier.out)] == [["1 of 2", "8", "8", "1", "1", "0"],
                                                            ["2 of 2", "8", "8", "1", "1", "0"]]


def test_benchmark_paths_plays_each_rewards_agent_beside_the_scripted_policies(small_corridor_run, tmp_path):
    shutil.copytree(small_corridor_run, tmp_path / "benchmark" / "runs" / "emmi_seed0")
    done = run_script(MEASUREMENTS / "benchmark_paths.py", tmp_path / "benchmark", "--seed", "7", "--baselines",
                      "close_loop_first", "frontier", "--out", tmp_path / "paths.png")
    assert done.code == 0, done.err
    header, *lines = done.out.splitlines()[:4]  # a fixed-width table: policy, closed the loop first, decisions ...
    assert header.split()[:3] == ["policy", "closed_loop_first", "decisions"]
    rows = {policy: line.split()[len(policy.split()):] for policy, line in
            zip(["emmi agent", "close_loop_first", "frontier"], lines, strict=True) if line.split()[0] in policy}
    assert len(rows) == 3 and all(1 <= int(cells[1]) <= 3 for cells in rows.values())  # at most max_decisions
    assert done.out.endswith(f"wrote {tmp_path / 'paths.png'}\n") and (tmp_path / "paths.png").stat().st_size > 10_000
    unfinished = run_script(MEASUREMENTS / "benchmark_paths.py", tmp_path / "benchmark")
    assert unfinished.code == 1 and "benchmark_episodes.csv: not found" in unfinished.err


def test_evaluations_paired_and_versions_paired_read_what_evaluate_writes(small_corridor_evaluation):
    done = run_script(MEASUREMENTS / "evaluations_paired.py", small_corridor_evaluation, "--policy", "agent",
                      "--baselines", "frontier", "--compact")
    assert done.code == 0, done.err
    assert [row[:2] for row in markdown_rows(done.out)] == [
        ["frontier", "2"], ["agent", "2"], ["agent - frontier, final", "2"], ["agent - frontier, equal time", "2"]]
    episodes = small_corridor_evaluation / "episodes.csv"
    same = run_script(MEASUREMENTS / "versions_paired.py", episodes, episodes)
    assert same.code == 0, same.err
    rows = markdown_rows(same.out)
    assert {row[0] for row in rows} == {"agent", "frontier"} and all(row[2] == "2" for row in rows)
    assert all(row[3] == row[4] and row[5].startswith("+0 [+0, +0]") for row in rows)  # a code against itself


def test_benchmark_attribution_reads_the_episodes_of_an_evaluation(small_corridor_evaluation):
    done = run_script(MEASUREMENTS / "benchmark_attribution.py", small_corridor_evaluation, "--bootstrap", "100")
    assert done.code == 0, done.err
    assert done.out.count("within 2 held-out episodes (each a world and seed every policy played)") == 2  # 2 scores
    terms = [row[0] for row in markdown_rows(done.out)]
    assert terms[:5] == ["closed the loop first", "revisit share", "robot time (1000 steps)", "residual of agent",
                         "residual of frontier"] and terms[5:] == terms[:5]
