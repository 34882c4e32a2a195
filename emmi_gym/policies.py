"""Scripted policies for the waypoint environments; they use the env's public API only
(``action_masks()``, ``targets``, ``estimated_pose``, ``world``).

- ``frontier``: the nearest frontier (slot 0), else the first valid slot;
- ``random``: a uniformly random valid slot;
- ``close_loop_first`` (the paper's A): from the decision point back to the start
  (closing the loop), then into the unexplored area, then nearest frontiers;
- ``explore_first`` (the paper's B): into the unexplored area first, then back to
  the start, then nearest frontiers.
"""

from __future__ import annotations

import numpy as np

#: A goal counts as reached when the estimated pose is this close (m).
GOAL_RADIUS = 2.0


def _core(env):
    return getattr(env, "unwrapped", env)


class FrontierPolicy:
    """Go to the nearest frontier (slot 0 holds it); with none, the first valid slot."""

    name = "frontier"

    def reset(self, seed: int | None = None) -> None:
        pass

    def __call__(self, env) -> int:
        return int(np.flatnonzero(_core(env).action_masks())[0])


class RandomPolicy:
    """A uniformly random valid slot, from its own seeded generator."""

    name = "random"

    def __init__(self):
        self.rng = np.random.default_rng(0)

    def reset(self, seed: int | None = None) -> None:
        self.rng = np.random.default_rng(seed)

    def __call__(self, env) -> int:
        return int(self.rng.choice(np.flatnonzero(_core(env).action_masks())))


class GoalSequencePolicy:
    """Visit named places of the world in order (each by the valid target nearest to it), then explore.

    ``phase`` counts the goals reached (judged on the estimated pose, within
    ``GOAL_RADIUS``); :meth:`advance` brings it up to date after a step.
    """

    def __init__(self, name: str, goals: tuple[str, ...]):
        self.name, self.goals = name, goals
        self.phase = 0

    def reset(self, seed: int | None = None) -> None:
        self.phase = 0

    @property
    def done(self) -> bool:
        """Whether every goal has been reached."""
        return self.phase >= len(self.goals)

    def advance(self, env) -> int:
        """Count the goals the robot now stands at (in order) and return the phase."""
        core = _core(env)
        pose = core.estimated_pose
        while not self.done:
            goal = core.world.place(self.goals[self.phase])
            if np.hypot(pose[0] - goal.x, pose[1] - goal.y) > GOAL_RADIUS:
                break
            self.phase += 1
        return self.phase

    def __call__(self, env) -> int:
        core = _core(env)
        self.advance(core)
        mask = core.action_masks()
        if self.done:
            return int(np.flatnonzero(mask)[0])
        goal = core.world.place(self.goals[self.phase])
        targets = core.targets
        valid = [k for k in np.flatnonzero(mask) if targets[k] is not None]
        if not valid:
            return int(np.flatnonzero(mask)[0])
        return int(min(valid, key=lambda k: np.hypot(targets[k].x - goal.x, targets[k].y - goal.y)))


def make_policy(name: str):
    """A fresh policy by name: frontier, random, close_loop_first, explore_first."""
    policies = {
        "frontier": FrontierPolicy,
        "random": RandomPolicy,
        "close_loop_first": lambda: GoalSequencePolicy("close_loop_first", ("target_a", "target_b")),
        "explore_first": lambda: GoalSequencePolicy("explore_first", ("target_b", "target_a")),
    }
    if name not in policies:
        raise ValueError(f"unknown policy {name!r}; choose one of {sorted(policies)}")
    return policies[name]()
