"""Scripted policies for the waypoint environments; they use the env's public API only
(``action_masks()``, ``targets``, ``loop_spreads``, ``geometry``, ``estimated_pose``, ``world``, ``truth``).

- ``frontier``: the nearest frontier (slot 0), else the first valid slot;
- ``random``: a uniformly random valid slot;
- ``close_loop_first`` (the paper's A): from the decision point back to the start
  (closing the loop), then into the unexplored area, then nearest frontiers;
- ``explore_first`` (the paper's B): into the unexplored area first, then back to
  the start, then nearest frontiers;
- ``active_loop_closing``: for any world, go back to close a loop when the particles
  disagree about it, else the nearest frontier (Stachniss, Hähnel and Burgard,
  "Exploration with active loop-closing for FastSLAM", IROS 2004).
"""

from __future__ import annotations

import numpy as np

#: A goal counts as reached when the estimated pose is this close (m, along the free space),
#: or within the laser's range when no candidate target leads nearer (see ``advance``).
GOAL_RADIUS = 2.0
#: How far (m) round a target the true free space is searched for its distance to a goal
#: (the map drifts from the truth by decimetres).
TARGET_SNAP = 0.5


def _unwrapped(env):
    """The emmi_gym env under ``env``'s wrappers (``env`` itself when it has none)."""
    return getattr(env, "unwrapped", env)


class FrontierPolicy:
    """Go to the nearest frontier (slot 0 holds it); with none, the first valid slot."""

    name = "frontier"

    def reset(self, seed: int | None = None) -> None:
        pass

    def __call__(self, env) -> int:
        return int(np.flatnonzero(_unwrapped(env).action_masks())[0])


class RandomPolicy:
    """A uniformly random valid slot, from its own seeded generator."""

    name = "random"

    def __init__(self):
        self.rng = np.random.default_rng(0)

    def reset(self, seed: int | None = None) -> None:
        self.rng = np.random.default_rng(seed)

    def __call__(self, env) -> int:
        return int(self.rng.choice(np.flatnonzero(_unwrapped(env).action_masks())))


class ActiveLoopClosingPolicy:
    """Close a loop while the particles disagree about it, else explore (Stachniss et al. 2004).

    Stachniss, Hähnel and Burgard detect a loop-closing opportunity where the map offers a
    short way back to a place that the robot's own path reaches only by a long detour,
    and go back there while the filter's uncertainty is high, since re-observing a known
    place is what lets the particle set resolve the loop. Here the environment's revisit
    targets are those opportunities, and each one's *loop spread*
    (:func:`~emmi_gym.certainty.loop_displacement_spread`: how much the particles disagree
    about the robot's position relative to that place) is the uncertainty that closing it
    can resolve. Above ``threshold_cells`` cells (default 1.5: beyond that the particles'
    maps of the place differ by more than a cell) the policy takes the revisit target of
    highest spread; otherwise, as after a loop closed, the nearest frontier. As in their
    scheme, loop closing interrupts exploration and does not replace it: after going back
    once the robot explores (one frontier) before it may go back again, and a place it went
    back to is not chosen again within ``REVISIT_SPACING`` metres, so a loop that does not
    close does not hold the robot.
    """

    name = "active_loop_closing"
    #: Metres round a revisited target in which no other revisit is chosen again.
    REVISIT_SPACING = 3.0

    def __init__(self, threshold_cells: float = 1.5):
        self.threshold_cells = threshold_cells
        self.revisited: list[tuple[float, float]] = []
        self.went_back = False  # the last decision went back to close a loop

    def reset(self, seed: int | None = None) -> None:
        self.revisited = []
        self.went_back = False

    def __call__(self, env) -> int:
        core = _unwrapped(env)
        mask, targets, spreads = core.action_masks(), core.targets, core.loop_spreads
        threshold = self.threshold_cells * core.geometry.resolution
        loops = [k for k in np.flatnonzero(mask) if targets[k] is not None and targets[k].kind == "revisit"
                 and spreads[k] > threshold and self._new(targets[k].xy)]
        frontiers = [k for k in np.flatnonzero(mask) if targets[k] is not None and targets[k].kind == "frontier"]
        if loops and not (self.went_back and frontiers):
            k = max(loops, key=lambda k: spreads[k])
            self.revisited.append(targets[k].xy)
            self.went_back = True
            return int(k)
        self.went_back = False
        return int(frontiers[0] if frontiers else np.flatnonzero(mask)[0])

    def _new(self, xy) -> bool:
        return all(np.hypot(xy[0] - x, xy[1] - y) > self.REVISIT_SPACING for x, y in self.revisited)


def distances_to(truth, place) -> np.ndarray:
    """Length (m) of the shortest path through the true free space from every cell to ``place``
    (inf in walls and outside), by scikit-image's cost-distance on the ground-truth grid."""
    from skimage.graph import MCP_Geometric

    from ...world.ground_truth import FREE

    geometry = truth.geometry
    costs = np.where(truth.grid == FREE, 1.0, np.inf)
    row, col = geometry.cell_of(place.x, place.y)
    if not (geometry.inside(row, col) and np.isfinite(costs[row, col])):
        raise ValueError(f"place ({place.x}, {place.y}) is not in the world's reachable free space")
    distances, _ = MCP_Geometric(costs).find_costs([(int(row), int(col))])
    return distances * geometry.resolution


class GoalSequencePolicy:
    """Visit named places of the world in order, then explore (nearest frontier).

    Towards a goal it takes the candidate target from which the goal is nearest along
    the true free space (within ``TARGET_SNAP`` metres of the target): a scripted
    experiment knows the building, as the paper's operator did when choosing path A or
    B, so a frontier behind a wall does not lure it the wrong way. The robot still gets
    to each target with the env's planning on its own map and estimated pose. ``phase``
    counts the goals reached (judged on the estimated pose, see :meth:`advance`), which
    brings it up to date after a step.
    """

    def __init__(self, name: str, goals: tuple[str, ...]):
        self.name, self.goals = name, goals
        self.phase = 0
        self._fields: dict[tuple, np.ndarray] = {}

    def reset(self, seed: int | None = None) -> None:
        self.phase = 0

    def _distance_field(self, core, goal_name: str) -> np.ndarray:
        key = (core.world.name, goal_name, core.truth.grid.shape)
        if key not in self._fields:
            self._fields[key] = distances_to(core.truth, core.world.place(goal_name))
        return self._fields[key]

    def _distance_from(self, core, field: np.ndarray, point) -> float:
        """Distance to the goal of ``field`` from a target or pose (its nearest free cell within TARGET_SNAP)."""
        geometry = core.geometry
        row, col = geometry.cell_of(point[0], point[1])
        snap = int(round(TARGET_SNAP / geometry.resolution))
        window = field[max(int(row) - snap, 0):int(row) + snap + 1, max(int(col) - snap, 0):int(col) + snap + 1]
        return float(window.min()) if window.size else float("inf")

    @property
    def done(self) -> bool:
        """Whether every goal has been reached."""
        return self.phase >= len(self.goals)

    def advance(self, env) -> int:
        """Count the goals reached (in order) and return the phase.

        A goal is reached when the estimated pose is within ``GOAL_RADIUS`` of it along the
        free space, or within the laser's range when no candidate target would bring it
        nearer: a goal in an area already seen, such as a dead end, gets no target of its
        own, and no action can take the robot nearer. (With a fixed 4 m the robot could stand
        4.6 m from a dead end it had seen, its estimate 0.8 m behind the truth, and wander
        off for good: the 10-particle demo's seed 0 under A.)
        """
        core = _unwrapped(env)
        pose = core.estimated_pose
        while not self.done:
            field = self._distance_field(core, self.goals[self.phase])
            here = self._distance_from(core, field, pose)
            targets = [t for t, ok in zip(core.targets, core.action_masks(), strict=False) if ok and t is not None]
            nearer = any(self._distance_from(core, field, t.xy) < here for t in targets)
            if not (here <= GOAL_RADIUS or (here <= core.laser_config.max_range and not nearer)):
                break
            self.phase += 1
        return self.phase

    def __call__(self, env) -> int:
        core = _unwrapped(env)
        self.advance(core)
        mask = core.action_masks()
        if self.done:
            return int(np.flatnonzero(mask)[0])
        field = self._distance_field(core, self.goals[self.phase])
        targets = core.targets
        valid = [k for k in np.flatnonzero(mask) if targets[k] is not None]
        if not valid:
            return int(np.flatnonzero(mask)[0])
        return int(min(valid, key=lambda k: (self._distance_from(core, field, targets[k].xy), targets[k].travel_cost)))


#: How each scripted policy is built, by name.
_FACTORIES = {
    "frontier": FrontierPolicy,
    "active_loop_closing": ActiveLoopClosingPolicy,
    "random": RandomPolicy,
    "close_loop_first": lambda: GoalSequencePolicy("close_loop_first", ("target_a", "target_b")),
    "explore_first": lambda: GoalSequencePolicy("explore_first", ("target_b", "target_a")),
}
#: The names :func:`make_policy` takes.
POLICY_NAMES = tuple(_FACTORIES)


def make_policy(name: str):
    """A fresh policy by name: frontier, active_loop_closing, random, close_loop_first, explore_first."""
    if name not in _FACTORIES:
        raise ValueError(f"unknown policy {name!r}; choose one of {sorted(_FACTORIES)}")
    return _FACTORIES[name]()
