"""The odometry motion model (Thrun et al., Probabilistic Robotics, sec. 5.4), shared by the
simulator (to corrupt true motion) and the RBPF (to propagate particles).

A relative motion is (rot1, trans, rot2): turn by rot1, drive trans, turn by rot2.
The four alphas scale the variances: rot from rot (alpha1, rad^2/rad^2), rot from
trans (alpha2, rad^2/m^2), trans from trans (alpha3, m^2/m^2), trans from rot
(alpha4, m^2/rad^2) — table 5.6 of the book.
"""

from __future__ import annotations

import math

import numpy as np


def wrap_angle(a):
    """Wrap angles to [-pi, pi)."""
    return (np.asarray(a) + math.pi) % (2.0 * math.pi) - math.pi


#: Below this translation (m) a motion is a turn on the spot: rot1 is 0, not the direction of a
#: few microns of jitter, whose arbitrary angle would scale the rotation noise (as in AMCL).
MIN_TRANSLATION = 0.01


def relative_motion(before, after) -> tuple[float, float, float]:
    """(rot1, trans, rot2) taking pose ``before`` to ``after``; trans < 0 for backward motion.

    Below ``MIN_TRANSLATION`` the whole turn goes to rot2 and the (tiny) translation is
    taken along the initial heading.
    """
    dx, dy = after[0] - before[0], after[1] - before[1]
    trans = math.hypot(dx, dy)
    if trans < MIN_TRANSLATION:
        along = dx * math.cos(before[2]) + dy * math.sin(before[2])
        return 0.0, along, float(wrap_angle(after[2] - before[2]))
    rot1 = float(wrap_angle(math.atan2(dy, dx) - before[2]))
    if abs(rot1) > math.pi / 2:  # moving backwards: keep the rotations small
        rot1 = float(wrap_angle(rot1 + math.pi))
        trans = -trans
    rot2 = float(wrap_angle(after[2] - before[2] - rot1))
    return rot1, trans, rot2


def compose_motion(poses, rot1, trans, rot2) -> np.ndarray:
    """Apply (rot1, trans, rot2) to pose(s) (..., 3); the motion may be arrays broadcasting with them."""
    poses = np.asarray(poses, dtype=np.float64)
    heading = poses[..., 2] + rot1
    out = np.empty(np.broadcast_shapes(poses.shape, np.shape(heading) + (3,)))
    out[..., 0] = poses[..., 0] + trans * np.cos(heading)
    out[..., 1] = poses[..., 1] + trans * np.sin(heading)
    out[..., 2] = wrap_angle(heading + rot2)
    return out


def motion_std(rot1, trans, rot2, alphas) -> tuple:
    """Standard deviations of (rot1, trans, rot2) under the model (table 5.6)."""
    a1, a2, a3, a4 = alphas
    return (np.sqrt(a1 * rot1 ** 2 + a2 * trans ** 2),
            np.sqrt(a3 * trans ** 2 + a4 * (rot1 ** 2 + rot2 ** 2)),
            np.sqrt(a1 * rot2 ** 2 + a2 * trans ** 2))


def perturb_motion(rot1: float, trans: float, rot2: float, alphas, normals: np.ndarray):
    """(rot1, trans, rot2) perturbed by standard normals (..., 3) scaled by the model's deviations."""
    s1, st, s2 = motion_std(rot1, trans, rot2, alphas)
    normals = np.asarray(normals)
    return rot1 + normals[..., 0] * s1, trans + normals[..., 1] * st, rot2 + normals[..., 2] * s2
