"""Scripted policies drive the waypoint env through its public API."""

import gymnasium as gym
import numpy as np
import pytest

import emmi_gym
from emmi_gym.tools.policies import TARGET_SNAP, make_policy

gym.register_envs(emmi_gym)


@pytest.mark.parametrize("name, first, second", [("close_loop_first", "target_a", "target_b"),
                                                 ("explore_first", "target_b", "target_a")])
def test_goal_sequences_visit_a_and_b_in_their_order(name, first, second):
    env = gym.make("emmi_gym/LoopCorridor-v1", particles=5, coverage_target=1.0)
    env.reset(seed=1)
    policy = make_policy(name)
    policy.reset(1)
    core = env.unwrapped
    reached = []
    for _ in range(30):
        env.step(policy(env))
        policy.advance(env)  # notice a goal reached by that step
        while len(reached) < policy.phase:
            reached.append(core.estimated_pose[:2].copy())
        if policy.phase == 2:
            break
    assert policy.phase == 2
    world = core.world
    # goals live in the map frame: each was reached, in order, by the estimated pose (under B the
    # truth may be well off by then: the loop was not closed before the new area was mapped); the
    # distance is read from the free cell nearest the pose within a TARGET_SNAP square
    bound = core.laser_config.max_range + TARGET_SNAP * np.sqrt(2)
    assert np.hypot(*(reached[0] - world.place(first).xy)) <= bound
    assert np.hypot(*(reached[1] - world.place(second).xy)) <= bound


def test_random_policy_is_seeded_and_valid():
    env = gym.make("emmi_gym/LoopCorridor-v1", particles=5)
    env.reset(seed=0)
    a, b = make_policy("random"), make_policy("random")
    a.reset(3)
    b.reset(3)
    mask = env.unwrapped.action_masks()
    picks = [a(env) for _ in range(20)]
    assert picks == [b(env) for _ in range(20)]
    assert all(mask[p] for p in picks)
    with pytest.raises(ValueError, match="unknown policy 'greedy'; choose one of"):
        make_policy("greedy")


class _Slots:
    """A waypoint env as the policies see it: slots, masks, loop spreads, the grid's resolution."""

    def __init__(self, targets, spreads, resolution=0.1):
        from emmi_gym.geometry.grid import GridGeometry

        self.targets, self.loop_spreads = targets, spreads
        self.geometry = GridGeometry(resolution, 0.0, 0.0, 10, 10)

    def action_masks(self):
        mask = np.array([t is not None for t in self.targets])
        mask[0] |= not mask.any()
        return mask


def test_active_loop_closing_goes_back_when_the_particles_disagree_and_explores_when_they_agree():
    from emmi_gym.navigation.candidates import Target

    near, far = Target("frontier", 2, 0, 2.0, 30), Target("frontier", 9, 0, 9.0, 30)
    weak, strong = Target("revisit", 0, 5, 6.0, 2.0, 10), Target("revisit", 0, -5, 7.0, 3.0, 4)
    policy = make_policy("active_loop_closing")
    policy.reset(0)
    # spreads of 0.05 and 0.1 m: below 1.5 cells (0.15 m), the loops are as good as closed -> nearest frontier
    assert policy(_Slots([near, far, weak, strong], [0, 0, 0.05, 0.1])) == 0
    # one loop the particles disagree on (0.4 m): go back there, the one of highest spread
    assert policy(_Slots([near, far, weak, strong], [0, 0, 0.2, 0.4])) == 3
    # having gone back once, explore before going back again ...
    assert policy(_Slots([near, far, weak, strong], [0, 0, 0.3, 0.1])) == 0
    # ... then the other loop; never the place already revisited
    assert policy(_Slots([near, far, weak, strong], [0, 0, 0.3, 0.5])) == 2
    assert policy(_Slots([near, far, None, strong], [0, 0, 0, 0.5])) == 0
    assert policy(_Slots([None, None, None, strong], [0, 0, 0, 0.5])) == 3  # no frontier: the only valid slot
    # the threshold is in cells: at 0.5 m cells a 0.4 m spread is within one cell
    policy.reset(0)
    assert policy(_Slots([near, far, weak, strong], [0, 0, 0.2, 0.4], resolution=0.5)) == 0


def test_active_loop_closing_runs_on_a_plan():
    env = gym.make("emmi_gym/ExplorePlans-v1", max_decisions=6)
    policy = make_policy("active_loop_closing")
    env.reset(seed=3)
    policy.reset(3)
    for _ in range(6):
        action = policy(env)
        assert env.unwrapped.action_masks()[action]
        chosen = env.unwrapped.targets[action]
        _, _, _, _, info = env.step(action)
        assert info["target_kind"] == (chosen.kind if chosen is not None else "none")
