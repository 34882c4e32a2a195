"""Pose, path and joint entropy of a particle set (the measures EMMI is compared with)."""

from __future__ import annotations

import math

import numpy as np

from . import _kernels
from .expected_map import joint_entropy_of_parts
from .grids import ParticleGrids
from .weights import normalize_weights

#: Floor on det(Sigma) (m^2 m^2 rad^2) so that a collapsed particle set (one particle,
#: or all particles on one pose) has a finite entropy: 1e-18 is the determinant of
#: independent standard deviations of 1 mm, 1 mm and 1 mrad (entropy -16.5 nats).
DEFAULT_DET_FLOOR = 1e-18

_LOG_2PIE_3 = 3.0 * math.log(2.0 * math.pi * math.e)


def _check_poses(poses, last_dims: int, name: str) -> np.ndarray:
    a = np.asarray(poses, dtype=np.float64)
    if a.ndim != last_dims or a.shape[-1] != 3:
        raise ValueError(f"{name} must have shape {'(M, 3)' if last_dims == 2 else '(M, T, 3)'}, got {a.shape}")
    if not np.isfinite(a).all():
        raise ValueError(f"{name} must be finite")
    return a


def _checked_paths(paths, weights, log_weights: bool) -> tuple[np.ndarray, np.ndarray]:
    """Paths (M, T >= 1, 3) and their M normalised weights, or a ValueError saying what is wrong."""
    p = _check_poses(paths, 3, "paths")
    w = normalize_weights(weights, log=log_weights)
    if w.shape[0] != p.shape[0]:
        raise ValueError(f"{p.shape[0]} paths but {w.shape[0]} weights")
    if p.shape[1] == 0:
        raise ValueError("paths must hold at least one pose")
    return p, w


def pose_entropy(poses, weights, *, log_weights: bool = False, det_floor: float = DEFAULT_DET_FLOOR) -> float:
    """Differential entropy (nats) of a Gaussian fitted to weighted particle poses.

    ``H = 0.5 ln((2 pi e)^3 det Sigma)`` over (x, y, theta), the pose-uncertainty
    measure the paper compares EMMI with (its refs. [4], [12], [18]); theta is taken
    about its circular mean and wrapped to (-pi, pi]; ``det Sigma`` is floored at
    ``det_floor``.
    """
    p = _check_poses(poses, 2, "poses")
    w = normalize_weights(weights, log=log_weights)
    if w.shape[0] != p.shape[0]:
        raise ValueError(f"{p.shape[0]} poses but {w.shape[0]} weights")
    p = p[:, None, :]
    return float(_kernels.pose_entropies(p, heading_sincos(p), w, det_floor, _LOG_2PIE_3)[0])


def path_entropy(paths, weights, *, log_weights: bool = False, det_floor: float = DEFAULT_DET_FLOOR) -> float:
    """Path entropy (nats): the pose entropy averaged over the T poses of the paths (M, T, 3).

    The approximation of the path posterior's entropy of Stachniss et al. (2005),
    used as the first term of the joint entropy, eq. (12).
    """
    p, _ = _checked_paths(paths, weights, log_weights)
    return path_entropy_of_parts(p, heading_sincos(p), weights, log_weights=log_weights, det_floor=det_floor)


def heading_sincos(poses) -> np.ndarray:
    """(..., 2) sines and cosines of the headings of poses (..., 3), as :func:`path_entropy_of_parts`
    takes them."""
    p = np.asarray(poses, dtype=np.float64)
    out = np.empty(p.shape[:-1] + (2,))
    _kernels.heading_sincos(np.ascontiguousarray(p[..., 2]), out)
    return out


def path_entropy_of_parts(paths, sincos, weights, *, log_weights: bool = False,
                          det_floor: float = DEFAULT_DET_FLOOR) -> float:
    """:func:`path_entropy` of paths (M, T, 3) whose headings' sines and cosines (M, T, 2) the caller keeps
    (:func:`heading_sincos`, computed once per pose as a path grows, not at every call: a third of the
    time of the sum over the path, which grows with it). The arrays are not checked."""
    w = normalize_weights(weights, log=log_weights)
    return float(_kernels.pose_entropies(paths, sincos, w, det_floor, _LOG_2PIE_3).mean())


def joint_entropy(paths, grids, weights, *, logodds: bool = False, lut=None, log_weights: bool = False,
                  det_floor: float = DEFAULT_DET_FLOOR) -> float:
    """Joint path-map entropy, eq. (12) (Stachniss et al. 2005), in nats.

    ``H(x_1:n) + sum_i w_i H(m_i)``: the path entropy plus the weighted entropies of
    the particles' own maps (eq. 8, converted from bits to nats so that both terms
    share a unit). Each map is scored on its own, so contradicting particles count as
    certain (the paper's Fig. 5).
    """
    w = normalize_weights(weights, log=log_weights)
    maps = ParticleGrids.from_arrays(grids, w, logodds=logodds, lut=lut)
    return joint_entropy_of_parts(path_entropy(paths, w, det_floor=det_floor), maps.entropies_bits(), w)


def loop_displacement_spread(paths, weights, since: int, *, log_weights: bool = False) -> float:
    """How uncertain the filter is about where the robot is relative to its pose at update ``since`` (m).

    The square root of the trace of the weighted covariance, over particles, of
    ``x_T - x_since`` (positions, each particle in its own path): what revisiting that
    pose and closing the loop can resolve. Each particle is sure of its own map, so the
    spread shows in EMMI (the mean information, eq. 10, of the expected map) only once the
    loop is closed: the robot back in view of a place that the particles put in different
    relative positions.
    """
    p = _check_poses(paths, 3, "paths")
    w = normalize_weights(weights, log=log_weights)
    if not -p.shape[1] <= since < p.shape[1]:
        raise ValueError(f"since={since} is not an update index of paths with {p.shape[1]} updates")
    return float(_displacement_spreads(p[:, -1, :2], p[:, [since], :2], w)[0])


def widest_loop_spread(paths, weights, *, log_weights: bool = False) -> float:
    """The largest :func:`loop_displacement_spread` over every earlier update of the paths (M, T, 3), m.

    How far apart the particles put the robot relative to the place of the path they disagree on most:
    the widest loop still open. It grows as odometry drifts (hardly while the robot stands or
    spins) and falls when a closed loop (or a resampling that keeps one lineage) makes the particles agree
    on where they are relative to where they have been. 0 for a single pose or particles that agree.
    """
    p, w = _checked_paths(paths, weights, log_weights)
    return float(_displacement_spreads(p[:, -1, :2], p[:, :, :2], w).max())


def _displacement_spreads(now: np.ndarray, then: np.ndarray, w: np.ndarray) -> np.ndarray:
    """(T,) the weighted spread, sqrt(sum_i w_i |d_ik - mean_i d_ik|^2), of d_ik = now_i - then_ik: positions
    now (M, 2) and at T earlier updates (M, T, 2)."""
    displacement = now[:, None, :] - then
    centred = displacement - np.einsum("i,itd->td", w, displacement)
    return np.sqrt(np.maximum(np.einsum("i,it->t", w, np.sum(centred ** 2, axis=2)), 0.0))
