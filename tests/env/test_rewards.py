"""Rewards as parts: the Reward type and its registry, what a step measures for them, the privileged rewards, and
an observation that never carries the ground truth."""

import dataclasses
import warnings

import gymnasium as gym
import numpy as np
import pytest
from helpers import assert_same

import emmi_gym
from emmi_gym import certainty
from emmi_gym.env import REWARDS, Reward, emmi_env, register_reward
from emmi_gym.env.reward_registry import privileged_rewards, reward_named
from emmi_gym.env.rewards import SCORES, Change, StepRewards
from emmi_gym.inputs.validation import OptionError
from emmi_gym.tools.policies import FrontierPolicy
from emmi_gym.world import FREE, OCCUPIED

gym.register_envs(emmi_gym)
#: A small generated world of a few rooms, waypoint actions: a decision takes a fraction of a second.
TINY = dict(particles=3, max_decisions=4, coverage_target=1.0, generator={"nx": 2, "ny": 2, "n_loops": 1})
frontier_action = FrontierPolicy()


@pytest.fixture
def restore_rewards():
    """The reward registry as it was: a test that registers a reward leaves nothing behind."""
    before = dict(REWARDS)
    yield
    REWARDS.clear()
    REWARDS.update(before)


def best_information(before, after):
    return after["mean_information_best"] - before["mean_information_best"]


def test_the_built_ins_are_registered_with_what_they_read():
    assert list(REWARDS)[:6] == ["emmi", "pose_entropy", "joint_entropy", "coverage", "emmi_coverage",
                                 "map_information"]
    assert set(privileged_rewards()) == {"coverage", "emmi_coverage", "oracle_accuracy", "wall_consistency", "ate"}
    assert not any(REWARDS[name].privileged for name in ("emmi", "pose_entropy", "joint_entropy", "map_information",
                                                         "loop_spread"))
    assert REWARDS["ate"].value({"ate": 0.5}, {"ate": 0.2}) == pytest.approx(0.3)  # a fall of the ATE pays
    assert REWARDS["oracle_accuracy"].value({"oracle_accuracy": 0.5}, {"oracle_accuracy": 0.6}) == pytest.approx(0.1)
    assert reward_named("emmi") is REWARDS["emmi"]
    with pytest.raises(KeyError, match="no reward named 'nothing'; registered: .*'ate'"):
        reward_named("nothing")


@pytest.mark.parametrize(("fields", "message"), [
    (dict(name="time"), "field 'name': expected a name .* not one of the costs"),
    (dict(name="two words"), "field 'name'"),
    (dict(reads=("emmi", "true_pose")), r"field 'reads': expected a non-empty list of the measures"),
    (dict(reads=()), "field 'reads'"),
    (dict(scale=0.0), r"field 'scale': expected a number in \(0, 1e\+06\]"),
    (dict(scale=float("nan")), "field 'scale'"),
    (dict(value="emmi"), "field 'value': expected a function"),
])
def test_a_malformed_reward_is_refused_naming_the_field(fields, message):
    with pytest.raises(OptionError, match=message):
        Reward(**{**dict(name="mine", reads=("emmi",), scale=1.0, value=Change("emmi")), **fields})


def test_the_registry_refuses_a_second_reward_under_a_name_taken(restore_rewards):
    mine = Reward("best_information", ("mean_information_best",), 10.0, best_information)
    assert register_reward(mine) is mine and register_reward(mine) is mine  # the same reward twice: one
    other = dataclasses.replace(mine, scale=1.0)
    with pytest.raises(ValueError, match="registered already .* pass replace=True"):
        register_reward(other)
    assert register_reward(other, replace=True) is REWARDS["best_information"] is other
    with pytest.raises(ValueError, match="'emmi' is a built-in reward's name"):
        register_reward(Reward("emmi", ("emmi",), 1.0, Change("emmi")), replace=True)
    with pytest.raises(TypeError, match="takes a Reward"):
        register_reward("emmi")


def test_options_name_registered_rewards_or_give_them(restore_rewards):
    with pytest.raises(OptionError, match=r"field 'reward': expected a registered reward's name \(one of \['emmi'"):
        gym.make("emmi_gym/Explore-v1", reward="best_information")
    mine = register_reward(Reward("best_information", ("mean_information_best",), 10.0, best_information))
    assert gym.make("emmi_gym/Explore-v1", reward="best_information").unwrapped.reward is mine
    for bad in ("nothing", ["emmi", 3], [Reward("emmi", ("emmi",), 1.0, Change("emmi"))]):
        with pytest.raises(OptionError, match="field 'info_rewards'"):
            gym.make("emmi_gym/Explore-v1", info_rewards=bad)
    env = gym.make("emmi_gym/Explore-v1", info_rewards=["coverage", "emmi"]).unwrapped
    assert [r.name for r in env.info_rewards] == ["coverage", "emmi"]
    assert len(gym.make("emmi_gym/Explore-v1", info_rewards="all").unwrapped.info_rewards) == len(REWARDS)


def test_a_reward_object_is_paid_at_its_scale_with_the_costs_and_shown_in_info():
    mine = Reward("best_information", ("mean_information_best",), 10.0, best_information)
    env = gym.make("emmi_gym/Explore-v1", reward=mine, reward_scale=2.0, **TINY)
    _, info = env.reset(seed=4)
    assert info["reward_components"] == {"best_information": 0.0, "time": 0.0, "collision": 0.0}
    before = info["mean_information_best"]
    _, reward, _, _, info = env.step(frontier_action(env))
    components = info["reward_components"]
    assert set(components) == {"best_information", "time", "collision"} and info["privileged_rewards"] == []
    assert components["best_information"] == pytest.approx(10.0 * (info["mean_information_best"] - before))
    assert reward == pytest.approx(2.0 * (info["mean_information_best"] - before) + components["time"]
                                   + components["collision"])


def counting(monkeypatch, name: str) -> list:
    """Count the calls of the score ``name`` the env makes."""
    calls, original = [], getattr(emmi_env, name)
    monkeypatch.setattr(emmi_env, name, lambda *args, **kwargs: calls.append(1) or original(*args, **kwargs))
    return calls


def test_the_ground_truth_is_scored_only_where_a_reward_info_or_the_end_asks(monkeypatch):
    """By default the scores are measured once, for the last info of the episode; a privileged reward or
    info_scores="always" measures them after every filter update (and gives the same figures)."""
    calls = counting(monkeypatch, "absolute_trajectory_error")
    env = gym.make("emmi_gym/Explore-v1", **TINY)
    with pytest.raises(RuntimeError, match="call reset"):
        env.unwrapped.ground_truth_scores()
    _, info = env.reset(seed=4)
    assert not set(SCORES) & set(info) and not calls
    done, infos = False, []
    while not done:
        _, _, terminated, truncated, info = env.step(frontier_action(env))
        done = terminated or truncated
        infos.append(info)
    assert all(not set(SCORES) & set(info) for info in infos[:-1]) and set(SCORES) <= set(infos[-1])
    assert len(calls) == 1  # the episode's end
    calls.clear()
    ate_fall = Reward("ate_fall", ("ate",), 10.0, Change("ate", falling=True))
    for options in (dict(info_scores="always"), dict(reward=ate_fall), dict(info_rewards=[ate_fall])):
        again = gym.make("emmi_gym/Explore-v1", **TINY, **options)
        again.reset(seed=4)
        assert len(calls) == 1  # the reset's (the measures before the first step)
        for _ in infos:
            _, _, _, _, last = again.step(frontier_action(again))
        assert len(calls) == 1 + len(infos) and {k: last[k] for k in SCORES} == {k: infos[-1][k] for k in SCORES}
        calls.clear()


def test_the_privileged_rewards_pay_the_change_of_the_scores_and_say_so():
    env = gym.make("emmi_gym/Explore-v1", reward="oracle_accuracy", info_rewards=["wall_consistency", "ate", "emmi"],
                   info_scores="always", **TINY)
    _, before = env.reset(seed=4)
    for _ in range(3):
        _, reward, _, _, info = env.step(frontier_action(env))
        components = info["reward_components"]
        assert components["oracle_accuracy"] == pytest.approx(50.0 * (info["oracle_accuracy"] -
                                                                       before["oracle_accuracy"]))
        assert components["wall_consistency"] == pytest.approx(
            10.0 * (info["wall_consistency"] - before["wall_consistency"]))
        assert components["ate"] == pytest.approx(10.0 * (before["ate"] - info["ate"]))  # a fall pays
        assert reward == pytest.approx(components["oracle_accuracy"] + components["time"] + components["collision"])
        assert info["privileged_rewards"] == ["oracle_accuracy", "wall_consistency", "ate"]
        before = info


def scramble_the_ground_truth(env) -> None:
    """Give ``env`` another ground truth behind the same filter input: the floor plan's free and occupied
    cells swapped, the oracle map fed scans the robot never made, the true poses moved by a metre. The
    simulator (the odometry and the laser the filter reads) is untouched."""
    env.truth = dataclasses.replace(env.truth, grid=np.where(env.truth.grid == FREE, OCCUPIED, env.truth.grid))
    for x in np.linspace(*env.world.bounds[::2], 5):
        env.episode.oracle.insert((x, env.world.bounds[1] + 1.0, 0.5), np.full(len(env.laser_config.angles), 3.0),
                                  env.laser_config.angles)
    truth = type(env.episode)

    class Moved(truth):
        @property
        def true_poses_at_updates(self):
            return super().true_poses_at_updates + np.array([1.0, 0.0, 0.0])

        @property
        def true_path(self):
            return [pose + np.array([1.0, 0.0, 0.0]) for pose in super().true_path]

    env.episode.__class__ = Moved


def test_the_observation_never_carries_the_ground_truth():
    """Two envs with the same filter input, one of them with a ground truth scrambled after the reset and
    paying a privileged reward: their observations (and the actions offered) stay the same bit for bit while
    every ground-truth score differs."""
    plain = gym.make("emmi_gym/Explore-v1", info_scores="always", **TINY)
    taught = gym.make("emmi_gym/Explore-v1", reward="oracle_accuracy", info_rewards="all", info_scores="always",
                      **TINY)
    observations = [env.reset(seed=4)[0] for env in (plain, taught)]
    assert_same(*observations)
    scramble_the_ground_truth(taught.unwrapped)
    differed = set()
    for _ in range(3):
        assert np.array_equal(plain.unwrapped.action_masks(), taught.unwrapped.action_masks())
        action = frontier_action(plain)
        (seen, _, _, _, info), (seen_too, _, _, _, taught_info) = plain.step(action), taught.step(action)
        assert_same(seen, seen_too)
        differed |= {k for k in (*SCORES, "coverage") if info[k] != taught_info[k]}
    assert differed == {*SCORES, "coverage"}  # the scramble reached every score: the test can fail


def test_step_rewards_refuse_two_rewards_of_one_name():
    with pytest.raises(ValueError, match="two different rewards are named 'emmi'"):
        StepRewards(REWARDS["emmi"], [Reward("emmi", ("emmi",), 1.0, Change("emmi"))], None, 0.0, 0.0)


def test_the_old_scales_by_name_still_read_with_a_warning():
    from emmi_gym import env

    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        scales = env.REWARD_SCALES
    assert scales["emmi"] == 10.0 and "deprecated" in str(caught[0].message)


def test_the_loop_spread_reward_pays_the_fall_of_the_widest_loop_the_paths_hold_open():
    """It reads the filter's paths at the step's end: its component is the fall of the widest open loop, x10."""
    env = gym.make("emmi_gym/Explore-v1", reward="loop_spread", **TINY)
    core = env.unwrapped
    env.reset(seed=3)

    def widest():
        return certainty.widest_loop_spread(core.slam.paths, core.slam.log_weights, log_weights=True)

    before, moved = widest(), False
    for _ in range(4):
        _, reward, terminated, truncated, info = env.step(frontier_action(env))
        after = widest()
        assert info["reward_components"]["loop_spread"] == pytest.approx(10.0 * (before - after))
        assert reward == pytest.approx(info["reward_components"]["loop_spread"] + info["reward_components"]["time"]
                                       + info["reward_components"]["collision"])
        moved |= after != before
        before = after
        if terminated or truncated:
            break
    assert moved and info["privileged_rewards"] == []
