"""The consistency checks of a particle set against the truth (NEES, ellipse coverage, relative motions)."""

import math

import numpy as np
import pytest
from scipy.stats import chi2
from scipy.stats import f as f_distribution

from emmi_gym.scoring.calibration import (
    check_pose,
    honest_cloud_summary,
    nees,
    nees_summary,
    pose_moments,
    relative_poses,
    true_relative_pose,
)


def _clouds(rng, scale: float, moments: int = 400, particles: int = 400):
    """``moments`` clouds of equally weighted particles from N(mu, P), each with a truth drawn from
    N(mu, (scale^2) P): an honest belief for scale 1, an over-confident one above."""
    covariance = np.array([[0.04, 0.01, 0.002], [0.01, 0.02, -0.001], [0.002, -0.001, 0.003]])
    chol = np.linalg.cholesky(covariance)
    checks = []
    for _ in range(moments):
        mean = np.array([rng.uniform(-5, 5), rng.uniform(-5, 5), rng.uniform(-math.pi, math.pi)])
        poses = mean + rng.standard_normal((particles, 3)) @ chol.T
        truth = mean + scale * chol @ rng.standard_normal(3)
        checks.append(check_pose(poses, np.full(particles, 1.0 / particles), truth))
    return checks


def test_an_honest_cloud_gives_the_chi_square_figures():
    """Truth drawn from the particles' own distribution: mean NEES 2 in (x, y) and 3 in (x, y, theta), the truth
    inside the p-ellipse a share p of the time, the spread equal to the error (RMS)."""
    checks = _clouds(np.random.default_rng(0), scale=1.0)
    xy = nees_summary([c.nees_xy for c in checks], 2)
    pose = nees_summary([c.nees_pose for c in checks], 3)
    assert xy["mean"] == pytest.approx(2.0, abs=0.3) and pose["mean"] == pytest.approx(3.0, abs=0.4)
    for level in (50, 90, 95):
        assert xy[f"inside_{level}"] == pytest.approx(level / 100, abs=0.06)
        assert pose[f"inside_{level}"] == pytest.approx(level / 100, abs=0.06)
    spread = math.sqrt(np.mean([c.spread ** 2 for c in checks]))
    error = math.sqrt(np.mean([c.error ** 2 for c in checks]))
    assert error == pytest.approx(spread, rel=0.15)


def test_a_cloud_three_times_too_sure_shows_it():
    """Errors three times the spread: NEES nine times the degrees of freedom, the truth mostly outside."""
    checks = _clouds(np.random.default_rng(1), scale=3.0)
    xy = nees_summary([c.nees_xy for c in checks], 2)
    assert xy["mean"] == pytest.approx(18.0, rel=0.2)
    assert xy["inside_95"] < 0.5


def test_the_heading_is_averaged_round_the_circle():
    """Particles either side of +-pi: their mean heading is pi, not 0, and the spread is theirs."""
    poses = np.array([[0.0, 0.0, math.pi - 0.01], [0.0, 0.0, -math.pi + 0.01]])
    mean, covariance = pose_moments(poses, np.array([0.5, 0.5]))
    assert abs(abs(mean[2]) - math.pi) < 1e-9
    assert covariance[2, 2] == pytest.approx(1e-4)
    check = check_pose(poses + [[0.0, 0.1, 0.0], [0.0, -0.1, 0.0]], np.array([0.5, 0.5]), [0.0, 0.0, math.pi])
    assert math.isfinite(check.nees_pose) and check.error == pytest.approx(0.0)


def test_a_belief_that_rules_the_truth_out_counts_as_outside():
    """All particles on one pose and the truth elsewhere: an infinite NEES, outside every ellipse."""
    assert nees([0.1, 0.0], np.zeros((2, 2))) == math.inf
    assert nees([0.0, 0.0], np.zeros((2, 2))) == 0.0
    summary = nees_summary([1.0, math.inf], 2)
    assert summary["mean"] == 1.0 and summary["inside_95"] == 0.5


def test_relative_motions_do_not_depend_on_the_map_frame():
    """The relative pose of every particle, and the truth's, are the same after the whole map is moved."""
    rng = np.random.default_rng(2)
    paths = rng.normal(size=(5, 8, 3))
    turn, shift = 0.7, np.array([3.0, -2.0])
    c, s = math.cos(turn), math.sin(turn)
    moved = paths.copy()
    moved[..., 0] = c * paths[..., 0] - s * paths[..., 1] + shift[0]
    moved[..., 1] = s * paths[..., 0] + c * paths[..., 1] + shift[1]
    moved[..., 2] = paths[..., 2] + turn
    np.testing.assert_allclose(relative_poses(moved, 2), relative_poses(paths, 2), atol=1e-12)
    np.testing.assert_allclose(true_relative_pose(moved[0, 2], moved[0, -1]), relative_poses(paths, 2)[0], atol=1e-12)


def test_no_moments_is_an_error():
    with pytest.raises(ValueError, match="no NEES"):
        nees_summary([], 2)


def test_an_honest_cloud_of_many_particles_scores_chi_square_and_of_few_the_hotelling_t2():
    many = honest_cloud_summary(1000, 0.0, 3000, np.random.default_rng(0))
    assert abs(many["mean"] - 2.0) < 0.15 and abs(many["inside_95"] - 0.95) < 0.015
    few = honest_cloud_summary(15, 0.0, 3000, np.random.default_rng(0))
    # normalised by the weights' sum (by M), the NEES is d (M + 1) / (M - d) times F(d, M - d) (Hotelling's
    # T^2): mean d (M + 1) / (M - d - 2) = 2.91, and the truth inside the chi-square 95% ellipse at 87.3%
    assert abs(few["mean"] - 2 * 16 / 11) < 0.3
    assert abs(few["inside_95"] - f_distribution.cdf(chi2.ppf(0.95, 2) * 13 / 32, 2, 13)) < 0.02
    uneven = honest_cloud_summary(15, 2.0, 3000, np.random.default_rng(0))
    assert uneven["neff"] < 5 and uneven["inside_95"] < few["inside_95"] - 0.15
    with pytest.raises(ValueError, match="more than dof"):
        honest_cloud_summary(2, 0.0, 10, np.random.default_rng(0))
