"""Named sensor and odometry settings: lasers after real scanners' datasheets, odometry of three qualities.

``gym.make(..., laser="sick_lms200", odometry_noise="poor")``; a dict picks a preset with its
``preset`` key and changes any field: ``laser={"preset": "hokuyo_urg04lx", "max_range": 4.0}``.

Lasers (field of view, beams, range, range noise 1 sigma, share of beams without echo):

- ``default``: 360 deg, 180 beams (2 deg), 8 m, 2 cm, 1% (a generic 2D lidar);
- ``sick_lms200``: 180 deg, 181 beams (1 deg), 30 m (the datasheet's range at 10%
  reflectivity; 80 m at best), 1 cm (systematic +-15 mm, statistical 5 mm), 0.5%: the
  scanner of the Radish logs (Intel, ACES, Freiburg);
- ``hokuyo_urg04lx``: 240 deg, 683 beams (0.352 deg), 5.6 m, 3 cm (1% of range), 1%;
- ``rplidar_a1``: 360 deg, 360 beams (1 deg), 12 m, 5 cm (under 2.5% of range), 2%.

Odometry (:class:`~emmi_gym.world.OdometryNoise` alphas per 0.1 s control period and heading
drift per metre): ``typical`` is the default; ``good`` a quarter of its noise and a third of its
drift (well-calibrated encoders on a hard floor); ``poor`` four times its noise and drift (carpet,
slipping wheels). ``measurements/odometry_drift.py --preset all`` measures each one's dead-reckoning
error after 100 m.
"""

from __future__ import annotations

import math

from ..inputs.validation import Options, check_value
from .laser import LaserConfig
from .odometry import OdometryNoise

LASER_PRESETS = {
    "default": {},
    "sick_lms200": dict(fov=math.pi, n_beams=181, max_range=30.0, range_sigma=0.01, drop_probability=0.005),
    "hokuyo_urg04lx": dict(fov=math.radians(240.0), n_beams=683, max_range=5.6, range_sigma=0.03,
                           drop_probability=0.01),
    "rplidar_a1": dict(fov=2.0 * math.pi, n_beams=360, max_range=12.0, range_sigma=0.05, drop_probability=0.02),
}

_TYPICAL = OdometryNoise()
ODOMETRY_PRESETS = {
    "good": dict(rot_from_rot=_TYPICAL.rot_from_rot / 4, rot_from_trans=_TYPICAL.rot_from_trans / 4,
                 trans_from_trans=_TYPICAL.trans_from_trans / 4, trans_from_rot=_TYPICAL.trans_from_rot / 4,
                 heading_drift=_TYPICAL.heading_drift / 3),
    "typical": {},
    "poor": dict(rot_from_rot=_TYPICAL.rot_from_rot * 4, rot_from_trans=_TYPICAL.rot_from_trans * 4,
                 trans_from_trans=_TYPICAL.trans_from_trans * 4, trans_from_rot=_TYPICAL.trans_from_rot * 4,
                 heading_drift=_TYPICAL.heading_drift * 4),
}


#: The ``laser`` and ``odometry_noise`` options: a preset's name, a dict of fields (with an optional ``preset``
#: they change) or the dataclass itself, built.
LASER_OPTIONS = Options(LaserConfig, LASER_PRESETS)
ODOMETRY_OPTIONS = Options(OdometryNoise, ODOMETRY_PRESETS)


def laser_config(value, label: str = "laser", source: str = "option") -> LaserConfig:
    """A :class:`LaserConfig` from a preset name (:data:`LASER_PRESETS`) or a dict of fields (``None``: the
    defaults); a mistake raises an ``OptionError`` naming ``source`` and the field ``label.name``."""
    return check_value({} if value is None else value, LASER_OPTIONS, source, label)


def odometry_config(value, label: str = "odometry_noise", source: str = "option") -> OdometryNoise:
    """An :class:`OdometryNoise` from a preset name (:data:`ODOMETRY_PRESETS`) or a dict of fields (``None``: the
    defaults), as :func:`laser_config`."""
    return check_value({} if value is None else value, ODOMETRY_OPTIONS, source, label)
