"""The loop-order family of worlds, ``LoopOrder-v1``, and the A/B experiment's options and sweep.

The sweep and the A/B runs here are tiny (two seeds, few particles, few decisions): they check
what the commands write and that the options reach the env, not what the experiment finds
(docs/results/order_matters.md has the figures).
"""

import csv
import hashlib
import math
from dataclasses import fields
from pathlib import Path

import gymnasium as gym
import numpy as np
import pytest
from gymnasium.utils.env_checker import check_env
from helpers import independent_loops

import emmi_gym  # noqa: F401
from emmi_gym.cli import main
from emmi_gym.experiments.ab import check_world
from emmi_gym.experiments.loop_order import LOOP_ORDER_KEY
from emmi_gym.experiments.sweep import SWEEP_MEASURES, SweepFileError, ab_settings, read_sweep
from emmi_gym.inputs.validation import OptionError
from emmi_gym.policies import make_policy
from emmi_gym.training.train import make_agent_env
from emmi_gym.world import rasterise
from emmi_gym.world.loop_worlds import LoopWorldConfig, generate_loop_world
from emmi_gym.world.presets import odometry_config

TINY = dict(particles=3, max_decisions=8)


@pytest.mark.parametrize("new_area_loop, loops", [(True, 2), (False, 1)])
def test_a_generated_world_is_the_loop_and_the_new_area_with_its_own_loop(new_area_loop, loops):
    world = generate_loop_world(4, LoopWorldConfig(new_area_loop=new_area_loop, size_jitter=0.15))
    check_world(world)  # decision, target_a, target_b and the route to the decision point
    assert independent_loops(world) == loops
    truth = rasterise(world, 0.1)
    for name in ("decision", "target_a", "target_b"):
        assert truth.reachable[truth.geometry.cell_of(*world.place(name).xy)]


def test_the_same_seed_draws_the_same_world_and_others_differ():
    config = LoopWorldConfig(size_jitter=0.15, loop_pillar_spacing=5.0)
    a, b, c = (generate_loop_world(s, config) for s in (7, 7, 8))
    assert np.array_equal(a.walls, b.walls) and a.places == b.places
    assert not (a.walls.shape == c.walls.shape and np.array_equal(a.walls, c.walls))


def pillar_corners(world):
    """The lower-left corners of the pillars (rectangles, four walls in a row, under 0.7 m each) of a world."""
    walls = world.walls
    short = walls[np.hypot(walls[:, 2] - walls[:, 0], walls[:, 3] - walls[:, 1]) < 0.7].reshape(-1, 4, 5)
    return {(round(float(p[:, [0, 2]].min()), 3), round(float(p[:, [1, 3]].min()), 3)) for p in short}


def test_pillars_line_the_walls_they_are_asked_for():
    plain = pillar_corners(generate_loop_world(1, LoopWorldConfig(new_area_pillar_spacing=0.0)))
    assert len(plain) == 2 and all(x > 0 for x, _ in plain)  # the two landmarks where the loop closes
    pillared = pillar_corners(generate_loop_world(1, LoopWorldConfig(new_area_pillar_spacing=2.0)))
    top = sorted(x for x, y in pillared if x < 0 and y > 9)  # on the new area's north wall (y = 10)
    assert len(top) >= 3 and np.allclose(np.diff(top), 2.0)
    looped = pillar_corners(generate_loop_world(1, LoopWorldConfig(new_area_pillar_spacing=0.0,
                                                                   loop_pillar_spacing=4.0)))
    assert len(looped) > 2 + 4 and all(x > 0 for x, _ in looped)


@pytest.mark.parametrize("options, field", [
    (dict(new_area_length=2.5), "new_area_length"),
    (dict(loop_height=16.0, size_jitter=0.3), "loop_height"),
    (dict(corridor_width=9.0), "corridor_width"),
])
def test_a_family_option_out_of_range_names_its_field(options, field):
    with pytest.raises(OptionError, match=field):
        gym.make("emmi_gym/LoopOrder-v1", generator=options)


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


@pytest.mark.parametrize("path", sorted((Path(__file__).resolve().parent.parent / "sweeps").glob("*.yaml")),
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


def test_the_world_page_states_every_family_option():
    text = (Path(__file__).resolve().parent.parent / "docs" / "world.md").read_text()
    block = text.split("<!-- loop-world-options")[1].split("<!-- /loop-world-options -->")[0]
    stated = [[cell.strip().strip("`") for cell in line.strip().strip("|").split(" | ")]
              for line in block.splitlines()[3:] if line.startswith("|")]
    assert stated == [[f.name, str(f.default), f.metadata["help"]] for f in fields(LoopWorldConfig)]
