"""The action and observation types of the environment: their spaces, the factories, how they act."""

import inspect
from types import SimpleNamespace

import gymnasium as gym
import numpy as np
import pytest
from gymnasium import spaces

import emmi_gym
from emmi_gym.env import emmi_env
from emmi_gym.env.actions import (
    ACTION_TYPES,
    DISCRETE_VELOCITIES,
    STAY_STEPS,
    VELOCITY_TYPES,
    ActionType,
    ContinuousVelocityAction,
    DiscreteVelocityAction,
    WaypointAction,
    action_factory,
)
from emmi_gym.env.config import ACTION_MODES, OBSERVATIONS, VELOCITY_ACTIONS
from emmi_gym.env.observation import (
    OBSERVATION_TYPES,
    TARGET_FEATURES,
    DictObservation,
    ImageObservation,
    observation_factory,
)
from emmi_gym.inputs.validation import OptionError

gym.register_envs(emmi_gym)
SMALL = {"particles": 5, "start_at": "start"}


def make(**options):
    return gym.make("emmi_gym/LoopCorridor-v1", **SMALL, **options).unwrapped


# ------------------------------------------------------------------ spaces


def test_waypoint_action_space_is_one_slot_per_target():
    env = make(n_frontiers=3, n_revisits=1)
    assert isinstance(env.action_type, WaypointAction)
    assert env.action_type.space() == spaces.Discrete(4) == env.action_space
    assert env.action_type.n_slots == 4


def test_continuous_velocity_action_space_and_scaling():
    env = make(action_mode="velocity")
    actions = env.action_type
    assert isinstance(actions, ContinuousVelocityAction)
    assert actions.space() == spaces.Box(-1.0, 1.0, (2,), dtype=np.float32) == env.action_space
    robot = env.robot_config
    assert (actions.command(np.array([0.5, -0.25], dtype=np.float32))
            == (0.5 * robot.max_speed, -0.25 * robot.max_turn_rate))
    assert actions.command([3.0, -2.0]) == (robot.max_speed, -robot.max_turn_rate)  # clipped to [-1, 1]
    assert actions.n_slots == 0 and actions.targets == [] and actions.loop_spreads == []


def test_discrete_velocity_action_space_and_commands():
    env = make(action_mode="velocity", velocity_actions="discrete")
    actions = env.action_type
    assert isinstance(actions, DiscreteVelocityAction)
    assert actions.space() == spaces.Discrete(5) == env.action_space
    robot = env.robot_config
    commands = [actions.command(k) for k in range(5)]
    assert commands == [(fv * robot.max_speed, fw * robot.max_turn_rate) for fv, fw in DISCRETE_VELOCITIES]
    stop, forward, left, right, back = commands
    assert stop == (0.0, 0.0) and forward[0] > 0 and left[1] > 0 > right[1] and back[0] < 0


@pytest.mark.parametrize("action_mode, n_slots", [("waypoint", 8), ("velocity", 0)])
def test_dict_observation_space_has_targets_only_with_target_slots(action_mode, n_slots):
    env = make(action_mode=action_mode, obs_size=36)
    assert isinstance(env.observation_type, DictObservation)
    space = env.observation_type.space()
    assert space == env.observation_space
    keys = {"map", "pose", "certainty"} | ({"targets"} if n_slots else set())
    assert set(space.spaces) == keys
    assert space["map"] == spaces.Box(0, 255, (2, 36, 36), dtype=np.uint8)
    assert space["pose"] == spaces.Box(-1.0, 1.0, (4,), dtype=np.float32)
    assert space["certainty"] == spaces.Box(-1.0, 1.0, (2,), dtype=np.float32)
    if n_slots:
        assert space["targets"] == spaces.Box(-1.0, 1.0, (n_slots, len(TARGET_FEATURES)), dtype=np.float32)


@pytest.mark.parametrize("action_mode", ["waypoint", "velocity"])
def test_image_observation_space_is_the_map_alone(action_mode):
    env = make(action_mode=action_mode, observation="image", obs_size=48)
    assert type(env.observation_type) is ImageObservation
    assert env.observation_type.space() == spaces.Box(0, 255, (2, 48, 48), dtype=np.uint8) == env.observation_space


# ------------------------------------------------------------------ factories


@pytest.mark.parametrize("action_mode, velocity_actions, kind", [
    ("waypoint", "continuous", WaypointAction),
    ("waypoint", "discrete", WaypointAction),
    ("velocity", "continuous", ContinuousVelocityAction),
    ("velocity", "discrete", DiscreteVelocityAction),
])
def test_action_factory_picks_the_type_by_name(action_mode, velocity_actions, kind):
    env = make(action_mode=action_mode, velocity_actions=velocity_actions)
    chosen = action_factory(env, SimpleNamespace(action_mode=action_mode, velocity_actions=velocity_actions))
    assert type(chosen) is kind and chosen.env is env and isinstance(chosen, ActionType)


@pytest.mark.parametrize("name, kind", [("dict", DictObservation), ("image", ImageObservation)])
def test_observation_factory_picks_the_type_by_name(name, kind):
    env = make()
    assert type(observation_factory(env, SimpleNamespace(observation=name))) is kind


@pytest.mark.parametrize("config, message", [
    (SimpleNamespace(action_mode="teleport", velocity_actions="continuous"),
     r"gym.make: field 'action_mode': expected one of \['waypoint', 'velocity'\], got 'teleport'"),
    (SimpleNamespace(action_mode="velocity", velocity_actions="joystick"),
     r"gym.make: field 'velocity_actions': expected one of \['continuous', 'discrete'\], got 'joystick'"),
    (SimpleNamespace(action_mode=["waypoint"], velocity_actions="continuous"),
     r"field 'action_mode': expected one of \['waypoint', 'velocity'\], got \['waypoint'\]"),
])
def test_action_factory_names_the_option_and_its_values_for_an_unknown_name(config, message):
    with pytest.raises(OptionError, match=message):
        action_factory(None, config)


def test_observation_factory_names_the_option_and_its_values_for_an_unknown_name():
    with pytest.raises(OptionError, match=r"gym.make: field 'observation': expected one of \['dict', 'image'\], "
                                          r"got 'video'"):
        observation_factory(None, SimpleNamespace(observation="video"))


def test_the_factories_know_exactly_the_values_the_options_take():
    assert tuple(ACTION_TYPES) == ACTION_MODES
    assert tuple(VELOCITY_TYPES) == VELOCITY_ACTIONS
    assert tuple(OBSERVATION_TYPES) == OBSERVATIONS


def test_the_env_does_not_branch_on_the_action_or_observation_modes():
    source = inspect.getsource(emmi_env)
    for name in (".action_mode", ".velocity_actions", ".observation ==", ".observation !="):
        assert name not in source


# ------------------------------------------------------------------ acting


def test_velocity_actions_take_one_step_and_mask_nothing():
    for velocity_actions, action in (("continuous", np.array([1.0, 0.0], dtype=np.float32)), ("discrete", 1)):
        env = make(action_mode="velocity", velocity_actions=velocity_actions)
        env.reset(seed=0)
        masks = env.action_masks()
        assert masks.dtype == bool and masks.all() and masks.size == getattr(env.action_space, "n", 1)
        for _ in range(3):
            _, _, _, truncated, info = env.step(action)
            assert info["sim_steps_this_step"] == 1 and "target_kind" not in info and not truncated
        assert env.decisions == 0 and env.targets == [] and env.loop_spreads == []


def test_waypoint_actions_count_decisions_and_truncate_at_max_decisions():
    env = make(max_decisions=2)
    env.reset(seed=0)
    assert env.decisions == 0 and env.targets == env.action_type.targets
    masks = env.action_masks()
    assert masks.tolist() == [t is not None for t in env.targets]
    assert len(env.loop_spreads) == env.config.n_actions
    truncations = []
    for _ in range(2):
        _, _, terminated, truncated, info = env.step(int(np.flatnonzero(env.action_masks())[0]))
        assert info["target_kind"] in ("frontier", "revisit") and not terminated
        truncations.append(truncated)
    assert truncations == [False, True] and env.decisions == 2
    env.reset(seed=0)
    assert env.decisions == 0 and env.action_type.blocked == []


def test_an_empty_waypoint_slot_stands_still_and_an_action_out_of_range_is_refused():
    env = make()
    env.reset(seed=0)
    env.action_type.slots = [next(t for t in env.targets if t is not None)] + [None] * (env.config.n_actions - 1)
    steps = env.sim_steps
    _, _, _, _, info = env.step(1)
    assert info["target_kind"] == "none" and env.sim_steps == steps + STAY_STEPS and env.decisions == 1
    with pytest.raises(ValueError, match=r"action 8 is outside Discrete\(8\)"):
        env.step(8)
    assert env.decisions == 1


def _revisits_offered(decisions=4, **options):
    """How many revisit targets each decision offered, taking a revisit whenever one is offered."""
    env = gym.make("emmi_gym/LoopCorridor-v1", particles=5, max_decisions=decisions, **options).unwrapped
    env.reset(seed=0)
    offered = []
    for _ in range(decisions):
        revisits = [k for k in np.flatnonzero(env.action_masks()) if env.targets[k].kind == "revisit"]
        offered.append(len(revisits))
        for k in revisits:
            assert env.loop_spreads[k] > env.config.min_loop_spread
        env.step(revisits[0] if revisits else int(np.flatnonzero(env.action_masks())[0]))
    return offered, env.action_type.revisited


def test_revisit_options_leave_out_loops_already_closed_or_gone_back_to():
    offered, revisited = _revisits_offered()  # by default every revisit target is offered, again and again
    assert all(n > 0 for n in offered) and len(revisited) == len(offered)
    offered, revisited = _revisits_offered(revisit_spacing=100.0)  # one place gone back to rules out the rest
    assert offered[0] > 0 and offered[1:] == [0] * (len(offered) - 1) and len(revisited) == 1
    offered, revisited = _revisits_offered(min_loop_spread=100.0)  # no loop is that open
    assert offered == [0] * len(offered) and revisited == []
