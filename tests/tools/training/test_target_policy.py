"""TargetScoringPolicy: one shared network scores every target slot from its observation row."""

import gymnasium as gym
import numpy as np
import pytest
import torch as th
from gymnasium import spaces
from sb3_contrib import MaskablePPO

import emmi_gym
from emmi_gym.tools.training.config import AgentConfigError, parse_agent_config
from emmi_gym.tools.training.target_policy import TargetScoringPolicy

gym.register_envs(emmi_gym)
N_SLOTS, N_FEATURES, SIZE = 8, 8, 36


class FindTheRevisit(gym.Env):
    """One decision per episode: the slot whose row says 'revisit' pays 1, any other slot 0. The revisit
    lands in a random slot each episode and some slots are empty (masked), so only a policy that reads the
    rows, not one that learns a favourite slot number, can be right more than 1/n of the time."""

    observation_space = spaces.Dict({
        "map": spaces.Box(0, 255, (2, SIZE, SIZE), dtype=np.uint8),
        "pose": spaces.Box(-1.0, 1.0, (4,), dtype=np.float32),
        "certainty": spaces.Box(-1.0, 1.0, (2,), dtype=np.float32),
        "targets": spaces.Box(-1.0, 1.0, (N_SLOTS, N_FEATURES), dtype=np.float32),
    })
    action_space = spaces.Discrete(N_SLOTS)

    def reset(self, *, seed=None, options=None):
        super().reset(seed=seed)
        rng = self.np_random
        self._mask = rng.random(N_SLOTS) < 0.7
        self._mask[rng.integers(N_SLOTS)] = True
        rows = np.zeros((N_SLOTS, N_FEATURES), dtype=np.float32)
        valid = np.flatnonzero(self._mask)
        rows[valid, 0] = 1.0
        rows[valid, 2:5] = rng.uniform(-0.5, 0.5, (valid.size, 3))
        self._good = int(rng.choice(valid))
        rows[self._good, 1] = 1.0
        rows[self._good, 6] = 0.5
        return {"map": np.zeros((2, SIZE, SIZE), np.uint8), "pose": np.zeros(4, np.float32),
                "certainty": np.zeros(2, np.float32), "targets": rows}, {}

    def step(self, action):
        return self.reset()[0], float(action == self._good), True, False, {}

    def action_masks(self):
        return self._mask.copy()


def policy_on(env, seed=0):
    return MaskablePPO(TargetScoringPolicy, env, n_steps=64, batch_size=64, learning_rate=3e-3, seed=seed,
                       device="cpu")


def logits(model, obs):
    o, _ = model.policy.obs_to_tensor(obs)
    with th.no_grad():
        return model.policy.mlp_extractor.forward_actor(model.policy.extract_features(o))[0].numpy()


def test_a_slot_scores_its_row_wherever_it_lands():
    env = gym.make("emmi_gym/LoopCorridor-v1", particles=5)
    model = policy_on(env)
    obs, _ = env.reset(seed=0)
    before = logits(model, obs)
    swapped = {key: value.copy() for key, value in obs.items()}
    swapped["targets"][[0, 6]] = swapped["targets"][[6, 0]]
    after = logits(model, swapped)
    np.testing.assert_allclose(after[[6, 0]], before[[0, 6]], rtol=1e-5)
    np.testing.assert_allclose(np.delete(after, [0, 6]), np.delete(before, [0, 6]), rtol=1e-5)
    # untrained, the choice is close to uniform over the valid slots and never an empty one
    mask = env.unwrapped.action_masks()
    o, _ = model.policy.obs_to_tensor(obs)
    with th.no_grad():
        probs = model.policy.get_distribution(o, action_masks=mask).distribution.probs[0].numpy()
    assert np.all(probs[~mask] == 0)
    np.testing.assert_allclose(probs[mask], 1 / mask.sum(), atol=0.01)


@pytest.mark.slow
def test_it_learns_to_follow_a_target_from_slot_to_slot():
    env = FindTheRevisit()
    model = policy_on(env)
    model.learn(3000)
    hits = 0
    for seed in range(200):
        obs, _ = env.reset(seed=10_000 + seed)
        action, _ = model.predict(obs, action_masks=env.action_masks(), deterministic=True)
        hits += int(action) == env._good
    assert hits >= 190  # a favourite slot number would be right about 1 time in 6


def test_it_is_for_maskable_ppo_on_the_waypoint_observation():
    data = {"env": {"id": "emmi_gym/LoopCorridor-v1"}, "algorithm": "PPO", "policy": "TargetScoringPolicy"}
    with pytest.raises(AgentConfigError, match="policy.*only with algorithm MaskablePPO"):
        parse_agent_config(data)
    assert parse_agent_config(dict(data, algorithm="MaskablePPO")).policy == "TargetScoringPolicy"
    image = gym.make("emmi_gym/LoopCorridor-v1", particles=5, observation="image")
    with pytest.raises(ValueError, match="waypoint Dict observation"):
        policy_on(image)
    with pytest.raises(ValueError, match="fixes 'net_arch'"):
        MaskablePPO(TargetScoringPolicy, gym.make("emmi_gym/LoopCorridor-v1", particles=5),
                    policy_kwargs={"net_arch": [32]}, device="cpu")
