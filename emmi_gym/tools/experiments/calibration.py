"""Whether the filter is as sure as it is right, measured over an env's episodes and over real logs.

At every filter update the particles' weighted belief is checked against the truth
(:mod:`emmi_gym.scoring.calibration`): the pose itself; the motion over the last ``w`` updates
in the frame of the pose then (the relative pose error's quantity, which a map frame that
drifts as a whole does not change, and the only one a real log's reference trajectory, in its
own frame, can check); and at every decision, each revisit target the env offers: its loop spread
(:func:`~emmi_gym.certainty.loop_displacement_spread`) against the true error of the particles'
mean displacement ``x_now - x_then``, the certainty a revisit claims it can resolve.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import gymnasium as gym
import numpy as np

from ...scoring.calibration import PoseCheck, check_pose, nees_summary, relative_poses, true_relative_pose
from ...slam import RBPF
from ..policies import make_policy

#: Windows (filter updates) of the relative checks.
WINDOWS = (1, 10, 50)
#: The families of checks a record holds, in the tables' order.
FAMILIES = ("pose", *(f"relative_{w}" for w in WINDOWS), "loops")


@dataclass
class CalibrationRecord:
    """The checks of one episode or log, by family (see :data:`FAMILIES`)."""

    checks: dict[str, list[PoseCheck]] = field(default_factory=lambda: {name: [] for name in FAMILIES})

    def extend(self, other: CalibrationRecord) -> None:
        for name, rows in other.checks.items():
            self.checks[name].extend(rows)


class UpdateChecks:
    """A watcher of an env's filter updates (:meth:`~emmi_gym.env.EmmiEnv.watch_updates`) that checks the
    particles' pose and relative motions against the truth into ``record`` (set it before each reset).

    ``unweighted`` checks the cloud with equal weights instead of the filter's: a diagnosis of whether the
    weights or the particles' positions make the belief too sure."""

    def __init__(self, windows=WINDOWS, unweighted: bool = False):
        self.windows = tuple(windows)
        self.unweighted = unweighted
        self.record = CalibrationRecord()
        self._truth: list[np.ndarray] = []

    def start(self, record: CalibrationRecord) -> None:
        """Check the next episode's updates into ``record``."""
        self.record, self._truth = record, []

    def __call__(self, slam: RBPF, true_pose) -> None:
        self._truth.append(np.asarray(true_pose, dtype=np.float64))
        weights = slam.weights
        if self.unweighted:
            weights = np.full(weights.shape, 1.0 / weights.size)
        self.record.checks["pose"].append(check_pose(slam.poses, weights, true_pose))
        paths = slam.paths
        for w in self.windows:
            if len(self._truth) > w and paths.shape[1] > w:
                truth = true_relative_pose(self._truth[-1 - w], self._truth[-1])
                self.record.checks[f"relative_{w}"].append(check_pose(relative_poses(paths, -1 - w), weights, truth))


def loop_checks(env, unweighted: bool = False) -> list[PoseCheck]:
    """For each revisit target the env offers now, the particles' displacement since the place it revisits
    (``x_now - x_then`` in the map's frame, with the heading's change) against the true one: its spread is
    the target's loop spread (``unweighted``: see :class:`UpdateChecks`)."""
    core = env.unwrapped
    paths, weights = core.slam.paths, core.slam.weights
    if unweighted:
        weights = np.full(weights.shape, 1.0 / weights.size)
    truth = core.episode.true_poses_at_updates
    checks = []
    for target in core.targets:
        if target is None or target.kind != "revisit" or target.path_index is None:
            continue
        since = target.path_index
        displacement = np.column_stack([paths[:, -1, :2] - paths[:, since, :2],
                                        paths[:, -1, 2] - paths[:, since, 2]])
        true_displacement = np.array([*(truth[-1, :2] - truth[since, :2]), truth[-1, 2] - truth[since, 2]])
        checks.append(check_pose(displacement, weights, true_displacement))
    return checks


def calibrate_episode(env, policy, seed: int, checks: UpdateChecks) -> CalibrationRecord:
    """One episode of ``policy`` (a scripted policy of :mod:`emmi_gym.tools.policies`) on ``env``, whose
    updates ``checks`` watches; its record."""
    record = CalibrationRecord()
    checks.start(record)
    env.reset(seed=seed)
    policy.reset(seed)
    record.checks["loops"].extend(loop_checks(env, checks.unweighted))
    terminated = truncated = False
    while not (terminated or truncated):
        _, _, terminated, truncated, _ = env.step(policy(env))
        record.checks["loops"].extend(loop_checks(env, checks.unweighted))
    return record


def calibrate_env(env_id: str, options: dict, policy_name: str, seeds, unweighted: bool = False) -> CalibrationRecord:
    """The checks of episodes ``seeds`` of ``env_id`` (with ``options``) under a scripted policy (``unweighted``:
    see :class:`UpdateChecks`)."""
    env = gym.make(env_id, **options)
    checks = UpdateChecks(unweighted=unweighted)
    env.unwrapped.watch_updates(checks)
    policy = make_policy(policy_name)
    total = CalibrationRecord()
    try:
        for seed in seeds:
            total.extend(calibrate_episode(env, policy, seed, checks))
    finally:
        env.close()
    return total


class LogChecks:
    """A replay's per-update hook (:func:`~emmi_gym.tools.experiments.replay.replay`'s ``on_update``) that keeps,
    for each window, the particles' relative motions and weights at every update: what the log's reference
    trajectory is compared with once the replay ends (:meth:`record`)."""

    def __init__(self, windows=WINDOWS):
        self.windows = tuple(windows)
        self._clouds: list[tuple[int, int, np.ndarray, np.ndarray]] = []  # (window, update, relative poses, weights)
        self._updates = 0

    def __call__(self, slam: RBPF) -> None:
        paths = slam.paths
        for w in self.windows:
            if paths.shape[1] > w:
                self._clouds.append((w, self._updates, relative_poses(paths, -1 - w), slam.weights))
        self._updates += 1

    def record(self, true_poses) -> CalibrationRecord:
        """The relative checks against ``true_poses`` (per update, a (3,) pose or None where the log has
        no reference there)."""
        record = CalibrationRecord()
        for w, update, poses, weights in self._clouds:
            before, after = true_poses[update - w], true_poses[update]
            if before is not None and after is not None:
                record.checks[f"relative_{w}"].append(check_pose(poses, weights, true_relative_pose(before, after)))
        return record


def summary(checks: list[PoseCheck]) -> dict[str, float]:
    """A family's figures: NEES in (x, y) and in (x, y, theta) (mean, median, the share inside the 50, 90 and
    95% ellipses), the RMS spread and RMS error (m; equal for an honest belief) and the mean error of the
    particle nearest the truth."""
    if not checks:
        return {"moments": 0.0}
    xy = nees_summary([c.nees_xy for c in checks], 2)
    pose = nees_summary([c.nees_pose for c in checks], 3)
    spread = np.array([c.spread for c in checks])
    error = np.array([c.error for c in checks])
    return {"moments": xy["moments"], **{f"xy_{k}": v for k, v in xy.items() if k != "moments"},
            **{f"pose_{k}": v for k, v in pose.items() if k != "moments"},
            "rms_spread": float(math.sqrt(np.mean(spread ** 2))), "rms_error": float(math.sqrt(np.mean(error ** 2))),
            "nearest": float(np.mean([c.nearest for c in checks]))}


def spread_against_error(checks: list[PoseCheck], bins: int = 8) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The calibration curve: moments put in ``bins`` bins of equal count by their predicted spread; per bin the
    RMS spread, the RMS error (on the diagonal for an honest belief) and the count."""
    spread = np.array([c.spread for c in checks])
    error = np.array([c.error for c in checks])
    order = np.argsort(spread)
    groups = [g for g in np.array_split(order, min(bins, max(1, len(order)))) if g.size]
    return (np.array([math.sqrt(np.mean(spread[g] ** 2)) for g in groups]),
            np.array([math.sqrt(np.mean(error[g] ** 2)) for g in groups]), np.array([g.size for g in groups]))
