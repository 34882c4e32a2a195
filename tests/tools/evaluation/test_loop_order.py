"""``LoopOrder-v1``, and the A/B experiment's options and sweep (the family's worlds themselves:
tests/world/test_loop_worlds.py).

The sweep and the A/B runs here are tiny (two seeds, few particles, few decisions): they check
what the commands write and that the options reach the env, not what the experiment finds
(docs/results/order_matters.md has the figures).
"""

import csv
import hashlib
import math

import gymnasium as gym
import numpy as np
import pytest
from gymnasium.utils.env_checker import check_env
from helpers import ROOT

import emmi_gym  # noqa: F401
from emmi_gym.tools.cli import main
from emmi_gym.tools.evaluation.loop_order import LOOP_ORDER_KEY
from emmi_gym.tools.experiments.sweep import SWEEP_MEASURES, SweepFileError, ab_settings, read_sweep
from emmi_gym.tools.policies import make_policy
from emmi_gym.tools.training.train import make_agent_env
from emmi_gym.world.presets import odometry_config

TINY = dict(particles=3, max_decisions=8)


@pytest.mark.slow
def test_loop_order_passes_the_checker_and_replays_bit_for_bit():
    env = gym.make("emmi_gym/LoopOrder-v1", **TINY)
    check_env(env.unwrapped, skip_render_check=True)

    def episode(seed):
        env = make_agent_env("emmi_gym/LoopOrder-v1", dict(TINY, max_decisions=3))
        digest = hashlib.sha256()
        obs, info = env.reset(seed=seed)
        names = (env.unwrapped.world.name, env.unwrapped.world.description)
        policy = make_policy("explore_first")
        policy.reset(seed)
        done = False
        while not done:
            obs, reward, terminated, truncated, info = env.step(policy(env))
            digest.update(obs["map"].tobytes() + obs["pose"].tobytes() + np.float64(reward).tobytes())
            done = terminated or truncated
        return digest.hexdigest(), names, info

    first, names, info = episode(11)
    again, names_again, _ = episode(11)
    other, other_names, _ = episode(12)
    assert (first, names) == (again, names_again)
    assert names != other_names and first != other  # each seed draws its own world
    assert info[LOOP_ORDER_KEY] in (0.0, 1.0) or math.isnan(info[LOOP_ORDER_KEY])


def test_the_ab_options_reach_the_env():
    settings = ab_settings("emmi_gym/LoopCorridor-v1", {"laser.max_range": 4.0, "odometry_scale": 2.0,
                                                        "slam.resample_threshold": 1.0, "particles": 5})
    env = settings.experiment_env().unwrapped
    poor = odometry_config("poor")
    assert env.laser_config.max_range == 4.0 and env.laser_config.n_beams == 181  # the env's preset, changed
    assert env.odometry_config.trans_from_trans == pytest.approx(2 * poor.trans_from_trans)
    assert env.odometry_config.heading_drift == pytest.approx(2 * poor.heading_drift)
    assert env.slam_config.resample_threshold == 1.0 and env.slam_config.particles == 5


@pytest.mark.slow
def test_ab_plays_loop_order_and_writes_the_runs(tmp_path):
    out = tmp_path / "ab"
    assert main(["ab", "--env-id", "emmi_gym/LoopOrder-v1", "--seeds", "2", "--particles", "3",
                 "--max-decisions", "8", "--workers", "1", "--quiet", "--out", str(out)]) == 0
    with open(out / "ab_runs.csv") as f:
        runs = list(csv.DictReader(f))
    assert [(r["seed"], r["arm"]) for r in runs] == [("0", "A"), ("0", "B"), ("1", "A"), ("1", "B")]
    for r in runs:
        assert float(r["ate"]) >= 0 and 0 <= float(r["oracle_accuracy"]) <= 1 and int(r["sim_steps"]) > 0


def write_sweep(path, grid="  particles: [2, 3]\n", extra=""):
    path.write_text("seeds: 2\nfirst_seed: 5\nmax_decisions: 8\noptions:\n  world: loop_order\n"
                    f"  generator.new_area_length: 8\n{extra}grid:\n{grid}")
    return path


@pytest.mark.slow
def test_a_sweep_writes_its_table_and_figure_and_resumes(tmp_path, capsys):
    sweep_file, out = write_sweep(tmp_path / "sweep.yaml"), tmp_path / "out"
    argv = ["ab", "--sweep", str(sweep_file), "--workers", "2", "--quiet", "--out", str(out)]
    assert main(argv) == 0
    with open(out / "sweep_runs.csv") as f:
        runs = list(csv.DictReader(f))
    assert sorted((r["label"], r["seed"], r["arm"]) for r in runs) == sorted(
        (f"particles={p}", s, arm) for p in (2, 3) for s in ("5", "6") for arm in "AB")
    with open(out / "sweep_summary.csv") as f:
        summary = list(csv.DictReader(f))
    assert [r["particles"] for r in summary] == ["2", "3"]
    for column in SWEEP_MEASURES:
        assert {f"{column}_diff", f"{column}_low", f"{column}_high"} <= set(summary[0])
    assert {"sim_steps_A", "sim_steps_B"} <= set(summary[0])
    table = (out / "sweep.md").read_text()
    assert "| particles=2 | 2 |" in table and "| particles=3 | 2 |" in table
    assert (out / "sweep_ate.png").stat().st_size > 0
    before = (out / "sweep_runs.csv").read_text()
    capsys.readouterr()
    assert main(argv) == 0  # every setting's runs are there: nothing runs again
    assert (out / "sweep_runs.csv").read_text() == before


@pytest.mark.parametrize("grid, extra, message", [
    ("  particles: 3\n", "", "grid.particles': expected a non-empty list"),
    ("  laser.max_range: [4.0, -1.0]\n", "", "laser.max_range=-1.0"),
    ("  particles: [3]\n", "colour: red\n", "'colour': expected one of the known options"),
    ("  particles: [3]\n", "figure: [odometry_scale, particles]\n", "field 'figure': expected grid keys"),
    ("  warp.speed: [1]\n", "", "a dotted key into one of the nested options"),
])
def test_a_bad_sweep_file_names_the_field(tmp_path, grid, extra, message):
    with pytest.raises(SweepFileError, match=message.replace("[", r"\[").replace(".", r"\.")):
        read_sweep(write_sweep(tmp_path / "bad.yaml", grid, extra))


@pytest.mark.parametrize("path", sorted((ROOT / "sweeps").glob("*.yaml")),
                         ids=lambda p: p.name)
def test_the_shipped_sweeps_read(path):
    sweep = read_sweep(path)  # the docs quote them: every setting makes its env
    assert len(sweep.settings) >= 6 and sweep.config.seeds >= 20 and len(sweep.figure_keys) == 2


@pytest.mark.parametrize("argv, message", [
    (["ab", "--odometry", "bogus"], "odometry_noise"),
    (["ab", "--set", "generator.new_area_length"], "--set expects KEY=VALUE"),
    (["ab", "--laser-fov", "400"], "expected a finite number in (0, 360]"),
    (["ab", "--world", "loop_order", "--set", "generator.new_area_length=2"], "generator.new_area_length"),
    (["ab", "--sweep", "missing.yaml"], "missing.yaml"),
])
def test_bad_ab_options_are_clear_errors(argv, message, capsys, tmp_path):
    with pytest.raises(SystemExit) as exit_:
        main(argv + ["--out", str(tmp_path / "out")])
    assert exit_.value.code == 2
    assert message in capsys.readouterr().err
