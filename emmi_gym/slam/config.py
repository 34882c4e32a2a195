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
    # Echoes beyond insertion_range only free the cells up to it (GMapping's maxUrange), and
    # beams beyond matching_range are left out of the matching and the weights; None: the
    # sensor's range. Long beams fix the heading: limit the insertion, not the matching.
    insertion_range: float | None = None
    matching_range: float | None = None
    # motion model of the filter, GMapping's (srr, srt, str, stt): translation from translation
    # (m/m), rotation from translation (rad/m), translation from rotation (m/rad), rotation
    # from rotation (rad/rad), deviations in the robot's frame (see motion.local_motion_std)
    motion_noise: tuple[float, float, float, float] = (0.05, 0.03, 0.02, 0.1)
    # update policy (GMapping's linearUpdate / angularUpdate); 0 and 0: every scan an update
    linear_update: float = 0.5
    angular_update: float = 0.3
    # scan matching (see _matching): GMapping's lstep / astep / iterations, a search radius in
    # metres around each end point, and a coarse stage on blocks of about coarse_resolution
    match_linear_step: float = 0.05
    match_angular_step: float = 0.05
    match_refinements: int = 3
    match_max_iterations: int = 60
    match_radius: float = 0.15            # beyond this an end point counts as unmatched
    # beams used while hill-climbing, evenly spread over the scan (GMapping climbs on all of
    # them; with 30 of a 180-degree scan the heading wanders and ACES is lost)
    match_climb_beams: int = 60
    coarse_resolution: float = 0.2        # block side of the coarse stage (a whole number of cells)
    coarse_angular_step: float = 0.05     # first heading step of the coarse climb
    coarse_trigger: float = 0.6           # run the coarse stage below this fraction of matched beams
    # likelihood and weights
    likelihood_sigma: float = 0.075
    # an end point with no surface within match_radius scores as if it were this far off
    # (GMapping's nullLikelihood): the cost of a beam that sees a wall where the map has none
    likelihood_null_distance: float = 0.2
    # radians between the beams of the likelihood: neighbouring beams see the same surface
    # and their errors are not independent (Thrun et al. 2005, sec. 6.4, subsample the beams)
    likelihood_beam_spacing: float = 0.035
    min_match_fraction: float = 0.3       # fall back to odometry below this fraction of matched beams
    # weights: an exponent on the likelihood (MRPT's powFactor; GMapping's 1 / (ogain * M)),
    # chosen by measurement (docs/slam.md): at 0.003 the loop_corridor loop closes without a
    # resampling before it on 19 of 20 seeds, but the closure then resolves too little of
    # the particles' disagreement for the A/B experiment to see it in EMMI; at 0.0075 it
    # does (and ACES and Intel end 0.05-0.26 m off), at the price of about one resampling
    # before the closure.
    likelihood_exponent: float = 0.0075
    resample_threshold: float = 0.5       # resample when Neff / M < this

    def __post_init__(self):
        positive = ("resolution", "logodds_occupied", "logodds_clamp", "logodds_step", "match_linear_step",
                    "match_angular_step", "match_radius", "coarse_resolution",
                    "coarse_angular_step", "likelihood_sigma", "likelihood_null_distance", "likelihood_beam_spacing",
                    "likelihood_exponent")
        for name in positive:
            value = getattr(self, name)
            if not (isinstance(value, (int, float)) and math.isfinite(value) and value > 0):
                raise ValueError(f"RBPF {name} must be a positive number, got {value!r}")
        for name in ("insertion_range", "matching_range"):
            value = getattr(self, name)
            if value is not None and not (isinstance(value, (int, float)) and value > 0):
                raise ValueError(f"RBPF {name} must be a positive number or None (the sensor's range), "
                                 f"got {value!r}")
        if not self.logodds_free < 0:
            raise ValueError(f"RBPF logodds_free must be negative, got {self.logodds_free!r}")
        if self.logodds_clamp / self.logodds_step > 127:
            raise ValueError(f"logodds_clamp / logodds_step must fit int8 codes (<= 127), got "
                             f"{self.logodds_clamp / self.logodds_step:.0f}")
        for name in ("linear_update", "angular_update"):
            value = getattr(self, name)
            if not (isinstance(value, (int, float)) and math.isfinite(value) and value >= 0):
                raise ValueError(f"RBPF {name} must be a number >= 0, got {value!r}")
        for name in ("particles", "match_refinements", "match_max_iterations", "match_climb_beams"):
            value = getattr(self, name)
            if not (isinstance(value, int) and value >= 1):
                raise ValueError(f"RBPF {name} must be an integer >= 1, got {value!r}")
        if len(self.motion_noise) != 4 or any(not (isinstance(a, (int, float)) and 0 <= a < math.inf)
                                              for a in self.motion_noise):
            raise ValueError(f"RBPF motion_noise must be four finite numbers >= 0, got {self.motion_noise!r}")
        if not 0.0 <= self.max_range_free:
            raise ValueError(f"RBPF max_range_free must be >= 0, got {self.max_range_free!r}")
        if not 0.0 <= self.coarse_trigger <= 1.0:
            raise ValueError(f"RBPF coarse_trigger must be in [0, 1], got {self.coarse_trigger!r}")
        if not 0.0 <= self.min_match_fraction <= 1.0:
            raise ValueError(f"RBPF min_match_fraction must be in [0, 1], got {self.min_match_fraction!r}")
        if not 0.0 <= self.resample_threshold <= 1.0:
            raise ValueError(f"RBPF resample_threshold must be in [0, 1], got {self.resample_threshold!r}")

    def coarse_block(self) -> int:
        """Cells per side of a coarse block: ``coarse_resolution`` in whole cells (at least 1)."""
        return max(1, int(round(self.coarse_resolution / self.resolution)))

    @classmethod
    def preset(cls, name: str, **overrides) -> "RBPFConfig":
        """A configuration from :data:`PRESETS` (GMapping ships such files per sensor), with ``overrides``."""
        if name not in PRESETS:
            raise ValueError(f"unknown RBPF preset {name!r}; the presets are {sorted(PRESETS)}")
        return cls(**{**PRESETS[name], **overrides})

    @classmethod
    def option_names(cls) -> list[str]:
        return [f.name for f in fields(cls)]


#: Named settings for other robots than the simulator's (the defaults). ``radish-noisy``: the
#: classic CARMEN logs (SICK LMS, 180 degrees, keyframes) with the odometry noise of
#: ``shared/datasets/radish-noisy`` (alphas 0.0004, 0.0001, 0.0004, 0.0001, a heading drift of
#: 0.002 rad/m, a 1% scale error), smaller than the simulator's, so a tighter motion model (with
#: the defaults ACES ends 1.5-2.4 m off, with GMapping's own 0.1, 0.2, 0.1, 0.2 it is lost);
#: 90 climbing beams (a 180-degree scan pins the heading less than a 360-degree one); and
#: tempering 0.003, which keeps Intel's first loop free of resampling until it closes.
#: Measured with scripts/slam_benchmark.py, see docs/slam.md.
PRESETS = {
    "radish-noisy": dict(motion_noise=(0.03, 0.02, 0.01, 0.05), match_climb_beams=90, likelihood_exponent=0.003),
}
