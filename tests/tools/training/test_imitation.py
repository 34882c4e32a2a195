"""Behaviour cloning: demonstrations of a scripted policy, the fit, and the run that train --init-from continues."""

import numpy as np
import pytest
import yaml

from emmi_gym.tools.cli import main
from emmi_gym.tools.training.config import parse_agent_config
from emmi_gym.tools.training.imitation import Demonstrations, agreement, cloned_model, collect_demonstrations

#: LoopCorridor-v1's waypoint agent, small: 3 particles, 3 decisions an episode.
CONFIG = {"env": {"id": "emmi_gym/LoopCorridor-v1", "kwargs": {"particles": 3, "max_decisions": 3}},
          "algorithm": "MaskablePPO", "policy": "TargetScoringPolicy",
          "hyperparameters": {"n_steps": 8, "batch_size": 8, "n_epochs": 1}, "n_envs": 1, "vec_env": "dummy",
          "total_timesteps": 8, "seed": 3, "eval": {"freq": 8, "episodes": 1, "seed": 500}}


@pytest.mark.slow
def test_demonstrations_record_every_decision_and_a_clone_learns_them(tmp_path):
    config = parse_agent_config(CONFIG)
    demos = collect_demonstrations(config, "close_loop_first", 2, 7, workers=1, progress=False)
    assert len(demos) == 6 and demos.episodes == 2 and demos.masks.shape == (6, 8)
    assert demos.masks[np.arange(6), demos.actions].all()  # every demonstrated action was a valid slot
    assert set(demos.observations) == {"map", "pose", "certainty", "targets"}
    assert demos.observations["map"].shape == (6, 2, 64, 64)
    demos.save(tmp_path / "demos.npz")
    again = Demonstrations.load(tmp_path / "demos.npz")
    assert np.array_equal(again.actions, demos.actions) and np.array_equal(again.masks, demos.masks)
    assert all(np.array_equal(again.observations[k], demos.observations[k]) for k in demos.observations)
    joined = Demonstrations.joined([demos, again])
    assert len(joined) == 12 and joined.episodes == 4

    model, losses = cloned_model(config, demos, epochs=200, batch_size=6, learning_rate=1e-3)
    assert losses[-1] < 0.5 * losses[0]
    assert agreement(model, demos) == 1.0  # six decisions, fitted


@pytest.mark.slow
def test_clone_command_writes_a_run_that_train_init_from_continues(tmp_path):
    (tmp_path / "agent.yaml").write_text(yaml.safe_dump(CONFIG))
    assert main(["clone", str(tmp_path / "agent.yaml"), "--policy", "frontier", "--episodes", "1", "--workers", "1",
                 "--epochs", "2", "--out", str(tmp_path / "bc"), "--quiet"]) == 0
    record = yaml.safe_load((tmp_path / "bc" / "clone.yaml").read_text())
    assert record["decisions"] == 3 and len(record["losses"]) == 2 and 0.0 <= record["agreement"] <= 1.0
    assert (tmp_path / "bc" / "demonstrations.npz").is_file()
    assert main(["train", str(tmp_path / "agent.yaml"), "--init-from", str(tmp_path / "bc" / "model.zip"),
                 "--out", str(tmp_path / "rl"), "--quiet"]) == 0
    assert yaml.safe_load((tmp_path / "rl" / "training.yaml").read_text())["init_from"].endswith("model.zip")


def test_bad_demonstrations_and_a_velocity_env_are_clear_errors(tmp_path):
    import pytest

    (tmp_path / "text.npz").write_text("not a zip")
    with pytest.raises(ValueError, match=r"text\.npz: expected a demonstrations file: an \.npz archive"):
        Demonstrations.load(tmp_path / "text.npz")
    np.savez(tmp_path / "short.npz", masks=np.ones((2, 8), bool), actions=np.zeros(3, np.int64), episodes=1,
             obs_map=np.zeros((3, 2, 64, 64), np.uint8))
    with pytest.raises(ValueError, match=r"short\.npz: field 'masks': expected a row per decision, 3 as there are"):
        Demonstrations.load(tmp_path / "short.npz")
    np.savez(tmp_path / "masked.npz", masks=np.zeros((1, 8), bool), actions=np.zeros(1, np.int64), episodes=1,
             obs_map=np.zeros((1, 2, 64, 64), np.uint8))
    with pytest.raises(ValueError, match=r"masked\.npz: field 'actions': expected every action to be a slot its mask"):
        Demonstrations.load(tmp_path / "masked.npz")
    other = Demonstrations({"map": np.zeros((1, 1, 8, 8), np.uint8)}, np.ones((1, 8), bool), np.zeros(1, np.int64), 1)
    with pytest.raises(ValueError, match="observations of shapes"):
        cloned_model(parse_agent_config(CONFIG), other, epochs=1)
    velocity = dict(CONFIG, env={"id": "emmi_gym/ExploreVelocity-v0", "kwargs": {"particles": 3}},
                    policy="MultiInputPolicy", algorithm="PPO")
    with pytest.raises(ValueError, match="need a waypoint env"):
        collect_demonstrations(parse_agent_config(velocity), "frontier", 1, 0, workers=1, progress=False)
    dqn = dict(CONFIG, algorithm="DQN", policy="MultiInputPolicy", hyperparameters={"learning_starts": 8})
    with pytest.raises(ValueError, match="algorithm DQN: behaviour cloning fits a MaskablePPO policy"):
        collect_demonstrations(parse_agent_config(dqn), "frontier", 1, 0, workers=1, progress=False)


def test_clone_refuses_a_policy_beside_demonstrations_files(tmp_path, capsys):
    (tmp_path / "agent.yaml").write_text(yaml.safe_dump(CONFIG))
    with pytest.raises(SystemExit) as stop:
        main(["clone", str(tmp_path / "agent.yaml"), "--policy", "frontier", "--demos", str(tmp_path / "a.npz"),
              "--out", str(tmp_path / "bc")])
    assert stop.value.code == 2
    err = capsys.readouterr().err
    assert "--policy frontier with --demos: the demonstrations files hold their own decisions" in err
    assert not (tmp_path / "bc").exists()
