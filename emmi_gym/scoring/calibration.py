"""Whether a particle set is as sure as it is right: its weighted spread against its error from the truth.

A filter's belief is *consistent* (Bar-Shalom, Li and Kirubarajan, *Estimation with Applications
to Tracking and Navigation*, 2001, sec. 5.4) when its error e = x_true - x_mean has the
covariance P the belief claims. The test statistic is the normalised estimation error squared,
NEES = e^T P^-1 e: for a consistent Gaussian belief in d dimensions it follows chi-square with d
degrees of freedom, so its mean is d (2 for (x, y), 3 for (x, y, theta)), and the truth lies
inside the belief's p-ellipse {NEES <= chi2_d^-1(p)} a share p of the time. An RBPF whose
particles share one map error has a NEES far above d (Bailey, Nieto and Nebot, "Consistency of the
FastSLAM algorithm", ICRA 2006): its certainty measures cannot see that error.

Pure functions of arrays (the particles' poses and weights, the true pose); the tools collect
them over episodes and logs (:mod:`emmi_gym.tools.experiments.calibration`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from scipy.stats import chi2

from ..geometry.motion import wrap_angle

#: The ellipses whose coverage is reported: the truth inside the p-ellipse a share p of the time.
COVERAGE_LEVELS = (0.5, 0.9, 0.95)


def pose_moments(poses, weights) -> tuple[np.ndarray, np.ndarray]:
    """The weighted mean (3,) and covariance (3, 3) of poses (M, 3) under normalised ``weights`` (M,);
    the heading's mean is the circular one and its deviations are wrapped about it."""
    p = np.asarray(poses, dtype=np.float64)
    w = np.asarray(weights, dtype=np.float64)
    heading = math.atan2(float(w @ np.sin(p[:, 2])), float(w @ np.cos(p[:, 2])))
    deviations = np.column_stack([p[:, :2] - w @ p[:, :2], wrap_angle(p[:, 2] - heading)])
    mean = np.array([*(w @ p[:, :2]), heading])
    return mean, (deviations * w[:, None]).T @ deviations


def nees(error, covariance) -> float:
    """e^T P^-1 e; infinite where P is singular along the error (the belief rules the truth out)."""
    e = np.asarray(error, dtype=np.float64)
    p = np.asarray(covariance, dtype=np.float64)
    try:
        value = float(e @ np.linalg.solve(p, e))
    except np.linalg.LinAlgError:
        return 0.0 if not e.any() else math.inf
    return value if value >= 0.0 else math.inf


@dataclass(frozen=True)
class PoseCheck:
    """One moment's belief against the truth: NEES in (x, y, theta) and in (x, y), the error of the
    weighted mean position (m), the belief's spread (the root of its (x, y) covariance's trace, m)
    and the error of the particle nearest the truth (m)."""

    nees_pose: float
    nees_xy: float
    error: float
    spread: float
    nearest: float


def check_pose(poses, weights, true_pose) -> PoseCheck:
    """The particle set's belief about the pose (poses (M, 3), normalised weights) against ``true_pose``."""
    mean, covariance = pose_moments(poses, weights)
    truth = np.asarray(true_pose, dtype=np.float64)
    error = np.array([*(truth[:2] - mean[:2]), wrap_angle(float(truth[2] - mean[2]))])
    nearest = float(np.min(np.hypot(*(np.asarray(poses)[:, :2] - truth[:2]).T)))
    return PoseCheck(nees(error, covariance), nees(error[:2], covariance[:2, :2]), float(np.hypot(*error[:2])),
                     float(math.sqrt(max(np.trace(covariance[:2, :2]), 0.0))), nearest)


def relative_poses(paths, since: int, until: int = -1) -> np.ndarray:
    """(M, 3) each particle's pose at update ``until`` in the frame of its own pose at ``since``: the motion
    between the two as that particle's path has it (the relative pose error's quantity, Kümmerle et al.,
    "On measuring the accuracy of SLAM algorithms", 2009), independent of the map's frame."""
    p = np.asarray(paths, dtype=np.float64)
    before, after = p[:, since], p[:, until]
    dx, dy = after[:, 0] - before[:, 0], after[:, 1] - before[:, 1]
    c, s = np.cos(before[:, 2]), np.sin(before[:, 2])
    return np.column_stack([c * dx + s * dy, -s * dx + c * dy, wrap_angle(after[:, 2] - before[:, 2])])


def true_relative_pose(before, after) -> np.ndarray:
    """The true motion from pose ``before`` to ``after``, in ``before``'s frame (as :func:`relative_poses`)."""
    return relative_poses(np.array([[before, after]]), 0, 1)[0]


def nees_summary(values, dof: int) -> dict[str, float]:
    """Mean and median NEES over moments, and the share of moments whose truth lies inside each of the
    :data:`COVERAGE_LEVELS` ellipses (chi-square with ``dof`` degrees of freedom); a consistent belief
    gives a mean of ``dof`` and shares equal to the levels. The mean is over the finite values (an
    infinite NEES counts as outside every ellipse)."""
    v = np.asarray(values, dtype=np.float64)
    if v.size == 0:
        raise ValueError("no NEES values to summarise")
    finite = v[np.isfinite(v)]
    summary = {"moments": float(v.size), "mean": float(finite.mean()) if finite.size else math.inf,
               "median": float(np.median(v))}
    for level in COVERAGE_LEVELS:
        summary[f"inside_{round(100 * level)}"] = float(np.mean(v <= chi2.ppf(level, dof)))
    return summary


def honest_cloud_summary(particles: int, log_weight_sd: float, moments: int, rng: np.random.Generator,
                         dof: int = 2) -> dict[str, float]:
    """What :func:`nees_summary` gives for a cloud that is honest by construction: at each of ``moments``
    moments the truth and ``particles`` particles are drawn from one Gaussian in ``dof`` dimensions, with
    weights exp(``log_weight_sd`` * N(0, 1)) that are independent of the draws. The mean NEES of such a
    cloud is the Hotelling T^2's, above ``dof`` for a few particles, and its coverage below the levels: the
    most a filter of that many particles, with weights that uneven, can show. ``"neff"``: the median
    effective sample size (1 / sum w^2) of the weights."""
    if particles <= dof:
        raise ValueError(f"particles must be more than dof = {dof} (the covariance of {particles} is singular)")
    values, neffs = np.empty(moments), np.empty(moments)
    for k in range(moments):
        points = rng.standard_normal((particles, dof))
        weights = np.exp(log_weight_sd * rng.standard_normal(particles))
        weights /= weights.sum()
        mean = weights @ points
        deviations = points - mean
        values[k] = nees(rng.standard_normal(dof) - mean, (deviations * weights[:, None]).T @ deviations)
        neffs[k] = 1.0 / float(weights @ weights)
    return {**nees_summary(values, dof), "neff": float(np.median(neffs))}
