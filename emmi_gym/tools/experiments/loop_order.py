"""The loop-closure order of an episode (the paper's A or B), reported in its last step's ``info``."""

from __future__ import annotations

import math

import gymnasium as gym

from .ab import closed_loop_first, new_area_now

#: The ``info`` key of the last step of an episode that started at a loop's decision point.
LOOP_ORDER_KEY = "closed_loop_first"


def hosts_loop_experiment(core) -> bool:
    """Whether episodes of this env start at a decision point between closing a loop and a new area."""
    places = core.world.places
    return core.config.start_at == "decision" and {"target_a", "target_b"} <= set(places)


class LoopOrderInfo(gym.Wrapper):
    """Adds ``info["closed_loop_first"]`` to the last step of an episode that starts at a loop's
    decision point (``LoopCorridor-v1``): 1.0 if the true path came back to the loop's start
    before it entered the new area (the paper's A), 0.0 if it entered the new area first (B),
    NaN if it did neither. The new area is what the expected map had not observed at the reset,
    and only the path driven after the reset counts (the reset's drive to the decision point
    began at the start). Other envs pass through unchanged.

    It goes in the last step's ``info`` so that SB3's ``EvalCallback`` can read it: a vectorised
    env has reset the episode by the time anything could look at the env itself.
    """

    def __init__(self, env: gym.Env):
        super().__init__(env)
        self._new_area = None
        self._first_pose = 0

    def reset(self, **kwargs):
        observation, info = self.env.reset(**kwargs)
        core = self.env.unwrapped
        self._new_area = new_area_now(core) if hosts_loop_experiment(core) else None
        self._first_pose = len(core.true_path)
        return observation, info

    def step(self, action):
        observation, reward, terminated, truncated, info = self.env.step(action)
        if self._new_area is not None and (terminated or truncated):
            core = self.env.unwrapped
            order = closed_loop_first(core.true_path[self._first_pose:, :2], core.world, core.geometry,
                                      self._new_area)
            info = dict(info, **{LOOP_ORDER_KEY: math.nan if order is None else float(order)})
        return observation, reward, terminated, truncated, info
