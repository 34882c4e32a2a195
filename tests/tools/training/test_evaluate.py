"""Playing trained agents: beside the scripted baselines on the same episodes, and the agents shipped."""

import csv

import gymnasium as gym
import pytest

from emmi_gym import pretrained
from emmi_gym.tools.cli import main
from emmi_gym.tools.evaluation.comparison import ComparisonSettings, play_on_world
from emmi_gym.tools.training.config import parse_agent_config
from emmi_gym.tools.training.run_folders import RunFolder
from emmi_gym.tools.training.train import train
from emmi_gym.world.map_sets import map_set_files

#: A tiny waypoint agent on a small generated world, two decisions an episode.
TINY_ENV = {"particles": 3, "generator": {"nx": 2, "ny": 2, "n_loops": 1}, "max_decisions": 2}


@pytest.fixture(scope="module")
def tiny_agent(tmp_path_factory):
    run = tmp_path_factory.mktemp("run")
    data = {"env": {"id": "emmi_gym/Explore-v1", "kwargs": TINY_ENV}, "algorithm": "MaskablePPO",
            "policy": "MultiInputPolicy",
            "hyperparameters": {"policy_kwargs": {"net_arch": [16]}, "n_steps": 8, "batch_size": 8, "n_epochs": 1},
            "n_envs": 1, "vec_env": "dummy", "total_timesteps": 8, "seed": 3,
            "eval": {"freq": 1000, "episodes": 1, "seed": 500}, "checkpoint_freq": 1000}
    return train(parse_agent_config(data), run, progress=False).model_path


def read_rows(path) -> list[dict]:
    with open(path) as f:
        return list(csv.DictReader(f))


@pytest.mark.slow
def test_evaluate_plays_the_model_and_the_baselines_on_the_same_episodes(tiny_agent, tmp_path, capsys):
    out = tmp_path / "eval"
    assert main(["evaluate", str(tiny_agent), "--episodes", "2", "--seed", "7", "--baselines", "frontier", "random",
                 "--workers", "1", "--quiet", "--out", str(out)]) == 0
    printed = capsys.readouterr().out
    assert "agent - frontier: 2 pairs" in printed and "agent - random: 2 pairs" in printed
    assert "agent - frontier at equal robot time" in printed and "agent - random at equal robot time" in printed
    assert (out / "front.png").stat().st_size > 10_000 and (out / "maps.png").stat().st_size > 10_000
    rows = read_rows(out / "episodes.csv")
    assert sorted((r["policy"], r["seed"]) for r in rows) == sorted(
        (p, s) for p in ("agent", "frontier", "random") for s in ("7", "8"))
    traces = read_rows(out / "traces.csv")
    for row in rows:  # each episode's trace starts at the reset and ends at its final scores
        own = [t for t in traces if (t["policy"], t["seed"]) == (row["policy"], row["seed"])]
        assert own[0]["sim_steps"] == "0.0" and len(own) == int(row["decisions"]) + 1
        assert all(float(own[-1][c]) == float(row[c]) for c in ("sim_steps", "ate", "oracle_accuracy", "coverage"))
    # the baseline's episodes are those the comparison plays on its own for the same world and seed
    config = RunFolder.config_of_model(tiny_agent)
    alone = play_on_world(None, 8, "frontier", ComparisonSettings(config.env_id, config.eval_env_kwargs))
    played = next(r for r in rows if r["policy"] == "frontier" and r["seed"] == "8")
    assert float(played["ate"]) == alone["ate"] and float(played["coverage"]) == alone["coverage"]


@pytest.mark.slow
def test_evaluate_on_a_map_set_plays_its_first_maps(tiny_agent, tmp_path, capsys):
    out = tmp_path / "eval"
    assert main(["evaluate", str(tiny_agent), "--name", "tiny", "--world", "dungeon_maps/test", "--episodes", "2",
                 "--baselines", "frontier", "--workers", "1", "--quiet", "--out", str(out)]) == 0
    plans = [f"dungeon_maps/test/{p.name}" for p in map_set_files("dungeon_maps/test")[:2]]
    rows = read_rows(out / "episodes.csv")
    assert sorted({r["world"] for r in rows}) == sorted(plans)
    assert {r["policy"] for r in rows} == {"tiny", "frontier"} and "tiny - frontier: 2 pairs" in capsys.readouterr().out


@pytest.mark.slow
def test_evaluate_refuses_unknown_baselines_and_agents(tiny_agent, capsys):
    for argv, expected in [([str(tiny_agent), "--baselines", "nearest"], "--baselines: unknown ['nearest']"),
                           (["--pretrained", "nope"], "no pretrained agent 'nope'"),
                           ([], "give a model .zip or --pretrained NAME"),
                           ([str(tiny_agent), "--pretrained", "loop_corridor_emmi"], "one of them"),
                           ([str(tiny_agent), "--baselines", "frontier", "loop_order_emmi"],
                            "--baselines: loop_order_emmi"),
                           (["--pretrained", "loop_order_emmi", "--baselines", "loop_order_emmi"],
                            "--baselines: loop_order_emmi is the model evaluated"),
                           ([str(tiny_agent), "--name", "emmi | seed 0"], "argument --name: expected 1-64 letters")]:
        with pytest.raises(SystemExit) as stop:
            main(["evaluate", *argv])
        assert stop.value.code == 2 and expected in capsys.readouterr().err


@pytest.mark.slow
@pytest.mark.parametrize("name", pretrained.names())
def test_each_shipped_agent_loads_in_one_line_and_picks_a_valid_target(name):
    model = pretrained.load(name)
    config = pretrained.config(name)
    card = (pretrained.FOLDER / name / "MODEL_CARD.md").read_text()
    assert f"{model.num_timesteps} decisions, seed {config.seed}" in card and "| ATE (m) |" in card
    env = gym.make(config.env_id, **config.eval_env_kwargs)
    observation, _ = env.reset(seed=200_000)
    masks = env.unwrapped.action_masks()
    action, _ = model.predict(observation, action_masks=masks, deterministic=True)
    assert masks[int(action)]
    env.close()


def test_the_package_ships_the_reference_agents():
    assert {"loop_corridor_emmi", "loop_order_emmi", "explore_plans_emmi"} <= set(pretrained.names())


@pytest.mark.slow
def test_score_checkpoints_plays_every_checkpoint_on_the_same_episodes(tmp_path, capsys):
    from emmi_gym.tools.experiments.report import read_csv
    from emmi_gym.tools.training.checkpoint_scores import score_checkpoints
    from emmi_gym.tools.training.evaluate import compare_model

    data = {"env": {"id": "emmi_gym/Explore-v1", "kwargs": TINY_ENV}, "algorithm": "MaskablePPO",
            "policy": "MultiInputPolicy",
            "hyperparameters": {"policy_kwargs": {"net_arch": [16]}, "n_steps": 4, "batch_size": 4, "n_epochs": 1},
            "n_envs": 1, "vec_env": "dummy", "total_timesteps": 8, "seed": 3,
            "eval": {"freq": 0, "episodes": 1, "seed": 500}, "checkpoint_freq": 4}
    run = tmp_path / "run"
    train(parse_agent_config(data), run, progress=False)
    (run / "checkpoints" / "model_12_steps.zip").write_bytes(b"cut short")  # a save a kill cut short
    with pytest.warns(UserWarning, match="skipping the damaged checkpoint .*model_12_steps.zip"):
        assert main(["score-checkpoints", str(run), "--episodes", "2", "--seed", "7", "--workers", "1"]) == 0
    assert f"{run}: 2 checkpoints x 2 episodes: wrote {run / 'checkpoint_scores.csv'}" in capsys.readouterr().out
    curve, rows = read_csv(run / "checkpoint_scores.csv"), read_csv(run / "checkpoint_episodes.csv")
    assert [row["timesteps"] for row in curve] == [4, 8]
    assert sorted((r["policy"], r["seed"]) for r in rows) == [(p, s) for p in ("model_4", "model_8") for s in (7, 8)]
    last = [r for r in rows if r["policy"] == "model_8"]
    assert curve[1]["ate"] == pytest.approx(sum(r["ate"] for r in last) / 2)
    alone = compare_model(run / "checkpoints" / "model_8_steps.zip", "model_8", episodes=2, seed=7, workers=1,
                          progress=False)
    assert [r["ate"] for r in alone] == [r["ate"] for r in last]  # the same episodes as evaluate plays

    data = dict(data, total_timesteps=12, checkpoint_freq=8)  # the last checkpoint 4 decisions before the end
    train(parse_agent_config(data), tmp_path / "ends_later", progress=False)
    capsys.readouterr()
    assert main(["score-checkpoints", str(tmp_path / "ends_later"), "--episodes", "1", "--seed", "7",
                 "--workers", "1", "--quiet"]) == 0
    assert "episodes:" not in capsys.readouterr().err, "--quiet: no progress bar"
    curve = read_csv(tmp_path / "ends_later" / "checkpoint_scores.csv")
    assert [row["timesteps"] for row in curve] == [8, 12], "the final model ends the curve"
    final = compare_model(tmp_path / "ends_later" / "model.zip", "final", episodes=1, seed=7, workers=1,
                          progress=False)
    assert curve[1]["ate"] == pytest.approx(final[0]["ate"])

    with pytest.raises(FileNotFoundError, match="run folder .*empty does not exist"):
        score_checkpoints(tmp_path / "empty", progress=False)
    (tmp_path / "empty").mkdir()
    with pytest.raises(FileNotFoundError, match="no checkpoint in .*empty/checkpoints"):
        score_checkpoints(tmp_path / "empty", progress=False)


def test_a_shipped_agent_named_as_a_baseline_plays_its_model():
    from emmi_gym.tools.commands.arguments import baseline_policies
    from emmi_gym.tools.training.evaluate import TrainedAgent

    frontier, clone = baseline_policies(["frontier", "explore_plans_emmi"])
    assert frontier == "frontier" and clone == TrainedAgent(str(pretrained.model_path("explore_plans_emmi")),
                                                            "explore_plans_emmi")
    with pytest.raises(ValueError, match=r"--baselines: unknown \['nearest'\]; choose scripted .* or shipped agents"):
        baseline_policies(["nearest"])


def test_the_tables_formatter_is_the_evaluations_and_its_old_name_warns():
    from emmi_gym.tools.evaluation import comparison
    from emmi_gym.tools.training import evaluate

    with pytest.warns(FutureWarning, match=r"training\.evaluate\.format_table is now emmi_gym\.tools\.evaluation"
                                           r"\.comparison\.format_table; the old name goes in emmi-gym 0\.5\.0"):
        assert evaluate.format_table is comparison.format_table
    with pytest.raises(AttributeError, match="has no attribute 'no_such_name'"):
        _ = evaluate.no_such_name
