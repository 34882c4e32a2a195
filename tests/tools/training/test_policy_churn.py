"""Policy churn across a run's checkpoints: a model agrees with itself at every decision, the decisions
counted are those of the final model's held-out episodes, and what cannot be compared is a clear error."""

import pytest

from emmi_gym.tools.training.config import parse_agent_config
from emmi_gym.tools.training.evaluate import evaluate_model
from emmi_gym.tools.training.policy_churn import agreement_with_final, checkpoints_to_compare
from emmi_gym.tools.training.train import train


def waypoint_run(tmp_path, **extra):
    config = {"env": {"id": "emmi_gym/LoopCorridor-v1", "kwargs": {"particles": 3, "max_decisions": 3}},
              "algorithm": "MaskablePPO", "policy": "MultiInputPolicy",
              "hyperparameters": {"policy_kwargs": {"net_arch": [16]}, "n_steps": 4, "batch_size": 4, "n_epochs": 1},
              "n_envs": 1, "vec_env": "dummy", "total_timesteps": 12, "seed": 3, "checkpoint_freq": 4,
              "eval": {"freq": 0, "episodes": 1, "seed": 500}, **extra}
    train(parse_agent_config(config), tmp_path, progress=False)
    return tmp_path


@pytest.mark.slow
def test_the_final_model_agrees_with_itself_on_every_decision_of_its_episodes(tmp_path):
    run = waypoint_run(tmp_path)
    (final_decisions, final), checkpoints = checkpoints_to_compare(run)
    assert final == run / "model.zip" and final_decisions == 12
    assert [count for count, _ in checkpoints] == [4, 8], "the checkpoints nearest 1/4, 1/2, 3/4 of 12, not the final"
    rows = agreement_with_final(final, [final, checkpoints[0][1]], episodes=2, seed=7)
    played = sum(row["env_steps"] for row in evaluate_model(final, episodes=2, seed=7))
    assert [row["decisions"] for row in rows] == [played, played]
    assert rows[0]["same_action"] == played and rows[0]["agreement"] == 1.0
    assert 0 <= rows[1]["same_action"] <= played


@pytest.mark.slow
def test_a_missing_checkpoint_or_continuous_actions_are_clear_errors(tmp_path):
    run = waypoint_run(tmp_path / "waypoints")
    missing = r"no whole checkpoint at \[5\] decisions; its checkpoints are at \[4, 8, 12\]"
    with pytest.raises(ValueError, match=missing):
        checkpoints_to_compare(run, [4, 5])
    for checkpoint in (run / "checkpoints").iterdir():
        checkpoint.unlink()
    with pytest.raises(ValueError, match="no checkpoint but the final model"):
        checkpoints_to_compare(run)
    velocity = waypoint_run(tmp_path / "velocity", env={"id": "emmi_gym/ExploreVelocity-v0", "kwargs": {
        "particles": 3, "generator": {"nx": 2, "ny": 2, "n_loops": 1}, "max_sim_steps": 40}}, algorithm="PPO")
    with pytest.raises(ValueError, match="discrete action, but the model acts in Box"):
        agreement_with_final(velocity / "model.zip", [velocity / "model.zip"])
