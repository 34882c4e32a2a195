"""Evaluation episodes under the ground-truth metrics, for trained agents and scripted policies alike."""

from __future__ import annotations

import math

import numpy as np

from .loop_order import LOOP_ORDER_KEY
from .robot_time import TRACE, TRACED, trace_point

#: What an episode's last ``info`` says against the ground truth (and the certainty it ended with): the columns of a
#: run's periodic evaluations (``eval_ground_truth.csv``, one header for a run and its resumptions).
GROUND_TRUTH = ("coverage", "map_accuracy", "oracle_accuracy", "wall_consistency", "ate", "emmi", "pose_entropy",
                "joint_entropy", "collisions", "sim_steps")
#: What an evaluation episode's row holds of its last ``info``: :data:`GROUND_TRUTH` and the building accuracy (the
#: share of the building mapped correctly, unmapped cells counting as wrong).
EPISODE_SCORES = (*GROUND_TRUTH, "building_accuracy")


def info_options(keep_steps: bool = False, keep_trace: bool = False) -> dict:
    """The ``gym.make`` options under which :func:`play_episode` can keep what it is asked to: every registered
    reward in each step's ``info`` (``keep_steps``: what any reward would have paid) and the ground-truth scores
    after the reset and every step (``keep_trace``: what reads the map at equal robot time). The env measures
    neither unasked; the episodes are the same either way."""
    return {**({"info_rewards": "all"} if keep_steps else {}), **({"info_scores": "always"} if keep_trace else {})}


class ModelActor:
    """Acts with a trained SB3 model (deterministically; MaskablePPO gets the env's action masks)."""

    def __init__(self, model, deterministic: bool = True):
        self.model, self.deterministic = model, deterministic
        self.masked = type(model).__name__ == "MaskablePPO"
        self.name = type(model).__name__

    def reset(self, seed: int) -> None:
        pass

    def __call__(self, env, observation):
        extra = {"action_masks": env.unwrapped.action_masks()} if self.masked else {}
        action, _ = self.model.predict(observation, deterministic=self.deterministic, **extra)
        return action


class PolicyActor:
    """Acts with a scripted policy of :mod:`emmi_gym.tools.policies` (reseeded every episode)."""

    def __init__(self, policy):
        self.policy, self.name = policy, policy.name

    def reset(self, seed: int) -> None:
        self.policy.reset(seed)

    def __call__(self, env, observation):
        return self.policy(env)


def play_episode(env, actor, seed: int, keep_steps: bool = False, keep_trace: bool = False) -> dict:
    """One episode with ``actor``; its return, steps and ground-truth measures (see :data:`EPISODE_SCORES`).

    ``sim_steps_to_target`` is the simulator steps until the coverage target (NaN if it was
    not reached); where the episode starts at a loop's decision point and ``env`` is wrapped in
    :class:`~emmi_gym.tools.evaluation.loop_order.LoopOrderInfo` (as
    ``emmi_gym.tools.training.train.make_agent_env`` does),
    ``closed_loop_first`` is 1.0 if the robot went back to the loop's start before entering the
    new area, 0.0 if it entered the new area first, NaN if neither. ``revisit_share`` is the
    fraction of waypoint decisions that chose a revisit target (``info["target_kind"]``; NaN
    in velocity mode): how much of its time the policy spent going back to close loops. With
    ``keep_steps``, ``steps`` lists each step's ``info["reward_components"]`` with its ``duration`` in
    simulator steps (what any reward variant, time cost and discount would have paid), the kind of
    target it chose and where that target was (``target_xy``, in the map's frame). With ``keep_trace``,
    ``trace`` lists the ground-truth scores at the reset and after every step, with the robot time
    (:func:`emmi_gym.tools.evaluation.robot_time.trace_point`): what reads the map at equal robot time. Both
    need ``env`` made with :func:`info_options` (a ``ValueError`` says so at the reset otherwise).
    """
    observation, info = env.reset(seed=seed)
    if keep_trace and any(k not in info for k in TRACED):
        raise ValueError("keep_trace reads the ground-truth scores after every step: make the env with "
                         "info_scores='always' (info_options(keep_trace=True))")
    actor.reset(seed)
    total, steps, revisits, terminated, truncated = 0.0, 0, 0, False, False
    kept, trace = [], [trace_point(info)] if keep_trace else None
    while not (terminated or truncated):
        action = actor(env, observation)
        target = _target_of(env, action) if keep_steps else None
        observation, reward, terminated, truncated, info = env.step(action)
        total += float(reward)
        steps += 1
        revisits += info.get("target_kind") == "revisit"
        if keep_steps:
            kept.append({**info["reward_components"], "duration": info["sim_steps_this_step"],
                         "target_kind": info.get("target_kind"), "target_xy": target})
        if keep_trace:
            trace.append(trace_point(info))
    row = {"episode_seed": seed, "return": total, "env_steps": steps, **{k: float(info[k]) for k in EPISODE_SCORES},
           "reached_target": float(terminated),
           "sim_steps_to_target": float(info["sim_steps"]) if terminated else math.nan,
           "revisit_share": revisits / steps if "target_kind" in info else math.nan}
    if LOOP_ORDER_KEY in info:
        row[LOOP_ORDER_KEY] = info[LOOP_ORDER_KEY]
    if keep_steps:
        row["steps"] = kept
    if keep_trace:
        row[TRACE] = trace
    return row


def _target_of(env, action) -> tuple[float, float] | None:
    """Where the waypoint ``action`` sends the robot (in the map's frame), or None (an empty slot,
    velocity actions)."""
    targets = getattr(env.unwrapped, "targets", [])
    if not targets or np.ndim(action) != 0 or not 0 <= int(action) < len(targets) or targets[int(action)] is None:
        return None
    target = targets[int(action)]
    return float(target.x), float(target.y)


def play_episodes(env, actor, seeds, keep_trace: bool = False) -> list[dict]:
    return [play_episode(env, actor, int(seed), keep_trace=keep_trace) for seed in seeds]


def nanmean(values) -> float:
    """Mean of the finite values; NaN when there is none."""
    finite = [v for v in values if np.isfinite(v)]
    return float(np.mean(finite)) if finite else math.nan


def summarise(rows: list[dict]) -> dict:
    """:func:`nanmean` of every column over episodes."""
    return {k: nanmean([r.get(k, math.nan) for r in rows]) for k in rows[0] if k != "episode_seed"}
