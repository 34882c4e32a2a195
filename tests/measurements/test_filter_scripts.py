"""The filter's measurements of measurements/ on tiny inputs (the loop_corridor loop, one seed; the test log,
``tests/data/intel-first-loop.log.gz``, standing in for the shared datasets' logs): each prints its tables and
writes its files with the columns its docstring names and values a filter can give."""

import csv
import json
import math
import re
import shutil

import numpy as np
import pytest
from helpers import DATA, MEASUREMENTS, markdown_rows, run_script

from emmi_gym.formats.carmen import read_log
from emmi_gym.scoring.calibration import PoseCheck
from emmi_gym.tools.experiments.calibration import FAMILIES
from emmi_gym.tools.experiments.replay import laser_stream, true_pose_at
from emmi_gym.world import load_world

LOG = DATA / "intel-first-loop.log.gz"


@pytest.fixture(scope="module")
def radish(tmp_path_factory):
    """A ``radish-noisy`` folder whose Intel log of odometry seed 0 is the test log."""
    folder = tmp_path_factory.mktemp("radish-noisy")
    shutil.copyfile(LOG, folder / "intel-seed0.log.gz")
    return folder


def test_slam_accuracy_beats_dead_reckoning_round_the_loop_and_sees_the_closure():
    done = run_script(MEASUREMENTS / "slam_accuracy.py", "--seeds", "1", "--particles", "2", "--odometry", "poor",
                      "--laser", '{"preset": "sick_lms200", "max_range": 8.0}')
    assert done.code == 0, done.err
    assert "1 seeds, 2 particles; laser 180 deg, 181 beams, 8 m; odometry alphas" in done.out
    best, dead_reckoning = (float(x) for x in re.search(
        r"ATE of the best path: median ([\d.]+) m.*dead reckoning median ([\d.]+) m", done.out).groups())
    assert best < dead_reckoning
    accuracy = float(re.search(r"map accuracy: median ([\d.]+)", done.out)[1])
    assert 0.5 < accuracy <= 1.0
    assert re.search(r"^loop closure: EMMI up on [01] of 1; ", done.out, re.MULTILINE)


def test_slam_accuracy_names_a_bad_laser_option():
    done = run_script(MEASUREMENTS / "slam_accuracy.py", "--laser", '{"n_beams": -1}')
    assert done.code == 2 and "--laser: field 'n_beams': expected an integer in [1, 10000]" in done.err, done.err


def test_slam_benchmark_replays_a_log_and_writes_its_map_trajectory_and_results(radish, tmp_path):
    done = run_script(MEASUREMENTS / "slam_benchmark.py", "--data", radish, "--logs", "intel", "--log-seeds", "0",
                      "--particles", "2", "--resolution", "0.1", "--out", tmp_path, "--jobs", "1")
    assert done.code == 0, done.err
    [row] = markdown_rows(done.out)
    assert row[:2] == ["intel-seed0", "130"]  # every keyframe an update
    dead_reckoning, ate = float(row[2]), float(row[3])
    assert 0 < ate < dead_reckoning
    [result] = json.loads((tmp_path / "results.json").read_text())
    assert result["log"] == "intel-seed0" and result["updates"] == 130 and result["ate"] == pytest.approx(ate, abs=5e-4)
    assert (tmp_path / "intel-seed0-best_map.png").stat().st_size > 1000
    assert len(np.loadtxt(tmp_path / "intel-seed0-best.tum")) == 130


def test_slam_benchmark_names_the_dataset_file_it_lacks(tmp_path):
    done = run_script(MEASUREMENTS / "slam_benchmark.py", "--data", tmp_path, "--logs", "aces", "--log-seeds", "1")
    assert done.code == 2 and "no aces-seed1.log.gz there (the radish-noisy files" in done.err, done.err


def checks_of(path) -> list[dict]:
    with open(path, newline="") as f:
        return list(csv.DictReader(f))


def test_calibration_checks_an_envs_episode_and_the_log_and_draws_their_curves(radish, tmp_path):
    env = run_script(MEASUREMENTS / "calibration.py", "env", "--env-id", "emmi_gym/LoopCorridor-v1", "--seeds", "1",
                     "--workers", "1", "--options", '{"particles": 3, "max_decisions": 1}', "--csv",
                     tmp_path / "env.csv", "--label", "env")
    logs = run_script(MEASUREMENTS / "calibration.py", "logs", "--data", radish, "--logs", "intel", "--particles", "2",
                      "--resolution", "0.1", "--workers", "1", "--csv", tmp_path / "logs.csv")
    for done, path, families in ((env, tmp_path / "env.csv", set(FAMILIES)),
                                 (logs, tmp_path / "logs.csv", set(FAMILIES) - {"pose", "loops"})):
        assert done.code == 0, done.err
        rows = checks_of(path)
        assert list(rows[0]) == ["label", "family", *PoseCheck.__dataclass_fields__]
        printed = {row[0]: int(row[1]) for row in markdown_rows(done.out)}  # family: moments
        assert set(printed) == families and printed == {f: sum(r["family"] == f for r in rows) for f in printed}
        assert all(float(row[k]) >= 0 for row in rows for k in PoseCheck.__dataclass_fields__
                   if not math.isnan(float(row[k])))
    assert {row["label"] for row in checks_of(tmp_path / "env.csv")} == {"env"}
    assert {row["label"] for row in checks_of(tmp_path / "logs.csv")} == {"logs"}  # the file's name by default
    drawn = run_script(MEASUREMENTS / "calibration.py", "plot", tmp_path / "env.csv", tmp_path / "logs.csv", "--out",
                       tmp_path / "curves.png")
    assert drawn.code == 0 and drawn.out == f"wrote {tmp_path / 'curves.png'}\n"
    assert (tmp_path / "curves.png").stat().st_size > 10_000


def test_trajectory_ate_of_the_logs_own_truth_is_zero_and_of_a_noisy_copy_its_noise(tmp_path):
    log = read_log(LOG)
    truth_at = true_pose_at(log)
    truth = np.array([(record.timestamp, *truth_at(record.timestamp, pose, position)[:3])
                      for position, pose, record in laser_stream(log)])
    np.savetxt(tmp_path / "truth.txt", truth, header="timestamp x y theta")
    done = run_script(MEASUREMENTS / "trajectory_ate.py", LOG, tmp_path / "truth.txt")
    assert done.code == 0, done.err
    assert done.out == "poses 130 of 130; ATE (aligned) 0.000 m\n"
    noisy = truth.copy()
    noisy[:, 1:3] += np.random.default_rng(0).normal(0.0, 0.05, (len(truth), 2))
    tum = np.column_stack([noisy[:, :3], np.zeros((len(truth), 4)), np.ones(len(truth))])  # t x y z qx qy qz qw
    np.savetxt(tmp_path / "noisy.tum", tum)
    done = run_script(MEASUREMENTS / "trajectory_ate.py", LOG, tmp_path / "noisy.tum")
    assert 0.05 < float(re.search(r"ATE \(aligned\) ([\d.]+) m", done.out)[1]) < 0.09  # sqrt(2) x 0.05 m
    np.savetxt(tmp_path / "three.txt", truth[:, :3])
    done = run_script(MEASUREMENTS / "trajectory_ate.py", LOG, tmp_path / "three.txt")
    assert done.code == 1 and "three.txt: expected 4 columns (t x y theta) or 8 (TUM), got 3" in done.err


def test_odometry_drift_measures_the_error_after_one_loop_and_after_100_m():
    done = run_script(MEASUREMENTS / "odometry_drift.py", "--seeds", "1", "--preset", "good")
    assert done.code == 0, done.err
    [row] = markdown_rows(done.out)
    assert row[0] == "good"
    after_loop, after_100 = (float(cell.split(" m")[0]) for cell in row[1:3])
    assert 0 < after_loop < 5 and 0 < after_100 < 5 and 0 <= float(row[3].split()[0]) < math.pi


def test_loop_cloud_finds_the_best_particles_loop_no_worse_than_the_median_or_the_nearest():
    done = run_script(MEASUREMENTS / "loop_cloud.py", "--env-id", "emmi_gym/LoopOrder-v1", "--seeds", "1")
    assert done.code == 0, done.err
    best, median, nearest = (float(x) for x in re.search(
        r"best particle ([\d.]+) m, median ([\d.]+) m, the particle nearest the truth ([\d.]+) m", done.out).groups())
    assert best <= median and best <= nearest


def test_build_building_worlds_builds_a_world_the_robot_can_stand_in_from_a_corrected_log(tmp_path):
    (tmp_path / "carmen").mkdir()
    shutil.copyfile(LOG, tmp_path / "carmen" / "intel-corrected.log.gz")
    done = run_script(MEASUREMENTS / "build_building_worlds.py", "--data", tmp_path / "carmen", "--buildings",
                      "intel", "--out", tmp_path / "worlds")
    assert done.code == 0, done.err
    [row] = markdown_rows(done.out)
    world = load_world(tmp_path / "worlds" / "intel.yaml")
    assert row[0] == "intel" and int(row[3]) == len(world.walls) > 100
    first = next(pose for _, pose, _ in laser_stream(read_log(LOG)) if pose is not None)
    assert (world.start.x, world.start.y) == pytest.approx(first[:2], abs=1e-3)
    assert world.clearance(world.start.x, world.start.y) > 0.2  # the log's first pose is in the free space
    assert not (tmp_path / "carmen" / "intel.yaml").exists()


def test_build_building_worlds_names_the_logs_it_lacks(tmp_path):
    done = run_script(MEASUREMENTS / "build_building_worlds.py", "--data", tmp_path, "--buildings", "aces", "fr079")
    assert done.code == 2, done.err
    assert "no aces-corrected.log.gz, freiburg-079-corrected.log.gz there (the carmen files" in done.err


@pytest.mark.slow  # four replays of the log
def test_ros_bags_of_the_log_decode_alike_and_replay_as_the_log_does(radish, tmp_path):
    pytest.importorskip("rosbags")
    done = run_script(MEASUREMENTS / "ros_bags.py", "--data", radish, "--logs", "intel", "--filter-seeds", "0",
                      "--bag-seeds", "0", "--particles", "2", "--out", tmp_path, "--jobs", "1")
    assert done.code == 0, done.err
    [row] = markdown_rows(done.out)
    assert row[0] == "intel" and row[4] == "yes"  # the three bags decode to the same scans and poses
    ros1, sqlite3, mcap = (float(ate) for ate in row[2].split(" / "))
    assert ros1 == sqlite3 == mcap == float(row[3])
    results = json.loads((tmp_path / "results.json").read_text())
    assert sorted(r["source"] for r in results) == ["carmen", "mcap", "ros1", "sqlite3"]
    assert {r["updates"] for r in results} == {130} and all(len(r["emmi"]) == 130 for r in results)
    assert float(row[5]) < 0.1  # bits per cell: the bag's EMMI curve is the log's
    assert sorted(p.name for p in (tmp_path / "intel").iterdir()) == ["bag-mcap", "bag-sqlite3", "bag.bag"]


def test_calibration_of_honest_clouds_comes_nearer_its_ideal_with_more_particles_and_even_weights():
    done = run_script(MEASUREMENTS / "calibration.py", "honest", "--particles", "3", "30", "--log-weight-sd", "0", "2",
                      "--moments", "300")
    assert done.code == 0, done.err
    rows = {(int(row[0]), float(row[1])): row[2:] for row in markdown_rows(done.out)}
    assert list(rows) == [(3, 0.0), (3, 2.0), (30, 0.0), (30, 2.0)]
    assert [float(rows[(m, 0.0)][0]) for m in (3, 30)] == [3.0, 30.0]  # equal weights: every particle counts
    assert all(float(rows[(m, 2.0)][0]) < m for m in (3, 30))
    nees = {key: float(cells[1]) for key, cells in rows.items()}
    assert nees[(30, 0.0)] < nees[(3, 0.0)] and nees[(30, 0.0)] < nees[(30, 2.0)]  # nearer 2, an honest belief's
    for value in ("-1", "inf"):
        bad = run_script(MEASUREMENTS / "calibration.py", "honest", "--log-weight-sd", value)
        assert bad.code == 2 and f"--log-weight-sd: expected a finite number >= 0, got '{value}'" in bad.err
