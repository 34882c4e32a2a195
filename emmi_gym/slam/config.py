"""Parameters of the RBPF, with GMapping's and MRPT's names where they have one."""

from __future__ import annotations

import math
from dataclasses import dataclass, fields


@dataclass(frozen=True)
class RBPFConfig:
    """Everything that tunes the filter. Distances in metres, angles in radians.

    Inverse sensor model (the paper's Fig. 2, in log-odds of occupancy, eq. 4):
    ``logodds_occupied`` is added to the cell of a beam's end point, ``logodds_free``
    to every cell the beam crosses before it; cells stay within +-``logodds_clamp``.
    Log-odds are stored as int8 codes of ``logodds_step`` (MRPT's layout).
    """

    particles: int = 15
    resolution: float = 0.1
    # inverse sensor model
    # peaked, as the paper's Fig. 2 ("due to the sensor high accuracy"): one scan nearly
    # settles a cell, so a map's information reflects agreement more than repetition
    logodds_occupied: float = 2.0         # p = 0.88 for a hit
    logodds_free: float = -1.2            # p = 0.23 for a pass
    logodds_clamp: float = 6.0            # p in [0.0025, 0.9975]
    logodds_step: float = 0.05            # one int8 code
    # A max-range reading frees this far (0: ignore such beams). Off by default: a
    # dropped echo also reads max range, and freeing along it would erase walls.
    max_range_free: float = 0.0
    # motion model of the filter (per update), the four alphas of Thrun's table 5.6
    motion_alphas: tuple[float, float, float, float] = (0.03, 0.0008, 0.002, 0.0005)
    # update policy (GMapping's linearUpdate / angularUpdate)
    linear_update: float = 0.5
    angular_update: float = 0.3
    # scan matching and likelihood (GMapping's lstep/astep, iterations, kernelSize, lsigma, lskip)
    match_linear_step: float = 0.05
    match_angular_step: float = 0.05
    match_refinements: int = 3
    match_max_iterations: int = 60
    match_window: int = 1                 # cells searched around a beam's end point
    match_beam_skip: int = 1              # use every n-th beam for the proposal and the weights
    match_climb_skip: int = 6             # ... and every n-th of those while hill-climbing (coarse to fine)
    likelihood_sigma: float = 0.075
    min_match_fraction: float = 0.3       # fall back to odometry below this fraction of matched beams
    # weights: an exponent on the likelihood (MRPT's powFactor; GMapping's 1 / (ogain * M))
    likelihood_exponent: float = 0.0075
    resample_threshold: float = 0.5       # resample when Neff / M < this

    def __post_init__(self):
        positive = ("resolution", "logodds_occupied", "logodds_clamp", "logodds_step", "linear_update",
                    "angular_update", "match_linear_step", "match_angular_step", "likelihood_sigma",
                    "likelihood_exponent")
        for name in positive:
            value = getattr(self, name)
            if not (isinstance(value, (int, float)) and math.isfinite(value) and value > 0):
                raise ValueError(f"RBPF {name} must be a positive number, got {value!r}")
        if not self.logodds_free < 0:
            raise ValueError(f"RBPF logodds_free must be negative, got {self.logodds_free!r}")
        if self.logodds_clamp / self.logodds_step > 127:
            raise ValueError(f"logodds_clamp / logodds_step must fit int8 codes (<= 127), got "
                             f"{self.logodds_clamp / self.logodds_step:.0f}")
        for name in ("particles", "match_refinements", "match_max_iterations", "match_beam_skip",
                     "match_climb_skip"):
            value = getattr(self, name)
            if not (isinstance(value, int) and value >= 1):
                raise ValueError(f"RBPF {name} must be an integer >= 1, got {value!r}")
        if not (isinstance(self.match_window, int) and self.match_window >= 0):
            raise ValueError(f"RBPF match_window must be an integer >= 0, got {self.match_window!r}")
        if len(self.motion_alphas) != 4 or any(not (a >= 0) for a in self.motion_alphas):
            raise ValueError(f"RBPF motion_alphas must be four numbers >= 0, got {self.motion_alphas!r}")
        if not 0.0 <= self.max_range_free:
            raise ValueError(f"RBPF max_range_free must be >= 0, got {self.max_range_free!r}")
        if not 0.0 <= self.min_match_fraction <= 1.0:
            raise ValueError(f"RBPF min_match_fraction must be in [0, 1], got {self.min_match_fraction!r}")
        if not 0.0 <= self.resample_threshold <= 1.0:
            raise ValueError(f"RBPF resample_threshold must be in [0, 1], got {self.resample_threshold!r}")

    @classmethod
    def option_names(cls) -> list[str]:
        return [f.name for f in fields(cls)]
