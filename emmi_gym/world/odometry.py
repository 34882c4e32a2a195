"""Noisy odometry: the odometry motion model of :mod:`emmi_gym.geometry.motion` plus a systematic drift.

A relative motion is split into (rot1, trans, rot2); each part is perturbed with
zero-mean Gaussian noise whose variance grows with the motion (the four alphas), and
a systematic heading drift per metre travelled is added (a wheel-radius mismatch).
The noise is drawn once per control period, so the alphas are per control period.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..geometry.motion import perturb_motion
from ..inputs.validation import Real, check_fields, option

#: Upper bound of each alpha: at 1 a motion's noise is as large as the motion itself (the
#: defaults are 0.0005-0.02); beyond, dead reckoning is meaningless and poses run off to 1e100s.
MAX_ALPHA = 1.0


@dataclass(frozen=True)
class OdometryNoise:
    """The four alphas of the odometry model and a systematic heading drift.

    - ``rot_from_rot`` (alpha1, rad^2/rad^2), ``rot_from_trans`` (alpha2, rad^2/m^2),
    - ``trans_from_trans`` (alpha3, m^2/m^2), ``trans_from_rot`` (alpha4, m^2/rad^2),
    - ``heading_drift`` (rad per metre travelled, signed).

    The defaults (with the 0.1 s control period) leave dead reckoning metres off after the
    74 m ``loop_corridor`` loop, so that closing it matters; ``measurements/odometry_drift.py``
    measures the drift of each preset.
    """

    rot_from_rot: float = option(0.02, Real(0.0, MAX_ALPHA),
                                 help="alpha1: rotation noise from rotation (rad^2/rad^2)")
    rot_from_trans: float = option(0.003, Real(0.0, MAX_ALPHA),
                                   help="alpha2: rotation noise from translation (rad^2/m^2)")
    trans_from_trans: float = option(0.01, Real(0.0, MAX_ALPHA),
                                     help="alpha3: translation noise from translation (m^2/m^2)")
    trans_from_rot: float = option(0.0005, Real(0.0, MAX_ALPHA),
                                   help="alpha4: translation noise from rotation (m^2/rad^2)")
    heading_drift: float = option(0.0015, Real(-1.0, 1.0, unit="rad/m"),
                                  help="systematic heading drift per metre travelled, signed (a wheel-radius mismatch)")

    def __post_init__(self):
        check_fields(self)

    @property
    def alphas(self) -> tuple[float, float, float, float]:
        return (self.rot_from_rot, self.rot_from_trans, self.trans_from_trans, self.trans_from_rot)


def noisy_motion(rot1: float, trans: float, rot2: float, noise: OdometryNoise,
                 rng: np.random.Generator) -> tuple[float, float, float]:
    """What the odometer reports for a true motion (rot1, trans, rot2): the model's noise plus drift."""
    r1, t, r2 = perturb_motion(rot1, trans, rot2, noise.alphas, rng.standard_normal(3))
    return float(r1), float(t), float(r2) + noise.heading_drift * abs(trans)
