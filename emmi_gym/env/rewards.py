"""Rewards: the change of a certainty measure over a step, scaled, minus the costs of time and collisions.

Each variant (see :data:`~emmi_gym.env.config.REWARD_SCALES` for the scales and why):

- ``emmi``: scale * (EMMI after - EMMI before), the paper's certainty (eq. 11);
- ``pose_entropy``: scale * (before - after): a fall of the pose entropy pays;
- ``joint_entropy``: scale * (before - after) of the joint entropy (eq. 12);
- ``coverage``: scale * the fraction of the reachable free space newly covered.

Whatever the variant, ``time_cost`` per simulator step and ``collision_cost`` per
colliding step are subtracted, so that standing still or spinning in place never pays
more than finishing the map (the episode ends when the coverage target is reached).
"""

from __future__ import annotations

from dataclasses import dataclass

from .config import REWARD_SCALES, EnvConfig


@dataclass(frozen=True)
class Snapshot:
    """The measures the rewards compare between two steps."""

    emmi: float
    pose_entropy: float
    joint_entropy: float
    coverage: float


def reward_components(before: Snapshot, after: Snapshot, sim_steps: int, collisions: int,
                      config: EnvConfig) -> dict[str, float]:
    """Every component, each with its default scale, plus the costs (negative)."""
    return {
        "emmi": REWARD_SCALES["emmi"] * (after.emmi - before.emmi),
        "pose_entropy": REWARD_SCALES["pose_entropy"] * (before.pose_entropy - after.pose_entropy),
        "joint_entropy": REWARD_SCALES["joint_entropy"] * (before.joint_entropy - after.joint_entropy),
        "coverage": REWARD_SCALES["coverage"] * (after.coverage - before.coverage),
        "time": -config.time_cost * sim_steps,
        "collision": -config.collision_cost * collisions,
    }


def total_reward(components: dict[str, float], config: EnvConfig) -> float:
    """The chosen variant at the configured scale, plus the time and collision costs."""
    chosen = components[config.reward] * config.scale / REWARD_SCALES[config.reward]
    return float(chosen + components["time"] + components["collision"])
