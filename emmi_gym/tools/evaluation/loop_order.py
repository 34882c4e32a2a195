"""The loop-closure order of an episode (the paper's A or B), reported in its last step's ``info``."""

from __future__ import annotations

import math

import gymnasium as gym
import numpy as np
from scipy import ndimage

from ...certainty import observed_cells
from ...world.ground_truth import FREE, UNKNOWN

#: The ``info`` key of the last step of an episode that started at a loop's decision point.
LOOP_ORDER_KEY = "closed_loop_first"
#: The world's place that lies in the unexplored area B enters.
NEW_AREA_PLACE = "target_b"


def new_area_mask(observed_at_decision: np.ndarray, truth_grid: np.ndarray, geometry, place,
                  margin: float = 0.3) -> np.ndarray:
    """The cells of the unexplored area round ``place``: the true free space that was still unknown
    at the decision point and is connected to ``place``'s cell, grown by ``margin`` metres so that
    its walls count, restricted to cells still unknown then that the ground truth labels."""
    unknown_then = ~observed_at_decision
    labels, _ = ndimage.label(unknown_then & (truth_grid == FREE))
    row, col = geometry.cell_of(place.x, place.y)
    if not geometry.inside(row, col) or labels[row, col] == 0:
        raise ValueError(f"the place {NEW_AREA_PLACE!r} at ({place.x}, {place.y}) was already mapped at the "
                         "decision point or lies off the grid: it does not mark an unexplored area")
    region = labels == labels[row, col]
    grown = ndimage.binary_dilation(region, iterations=max(1, int(round(margin / geometry.resolution))))
    return grown & unknown_then & (truth_grid != UNKNOWN)


def new_area_now(core) -> np.ndarray:
    """:func:`new_area_mask` for an environment (unwrapped) as it is now, e.g. at the decision point."""
    return new_area_mask(observed_cells(core.expected_map), core.truth.grid, core.geometry,
                         core.world.place(NEW_AREA_PLACE))


def closed_loop_first(true_xy: np.ndarray, world, geometry, new_area: np.ndarray) -> bool | None:
    """Whether a true path came back to the loop's start (``target_a``, within the policies'
    ``GOAL_RADIUS``) before it entered ``new_area``; None if it did neither."""
    from ..policies import GOAL_RADIUS

    goal = world.place("target_a")
    back = np.flatnonzero(np.hypot(true_xy[:, 0] - goal.x, true_xy[:, 1] - goal.y) <= GOAL_RADIUS)
    rows, cols = geometry.cell_of(true_xy[:, 0], true_xy[:, 1])
    inside = geometry.inside(rows, cols)
    entered = np.flatnonzero(inside)[new_area[rows[inside], cols[inside]]]
    if back.size == 0 and entered.size == 0:
        return None
    return bool(back.size and (entered.size == 0 or back[0] < entered[0]))


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
