"""Semi-Markov discounting for macro-actions (Sutton, Precup & Singh 1999, "Between MDPs and semi-MDPs").

A waypoint action lasts anything from one simulator step (a target found blocked at once)
to hundreds (a drive round a corridor). Discounting once per *decision*, as SB3 does,
makes time spent in many short hops cheaper than the same time spent in one long drive,
and lets an agent postpone every cost by spending decisions that take no time. On
``LoopCorridor-v1`` that alone made nearest-frontier hopping (about 20 decisions) score
above closing the loop (one 350-step drive) under the EMMI reward, although the loop
closure earns more EMMI per unit of robot time (``measurements/reward_returns.py``).

In a semi-MDP the value after an option of duration tau is discounted by gamma**tau.
Here ``gamma`` applies per ``unit`` simulator steps: after a step that took tau
simulator steps (the env's ``info["sim_steps_this_step"]``), what follows is
discounted by ``gamma ** (tau / unit)``. For the on-policy algorithms (PPO, A2C,
MaskablePPO) the rollout buffers below keep one discount per step and
:class:`SemiMarkovDiscounts` fills it. (The off-policy ones are not covered: SB3's replay
buffers draw the env index of a sample internally, so a per-transition discount cannot be
matched to it without rewriting their sampling.)
"""

from __future__ import annotations

import numpy as np
import torch as th
from sb3_contrib.common.maskable.buffers import MaskableDictRolloutBuffer, MaskableRolloutBuffer
from stable_baselines3.common.buffers import DictRolloutBuffer, RolloutBuffer
from stable_baselines3.common.callbacks import BaseCallback

#: The ``info`` key with the simulator steps a step took (the env sets it on every step).
DURATION_KEY = "sim_steps_this_step"
#: The algorithms whose buffers below support per-step discounts.
SUPPORTED = ("PPO", "A2C", "MaskablePPO")


def step_discounts(gamma: float, unit: int, infos) -> np.ndarray:
    """``gamma ** (tau / unit)`` for each env's step duration tau (simulator steps)."""
    durations = np.array([info[DURATION_KEY] for info in infos], dtype=np.float64)
    return (gamma ** (durations / unit)).astype(np.float32)


class _PerStepDiscountGAE:
    """A rollout buffer whose GAE (Schulman et al. 2016) uses ``discounts[step]`` in place of gamma."""

    def reset(self) -> None:
        super().reset()
        self.discounts = np.full((self.buffer_size, self.n_envs), self.gamma, dtype=np.float32)

    def compute_returns_and_advantage(self, last_values: th.Tensor, dones: np.ndarray) -> None:
        """SB3's GAE / TD(lambda) recursion with delta_t = r_t + d_t V(s_{t+1}) - V(s_t), d_t = gamma**(tau_t/unit)."""
        last_values = last_values.clone().cpu().numpy().flatten()
        last_gae_lam = 0.0
        for step in reversed(range(self.buffer_size)):
            if step == self.buffer_size - 1:
                next_non_terminal = 1.0 - dones.astype(np.float32)
                next_values = last_values
            else:
                next_non_terminal = 1.0 - self.episode_starts[step + 1]
                next_values = self.values[step + 1]
            discount = self.discounts[step]
            delta = self.rewards[step] + discount * next_values * next_non_terminal - self.values[step]
            last_gae_lam = delta + discount * self.gae_lambda * next_non_terminal * last_gae_lam
            self.advantages[step] = last_gae_lam
        self.returns = self.advantages + self.values


class SemiMarkovRolloutBuffer(_PerStepDiscountGAE, RolloutBuffer):
    pass


class SemiMarkovDictRolloutBuffer(_PerStepDiscountGAE, DictRolloutBuffer):
    pass


class SemiMarkovMaskableRolloutBuffer(_PerStepDiscountGAE, MaskableRolloutBuffer):
    pass


class SemiMarkovMaskableDictRolloutBuffer(_PerStepDiscountGAE, MaskableDictRolloutBuffer):
    pass


def rollout_buffer_class(algorithm: str, dict_observation: bool):
    """The semi-Markov rollout buffer for ``algorithm`` (its ``rollout_buffer_class`` keyword)."""
    if algorithm not in SUPPORTED:
        raise ValueError(f"semi-Markov discounting is implemented for {list(SUPPORTED)}, not {algorithm}")
    if algorithm == "MaskablePPO":
        return SemiMarkovMaskableDictRolloutBuffer if dict_observation else SemiMarkovMaskableRolloutBuffer
    else:
        cls = SemiMarkovDictRolloutBuffer if dict_observation else SemiMarkovRolloutBuffer
    return cls


class SemiMarkovDiscounts(BaseCallback):
    """Fills an on-policy rollout buffer's per-step discounts from the steps' durations.

    It runs right after each ``env.step`` and before SB3 stores the step. SB3 then bootstraps
    a truncated episode's reward with ``gamma * V(terminal observation)``; this callback adds
    ``(discount - gamma) * V`` to that reward first, so the bootstrap is discounted by the
    step's duration too.
    """

    def __init__(self, unit: int):
        super().__init__()
        self.unit = unit

    def _on_step(self) -> bool:
        infos, dones, rewards = self.locals["infos"], self.locals["dones"], self.locals["rewards"]
        buffer, policy, gamma = self.model.rollout_buffer, self.model.policy, self.model.gamma
        discounts = step_discounts(gamma, self.unit, infos)
        buffer.discounts[buffer.pos] = discounts
        for idx, done in enumerate(dones):
            info = infos[idx]
            if done and info.get("terminal_observation") is not None and info.get("TimeLimit.truncated", False):
                terminal_obs = policy.obs_to_tensor(info["terminal_observation"])[0]
                with th.no_grad():
                    value = float(policy.predict_values(terminal_obs)[0].item())
                rewards[idx] += (float(discounts[idx]) - gamma) * value
        return True
