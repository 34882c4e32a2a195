"""Action types: what an action of :class:`~emmi_gym.env.EmmiEnv` is and how the environment carries it out.

Each type gives the action space (:meth:`ActionType.space`), carries out one action
(:meth:`ActionType.act`) and says which actions are valid now (:meth:`ActionType.action_masks`).
:func:`action_factory` picks the type from the options ``action_mode`` and, in velocity mode,
``velocity_actions``:

========================  ====================  ===================================
``action_mode``           ``velocity_actions``  type
========================  ====================  ===================================
``"waypoint"``            (not read)            :class:`WaypointAction`
``"velocity"``            ``"continuous"``      :class:`ContinuousVelocityAction`
``"velocity"``            ``"discrete"``        :class:`DiscreteVelocityAction`
========================  ====================  ===================================

A type reads the environment's public state (``env.config``, ``env.geometry``, ``env.slam``,
``env.expected_map``) and drives the episode's robot, ``env.episode`` (a
:class:`~emmi_gym.env.episode.RobotEpisode`: one simulator step at a time, the filter fed as it
goes), as HighwayEnv's action types drive the env's vehicle; the environment owns the loop round it.
"""

from __future__ import annotations

import gymnasium as gym
import numpy as np
from gymnasium import spaces

from .. import certainty
from ..inputs.validation import OptionError
from ..navigation.candidates import Target
from ..navigation.executor import Limits, MacroActionExecutor
from .config import SOURCE

#: Discrete velocity actions: (v, omega) as fractions of the robot's limits.
DISCRETE_VELOCITIES = ((0.0, 0.0), (1.0, 0.0), (0.3, 1.0), (0.3, -1.0), (-0.5, 0.0))
#: Simulator steps (15 s) an invalid (masked) waypoint action stands still for: doing nothing
#: through the default 60 decisions costs 9000 steps of time, about what it costs in velocity mode.
STAY_STEPS = 150


class ActionType:
    """What an action is (:meth:`space`) and how the environment carries it out (:meth:`act`).

    The environment calls :meth:`set_world` when it loads a world, :meth:`reset` at every reset,
    :meth:`refresh` whenever the filter updated (after the expected map and its measures were
    recomputed) or :meth:`wants_refresh` says so, :meth:`act` once per step and :meth:`truncated`
    after it. ``env`` is the :class:`~emmi_gym.env.EmmiEnv` the type belongs to.
    """

    #: Action slots that hold candidate targets (the rows of the observation's ``targets``); 0: none.
    n_slots = 0

    def __init__(self, env: gym.Env):
        self.env = env
        self.decisions = 0

    def space(self) -> spaces.Space:
        """The action space."""
        raise NotImplementedError

    def act(self, action) -> dict:
        """Carry out ``action`` (one or more simulator steps); what to add to the step's ``info``."""
        raise NotImplementedError

    def action_masks(self) -> np.ndarray:
        """Which actions are valid now, for sb3-contrib's MaskablePPO: all of them (one entry for a Box)."""
        return np.ones(getattr(self.env.action_space, "n", 1), dtype=bool)

    def set_world(self) -> None:
        """The environment loaded a world (a new grid, ``env.geometry``)."""

    def reset(self) -> None:
        """A new episode begins."""
        self.decisions = 0

    def refresh(self) -> None:
        """The filter updated: recompute what depends on the expected map."""

    def wants_refresh(self) -> bool:
        """Whether :meth:`refresh` must run after this step although the filter did not update (the type's
        own state changed what it offers)."""
        return False

    def truncated(self) -> bool:
        """Whether the episode ends for this type's own budget (the simulator's time is the environment's)."""
        return False

    @property
    def targets(self) -> list[Target | None]:
        """The candidate target of each action slot (None: empty); no slots unless the type has them."""
        return []

    @property
    def loop_spreads(self) -> list[float]:
        """The loop spread (m) of each action slot's revisit target; 0 for frontiers and empty slots."""
        return []


class WaypointAction(ActionType):
    """``Discrete(n_frontiers + n_revisits)``: go to the candidate target of a slot (a macro-action).

    The first ``n_frontiers`` slots hold frontier targets, the others revisit (loop-closing)
    targets, recomputed whenever the filter updates (:meth:`refresh`). An action plans a path
    on the expected map and follows it with the estimated pose
    (:class:`~emmi_gym.navigation.executor.MacroActionExecutor`) until the robot arrives, is
    blocked, or ``macro_timeout`` simulator steps pass. A target whose attempt ended blocked, or
    that the robot could not set off for, is not offered again this episode; nor, with the options
    ``min_loop_spread`` and ``revisit_spacing``, is a revisit target whose loop the particles
    already agree on or that lies near a place the robot already went back to.

    An empty slot (masked by :meth:`action_masks`) makes the robot stand still for
    :data:`STAY_STEPS` simulator steps (15 s), which costs time; so does a target it cannot set
    off for. With no target left at all (the masks keep slot 0 valid then) it turns in place
    for those 15 s instead, as move_base's rotate recovery. Every action is a decision; the
    episode is truncated after ``max_decisions``. ``info["target_kind"]`` says what the slot
    held: ``"frontier"``, ``"revisit"`` or ``"none"``.
    """

    def __init__(self, env: gym.Env):
        super().__init__(env)
        self.n_slots = env.config.n_actions
        self.navigation: MacroActionExecutor | None = None
        self.slots: list[Target | None] = []
        self.spreads: list[float] = []
        self.blocked: list[tuple[float, float]] = []  # where attempts ended blocked this episode
        self.revisited: list[tuple[float, float]] = []  # the revisit targets gone to this episode
        self._gave_up_target = False  # since the last refresh: the slots must be recomputed without it

    def space(self) -> spaces.Discrete:
        return spaces.Discrete(self.n_slots)

    def set_world(self) -> None:
        env = self.env
        robot, laser = env.robot_config, env.laser_config
        limits = Limits(robot.radius, robot.max_speed, robot.max_turn_rate, laser.angles, laser.max_range)
        self.navigation = MacroActionExecutor(env.geometry, limits, env.config.macro_timeout)

    def reset(self) -> None:
        super().reset()
        self.blocked = []
        self.revisited = []

    def refresh(self) -> None:
        env, cfg = self.env, self.env.config
        slam = env.slam
        spreads: dict[int, float] = {}

        def spread(target: Target) -> float:
            if target.path_index not in spreads:
                spreads[target.path_index] = certainty.loop_displacement_spread(
                    slam.paths, slam.log_weights, target.path_index, log_weights=True)
            return spreads[target.path_index]

        def worth_closing(target: Target) -> bool:
            return spread(target) > cfg.min_loop_spread and all(
                np.hypot(target.x - x, target.y - y) > cfg.revisit_spacing for x, y in self.revisited)

        keep = worth_closing if cfg.min_loop_spread > 0 or cfg.revisit_spacing > 0 else None
        self.slots = self.navigation.targets(env.episode, env.expected_map, slam.paths[slam.best],
                                             cfg.n_frontiers, cfg.n_revisits, self.blocked, keep)
        self.spreads = [spread(t) if t is not None and t.kind == "revisit" else 0.0 for t in self.slots]
        self._gave_up_target = False

    def wants_refresh(self) -> bool:
        """After a target was given up: the slots are recomputed without it."""
        return self._gave_up_target

    def act(self, action) -> dict:
        target_kind = self._go_to_slot(int(action))
        self.decisions += 1
        return {"target_kind": target_kind}

    def _go_to_slot(self, action: int) -> str:
        """Drive the episode's robot to the target of slot ``action``; the kind of target it was ("frontier",
        "revisit", or "none" for an empty slot)."""
        if not 0 <= action < self.n_slots:
            raise ValueError(f"action {action} is outside Discrete({self.n_slots})")
        robot = self.env.episode
        target: Target | None = self.slots[action]
        if target is not None and target.kind == "revisit":
            self.revisited.append(target.xy)
        outcome = self.navigation.follow(robot, target) if target is not None else "stayed"
        if outcome == "blocked" or (outcome == "stayed" and target is not None):  # never offer it again
            self.blocked.append((target.x, target.y))
            self._gave_up_target = True
        if outcome == "stayed":  # an empty slot, or a target the robot cannot leave for
            omega = self._recovery_turn_rate()
            for _ in range(STAY_STEPS):
                robot.step(0.0, omega)
        return "none" if target is None else target.kind

    def _recovery_turn_rate(self) -> float:
        """How fast the robot turns while it stays: in place at full rate when no slot holds a target
        (move_base's rotate recovery: the scans of the turns update the filter, which can clear a wall
        the particles dispute that shut the robot in; standing still never updates it), else not at
        all. So an agent that picks an empty slot while targets are left gains nothing by it (a turn
        in place re-scans the same cells, which raises EMMI: docs/rewards.md)."""
        return self.env.robot_config.max_turn_rate if all(slot is None for slot in self.slots) else 0.0

    def action_masks(self) -> np.ndarray:
        """The non-empty target slots; never all False: with no target at all, slot 0 (turning in
        place) stays valid."""
        mask = np.array([slot is not None for slot in self.slots], dtype=bool)
        if not mask.any():
            mask[0] = True
        return mask

    def truncated(self) -> bool:
        return self.decisions >= self.env.config.max_decisions

    @property
    def targets(self) -> list[Target | None]:
        return list(self.slots)

    @property
    def loop_spreads(self) -> list[float]:
        return list(self.spreads)


class VelocityAction(ActionType):
    """A velocity command (v, omega) for one simulator step (0.1 s); the subclasses say how an action
    gives it, as fractions of the robot's top speed and turn rate (:meth:`fractions`)."""

    def fractions(self, action) -> tuple[float, float]:
        """(v, omega) of ``action`` as fractions of the robot's limits."""
        raise NotImplementedError

    def command(self, action) -> tuple[float, float]:
        """(v in m/s, omega in rad/s) of ``action``."""
        fv, fw = self.fractions(action)
        robot = self.env.robot_config
        return float(fv) * robot.max_speed, float(fw) * robot.max_turn_rate

    def act(self, action) -> dict:
        v, omega = self.command(action)
        self.env.episode.step(v, omega)
        return {}


class ContinuousVelocityAction(VelocityAction):
    """``Box(-1, 1, (2,), float32)``: (v, omega) as fractions of the robot's top speed and turn rate,
    clipped to [-1, 1], for one simulator step."""

    def space(self) -> spaces.Box:
        return spaces.Box(-1.0, 1.0, (2,), dtype=np.float32)

    def fractions(self, action) -> tuple[float, float]:
        fv, fw = np.clip(np.asarray(action, dtype=np.float64), -1.0, 1.0)
        return fv, fw


class DiscreteVelocityAction(VelocityAction):
    """``Discrete(5)``: one of five commands for one simulator step (:data:`DISCRETE_VELOCITIES`, as
    fractions of the robot's top speed and turn rate): 0 stop, 1 forward, 2 left (turning while
    creeping forward), 3 right, 4 back."""

    def space(self) -> spaces.Discrete:
        return spaces.Discrete(len(DISCRETE_VELOCITIES))

    def fractions(self, action) -> tuple[float, float]:
        return DISCRETE_VELOCITIES[int(action)]


#: The action types by ``velocity_actions``.
VELOCITY_TYPES: dict[str, type[VelocityAction]] = {
    "continuous": ContinuousVelocityAction,
    "discrete": DiscreteVelocityAction,
}
#: The action types by ``action_mode``; in velocity mode ``velocity_actions`` picks from :data:`VELOCITY_TYPES`.
ACTION_TYPES: dict[str, type[ActionType] | dict[str, type[VelocityAction]]] = {
    "waypoint": WaypointAction,
    "velocity": VELOCITY_TYPES,
}


def by_name(table: dict, option: str, name):
    """``table[name]``; an unknown name raises an :class:`~emmi_gym.inputs.validation.OptionError` naming
    the option and the names it takes."""
    try:
        return table[name]
    except (KeyError, TypeError):  # TypeError: an unhashable value
        raise OptionError(SOURCE, option, f"one of {list(table)}", name) from None


def action_factory(env: gym.Env, config) -> ActionType:
    """The action type the options ``action_mode`` (and ``velocity_actions``) of ``config`` name, for ``env``."""
    chosen = by_name(ACTION_TYPES, "action_mode", config.action_mode)
    if isinstance(chosen, dict):  # a family: the second option picks its member
        chosen = by_name(chosen, "velocity_actions", config.velocity_actions)
    return chosen(env)

