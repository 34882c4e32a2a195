"""A simulated 2D laser range finder: beams against the world's pymunk wall shapes, with noise."""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ._raycast import cast_rays


@dataclass(frozen=True)
class LaserConfig:
    """Laser parameters. Defaults: a 360 deg, 180-beam, 8 m scanner with 2 cm range noise.

    ``drop_probability`` is the chance that a beam returns nothing (reported as
    ``max_range``, as real scanners report a missing echo).
    """

    fov: float = 2.0 * math.pi
    n_beams: int = 180
    max_range: float = 8.0
    range_sigma: float = 0.02
    drop_probability: float = 0.01

    def __post_init__(self):
        if not (0.0 < self.fov <= 2.0 * math.pi):
            raise ValueError(f"laser fov must be in (0, 2 pi] radians, got {self.fov!r}")
        if int(self.n_beams) != self.n_beams or self.n_beams < 1:
            raise ValueError(f"laser n_beams must be a positive integer, got {self.n_beams!r}")
        if not self.max_range > 0:
            raise ValueError(f"laser max_range must be positive, got {self.max_range!r}")
        if not self.range_sigma >= 0:
            raise ValueError(f"laser range_sigma must be >= 0, got {self.range_sigma!r}")
        if not 0.0 <= self.drop_probability < 1.0:
            raise ValueError(f"laser drop_probability must be in [0, 1), got {self.drop_probability!r}")

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
    """Casts the configured beams from a pose against a set of capsules (the walls)."""

    def __init__(self, config: LaserConfig, capsules: np.ndarray):
        self.config = config
        self.capsules = np.ascontiguousarray(capsules, dtype=np.float64)
        self._angles = config.angles
        self._buffer = np.empty(config.n_beams)

    def true_ranges(self, pose) -> np.ndarray:
        """Noise-free ranges from pose (x, y, theta); beams that hit nothing return max_range."""
        x, y, theta = pose
        cast_rays(float(x), float(y), self._angles + theta, self.config.max_range, self.capsules, self._buffer)
        return self._buffer.copy()

    def scan(self, pose, rng: np.random.Generator) -> np.ndarray:
        """A noisy scan: Gaussian range noise on hits, clipped to [0, max_range]; dropped beams read max_range."""
        cfg = self.config
        ranges = self.true_ranges(pose)
        hit = ranges < cfg.max_range
        noise = rng.normal(0.0, cfg.range_sigma, ranges.size) if cfg.range_sigma > 0 else 0.0
        ranges = np.where(hit, np.clip(ranges + noise, 0.0, cfg.max_range), cfg.max_range)
        if cfg.drop_probability > 0:
            ranges[rng.random(ranges.size) < cfg.drop_probability] = cfg.max_range
        return ranges
