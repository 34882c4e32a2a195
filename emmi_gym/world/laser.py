"""A simulated 2D laser range finder: beams against the world's pymunk wall shapes, with noise."""

from __future__ import annotations

import math
from dataclasses import dataclass

import numba as nb
import numpy as np

from ..inputs.validation import MAX_LASER_RANGE, Integer, Real, check_fields, option
from ._raycast import capsule_grid, cast_rays

#: Upper bound of the beams: real scanners have at most a few thousand.
MAX_BEAMS = 10_000


@dataclass(frozen=True)
class LaserConfig:
    """Laser parameters. Defaults: a 360 deg, 180-beam, 8 m scanner with 2 cm range noise.

    ``drop_probability`` is the chance that a beam returns nothing (reported as
    ``max_range``, as real scanners report a missing echo).
    """

    fov: float = option(2.0 * math.pi, Real(0.0, 2.0 * math.pi, open_lo=True, unit="radians"),
                        help="field of view, centred ahead")
    n_beams: int = option(180, Integer(1, MAX_BEAMS, "each beam is cast at every simulator step"),
                          help="beams per scan, spread evenly over the field of view")
    max_range: float = option(8.0, Real(0.0, MAX_LASER_RANGE, open_lo=True, unit="m"),
                              help="range; a beam with no echo reads this")
    range_sigma: float = option(0.02, Real(0.0, 1.0, unit="m"),
                                help="Gaussian range noise, one sigma")
    drop_probability: float = option(0.01, Real(0.0, 1.0, open_hi=True),
                                     help="chance that a beam returns no echo (reads max_range)")

    def __post_init__(self):
        check_fields(self)

    @property
    def angles(self) -> np.ndarray:
        """Beam angles in the robot frame, counter-clockwise; a full circle has no repeated beam."""
        if math.isclose(self.fov, 2.0 * math.pi):
            return -math.pi + np.arange(self.n_beams) * (2.0 * math.pi / self.n_beams)
        if self.n_beams == 1:
            return np.zeros(1)
        return np.linspace(-self.fov / 2, self.fov / 2, self.n_beams)

    @property
    def angular_resolution(self) -> float:
        a = self.angles
        return float(a[1] - a[0]) if a.size > 1 else self.fov


class Laser:
    """Casts the configured beams from a pose against a set of capsules (the walls) inside ``bounds``
    (xmin, ymin, xmax, ymax), bucketed once (see :mod:`._raycast`)."""

    def __init__(self, config: LaserConfig, capsules: np.ndarray, bounds):
        self.config = config
        self.capsules = np.ascontiguousarray(capsules, dtype=np.float64)
        self._grid = capsule_grid(self.capsules, bounds)
        self._angles = config.angles
        self._buffer = np.empty(config.n_beams)

    def true_ranges(self, pose) -> np.ndarray:
        """Noise-free ranges from pose (x, y, theta); beams that hit nothing return max_range."""
        return self._cast(pose).copy()

    def _cast(self, pose) -> np.ndarray:
        """:meth:`true_ranges` in the laser's own buffer, which the next cast overwrites."""
        x, y, theta = pose
        cast_rays(float(x), float(y), self._angles + theta, self.config.max_range, self.capsules, *self._grid,
                  self._buffer)
        return self._buffer

    def scan(self, pose, rng: np.random.Generator) -> np.ndarray:
        """A noisy scan: Gaussian range noise on hits, clipped to [0, max_range]; dropped beams read max_range."""
        cfg = self.config
        ranges = self._cast(pose)
        normals = rng.standard_normal(ranges.size) if cfg.range_sigma > 0 else _NO_DRAWS
        uniforms = rng.random(ranges.size) if cfg.drop_probability > 0 else _NO_DRAWS
        return _noisy_ranges(ranges, normals, uniforms, cfg.range_sigma, cfg.drop_probability, cfg.max_range)


_NO_DRAWS = np.zeros(0)


@nb.njit(cache=True)
def _noisy_ranges(true_ranges, normals, uniforms, sigma, drop_probability, max_range):
    """Noisy readings of ``true_ranges``: a hit (below ``max_range``) plus ``sigma`` times its normal draw,
    clipped to [0, max_range]; a beam whose uniform draw is below ``drop_probability`` reads ``max_range``
    (no draws given: no noise, no drops)."""
    out = np.empty_like(true_ranges)
    for k in range(true_ranges.size):
        r = true_ranges[k]
        if r < max_range:
            if normals.size:
                r = min(max(r + sigma * normals[k], 0.0), max_range)
        else:
            r = max_range
        if uniforms.size and uniforms[k] < drop_probability:
            r = max_range
        out[k] = r
    return out
