"""Rewards: the change of a certainty measure over a step, scaled, minus the costs of time and collisions.

Each variant (see :data:`~emmi_gym.env.config.REWARD_SCALES` for the scales and why):

- ``emmi``: scale * (EMMI after - EMMI before), the paper's certainty (eq. 11);
- ``pose_entropy``: scale * (before - after): a fall of the pose entropy pays;
- ``joint_entropy``: scale * (before - after) of the joint entropy (eq. 12);
- ``coverage``: scale * the fraction of the reachable free space newly swept by the scans (read on the
  oracle map, see ``EmmiEnv._refresh``);
- ``emmi_coverage``: scale * the change of EMMI x coverage: the mean information spread over
  the whole reachable free space (unexplored cells count as 0 bits) rather than over the
  observed cells only;
- ``map_information``: scale * the change of the expected map's information, eq. (9) summed over
  its observed cells (EMMI's numerator): a scan pays for the cells it adds to the map when the
  particles agree where it lands, and a closed loop pays as the disputed cells come to agree,
  while re-scanning cells already at the clamp pays nothing.

EMMI is a *mean* over the observed cells: re-scanning the same cells raises it as each
cell's log-odds approach the clamp, so spinning in place pays under ``emmi`` (and under
``joint_entropy``). Weighted by coverage (``emmi_coverage``), a rise of EMMI pays in proportion
to how much of the building the map holds: re-scanning a corner is worth little, closing a loop
when the map is large much. ``measurements/reward_farming.py`` measures what each variant pays for
standing still, spinning in place and exploring.
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
    map_information: float


def reward_components(before: Snapshot, after: Snapshot, sim_steps: int, collisions: int,
                      config: EnvConfig) -> dict[str, float]:
    """Every component, each with its default scale, plus the costs (negative)."""
    return {
        "emmi": REWARD_SCALES["emmi"] * (after.emmi - before.emmi),
        "pose_entropy": REWARD_SCALES["pose_entropy"] * (before.pose_entropy - after.pose_entropy),
        "joint_entropy": REWARD_SCALES["joint_entropy"] * (before.joint_entropy - after.joint_entropy),
        "coverage": REWARD_SCALES["coverage"] * (after.coverage - before.coverage),
        "emmi_coverage": REWARD_SCALES["emmi_coverage"] * (after.emmi * after.coverage - before.emmi * before.coverage),
        "map_information": REWARD_SCALES["map_information"] * (after.map_information - before.map_information),
        "time": -config.time_cost * sim_steps,
        "collision": -config.collision_cost * collisions,
    }


def total_reward(components: dict[str, float], config: EnvConfig) -> float:
    """The chosen variant at the configured scale, plus the time and collision costs."""
    chosen = components[config.reward] * config.scale / REWARD_SCALES[config.reward]
    return float(chosen + components["time"] + components["collision"])
