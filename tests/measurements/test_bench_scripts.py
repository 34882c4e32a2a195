"""The speed benchmarks of measurements/ on tiny inputs: each prints every part its docstring promises, with
counts that match what it was asked to play and times that are numbers (never compared with a wall-clock
bound); the methods it wraps to time them are put back after it."""

import gzip
import math
import re
import subprocess
import sys

import pytest
import yaml
from helpers import MEASUREMENTS, markdown_rows, run_script

from emmi_gym.slam import RBPF
from emmi_gym.world import Simulator, load_world


def numbers(text: str) -> list[float]:
    return [float(x) for x in re.findall(r"-?\d+(?:\.\d+)?", text)]


def test_bench_env_times_each_id_and_splits_a_step_into_parts_that_add_up():
    step, process = Simulator.step, RBPF.process
    done = run_script(MEASUREMENTS / "bench_env.py", "--decisions", "2", "--velocity-steps", "20", "--repeats", "1",
                      "--ids", "Explore-v1", "ExploreVelocity-v0")
    assert done.code == 0, done.err
    lines = done.out.splitlines()
    for env_id, steps in (("Explore-v1", 2), ("ExploreVelocity-v0", 20)):
        k = next(i for i, line in enumerate(lines) if line.startswith(f"emmi_gym/{env_id}:"))
        assert f"({steps} env steps, " in lines[k] and numbers(lines[k].split(": ", 1)[1])[0] > 0
        shares = dict(part.rsplit(" ", 1) for part in lines[k + 1].removeprefix("  time share: ").split(", "))
        assert {"physics", "laser", "rbpf", "other"} <= set(shares)
        assert sum(int(share.rstrip("%")) for share in shares.values()) == pytest.approx(100, abs=len(shares))
    assert (Simulator.step, RBPF.process) == (step, process), "the timing wrappers were not put back"


def test_bench_env_refuses_an_option_of_no_env_naming_it():
    done = run_script(MEASUREMENTS / "bench_env.py", "--ids", "Explore-v1", "--options", '{"particles": 0}')
    assert done.code == 2 and "--options: field 'particles': expected an integer in [1, 1000]" in done.err


def test_bench_env_s_worker_imports_nothing_older_code_lacks():
    """``--against DIR`` runs this script's worker on the code in DIR (``PYTHONPATH``), which may predate the
    package's tools (``emmi_gym.tools``, where the scripts' argument types live): the worker must not import
    them, or this checkout's would be mixed into the older package and the worker die on an import."""
    done = subprocess.run([sys.executable, "-X", "importtime", str(MEASUREMENTS / "bench_env.py"), "--worker",
                           "emmi_gym/Explore-v1", "--options", "{}"], stdin=subprocess.DEVNULL, capture_output=True,
                          text=True, timeout=300)
    assert done.returncode == 0, done.stderr
    imported = {line.rsplit("|", 1)[-1].strip() for line in done.stderr.splitlines() if line.startswith("import time")}
    assert "emmi_gym.slam" in imported  # the worker did load the package it times
    assert not {name for name in imported if name.startswith("emmi_gym.tools")}


def test_bench_world_times_the_laser_and_a_step_on_each_kind_of_world():
    done = run_script(MEASUREMENTS / "bench_world.py", "--repeats", "2")
    assert done.code == 0, done.err
    rows = {row[0]: row[1:] for row in markdown_rows(done.out)}
    assert list(rows) == ["loop_corridor", "generated lattice", "DungeonMaps plan", "intel (from its log)"]
    assert int(rows["intel (from its log)"][0]) == len(load_world("intel").walls)
    assert all(float(cell) > 0 for row in rows.values() for cell in row)


def test_bench_slam_times_every_update_of_the_loop_and_its_phases():
    done = run_script(MEASUREMENTS / "bench_slam.py", "--particles", "2")
    assert done.code == 0, done.err
    updates = int(re.search(r"\((\d+) updates", done.out)[1])
    assert updates > 100  # the 74 m loop, an update every half metre or so
    phases = dict(part.split(" ") for part in done.out.split("of which (medians) ")[1].strip().split(", ")
                  if not part.startswith("longest"))
    assert {"scan_matching", "insertion", "metrics", "resampling"} <= set(phases)


@pytest.fixture(scope="module")
def aces_data(tmp_path_factory):
    """A folder of ``aces-corrected.log.gz``: a corrected log of a straight 4 m drive from the ACES world's start
    eastwards, where the building is free."""
    world, folder = load_world("aces"), tmp_path_factory.mktemp("carmen")
    x, y = world.start.x, world.start.y
    assert all(world.clearance(x + d, y) > 0.3 for d in range(5)), "the drive runs into a wall"
    scan = " ".join(["5.0"] * 180)
    lines = [f"FLASER 180 {scan} {x + d:.3f} {y:.3f} 0 {x + d:.3f} {y:.3f} 0 {k}.0 h {k}.0"
             for k, d in enumerate(i * 0.25 for i in range(17))]
    (folder / "aces-corrected.log.gz").write_bytes(gzip.compress(("\n".join(lines) + "\n").encode()))
    return folder


def test_bench_large_map_drives_the_aces_path_and_times_the_filter_over_it(aces_data, tmp_path):
    done = run_script(MEASUREMENTS / "bench_large_map.py", "--data", aces_data, "--metres", "3", "--particles", "2",
                      "--resolution", "0.2", "--slam", '{"linear_update": 0.1}', "--filter-seeds", "1", "2",
                      "--out", tmp_path / "tour.log")
    assert done.code == 0, done.err
    assert re.search(r"^drove 3 m of the ACES path .* reached its end\)$", done.out, re.MULTILINE), done.out
    assert (tmp_path / "tour.log").read_text().count("\nROBOTLASER1 ") == int(re.search(r"(\d+) scans", done.out)[1])
    assert "RBPF, 2 particles, 361 beams over 180 deg to 30 m, 0.2 m cells" in done.out
    ates = [float(ate) for _, ate in re.findall(r"(\d+): ATE ([\d.]+) m", done.out)]
    assert len(ates) == 2 and all(math.isfinite(ate) and ate < 0.5 for ate in ates)  # a straight drive


@pytest.mark.parametrize("option, expected", [
    (["--data", "EMPTY"], "no aces-corrected.log.gz there (the carmen files, shared/datasets/carmen)"),
    (["--slam", '{"particle": 3}'], "--slam: field 'particle'"),
    (["--slam", "[1]"], "--slam: expected a JSON object of fields"),
])
def test_bench_large_map_stops_before_any_work_on_a_missing_file_or_a_bad_option(aces_data, tmp_path, option,
                                                                                expected):
    option = [str(tmp_path) if word == "EMPTY" else word for word in option]
    done = run_script(MEASUREMENTS / "bench_large_map.py", "--data", aces_data, *option)
    assert done.code == 2 and expected in done.err, done.err


@pytest.mark.slow  # starts worker processes for the vector envs
def test_bench_vec_rates_every_vectorisation_against_a_single_process():
    done = run_script(MEASUREMENTS / "bench_vec.py", "--env-id", "emmi_gym/Explore-v1", "--seconds", "0.1",
                      "--envs", "1")
    assert done.code == 0, done.err
    rows = markdown_rows(done.out)
    assert [(row[0], row[1]) for row in rows] == [("single process", "1"), ("gymnasium sync", "1"),
                                                  ("gymnasium async", "1"), ("SB3 DummyVecEnv", "1"),
                                                  ("SB3 SubprocVecEnv", "1")]
    assert rows[0][3] == "1.00x" and all(float(row[2]) > 0 for row in rows)


@pytest.mark.slow  # trains, and plays the first decisions in a worker process of its own
def test_bench_train_splits_the_training_wall_time_and_predicts_the_efficiency_on_more_workers(tmp_path):
    config = tmp_path / "agent.yaml"
    config.write_text(yaml.safe_dump({
        "env": {"id": "emmi_gym/Explore-v1", "kwargs": {"particles": 3, "max_decisions": 2,
                                                       "generator": {"nx": 2, "ny": 2, "n_loops": 1}}},
        "algorithm": "MaskablePPO", "policy": "MultiInputPolicy", "n_envs": 1, "vec_env": "dummy",
        "hyperparameters": {"n_steps": 4, "batch_size": 4, "n_epochs": 1, "policy_kwargs": {"net_arch": [8]}},
        "total_timesteps": 8, "seed": 1, "eval": {"freq": 0}, "checkpoint_freq": 8}))
    done = run_script(MEASUREMENTS / "bench_train.py", "--config", config, "--single", "2", "--out", tmp_path)
    assert done.code == 0, done.err
    assert "MaskablePPO on emmi_gym/Explore-v1, 1 env(s) (dummy), 8 decisions" in done.out
    assert "one worker alone:" in done.out and "(2 decisions; per decision median" in done.out
    parts = dict(re.findall(r"^  ([\w ()',]+): ([\d.]+) s \(\d+%\)$", done.out, re.MULTILINE))
    assert set(parts) == {"waiting for the envs", "evaluation", "learning (train())",
                          "other (the learner's replay, checkpoints, logging)"}
    assert float(parts["learning (train())"]) > 0 and float(parts["evaluation"]) == 0  # eval.freq 0
    predicted = re.findall(r"^ +(\d+) workers: rollout workers (\d+)% / (\d+)%", done.out, re.MULTILINE)
    assert [int(w) for w, _, _ in predicted] == [1, 16, 64]
    assert all(int(measured) <= int(free) for _, measured, free in predicted)  # a learner that holds up the workers
    assert (tmp_path / "run" / "model.zip").is_file()
