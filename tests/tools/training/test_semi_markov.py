"""Semi-Markov discounting: a macro-action of tau simulator steps discounts what follows by
gamma ** (tau / unit), in the GAE returns and in the bootstrap of a truncated episode."""

import numpy as np
import pytest
import torch as th
from gymnasium import spaces
from stable_baselines3 import PPO
from stable_baselines3.common.buffers import RolloutBuffer

from emmi_gym.tools.training.config import AgentConfigError, parse_agent_config
from emmi_gym.tools.training.semi_markov import (
    SemiMarkovDictRolloutBuffer,
    SemiMarkovDiscounts,
    SemiMarkovMaskableDictRolloutBuffer,
    SemiMarkovRolloutBuffer,
    rollout_buffer_class,
)
from emmi_gym.tools.training.train import train

GAMMA, UNIT = 0.9, 100


def filled(cls, rewards, values, starts, gae_lambda=0.95):
    obs_space, action_space = spaces.Box(-1, 1, (2,)), spaces.Discrete(3)
    buffer = cls(len(rewards), obs_space, action_space, gamma=GAMMA, gae_lambda=gae_lambda, n_envs=1)
    for r, v, s in zip(rewards, values, starts, strict=False):
        buffer.add(np.zeros((1, 2)), np.zeros((1, 1)), np.array([r]), np.array([s]), th.tensor([v]), th.zeros(1))
    return buffer


def test_with_every_step_one_unit_long_it_is_sb3s_gae():
    rng = np.random.default_rng(0)
    rewards, values = rng.normal(size=12), rng.normal(size=12)
    starts = np.array([1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 0, 0], dtype=np.float32)
    ours, sb3 = filled(SemiMarkovRolloutBuffer, rewards, values, starts), filled(RolloutBuffer, rewards, values, starts)
    for buffer in (ours, sb3):
        buffer.compute_returns_and_advantage(th.tensor([0.7]), np.array([False]))
    np.testing.assert_allclose(ours.advantages, sb3.advantages, rtol=1e-5, atol=1e-6)  # float32 discounts
    np.testing.assert_allclose(ours.returns, sb3.returns, rtol=1e-5, atol=1e-6)


def test_returns_discount_each_step_by_its_duration():
    # with lambda = 1 the return is the duration-discounted sum: R_t = r_t + gamma**(tau_t/unit) R_{t+1}
    rewards, durations = np.array([1.0, -0.5, 2.0]), np.array([100, 350, 1])
    buffer = filled(SemiMarkovRolloutBuffer, rewards, np.zeros(3), np.array([1.0, 0.0, 0.0]), gae_lambda=1.0)
    buffer.discounts[:, 0] = GAMMA ** (durations / UNIT)
    buffer.compute_returns_and_advantage(th.tensor([5.0]), np.array([True]))  # the episode ended: no bootstrap
    r2 = 2.0
    r1 = -0.5 + GAMMA ** 3.5 * r2
    r0 = 1.0 + GAMMA * r1
    np.testing.assert_allclose(buffer.returns[:, 0], [r0, r1, r2], rtol=1e-6)


def test_callback_sets_the_discounts_and_discounts_a_truncated_episodes_bootstrap():
    model = PPO("MlpPolicy", "CartPole-v1", n_steps=4, batch_size=4, rollout_buffer_class=SemiMarkovRolloutBuffer,
                seed=0)
    callback = SemiMarkovDiscounts(UNIT)
    callback.init_callback(model)
    terminal = np.array([0.1, 0.2, -0.1, 0.3], dtype=np.float32)
    infos = [{"sim_steps_this_step": 250, "terminal_observation": terminal, "TimeLimit.truncated": True}]
    rewards = np.array([1.0], dtype=np.float32)
    callback.update_locals({"infos": infos, "dones": np.array([True]), "rewards": rewards})
    assert callback.on_step()
    discount = model.gamma ** 2.5
    assert model.rollout_buffer.discounts[0, 0] == pytest.approx(discount)
    with th.no_grad():
        value = model.policy.predict_values(model.policy.obs_to_tensor(terminal)[0])[0].item()
    # SB3 adds gamma * V next; after it the reward carries discount * V
    assert rewards[0] + model.gamma * value == pytest.approx(1.0 + discount * value, rel=1e-5)


def test_buffer_class_per_algorithm_and_observation():
    assert rollout_buffer_class("MaskablePPO", True) is SemiMarkovMaskableDictRolloutBuffer
    assert rollout_buffer_class("PPO", True) is SemiMarkovDictRolloutBuffer
    assert rollout_buffer_class("A2C", False) is SemiMarkovRolloutBuffer
    with pytest.raises(ValueError, match="not DQN"):
        rollout_buffer_class("DQN", True)


@pytest.mark.parametrize("change, field, expected", [
    ({"algorithm": "DQN", "hyperparameters": {}}, "discount_unit", "absent for DQN"),
    ({"discount_unit": 0}, "discount_unit", "an integer in [1, 1000000] or null"),
    ({"hyperparameters": {"rollout_buffer_kwargs": {}}}, "hyperparameters.rollout_buffer_kwargs", "not given with"),
])
def test_bad_discount_unit_is_a_clear_error(change, field, expected):
    data = {"env": {"id": "emmi_gym/LoopCorridor-v1"}, "algorithm": "MaskablePPO", "discount_unit": 100, **change}
    with pytest.raises(AgentConfigError) as error:
        parse_agent_config(data, source="agent.yaml")
    assert error.value.field == field and expected in str(error.value)


@pytest.mark.slow
def test_waypoint_agent_discounts_each_decision_by_its_duration(tmp_path):
    from sb3_contrib import MaskablePPO
    from stable_baselines3.common.callbacks import BaseCallback

    from emmi_gym.tools.training.train import make_agent_env

    durations = []

    class Durations(BaseCallback):
        def _on_step(self):
            durations.append(self.locals["infos"][0]["sim_steps_this_step"])
            return True

    env = make_agent_env("emmi_gym/LoopCorridor-v1", {"particles": 3, "max_decisions": 4})
    model = MaskablePPO("MultiInputPolicy", env, n_steps=8, batch_size=8, n_epochs=1, gamma=GAMMA, seed=1,
                        policy_kwargs={"net_arch": [16]}, rollout_buffer_class=SemiMarkovMaskableDictRolloutBuffer)
    model.learn(8, callback=[Durations(), SemiMarkovDiscounts(UNIT)])
    durations = np.array(durations, dtype=float)
    assert durations.min() >= 1 and durations.max() > 5 * durations.min()  # macro-actions of very different lengths
    np.testing.assert_allclose(model.rollout_buffer.discounts[:, 0], GAMMA ** (durations / UNIT), rtol=1e-5)


@pytest.mark.slow
def test_train_command_uses_the_configured_discount_unit(tmp_path):
    from emmi_gym.tools.training.evaluate import evaluate_model

    data = {"env": {"id": "emmi_gym/LoopCorridor-v1", "kwargs": {"particles": 3, "max_decisions": 2}},
            "algorithm": "MaskablePPO", "hyperparameters": {"n_steps": 4, "batch_size": 4, "n_epochs": 1,
                                                            "policy_kwargs": {"net_arch": [16]}},
            "discount_unit": UNIT, "n_envs": 1, "vec_env": "dummy", "total_timesteps": 4, "seed": 1,
            "eval": {"freq": 100, "episodes": 1}, "checkpoint_freq": 100}
    result = train(parse_agent_config(data), tmp_path, progress=False)
    from sb3_contrib import MaskablePPO

    model = MaskablePPO.load(result.model_path)
    assert model.rollout_buffer_class is SemiMarkovMaskableDictRolloutBuffer
    assert len(evaluate_model(result.model_path, episodes=1)) == 1
