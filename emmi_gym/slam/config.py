"""Parameters of the RBPF, with GMapping's and MRPT's names where they have one."""

from __future__ import annotations

import math
from dataclasses import dataclass, fields

from ..inputs.validation import Integer, Maybe, Real, Tuple, check_fields, fail, option

#: Upper bounds: particles (each holds a whole map: 1000 of a 100 x 100 m world at 0.1 m take 1 GB)
#: and the finest cell side.
MAX_PARTICLES = 1000
MIN_RESOLUTION = 0.01


@dataclass(frozen=True)
class RBPFConfig:
    """Everything that tunes the filter. Distances in metres, angles in radians.

    Inverse sensor model (the paper's Fig. 2, in log-odds of occupancy, eq. 4):
    ``logodds_occupied`` is added to the cell of a beam's end point, ``logodds_free``
    to every cell the beam crosses before it; cells stay within +-``logodds_clamp``.
    Log-odds are stored as int8 codes of ``logodds_step`` (MRPT's layout).
    """

    particles: int = option(15, Integer(1, MAX_PARTICLES, "each particle holds a whole map"),
                            help="particles (each holds a whole map)")
    resolution: float = option(0.1, Real(MIN_RESOLUTION, 1.0, unit="m"),
                               help="cell side of the maps")
    # inverse sensor model
    # peaked, as the paper's Fig. 2 ("due to the sensor high accuracy"): one scan nearly
    # settles a cell, so a map's information reflects agreement more than repetition
    logodds_occupied: float = option(2.0, Real(0.0, 20.0, open_lo=True),  # p = 0.88 for a hit
                                     help="log-odds added to a beam's end cell (p = 0.88 for a hit)")
    logodds_free: float = option(-1.2, Real(-20.0, 0.0, open_hi=True),  # p = 0.23 for a pass
                                 help="log-odds added to each cell a beam crosses before its end (p = 0.23)")
    logodds_clamp: float = option(6.0, Real(0.0, 20.0, open_lo=True),  # p in [0.0025, 0.9975]
                                  help="cells stay within +- this log-odds")
    logodds_step: float = option(0.05, Real(0.001, 1.0),  # one int8 code
                                 help="log-odds of one int8 code of the stored maps")
    # A max-range reading beside another frees this far (0: ignore such beams); a lone one is a
    # dropped echo and frees nothing (occupancy.open_space_beams). Off by default.
    max_range_free: float = option(0.0, Real(0.0, 100.0, unit="m"),
                                   help="a max-range reading beside another frees this far along its beam "
                                        "(a lone one is a dropped echo); 0: such beams are ignored")
    # Echoes beyond insertion_range only free the cells up to it (GMapping's maxUrange), and
    # beams beyond matching_range are left out of the matching and the weights; None: the
    # sensor's range. Long beams fix the heading: limit the insertion, not the matching.
    insertion_range: float | None = option(
        None, Maybe(Real(0.0, 100.0, open_lo=True, unit="m"), "the sensor's range"),
        help="echoes beyond it only free the cells up to it (GMapping's maxUrange); None: the sensor's range")
    matching_range: float | None = option(
        None, Maybe(Real(0.0, 100.0, open_lo=True, unit="m"), "the sensor's range"),
        help="beams beyond it are left out of the matching and the weights; None: the sensor's range")
    # motion model of the filter, GMapping's (srr, srt, str, stt): translation from translation
    # (m/m), rotation from translation (rad/m), translation from rotation (m/rad), rotation
    # from rotation (rad/rad), deviations in the robot's frame (see motion.local_motion_std)
    motion_noise: tuple[float, float, float, float] = option(
        (0.05, 0.03, 0.02, 0.1), Tuple(Real(0.0, 10.0), 4),
        help="motion model (srr, srt, str, stt), GMapping's: deviations per metre or radian moved")
    # update policy (GMapping's linearUpdate / angularUpdate); 0 and 0: every scan an update
    linear_update: float = option(
        0.5, Real(0.0, 100.0, unit="m"),
        help="odometry travel after which a scan updates the filter (GMapping's linearUpdate)")
    angular_update: float = option(
        0.3, Real(0.0, 2 * math.pi, unit="rad"),
        help="odometry turn after which a scan updates the filter (GMapping's angularUpdate)")
    # scan matching (see _matching): GMapping's lstep / astep / iterations, a search radius in
    # metres around each end point, and a coarse stage on blocks of about coarse_resolution
    match_linear_step: float = option(0.05, Real(0.0, 1.0, open_lo=True, unit="m"),
                                      help="first translation step of the scan matcher's climb (GMapping's lstep)")
    match_angular_step: float = option(0.05, Real(0.0, math.pi, open_lo=True, unit="rad"),
                                       help="first heading step of the climb (GMapping's astep)")
    match_refinements: int = option(3, Integer(1, 20),
                                    help="times the climb halves its steps when no move helps")
    match_max_iterations: int = option(60, Integer(1, 10_000),
                                       help="most moves of the climb per scan")
    # beyond this an end point counts as unmatched
    match_radius: float = option(0.15, Real(0.0, 5.0, open_lo=True, unit="m"),
                                 help="an end point with no surface within this counts as unmatched")
    # beams used while hill-climbing, evenly spread over the scan (GMapping climbs on all of
    # them; too few of a 180-degree scan let the heading wander)
    match_climb_beams: int = option(60, Integer(1, 10_000),
                                    help="beams used while climbing, spread evenly over the scan")
    # block side of the coarse stage (a whole number of cells)
    coarse_resolution: float = option(0.2, Real(0.0, 5.0, open_lo=True, unit="m"),
                                      help="block side of the matcher's coarse stage (whole cells)")
    # first heading step of the coarse climb
    coarse_angular_step: float = option(0.05, Real(0.0, math.pi, open_lo=True, unit="rad"),
                                        help="first heading step of the coarse climb")
    coarse_trigger: float = option(0.6, Real(0.0, 1.0),  # run the coarse stage below this fraction of matched beams
                                   help="run the coarse stage below this share of matched beams")
    # The improved proposal's Gaussian is fitted to a likelihood that counts every beam as independent;
    # neighbouring beams see one surface and share its map error, so the fit is narrower than the
    # pose's uncertainty. Its covariance times this (1: GMapping's fit as it is).
    proposal_inflation: float = option(1.0, Real(1.0, 100.0),
                                       help="factor on the covariance of the proposal's fitted Gaussian")
    # likelihood and weights
    likelihood_sigma: float = option(
        0.075, Real(0.001, 10.0, unit="m"),
        help="deviation of an end point's distance to the nearest surface in the likelihood")
    # an end point with no surface within match_radius scores as if it were this far off
    # (GMapping's nullLikelihood): the cost of a beam that sees a wall where the map has none
    likelihood_null_distance: float = option(
        0.2, Real(0.0, 10.0, open_lo=True, unit="m"),
        help="the distance an unmatched end point scores as (GMapping's nullLikelihood)")
    # radians between the beams of the likelihood: neighbouring beams see the same surface
    # and their errors are not independent (Thrun et al. 2005, sec. 6.4, subsample the beams)
    likelihood_beam_spacing: float = option(
        0.035, Real(0.0, 2 * math.pi, open_lo=True, unit="rad"),
        help="angle between the beams of the likelihood (neighbours see the same surface)")
    # fall back to odometry below this fraction of matched beams
    min_match_fraction: float = option(0.3, Real(0.0, 1.0),
                                       help="below this share of matched beams the pose falls back to odometry")
    # weights: exponents on the likelihood (MRPT's powFactor; GMapping's 1 / (ogain * M)), one
    # for the beams that see a place again and one for the others. A beam sees a place again
    # when its end point falls in a block (within revisit_reach of an end point then) that the
    # scans reached again revisit_gap or more updates after they last had: the fit to a
    # particle's own recent map differs between particles by noise that the weights re-count
    # update after update (likelihood_exponent, small), a place seen again tests the
    # particle's path since (revisit_exponent); None: every beam with likelihood_exponent (see
    # slam/revisits.py): with one exponent on every beam the set resamples along a plain
    # corridor, before the loop closes, and the closure's evidence is lost.
    likelihood_exponent: float = option(
        0.004, Real(0.0, 1.0, open_lo=True),
        help="exponent on the likelihood of beams that see no place again (MRPT's powFactor)")
    resample_threshold: float = option(0.5, Real(0.0, 1.0),  # resample when Neff / M < this
                                       help="resample when Neff / particles falls below this")
    revisit_gap: int | None = option(
        10, Maybe(Integer(1, 1_000_000), "every beam with likelihood_exponent"),
        help="updates after which a place the scans reach again counts as seen again; None: one exponent")
    revisit_reach: float = option(0.4, Real(0.0, 10.0, unit="m"),
                                  help="distance round a scan's end points within which a place counts as reached")
    revisit_exponent: float = option(0.05, Real(0.0, 1.0),
                                     help="exponent on the likelihood of beams that see a place again")
    # at most this many beams' worth of places seen again per update (None: no bound): a laser
    # that reaches across a building sees places again at almost every update (revisits.py);
    # 30-45 suit a 30 m laser, and the default keeps the 8 m lasers' closures at full strength
    revisit_beams: int | None = option(None, Maybe(Integer(1, 100_000), "no bound"),
                                       help="most beams' worth of places seen again per update; None: no bound")

    def __post_init__(self):
        check_fields(self)
        if not self.logodds_step <= min(self.logodds_occupied, -self.logodds_free, self.logodds_clamp):
            fail(self, "logodds_step", "at most logodds_occupied, -logodds_free and logodds_clamp (one int8 code "
                 "smaller than one update)", self.logodds_step)
        if self.logodds_clamp / self.logodds_step > 127:
            fail(self, "logodds_clamp", f"at most 127 * logodds_step = {127 * self.logodds_step:g} (int8 codes)",
                 self.logodds_clamp)

    def coarse_block(self) -> int:
        """Cells per side of a coarse block: ``coarse_resolution`` in whole cells (at least 1)."""
        return max(1, int(round(self.coarse_resolution / self.resolution)))

    @classmethod
    def preset(cls, name: str, **overrides) -> RBPFConfig:
        """A configuration from :data:`PRESETS` (GMapping ships such files per sensor), with ``overrides``."""
        if name not in PRESETS:
            raise ValueError(f"unknown RBPF preset {name!r}; the presets are {sorted(PRESETS)}")
        return cls(**{**PRESETS[name], **overrides})

    @classmethod
    def option_names(cls) -> list[str]:
        return [f.name for f in fields(cls)]


#: Named settings for other robots than the simulator's (the defaults). ``radish-noisy``: the
#: classic CARMEN logs (SICK LMS, 180 degrees, 30 m, keyframes) with the odometry noise of the
#: radish-noisy set (alphas 0.0004, 0.0001, 0.0004, 0.0001, a heading drift of 0.002 rad/m, a 1%
#: scale error), smaller than the simulator's, so a tighter motion model; 90 climbing beams (a
#: 180-degree scan pins the heading less than a 360-degree one); tempering 0.003 on every beam
#: (30 m beams in small rooms see places again at almost every update), which keeps Intel's
#: first loop free of resampling until it closes; a weaker pass (-0.8, p = 0.31), since a 30 m
#: beam that grazes a far wall crosses its cells before it reaches its end cell; and cells
#: clamped at +-9 log-odds (codes of 0.1), so that what was seen many times, free space and
#: walls alike, outlasts a few contrary readings and a place seen again on a long tour still
#: matches it. Its figures: docs/results/filter.md.
PRESETS = {
    "radish-noisy": dict(motion_noise=(0.03, 0.02, 0.01, 0.05), match_climb_beams=90, likelihood_exponent=0.003,
                         revisit_gap=None, logodds_free=-0.8, logodds_clamp=9.0, logodds_step=0.1),
}
