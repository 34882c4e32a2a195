"""The measurements of measurements/ that read episodes (the CSV files of ``emmi-gym evaluate``,
``compare-policies`` and ``benchmark``, written here with known scores, so that every figure of their tables
can be checked), that count stuck episodes, or that read the shipped agents' model files."""

import csv
import re
import shutil

import numpy as np
import pytest
from helpers import MEASUREMENTS, markdown_rows, run_script

from emmi_gym import pretrained


def write_csv(path, rows: list[dict]) -> None:
    path.parent.mkdir(parents=True, exist_ok=True)
    with open(path, "w", newline="") as f:
        writer = csv.DictWriter(f, fieldnames=list(rows[0]))
        writer.writeheader()
        writer.writerows(rows)


def evaluation(folder, policy: str, ate: float, sim_steps: int):
    """``folder`` as ``emmi-gym evaluate --out`` writes it: two episodes of ``policy`` on loop_corridor (ATE
    ``ate`` and ``ate + 0.01``, coverage 0.5 and 0.6, after ``sim_steps``), each traced from its reset (coverage 0)
    to its final scores."""
    episodes, traces = [], []
    for seed in (0, 1):
        final = {"oracle_accuracy": 0.9 - ate, "ate": ate + 0.01 * seed, "wall_consistency": 0.8,
                 "coverage": 0.5 + 0.1 * seed}
        keys = {"world": "loop_corridor", "seed": seed, "policy": policy}
        episodes.append({**keys, **final, "sim_steps": sim_steps, "revisit_share": 0.1, "decisions": 3})
        traces += [{**keys, "sim_steps": 0, "oracle_accuracy": 0.5, "ate": 0.0, "wall_consistency": 1.0,
                    "coverage": 0.0}, {**keys, "sim_steps": sim_steps, **final}]
    write_csv(folder / "episodes.csv", episodes)
    write_csv(folder / "traces.csv", traces)
    return folder


def cells(out: str, first: str) -> list[str]:
    return next(row for row in markdown_rows(out) if row[0] == first)


def test_evaluations_paired_pairs_separate_runs_at_their_final_maps_and_at_equal_robot_time(tmp_path):
    agent, frontier = evaluation(tmp_path / "A", "agent", 0.2, 1000), evaluation(tmp_path / "B", "frontier", 0.3, 2000)
    done = run_script(MEASUREMENTS / "evaluations_paired.py", agent, frontier, "--policy", "agent", "--baselines",
                      "frontier")
    assert done.code == 0, done.err
    final, equal_time = done.out.split("at equal robot time: ")
    assert "agent - frontier: 2 pairs (world, seed)" in final
    assert cells(final, "ATE (m)")[4] == "-0.100 [-0.100, -0.100]" and cells(final, "ATE (m)")[6] == "2/2"
    assert cells(final, "ATE (m)")[5] == "0.000"  # the smallest difference it detects: no spread, none missed
    assert cells(final, "simulator steps")[4] == "-1000 [-1000, -1000]"
    # at 1000 steps, halfway through frontier's episodes: half their coverage, the agent's at its end
    assert cells(equal_time, "coverage")[2:4] == ["0.275 [0.000, 0.593]", "0.550 [0.000, 1.000]"]
    compact = run_script(MEASUREMENTS / "evaluations_paired.py", agent, frontier, "--policy", "agent", "--baselines",
                         "frontier", "--compact", "--at", "equal_time")
    assert compact.code == 0, compact.err
    assert cells(compact.out, "frontier")[1:3] == ["2", "0.600"] and cells(compact.out, "agent")[1:3] == ["2", "0.700"]
    assert cells(compact.out, "agent - frontier")[1:] == ["2", "+0.150 [+0.150, +0.150]", "+0.053 [+0.021, +0.084]",
                                                         "-0.100 [-0.100, -0.100]", "+0.275 [-0.043, +0.593]",
                                                         "-", "at 1000"]  # traces without the building accuracy


def test_evaluations_paired_refuses_one_episode_in_two_folders_and_a_policy_of_none(tmp_path):
    agent = evaluation(tmp_path / "A", "agent", 0.2, 1000)
    twice = run_script(MEASUREMENTS / "evaluations_paired.py", agent, evaluation(tmp_path / "B", "agent", 0.3, 900),
                       "--policy", "agent", "--baselines", "agent")
    assert twice.code == 1 and "is also in" in twice.err and "evaluate each agent under its own --name" in twice.err
    shutil.copytree(agent, tmp_path / "C")  # the same episodes (two evaluations that share a played/): counted once
    alike = run_script(MEASUREMENTS / "evaluations_paired.py", agent, tmp_path / "C", "--policy", "agent",
                       "--baselines", "agent", "--compact")
    assert alike.code == 0, alike.err
    assert cells(alike.out, "agent")[1] == "2"
    unknown = run_script(MEASUREMENTS / "evaluations_paired.py", agent, "--policy", "agent", "--baselines", "random")
    assert unknown.code == 2 and "['random']: no episodes of them in the folders, which hold ['agent']" in unknown.err


def test_versions_paired_gives_each_scores_change_with_its_interval_and_robot_time_as_a_share(tmp_path):
    rows = [{"plan": "img_1.png", "seed": seed, "policy": "frontier", "ate": 0.2 + 0.1 * seed,
             "oracle_accuracy": 0.8, "sim_steps": 1000 + 100 * seed} for seed in range(3)]
    write_csv(tmp_path / "before.csv", rows)
    write_csv(tmp_path / "after.csv", [dict(row, ate=row["ate"] - 0.05, sim_steps=row["sim_steps"] * 1.1)
                                       for row in rows])
    done = run_script(MEASUREMENTS / "versions_paired.py", tmp_path / "before.csv", tmp_path / "after.csv",
                      "--scores", "ate", "sim_steps")
    assert done.code == 0, done.err
    ate, steps = markdown_rows(done.out)
    assert ate[:5] == ["frontier", "ate", "3", "0.3", "0.25"] and ate[5].startswith("-0.05 [-0.05, -0.05]")
    # differences 100, 110, 120: their mean and Student-t interval, and as a share of the 1100 before
    assert steps == ["frontier", "sim_steps", "3", "1100", "1210", "+110 [+85.16, +134.8] = +10.0% [+7.7%, +12.3%]"]
    write_csv(tmp_path / "other.csv", [dict(row, seed=row["seed"] + 10) for row in rows])
    apart = run_script(MEASUREMENTS / "versions_paired.py", tmp_path / "before.csv", tmp_path / "other.csv",
                       "--scores", "ate")
    assert apart.code == 1 and "the two files share no (plan, seed, policy)" in apart.err
    lacking = run_script(MEASUREMENTS / "versions_paired.py", tmp_path / "before.csv", tmp_path / "after.csv")
    assert lacking.code == 1 and "before.csv: expected a" in lacking.err and "['wall_consistency', 'coverage']" \
        in lacking.err


def test_benchmark_attribution_finds_the_policy_that_maps_better_than_its_route_explains(tmp_path):
    rng = np.random.default_rng(0)
    rows = []
    for world in range(12):  # every policy on every world: an ATE of the world, the route and the policy's own
        for policy, offset in (("emmi", -0.05), ("explore_first", 0.0), ("frontier", 0.0)):
            closed, revisits, steps = float(rng.integers(0, 2)), rng.uniform(0, 0.5), rng.uniform(800, 1400)
            ate = 0.5 - 0.05 * closed - 0.2 * revisits + 0.01 * steps / 1000 + offset + 0.002 * rng.normal()
            rows.append({"episode_seed": 1000 + world, "kind": "agent" if policy == "emmi" else "baseline",
                         "variant": policy, "ate": ate, "oracle_accuracy": 1.0 - ate, "closed_loop_first": closed,
                         "revisit_share": revisits, "sim_steps": steps})
    write_csv(tmp_path / "benchmark_episodes.csv", rows)
    done = run_script(MEASUREMENTS / "benchmark_attribution.py", tmp_path, "--bootstrap", "200")
    assert done.code == 0, done.err
    residual = re.search(r"\| residual of emmi agents \| ([+-][\d.]+) \[([+-][\d.]+), ([+-][\d.]+)\] \|", done.out)
    assert float(residual[1]) < 0 and float(residual[3]) < 0, "the emmi agents map better than their routes say"
    assert "within 12 held-out episodes" in done.out
    only = run_script(MEASUREMENTS / "benchmark_attribution.py", tmp_path, "--policies", "emmi agents", "frontier",
                      "--bootstrap", "200")
    assert only.code == 0 and "residual of explore_first" not in only.out and "residual of frontier" in only.out
    unknown = run_script(MEASUREMENTS / "benchmark_attribution.py", tmp_path, "--policies", "random")
    assert unknown.code == 2 and "--policies: no episodes of ['random'] in the folders" in unknown.err


def test_stuck_episodes_counts_the_decisions_left_without_a_target():
    done = run_script(MEASUREMENTS / "stuck_episodes.py", "--episodes", "2", "--options",
                      '{"particles": 3, "max_decisions": 3}')
    assert done.code == 0, done.err
    found = re.fullmatch(r"emmi_gym/Explore-v1, random policy, 2 episodes: (\d) stuck \(seeds \[.*\]\), (\d+) "
                         r"decisions with no target; coverage mean ([\d.]+), median ([\d.]+)\n", done.out)
    assert found and int(found[1]) <= 2 and int(found[2]) <= 6 and 0 < float(found[3]) <= 1
    bad = run_script(MEASUREMENTS / "stuck_episodes.py", "--options", '{"particles": 0}')
    assert bad.code == 2 and "gym.make: field 'particles': expected an integer in [1, 1000]" in bad.err


def test_lost_updates_counts_the_updates_each_shipped_agent_made_against_its_decisions(tmp_path):
    done = run_script(MEASUREMENTS / "lost_updates.py")
    assert done.code == 0, done.err
    rows = markdown_rows(done.out)
    assert {row[0] for row in rows} == set(pretrained.names())
    for _, _, decisions, per_update, expected, made, lost in rows:
        assert int(decisions) // int(per_update) == int(expected)
        assert made == "?" or int(expected) - int(made) == int(lost) >= 0
    assert [row[1] for row in rows if row[0] == "explore_plans_emmi"] == ["1 of 2", "2 of 2"]  # its earlier stage
    (tmp_path / "bad.zip").write_bytes(b"not a zip")
    bad = run_script(MEASUREMENTS / "lost_updates.py", tmp_path / "bad.zip")
    assert bad.code == 2 and "bad.zip" in bad.err and "Traceback" not in bad.err
    early = run_script(MEASUREMENTS / "lost_updates.py", "--earlier", "1:1:1:1:1")
    assert early.code == 2 and "--earlier: the stages of the MODEL files given" in early.err


@pytest.mark.parametrize("stage", ["1:2:3", "1:0:1:1:1", "a:1:1:1:1"])
def test_lost_updates_refuses_a_stage_not_of_five_counts(stage, tmp_path):
    done = run_script(MEASUREMENTS / "lost_updates.py", tmp_path / "m.zip", "--earlier", stage)
    assert done.code == 2 and "expected DECISIONS:N_ENVS:N_STEPS:BATCH_SIZE:N_EPOCHS" in done.err


def _lookahead_config(tmp_path):
    path = tmp_path / "plans.yaml"
    path.write_text("env:\n  id: emmi_gym/ExplorePlans-v1\n  kwargs: {particles: 3, max_decisions: 2}\n"
                    "algorithm: MaskablePPO\npolicy: MultiInputPolicy\nn_envs: 1\ntotal_timesteps: 16\n"
                    "eval: {freq: 0, env_kwargs: {world: dungeon_maps/test}}\n")
    return path


def test_target_lookahead_takes_the_target_whose_outcome_is_best(tmp_path, monkeypatch):
    """At each decision the planner's choice is the offered target whose step, played on a copy, leaves the best
    objective: played again slot by slot from the same state, no other slot leaves a better one, and the env's own
    step then leaves the outcome foreseen."""
    import gymnasium as gym

    monkeypatch.syspath_prepend(str(MEASUREMENTS))
    import target_lookahead

    env = gym.make("emmi_gym/ExplorePlans-v1", particles=3, world="dungeon_maps/test")
    env.reset(seed=4)
    for objective in ("building_accuracy", "ate"):
        actor = target_lookahead.LookaheadActor(objective)
        chosen = actor(env, None)
        outcomes = {int(slot): actor.outcome(env, int(slot)) for slot in np.flatnonzero(env.unwrapped.action_masks())}
        assert outcomes[chosen] == max(outcomes.values())
    fresh = target_lookahead.LookaheadActor("ate", noise="fresh")  # copies that draw noise of their own
    fresh.reset(1)
    first = fresh.outcome(env, chosen)
    fresh.reset(1)
    assert fresh.outcome(env, chosen) == first  # seeded by the episode
    fresh.reset(2)
    assert fresh.outcome(env, chosen) != first != outcomes[chosen]  # not the env's own next draws
    with pytest.raises(ValueError, match=r"noise: expected one of \['foreseen', 'fresh'\], got 'future'"):
        target_lookahead.LookaheadActor("ate", noise="future")
    env.step(chosen)  # the copies left the env as it was, and drew the noise it draws now: the outcome foreseen
    assert -env.unwrapped.ground_truth_scores()["ate"] == outcomes[chosen]
    env.close()


def test_target_lookahead_plays_beside_the_baselines_and_reads_back_what_it_kept(tmp_path):
    config = _lookahead_config(tmp_path)
    argv = ["--config", config, "--episodes", "2", "--baselines", "frontier", "--out", tmp_path / "out",
            "--workers", "1"]
    done = run_script(MEASUREMENTS / "target_lookahead.py", *argv)
    assert done.code == 0, done.err
    assert "lookahead_building_accuracy: 0 episodes kept" in done.out and "frontier: 0 episodes kept" in done.out
    assert "lookahead_building_accuracy - frontier: 2 pairs (world, seed) on 2 plans" in done.out
    assert "at equal robot time" in done.out
    first = (tmp_path / "out" / "summary.md").read_text()
    again = run_script(MEASUREMENTS / "target_lookahead.py", *argv)
    assert again.code == 0, again.err
    assert "lookahead_building_accuracy: 2 episodes kept" in again.out and "0 to play" in again.out
    assert (tmp_path / "out" / "summary.md").read_text() == first
    wider = run_script(MEASUREMENTS / "target_lookahead.py", *argv, "--planner-options", '{"n_revisits": 4}',
                       "--name", "wider")
    assert wider.code == 0, wider.err
    assert "wider: 0 episodes kept" in wider.out and "frontier: 2 episodes kept" in wider.out
    assert "(emmi_gym/ExplorePlans-v1, the planner with {'n_revisits': 4})" in wider.out
    for options, message in (("{]", "--planner-options: not JSON"), ('{"n_revisits": -1}', "n_revisits"),
                             ("[4]", "a JSON object of gym.make options expected")):
        bad = run_script(MEASUREMENTS / "target_lookahead.py", *argv, "--planner-options", options)
        assert bad.code == 2 and message in bad.err, bad.err
    bad = run_script(MEASUREMENTS / "target_lookahead.py", "--config", config, "--baselines", "nobody", "--out",
                     tmp_path / "x")
    assert bad.code == 2 and "--baselines: unknown ['nobody']" in bad.err


def test_lookahead_demonstrations_are_the_planners_choices_and_clone_fits_them(tmp_path):
    from emmi_gym.tools.training.demonstrations import Demonstrations

    config = _lookahead_config(tmp_path)
    out = tmp_path / "demos" / "lookahead.npz"
    done = run_script(MEASUREMENTS / "lookahead_demonstrations.py", "--config", config, "--episodes", "2",
                      "--seed", "11", "--out", out, "--workers", "1")
    assert done.code == 0, done.err
    demos = Demonstrations.load(out)
    assert demos.episodes == 2 and len(demos) == 4  # max_decisions 2 in each episode
    assert demos.masks[np.arange(4), demos.actions].all()
    assert "4 decisions of lookahead_building_accuracy in 2 episodes" in done.out and "(seeds 11-12)" in done.out
    bad = run_script(MEASUREMENTS / "lookahead_demonstrations.py", "--config", config, "--out", tmp_path / "d.txt")
    assert bad.code == 2 and "--out: a demonstrations file ends in .npz" in bad.err
