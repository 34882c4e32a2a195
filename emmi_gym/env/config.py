"""The environment's options: every keyword ``gym.make`` accepts, with its checks and defaults."""

from __future__ import annotations

import math
from dataclasses import dataclass, field, fields

REWARDS = ("emmi", "pose_entropy", "joint_entropy", "coverage")
ACTION_MODES = ("waypoint", "velocity")
VELOCITY_ACTIONS = ("continuous", "discrete")
OBSERVATIONS = ("dict", "image")
STARTS = ("decision", "start")

#: Reward scales: each turns its measure's typical change over one macro-action into O(0.1-1).
#: EMMI lies in [0, 1] bits/cell and moves by 0.01-0.1 per macro-action; the pose entropy
#: (nats) by about 1; the joint entropy (nats, dominated by eq. 8 over the whole grid) by
#: thousands as cells get observed; coverage is a fraction of the reachable free space.
REWARD_SCALES = {"emmi": 10.0, "pose_entropy": 0.1, "joint_entropy": 1e-3, "coverage": 10.0}


@dataclass(frozen=True)
class EnvConfig:
    """Options of :class:`~emmi_gym.env.EmmiEnv`; ``gym.make(id, **options)`` sets any of them.

    - ``world``: built-in name or .yaml path; ``None`` draws a new generated world at
      every reset (``generator`` holds :class:`~emmi_gym.world.GeneratorConfig` fields).
    - ``start_at``: ``"decision"`` drives the world's ``to_decision`` route with the RBPF
      running before the first observation (the paper's robot up to its step 65);
      ``"start"`` begins at the start pose.
    - ``reward``: one of :data:`REWARDS`; all are computed and put in ``info``.
    - ``time_cost`` per simulator step and ``collision_cost`` per colliding step are
      subtracted whatever the reward, so doing nothing never pays.
    - ``laser``, ``odometry_noise``, ``slam``: dicts of :class:`LaserConfig`,
      :class:`OdometryNoise` and :class:`RBPFConfig` fields; ``particles`` and
      ``resolution`` are shortcuts into ``slam``.
    """

    world: str | None = "loop_corridor"
    generator: dict = field(default_factory=dict)
    start_at: str = "decision"
    action_mode: str = "waypoint"
    velocity_actions: str = "continuous"
    reward: str = "emmi"
    reward_scale: float | None = None
    time_cost: float = 0.002
    collision_cost: float = 0.05
    coverage_target: float = 0.9
    particles: int = 15
    resolution: float = 0.1
    laser: dict = field(default_factory=dict)
    odometry_noise: dict = field(default_factory=dict)
    slam: dict = field(default_factory=dict)
    observation: str = "dict"
    obs_size: int = 64
    egocentric: bool = False
    egocentric_extent: float = 16.0
    n_frontiers: int = 6
    n_revisits: int = 2
    max_decisions: int = 60
    max_sim_steps: int = 12000
    macro_timeout: int = 900

    def __post_init__(self):
        choices = {"start_at": STARTS, "action_mode": ACTION_MODES, "velocity_actions": VELOCITY_ACTIONS,
                   "reward": REWARDS, "observation": OBSERVATIONS}
        for name, valid in choices.items():
            if getattr(self, name) not in valid:
                raise ValueError(f"{name}={getattr(self, name)!r} is not valid; choose one of {list(valid)}")
        for name in ("particles", "obs_size", "n_frontiers", "max_decisions", "max_sim_steps", "macro_timeout"):
            value = getattr(self, name)
            if not (isinstance(value, int) and not isinstance(value, bool) and value >= 1):
                raise ValueError(f"{name} must be an integer >= 1, got {value!r}")
        if not (isinstance(self.n_revisits, int) and self.n_revisits >= 0):
            raise ValueError(f"n_revisits must be an integer >= 0, got {self.n_revisits!r}")
        if self.obs_size < 16:
            raise ValueError(f"obs_size must be at least 16 pixels, got {self.obs_size}")
        for name in ("time_cost", "collision_cost"):
            value = getattr(self, name)
            if not (isinstance(value, (int, float)) and math.isfinite(value) and value >= 0):
                raise ValueError(f"{name} must be a number >= 0, got {value!r}")
        for name in ("resolution", "egocentric_extent"):
            value = getattr(self, name)
            if not (isinstance(value, (int, float)) and math.isfinite(value) and value > 0):
                raise ValueError(f"{name} must be a positive number, got {value!r}")
        if not 0.0 < self.coverage_target <= 1.0:
            raise ValueError(f"coverage_target must be in (0, 1], got {self.coverage_target!r}")
        if self.reward_scale is not None and not (isinstance(self.reward_scale, (int, float)) and self.reward_scale > 0):
            raise ValueError(f"reward_scale must be a positive number or None, got {self.reward_scale!r}")
        for name in ("generator", "laser", "odometry_noise", "slam"):
            if not isinstance(getattr(self, name), dict):
                raise ValueError(f"{name} must be a dict of options, got {getattr(self, name)!r}")

    @property
    def scale(self) -> float:
        return self.reward_scale if self.reward_scale is not None else REWARD_SCALES[self.reward]

    @property
    def n_actions(self) -> int:
        return self.n_frontiers + self.n_revisits


def make_config(**options) -> EnvConfig:
    """An :class:`EnvConfig` from keyword options; an unknown option raises ValueError listing the valid ones."""
    valid = [f.name for f in fields(EnvConfig)]
    unknown = sorted(set(options) - set(valid))
    if unknown:
        raise ValueError(f"unknown option(s) {unknown}; valid options are {valid}")
    return EnvConfig(**options)
