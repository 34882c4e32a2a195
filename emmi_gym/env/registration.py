"""Registration of the environment ids with Gymnasium (idempotent; runs on ``import emmi_gym``)."""

from __future__ import annotations

import gymnasium as gym

ENTRY_POINT = "emmi_gym.env.emmi_env:EmmiEnv"

#: id (without namespace) -> default options. An id's version goes up whenever its episodes change (Gymnasium's
#: rule): asked for an older version, ``gym.make`` raises Gymnasium's ``DeprecatedEnv`` naming the current one.
ENV_IDS = {
    # the paper's experiment with a laser of its era (a SICK LMS200, 180 degrees, at 8 m) and poor odometry: the
    # particles then disagree about the loop until it closes, so closing it first is worth learning
    "LoopCorridor-v1": dict(world="loop_corridor", start_at="decision", action_mode="waypoint",
                            laser={"preset": "sick_lms200", "max_range": 8.0}, odometry_noise="poor"),
    # the paper's experiment generalised: a corridor loop, featureless along its length, left open at the decision
    # point beside a long dead-end new area, a new world per seed (emmi_gym.world.loop_worlds); exploring the new
    # area first and back resamples away a fifth to a third of the loop's hypotheses (docs/results/order_matters.md)
    "LoopOrder-v1": dict(world="loop_order",
                         generator={"new_area_length": 20.0, "new_area_loop": False, "size_jitter": 0.15},
                         start_at="decision", action_mode="waypoint",
                         laser={"preset": "sick_lms200", "max_range": 8.0}, odometry_noise="poor"),
    "Explore-v1": dict(world=None, start_at="start", action_mode="waypoint"),
    "ExploreVelocity-v0": dict(world=None, start_at="start", action_mode="velocity"),
    # the hard configuration: real floor plans, a SICK LMS200 at its 8 m range, poor odometry; rooms wider than
    # the range leave runs of beams without echo, which free the cells up to it (GMapping's maxUrange < maxRange)
    "ExplorePlans-v1": dict(world="dungeon_maps/train", start_at="start", action_mode="waypoint",
                            laser={"preset": "sick_lms200", "max_range": 8.0}, odometry_noise="poor",
                            slam={"max_range_free": 8.0},
                            max_decisions=120, max_sim_steps=30000),
}


def register_envs() -> None:
    """Register ``emmi_gym/<Id>`` and, for ``gym.make("emmi_gym:<Id>")``, the bare ``<Id>``."""
    for name, kwargs in ENV_IDS.items():
        for env_id in (f"emmi_gym/{name}", name):
            if env_id not in gym.registry:
                gym.register(id=env_id, entry_point=ENTRY_POINT, kwargs=dict(kwargs))

