"""A Rao-Blackwellized particle filter for grid SLAM (GMapping's design, Grisetti et al. 2007).

Each particle is a pose path and its own occupancy grid. An update, once the robot
has moved far enough (GMapping's linearUpdate / angularUpdate):

1. propagate each particle with the odometry motion model in the robot's frame
   (GMapping's, noise sampled);
2. scan-match it against its own grid (``_matching``: a search radius in metres and a
   coarse stage, so the capture basin does not shrink with the cells) and draw its pose
   from the Gaussian fitted around the match (the improved proposal), or keep the
   odometry sample when the match is poor;
3. weight by the proposal's normaliser (the scan likelihood over beams decimated to
   ``likelihood_beam_spacing``), in log space, tempered by ``revisit_exponent`` for the
   beams that see a place again after ``revisit_gap`` updates (``revisits``: where a loop
   closes; as if at most ``revisit_beams`` of them did) and by ``likelihood_exponent`` for
   the rest;
4. resample (systematic) only when Neff / M < ``resample_threshold``;
5. insert the scan into each particle's grid (eq. 4, log-odds) and extend its path;
6. measure the certainty of the particle set (EMMI and the rest): at once, or when
   :meth:`RBPF.measure` asks (a caller that reads it once per many updates, as an
   environment step, skips the rest).

The filter sees only odometry poses and laser ranges: it imports nothing from the
simulator, so it runs the same on a recorded CARMEN log.
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass, field

import numpy as np

from .. import certainty
from ..concurrency.threads import run_in_chunks
from ..geometry.grid import GridGeometry
from ..geometry.motion import compose_local, local_delta, local_motion_std
from ..inputs.validation import MAX_LASER_RANGE, Real, check_value
from . import _matching
from .config import RBPFConfig
from .occupancy import ParticleMaps
from .resampling import survivors_in_place, systematic_resample
from .revisits import RevisitGrid, revisit_exponent
from .sensor_model import CellCodes

#: Floors on the motion model's pose deviations (m, m, rad), so that a standing update stays proper.
_MOTION_FLOOR = np.array([0.01, 0.01, 0.005])
_PHASES = ("scan_matching", "insertion", "weighting", "resampling", "metrics")


@dataclass
class UpdateMetrics:
    """The certainty of the particle set after one update, and what the update did."""

    step: int
    time: float
    emmi: float                    # bits/cell, eq. (11)
    map_information: float         # bits, eq. (9) summed over the expected map's observed cells
    mean_information_best: float   # bits/cell, eq. (10) of the best particle's map
    pose_entropy: float            # nats
    weight_entropy: float          # nats
    path_entropy: float            # nats
    joint_entropy: float           # nats, eq. (12)
    neff: float
    resampled: bool
    matched_fraction: float        # particles whose scan match was good enough
    update_ms: float               # wall time
    cpu_ms: float = 0.0            # CPU time of the process, all its threads (the kernels run on several)
    phase_ms: dict = field(default_factory=dict)

    def measures(self) -> dict:
        """What the update measured, without its timings (which differ from run to run)."""
        return {k: v for k, v in self.__dict__.items() if k not in ("phase_ms", "update_ms", "cpu_ms")}

    def as_row(self) -> dict:
        """The measures and the timings, for a CSV row."""
        row = self.measures()
        row["update_ms"], row["cpu_ms"] = self.update_ms, self.cpu_ms
        row.update({f"{k}_ms": v for k, v in self.phase_ms.items()})
        return row


class RBPF:
    """Grid SLAM with M particles.

    ``geometry`` fixes the grids' extent (``None``: a square around the start pose);
    with ``grow_chunk`` (metres) the grids grow in such chunks whenever a particle's
    laser reach leaves them. The joint entropy's map term (eq. 8) counts every cell of
    the extent, so it is comparable between updates only while the extent is fixed.
    """

    def __init__(self, config: RBPFConfig = RBPFConfig(), *, max_range: float,
                 geometry: GridGeometry | None = None, grow_chunk: float | None = None):
        check_value(max_range, Real(0.0, MAX_LASER_RANGE, open_lo=True, unit="m"), "RBPF", "max_range")
        self.config = config
        self.max_range = float(max_range)
        self.cell_codes = CellCodes.from_config(config)
        self._initial_geometry = geometry
        self.grow_chunk = grow_chunk
        self.rng = np.random.default_rng(0)
        self.maps: ParticleMaps | None = None
        self.poses = np.zeros((config.particles, 3))
        self.log_weights = np.zeros(config.particles)
        self.accumulated_log_weights = np.zeros(config.particles)
        self._best: int | None = None  # kept until the weights change
        self._paths = np.zeros((config.particles, 64, 3))
        self._path_sincos = np.zeros((config.particles, 64, 2))  # their headings' sines and cosines
        self._n_path = 0
        self._last_odometry: np.ndarray | None = None
        self.step = 0
        self._latest: UpdateMetrics | tuple | None = None  # the last update's metrics, or what measuring them needs

    # ------------------------------------------------------------------ state

    @property
    def weights(self) -> np.ndarray:
        return certainty.normalize_weights(self.log_weights, log=True)

    @property
    def paths(self) -> np.ndarray:
        """(M, T, 3) pose of each particle at every update so far."""
        return self._paths[:, :self._n_path]

    @property
    def best(self) -> int:
        """The particle of highest weight (the posterior's most likely path); among equal weights, as
        right after a resampling, the one whose weight accumulated over its whole history is highest
        (GMapping's choice)."""
        if self._best is None:
            self._best = int(np.lexsort((-self.accumulated_log_weights, -self.log_weights))[0])
        return self._best

    @property
    def geometry(self) -> GridGeometry:
        return self.maps.geometry

    def pose_estimate(self, odometry_pose) -> np.ndarray:
        """The best particle's pose moved on by the odometry since the last update (for control in between)."""
        base = self.poses[self.best]
        if self._last_odometry is None:
            return base.copy()
        return compose_local(base, local_delta(self._last_odometry, np.asarray(odometry_pose, dtype=np.float64)))

    def expected_map(self) -> np.ndarray:
        """EM, eq. (6): probability grid (H, W), averaged over the cells the particles dispute only; kept up to
        date from call to call (:meth:`ParticleMaps.expected_map`): a read-only view that the next call
        changes, to copy if kept or modified."""
        return self.maps.expected_map(self.weights)

    def best_map(self) -> np.ndarray:
        return self.maps.probabilities(self.best)

    # ------------------------------------------------------------------ filtering

    def reset(self, pose, rng: np.random.Generator) -> None:
        """Start every particle at ``pose`` with empty grids; all randomness will come from ``rng``."""
        pose = np.asarray(pose, dtype=np.float64)
        m = self.config.particles
        self.rng = rng
        geometry = self._initial_geometry or GridGeometry.covering(
            pose[0] - self.max_range - 2, pose[1] - self.max_range - 2,
            pose[0] + self.max_range + 2, pose[1] + self.max_range + 2, self.config.resolution)
        self.maps = ParticleMaps(geometry, m, self.cell_codes, self.config.coarse_block())
        self.revisits = (RevisitGrid(geometry, self.maps.block, self.config.revisit_reach)
                         if self.config.revisit_gap is not None else None)
        self.poses = np.tile(pose, (m, 1))
        self.log_weights = np.zeros(m)
        self.accumulated_log_weights = np.zeros(m)
        self._best = None
        self._n_path = 0
        self._last_odometry = None
        self.step = 0
        self._latest = None

    def update_due(self, odometry_pose) -> bool:
        """Whether a scan taken at ``odometry_pose`` would be used: the first one, or once the odometry
        has moved ``linear_update`` metres or turned ``angular_update`` radians since the last update."""
        if self._last_odometry is None:
            return True
        dx, dy, dtheta = local_delta(self._last_odometry, odometry_pose)
        return math.hypot(dx, dy) >= self.config.linear_update or abs(dtheta) >= self.config.angular_update

    def process(self, odometry_pose, ranges, angles, timestamp: float = 0.0,
                measure: bool = True) -> UpdateMetrics | None:
        """Feed one scan with the odometry pose at which it was taken.

        The first scan initialises the grids. Later scans update the filter only when
        :meth:`update_due` (odometry in between accumulates); others return None. An update
        returns its metrics, or with ``measure=False`` None: the certainty of the particle set
        is then computed only if :meth:`measure` is called before the next update.
        """
        odometry_pose = np.asarray(odometry_pose, dtype=np.float64)
        ranges = np.ascontiguousarray(ranges, dtype=np.float64)
        angles = np.ascontiguousarray(angles, dtype=np.float64)
        if ranges.shape != angles.shape:
            raise ValueError(f"{ranges.size} ranges but {angles.size} beam angles")
        if self.maps is None:
            raise RuntimeError("call reset(pose, rng) before process()")
        if self._last_odometry is None:
            self._initialise(odometry_pose, ranges, angles, timestamp)
        elif self.update_due(odometry_pose):
            motion = local_delta(self._last_odometry, odometry_pose)
            self._last_odometry = odometry_pose
            self._update(motion, ranges, angles, timestamp)
        else:
            return None
        return self.measure() if measure else None

    def measure(self) -> UpdateMetrics:
        """The metrics of the last update: what it did, and the certainty of the particle set after it
        (computed once, on the first call after the update)."""
        if self._latest is None:
            raise RuntimeError("no update to measure: process() a scan first")
        if not isinstance(self._latest, UpdateMetrics):
            self._latest = self._measure(*self._latest)
        return self._latest

    def _initialise(self, odometry_pose, ranges, angles, timestamp) -> None:
        self._last_odometry = odometry_pose
        cpu0, t0 = time.process_time(), time.perf_counter()
        self._ensure_extent()
        self._insert(ranges, angles)
        self._append_path()
        self._stamp(ranges, angles)
        phases = dict.fromkeys(_PHASES, 0.0)
        phases["insertion"] = time.perf_counter() - t0
        self._finish(timestamp, False, 0.0, phases, cpu0)

    def _update(self, motion, ranges, angles, timestamp) -> None:
        cfg, m = self.config, self.config.particles
        phases = {}
        cpu0, t0 = time.process_time(), time.perf_counter()
        # 1-3: motion sample, scan matching, improved proposal and its weight
        motion_normals = self.rng.standard_normal((m, 3))
        proposal_normals = self.rng.standard_normal((m, 3))
        sd = local_motion_std(motion, cfg.motion_noise)
        samples = compose_local(self.poses, motion + motion_normals * sd)
        means = compose_local(self.poses, motion)
        precisions, lognorms = self._motion_gaussians(sd)
        matching_ranges = self._matching_ranges(ranges)
        climb, likelihood = self._beam_subsets(angles)
        climb_ranges, climb_angles = np.ascontiguousarray(matching_ranges[climb]), np.ascontiguousarray(angles[climb])
        beam_ranges = np.ascontiguousarray(matching_ranges[likelihood])
        beam_angles = np.ascontiguousarray(angles[likelihood])
        weight_ranges = self._weight_ranges(compose_local(self.poses[self.best], motion), beam_ranges, beam_angles)
        new_poses = np.empty_like(self.poses)
        increments = np.empty(m)
        matched = np.zeros(m, dtype=np.bool_)
        g = self.geometry
        settings = _matching.match_settings(cfg, g.origin_x, g.origin_y, g.resolution, self.maps.block,
                                            revisit_exponent(cfg, np.count_nonzero(weight_ranges < self.max_range)))
        run_in_chunks(_matching.improved_proposal, m, self.maps.codes, self.maps.hits, self.maps.coarse, samples,
                      means, precisions, lognorms, proposal_normals, climb_ranges, climb_angles, beam_ranges,
                      beam_angles, weight_ranges, self.revisits is not None, self.max_range, settings, new_poses,
                      increments, matched)
        self.poses = new_poses
        t1 = time.perf_counter()
        phases["scan_matching"] = t1 - t0
        # 3: weights in log space
        self.log_weights = self.log_weights + increments
        self.log_weights -= self.log_weights.max()
        self.accumulated_log_weights += increments
        self._best = None
        neff = certainty.effective_sample_size(self.log_weights, log=True)
        t2 = time.perf_counter()
        phases["weighting"] = t2 - t1
        # 4: selective resampling
        resampled = neff < cfg.resample_threshold * m
        if resampled:
            self._resample(survivors_in_place(systematic_resample(self.weights, self.rng)))
        t3 = time.perf_counter()
        phases["resampling"] = t3 - t2
        # 5: map update and path
        self._ensure_extent()
        self._insert(ranges, angles)
        self._append_path()
        self._stamp(ranges, angles)
        phases["insertion"] = time.perf_counter() - t3
        self._finish(timestamp, resampled, float(matched.mean()), phases, cpu0)

    def _finish(self, timestamp: float, resampled: bool, matched: float, phases: dict, cpu0: float) -> None:
        """Count the update and keep what :meth:`measure` needs (the CPU time so far, in ms)."""
        self._latest = (self.step, timestamp, resampled, matched, phases, 1e3 * (time.process_time() - cpu0))
        self.step += 1

    def _insert(self, ranges, angles) -> None:
        self.maps.insert(self.poses, ranges, angles, self.max_range, self.config.max_range_free,
                         self.config.insertion_range)

    def _weight_ranges(self, predicted_best, ranges: np.ndarray, angles: np.ndarray) -> np.ndarray:
        """The likelihood beams the weights count: with ``revisit_gap``, those that from the best particle's
        predicted pose end where the scans last reached at least that many updates ago (the others read
        as no echo); otherwise all of them."""
        if self.revisits is None:
            return ranges
        seen_again = self.revisits.revisited(predicted_best, ranges, angles, self.max_range, self._n_path + 1,
                                             self.config.revisit_gap)
        return np.where(seen_again, ranges, self.max_range)

    def _stamp(self, ranges, angles) -> None:
        """Record the places this update's scan reached (at the best particle's pose), for ``revisit_gap``."""
        if self.revisits is not None:
            self.revisits.stamp(self.poses[self.best], ranges, angles, self.max_range, self._n_path,
                                self.config.revisit_gap)

    def _matching_ranges(self, ranges: np.ndarray) -> np.ndarray:
        """The ranges the matcher sees: beyond ``matching_range`` a beam reads as no echo."""
        limit = self.config.matching_range
        if limit is None or limit >= self.max_range:
            return ranges
        return np.where(ranges > limit, self.max_range, ranges)

    def _beam_subsets(self, angles: np.ndarray) -> tuple[slice, slice]:
        """Every n-th beam for hill-climbing (about ``match_climb_beams`` of them) and for the likelihood
        (beams ``likelihood_beam_spacing`` apart)."""
        if angles.size < 2:
            return slice(None), slice(None)
        step = float(angles[-1] - angles[0]) / (angles.size - 1)
        climb = max(1, angles.size // self.config.match_climb_beams)
        likelihood = max(1, int(round(self.config.likelihood_beam_spacing / step)))
        return slice(None, None, climb), slice(None, None, likelihood)

    def _motion_gaussians(self, sd: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Precision matrices and log-normalisers of the motion model in the world frame, per particle:
        the robot-frame deviations ``sd`` (dx, dy, dtheta) turned by each particle's heading."""
        m = self.poses.shape[0]
        c, s = np.cos(self.poses[:, 2]), np.sin(self.poses[:, 2])
        rot = np.zeros((m, 3, 3))
        rot[:, 0, 0], rot[:, 0, 1], rot[:, 1, 0], rot[:, 1, 1], rot[:, 2, 2] = c, -s, s, c, 1.0
        cov = rot @ np.diag(sd ** 2) @ rot.transpose(0, 2, 1) + np.diag(_MOTION_FLOOR ** 2)
        sign, logdet = np.linalg.slogdet(cov)
        return np.ascontiguousarray(np.linalg.inv(cov)), -0.5 * (3 * math.log(2 * math.pi) + logdet)

    def _resample(self, indices: np.ndarray) -> None:
        self.maps.resample(indices)
        self.poses = self.poses[indices]
        self._paths[:, :self._n_path] = self._paths[indices, :self._n_path]
        self._path_sincos[:, :self._n_path] = self._path_sincos[indices, :self._n_path]
        self.accumulated_log_weights = self.accumulated_log_weights[indices]
        self.log_weights = np.zeros_like(self.log_weights)
        self._best = None

    def _append_path(self) -> None:
        if self._n_path == self._paths.shape[1]:
            self._paths = np.concatenate([self._paths, np.zeros_like(self._paths)], axis=1)
            self._path_sincos = np.concatenate([self._path_sincos, np.zeros_like(self._path_sincos)], axis=1)
        self._paths[:, self._n_path] = self.poses
        self._path_sincos[:, self._n_path] = certainty.heading_sincos(self.poses)
        self._n_path += 1

    def _ensure_extent(self) -> None:
        if self.grow_chunk is None:
            return
        reach = self.max_range + 1.0
        lo, hi = self.poses[:, :2].min(axis=0) - reach, self.poses[:, :2].max(axis=0) + reach
        if self.maps.grow_to_contain(lo[0], lo[1], hi[0], hi[1], self.grow_chunk) and self.revisits is not None:
            self.revisits.follow(self.maps.geometry)

    def _measure(self, step: int, timestamp: float, resampled: bool, matched: float, phases: dict,
                 cpu_ms: float) -> UpdateMetrics:
        """Every certainty measure of the particle set, through :mod:`emmi_gym.certainty`.

        EMMI and the expected map's information need a pass over the cells the particles dispute
        only (the agreed cells enter through their code histogram,
        :func:`certainty.expected_map_information_of_parts`); map
        entropies and the best map's mean information come from the grids' code
        histograms. All are kept current by the insertion and the resampling.
        """
        cpu0, t0 = time.process_time(), time.perf_counter()
        lut, counts = self.cell_codes.probability, self.maps.counts
        w = self.weights
        path_entropy = certainty.path_entropy_of_parts(self.paths, self._path_sincos[:, :self._n_path], w)
        information, n_observed = certainty.expected_map_information_of_parts(
            self.maps.disputed_codes(), w, self.maps.agreed_counts, lut=lut)
        metrics = UpdateMetrics(
            step=step, time=timestamp, emmi=information / n_observed if n_observed else 0.0,
            map_information=information,
            mean_information_best=certainty.mean_information_of_code_counts(counts[self.best], lut),
            pose_entropy=certainty.pose_entropy(self.poses, w),
            weight_entropy=certainty.weight_entropy(w),
            path_entropy=path_entropy,
            joint_entropy=certainty.joint_entropy_of_parts(
                path_entropy, certainty.map_entropy_of_code_counts(counts, lut), w),
            neff=certainty.effective_sample_size(w),
            resampled=bool(resampled), matched_fraction=matched, update_ms=0.0)
        phases["metrics"] = time.perf_counter() - t0
        metrics.phase_ms = {k: 1e3 * phases.get(k, 0.0) for k in _PHASES}
        metrics.update_ms = sum(metrics.phase_ms.values())
        metrics.cpu_ms = cpu_ms + 1e3 * (time.process_time() - cpu0)
        return metrics
