"""Odometry motion models.

The simulator corrupts true motion with the odometry model of Thrun et al.
(Probabilistic Robotics, sec. 5.4): a relative motion is (rot1, trans, rot2), turn by
rot1, drive trans, turn by rot2, and four alphas scale the variances: rot from rot
(alpha1, rad^2/rad^2), rot from trans (alpha2, rad^2/m^2), trans from trans (alpha3,
m^2/m^2), trans from rot (alpha4, m^2/rad^2), table 5.6 of the book.

The RBPF propagates particles with GMapping's model in the robot's frame (dx, dy,
dtheta), see :func:`local_motion_std`: it has no rot1 to inflate when a keyframe's
translation is short or sideways, as real logs' keyframes often are.
"""

from __future__ import annotations

import math

import numpy as np


def wrap_angle(a):
    """Wrap angles to [-pi, pi). A float in, a float out (the same number as NumPy's, without its call cost:
    both take the remainder of C's fmod, made to carry the divisor's sign)."""
    if isinstance(a, float):
        return (a + math.pi) % (2.0 * math.pi) - math.pi
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
    if poses.shape == (3,) and all(isinstance(m, float) for m in (rot1, trans, rot2)):
        return _compose_one(*poses.tolist(), rot1, trans, rot2)
    heading = poses[..., 2] + rot1
    out = np.empty(np.broadcast_shapes(poses.shape, np.shape(heading) + (3,)))
    out[..., 0] = poses[..., 0] + trans * np.cos(heading)
    out[..., 1] = poses[..., 1] + trans * np.sin(heading)
    out[..., 2] = wrap_angle(heading + rot2)
    return out


def _compose_one(x: float, y: float, theta: float, rot1: float, trans: float, rot2: float) -> np.ndarray:
    """:func:`compose_motion` of one pose by one motion, in floats: the same numbers (the simulator's
    odometry, every step), a fifth of the time."""
    heading = theta + rot1
    return np.array([x + trans * math.cos(heading), y + trans * math.sin(heading), wrap_angle(heading + rot2)])


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


# ----------------------------------------------------------------------------- robot-frame model


def local_delta(before, after) -> np.ndarray:
    """The motion from pose ``before`` to ``after`` in ``before``'s frame: (dx, dy, dtheta)."""
    dx, dy = after[0] - before[0], after[1] - before[1]
    c, s = math.cos(before[2]), math.sin(before[2])
    return np.array([c * dx + s * dy, -s * dx + c * dy, float(wrap_angle(after[2] - before[2]))])


def compose_local(poses, delta) -> np.ndarray:
    """Poses (..., 3) moved by robot-frame motions ``delta`` (..., 3) (broadcasting): pose ⊕ delta."""
    poses = np.asarray(poses, dtype=np.float64)
    delta = np.asarray(delta, dtype=np.float64)
    if poses.shape == delta.shape == (3,):  # one pose (the pose estimate, every step): in floats, the same numbers
        (x, y, theta), (dx, dy, dtheta) = poses.tolist(), delta.tolist()
        c, s = math.cos(theta), math.sin(theta)
        return np.array([x + c * dx - s * dy, y + s * dx + c * dy, wrap_angle(theta + dtheta)])
    c, s = np.cos(poses[..., 2]), np.sin(poses[..., 2])
    out = np.empty(np.broadcast_shapes(poses.shape, delta.shape))
    out[..., 0] = poses[..., 0] + c * delta[..., 0] - s * delta[..., 1]
    out[..., 1] = poses[..., 1] + s * delta[..., 0] + c * delta[..., 1]
    out[..., 2] = wrap_angle(poses[..., 2] + delta[..., 2])
    return out


def local_motion_std(delta, noise) -> np.ndarray:
    """Standard deviations of (dx, dy, dtheta) for a robot-frame motion, GMapping's motion model
    (``MotionModel::drawFromMotion``, Grisetti et al. 2007).

    ``noise`` = (srr, srt, str, stt): translation from translation (m/m), rotation from
    translation (rad/m), translation from rotation (m/rad), rotation from rotation
    (rad/rad); the cross-axis term uses 0.3 * srr, as GMapping. Deviations grow linearly
    with the motion, and no part depends on the direction of a short translation: a turn
    on the spot of a laser mounted ahead of the axle (a sideways move of the laser) gets
    the noise of a turn, not that of a 90-degree heading change followed by a drive, as
    the rot1-trans-rot2 split of :func:`motion_std` gives it.
    """
    srr, srt, str_, stt = noise
    dx, dy, dth = np.abs(delta[0]), np.abs(delta[1]), np.abs(delta[2])
    sxy = 0.3 * srr
    return np.array([srr * dx + str_ * dth + sxy * dy,
                     srr * dy + str_ * dth + sxy * dx,
                     stt * dth + srt * math.hypot(dx, dy)])


def interpolate_poses(times: np.ndarray, poses: np.ndarray, at) -> np.ndarray:
    """Poses (len(at), 3) at the times ``at``, linear between the two samples around each (the heading along
    the shorter turn), as tf2 interpolates a transform between two stamps; NaN outside ``[times[0],
    times[-1]]`` (no extrapolation). ``times`` ascending (ties: the last sample of a time counts). A time
    equal to a sample's gives that sample's pose bit for bit; headings are not wrapped again."""
    times, poses, at = np.asarray(times, dtype=np.float64), np.asarray(poses, dtype=np.float64), np.asarray(at)
    k = np.clip(np.searchsorted(times, at, side="right") - 1, 0, times.size - 1)
    after = np.minimum(k + 1, times.size - 1)
    span = times[after] - times[k]
    w = np.where(span > 0.0, (at - times[k]) / np.where(span > 0.0, span, 1.0), 0.0)[:, None]
    step = poses[after] - poses[k]
    step[:, 2] = wrap_angle(step[:, 2])
    out = np.where(w > 0.0, poses[k] + w * step, poses[k])
    out[(at < times[0]) | (at > times[-1])] = np.nan
    return out
