"""Rewards as parts: each one small object, the scaled change over a step of what it reads, less the costs.

A :class:`Reward` has a name, the measures it reads, its default scale and its value per step from
those measures before and after the step. What it reads decides what the environment computes: the
filter's certainty (:data:`FILTER_MEASURES`, computed after every filter update for the observation
anyway) or the ground truth (:data:`TRUTH_MEASURES`). A reward that reads the ground truth is
**privileged**: it exists in simulation only, for training with the truth as teacher while the agent
acts on the filter's belief alone (the observation never carries it). The environment pays

``r_t = scale * value(before, after) - time_cost * (simulator steps) - collision_cost * (colliding steps)``

with ``scale`` the reward's own unless ``reward_scale`` is given, and puts each reward it shows
(the one paid and those ``info_rewards`` names) in ``info["reward_components"]`` at its own scale
(:class:`StepRewards`). The built-ins (:data:`BUILT_IN`, registered by name in
:mod:`emmi_gym.env.reward_registry`):

- ``emmi``: the change of EMMI, the paper's certainty (eq. 11);
- ``pose_entropy``, ``joint_entropy`` (eq. 12): their fall;
- ``map_information``: the change of the expected map's information, eq. (9) over its observed cells
  (EMMI's numerator): a scan pays for the cells it adds where the particles agree, a closed loop as the
  disputed cells come to agree; re-scanning cells at the clamp pays nothing;
- ``coverage``: the share of the reachable free space newly swept by the scans, read on the oracle map
  (privileged: the scans at the true poses);
- ``emmi_coverage``: the change of EMMI x coverage, the mean information over the whole reachable free
  space (unexplored cells count as 0 bits) rather than over the observed cells (privileged, as coverage);
- ``loop_spread``: the fall of the widest loop the particles hold open (how far apart they put the robot
  relative to the place of its path they disagree on most, :func:`~emmi_gym.certainty.widest_loop_spread`):
  odometry drift costs, a closed loop pays, standing and spinning earn no reward;
- ``oracle_accuracy``, ``wall_consistency``: their change; ``ate``: its fall (privileged: the ground-truth
  scores of :mod:`emmi_gym.scoring.scores`).

EMMI is a *mean* over the observed cells: re-scanning the same cells raises it as each cell's log-odds
approach the clamp, so spinning in place pays under ``emmi`` (and ``joint_entropy``).
``measurements/reward_farming.py`` measures what each reward pays for standing still, spinning and exploring.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass

from ..inputs.validation import OptionError

#: What a reward may read of the filter: the certainty of the particle set (:class:`~emmi_gym.slam.UpdateMetrics`,
#: measured at every filter update) and the widest loop its paths hold open (``loop_spread``,
#: :func:`~emmi_gym.certainty.widest_loop_spread`, measured only when a reward reads it).
FILTER_MEASURES = ("emmi", "map_information", "mean_information_best", "pose_entropy", "weight_entropy",
                   "path_entropy", "joint_entropy", "neff", "loop_spread")
#: The ground-truth scores the environment computes only when a reward, ``info`` or the episode's end needs them.
SCORES = ("map_accuracy", "oracle_accuracy", "wall_consistency", "ate", "building_accuracy")
#: What a reward may read of the ground truth (coverage is read on the oracle map, the scans at the true poses; the
#: episode's end reads it at every step).
TRUTH_MEASURES = ("coverage", *SCORES)
#: The costs every reward pays, and the names no reward may take.
COSTS = ("time", "collision")
#: The largest default scale a reward may have.
MAX_SCALE = 1e6

#: A reward's value per step: (the measures it reads before the step, after it) -> the change, unscaled.
Value = Callable[[Mapping[str, float], Mapping[str, float]], float]


@dataclass(frozen=True)
class Reward:
    """A reward: ``name``, the measures it ``reads`` (of :data:`FILTER_MEASURES` and :data:`TRUTH_MEASURES`), its
    default ``scale`` (which makes its typical change over one decision O(0.1-1)), and its ``value`` per step:
    ``value(before, after)``, each a mapping of the measures it reads (and those alone), gives the change the
    reward pays before scaling. ``meaning`` is a line for the docs and the tables."""

    name: str
    reads: tuple[str, ...]
    scale: float
    value: Value
    meaning: str = ""

    def __post_init__(self):
        if not isinstance(self.name, str) or not self.name.isidentifier() or self.name in COSTS:
            raise OptionError("Reward", "name", f"a name made of letters, digits and underscores, not one of the "
                              f"costs {list(COSTS)}", self.name)
        reads = (self.reads,) if isinstance(self.reads, str) else self.reads
        known = (*FILTER_MEASURES, *TRUTH_MEASURES)
        if not isinstance(reads, (tuple, list)) or not reads or any(m not in known for m in reads):
            raise OptionError("Reward", "reads", f"a non-empty list of the measures {list(known)}", self.reads)
        object.__setattr__(self, "reads", tuple(dict.fromkeys(reads)))
        scale = self.scale
        if isinstance(scale, bool) or not isinstance(scale, (int, float)) or not 0 < scale <= MAX_SCALE:
            raise OptionError("Reward", "scale", f"a number in (0, {MAX_SCALE:g}]", scale)
        object.__setattr__(self, "scale", float(scale))
        if not callable(self.value):
            raise OptionError("Reward", "value", "a function (before, after) -> float", self.value)

    @property
    def privileged(self) -> bool:
        """Whether it reads the ground truth (simulation only: for training, never for a real robot)."""
        return any(m in TRUTH_MEASURES for m in self.reads)


@dataclass(frozen=True)
class Change:
    """The value of a reward that pays the change of one measure: after - before (``falling``: before - after,
    a fall pays)."""

    measure: str
    falling: bool = False

    def __call__(self, before: Mapping[str, float], after: Mapping[str, float]) -> float:
        m = self.measure
        return before[m] - after[m] if self.falling else after[m] - before[m]


def emmi_coverage_change(before: Mapping[str, float], after: Mapping[str, float]) -> float:
    """The change of EMMI x coverage: bits per cell of the reachable free space."""
    return after["emmi"] * after["coverage"] - before["emmi"] * before["coverage"]


def change_reward(measure: str, scale: float, meaning: str, falling: bool = False, name: str | None = None) -> Reward:
    """A reward named ``measure`` (or ``name``) that pays ``scale`` times its change (its fall with ``falling``)."""
    return Reward(name or measure, (measure,), scale, Change(measure, falling), meaning)


#: The built-in rewards. Each scale turns its measure's typical change over one decision into O(0.1-1): EMMI lies in
#: [0, 1] bits/cell and moves by 0.01-0.1 per macro-action; the pose entropy (nats) by about 1; the joint entropy
#: (nats, dominated by eq. 8 over the whole grid) by thousands as cells get observed; coverage is a fraction of
#: the reachable free space, and so is EMMI x coverage (bits per reachable cell); the expected map's information
#: (bits, one per certain cell) grows by hundreds to thousands as a macro-action observes new cells. The
#: privileged scores on ExplorePlans-v1's plans (measurements/reward_scales.py, docs/results/rewards.md): the
#: oracle accuracy moves by about 0.003 per decision (0.015 at the 90th percentile), the wall consistency by
#: 0.008 (0.05), the ATE by 0.01 m (0.08 m), the widest loop spread by 0.02 m (0.08 m): scaled to 0.1-0.8 as
#: EMMI and coverage are.
BUILT_IN = (
    change_reward("emmi", 10.0, "EMMI, eq. (11), bits per cell"),
    change_reward("pose_entropy", 0.1, "the pose entropy, nats (a fall pays)", falling=True),
    change_reward("joint_entropy", 1e-3, "the joint entropy, eq. (12), nats (a fall pays)", falling=True),
    change_reward("coverage", 10.0, "the share of the reachable free space swept (the oracle map)"),
    Reward("emmi_coverage", ("emmi", "coverage"), 10.0, emmi_coverage_change, "EMMI x coverage"),
    change_reward("map_information", 1e-3, "the expected map's information, eq. (9) over its observed cells, bits"),
    change_reward("loop_spread", 10.0, "the widest open loop's spread, m (a fall pays)", falling=True),
    change_reward("oracle_accuracy", 50.0, "the accuracy against the oracle map"),
    change_reward("wall_consistency", 10.0, "the wall consistency against the oracle map"),
    change_reward("ate", 10.0, "the ATE of the best particle's path, m (a fall pays)", falling=True),
)


class StepRewards:
    """The rewards of an environment's steps: ``paid`` (at ``scale``; None: its own) and the ``shown`` ones,
    each at its own scale in ``info["reward_components"]``, with the costs of time and collisions.

    :attr:`reads` is every measure they read (what the environment must measure before and after a
    step), :attr:`privileged` the names of those that read the ground truth."""

    def __init__(self, paid: Reward, shown: Sequence[Reward], scale: float | None, time_cost: float,
                 collision_cost: float):
        by_name = {paid.name: paid}
        for reward in shown:
            if by_name.setdefault(reward.name, reward) != reward:
                raise ValueError(f"two different rewards are named {reward.name!r}: {by_name[reward.name]} and "
                                 f"{reward}")
        self.paid = paid
        self.rewards = tuple(by_name.values())
        self.scale = paid.scale if scale is None else float(scale)
        self.time_cost, self.collision_cost = time_cost, collision_cost
        self.reads = tuple(dict.fromkeys(m for reward in self.rewards for m in reward.reads))
        self.privileged = tuple(reward.name for reward in self.rewards if reward.privileged)

    def components(self, before: Mapping[str, float], after: Mapping[str, float], sim_steps: int,
                   collisions: int) -> dict[str, float]:
        """Every reward shown at its own scale, given the measures before and after the step (:attr:`reads`),
        and the costs (negative) of its ``sim_steps`` and ``collisions``."""
        components = {}
        for reward in self.rewards:
            value = reward.value({m: before[m] for m in reward.reads}, {m: after[m] for m in reward.reads})
            if not math.isfinite(value):
                raise ValueError(f"the reward {reward.name!r} gave {value!r}, not a finite number")
            components[reward.name] = reward.scale * value
        components["time"] = -self.time_cost * sim_steps
        components["collision"] = -self.collision_cost * collisions
        return components

    def none(self) -> dict[str, float]:
        """The components of no step (what ``reset``'s ``info`` holds)."""
        return {name: 0.0 for name in (*(reward.name for reward in self.rewards), *COSTS)}

    def total(self, components: Mapping[str, float]) -> float:
        """The reward paid: the paid one's component at :attr:`scale`, plus the costs."""
        chosen = components[self.paid.name] * self.scale / self.paid.scale
        return float(chosen + components["time"] + components["collision"])
