"""Run the RBPF on a CARMEN log and write what it measured: CSV, metric plot, map images."""

from __future__ import annotations

import math
from dataclasses import dataclass, replace
from functools import partial
from pathlib import Path

import numpy as np

from ...formats import carmen
from ...formats.atomic_files import write_atomically
from ...geometry.grid import GridGeometry
from ...geometry.motion import compose_motion
from ...scoring.scores import absolute_trajectory_error
from ...slam.config import RBPFConfig
from ...slam.rbpf import RBPF, UpdateMetrics
from .report import write_csv


@dataclass
class ReplayResult:
    """What a replay produced: per-update metrics, the filter at the end, and per update its scan's
    timestamp, the odometry pose and the true pose (TRUEPOS nearest in time, or None)."""

    rows: list[UpdateMetrics]
    slam: RBPF
    timestamps: np.ndarray
    update_odometry: np.ndarray            # (updates, 3)
    true_poses: list                        # per update: (3,) array or None
    scans_used: int = 0
    scans_without_odometry: int = 0
    log: carmen.CarmenLog | None = None

    def _with_truth(self) -> np.ndarray:
        return np.array([k for k, t in enumerate(self.true_poses) if t is not None], dtype=np.int64)

    def ate(self) -> float | None:
        """ATE (m, aligned) of the best particle's path against TRUEPOS at the updates that have one."""
        keep = self._with_truth()
        if keep.size == 0:
            return None
        truth = np.array([self.true_poses[k] for k in keep])
        return absolute_trajectory_error(self.slam.paths[self.slam.best][keep], truth)

    def dead_reckoning_ate(self) -> float | None:
        """The same ATE for the odometry alone."""
        keep = self._with_truth()
        if keep.size == 0:
            return None
        return absolute_trajectory_error(self.update_odometry[keep], np.array([self.true_poses[k] for k in keep]))


def true_pose_at(log: carmen.CarmenLog, tolerance: float = 0.05):
    """A function of (timestamp, odometry pose, position in ``log.records``) of a scan giving the
    TRUEPOS pose logged nearest in time (before or after the scan, within ``tolerance`` seconds),
    or None. Where several share that time (logs whose timestamps were rounded, as CSAIL's to
    1e4 s), the one whose own odometry pose is nearest the scan's (a TRUEPOS line carries both),
    then the nearest in the file. None for a log without TRUEPOS lines."""
    found = [(k, r) for k, r in enumerate(log.records) if isinstance(r, carmen.TruePoseRecord)]
    if not found:
        return None
    positions = np.array([k for k, _ in found])
    times = np.array([r.timestamp for _, r in found])
    poses = np.array([r.true_pose for _, r in found])
    odometry = np.array([r.odometry_pose[:2] for _, r in found])

    def lookup(timestamp: float, odometry_pose, position: int):
        gap = np.abs(times - timestamp)
        nearest = gap.min()
        if nearest > tolerance:
            return None
        ties = np.flatnonzero(gap == nearest)
        apart = np.hypot(*(odometry[ties] - np.asarray(odometry_pose)[:2]).T)
        return poses[ties[np.lexsort((np.abs(positions[ties] - position), apart))[0]]]

    return lookup


def laser_stream(log: carmen.CarmenLog):
    """(position in ``log.records``, laser pose by odometry, scan record) for every scan; the pose is
    None before any odometry.

    ROBOTLASER1 and FLASER lines carry the robot's odometry pose; a RAWLASER1 line takes
    the latest ODOM before it. The laser's mounting offset (ROBOTLASER1) is applied, so
    the filter tracks the laser itself.
    """
    odometry = None
    for position, record in enumerate(log.records):
        if isinstance(record, carmen.OdometryRecord):
            odometry = record.pose
        elif isinstance(record, carmen.LaserRecord):
            pose = record.odometry_pose if record.odometry_pose is not None else odometry
            if pose is None:
                yield position, None, record
                continue
            if record.laser_offset is not None and np.any(record.laser_offset):
                ox, oy, otheta = record.laser_offset
                pose = compose_motion(pose, np.arctan2(oy, ox), np.hypot(ox, oy), otheta - np.arctan2(oy, ox))
            yield position, pose, record


def log_extent(poses: np.ndarray, max_range: float, resolution: float, drift_margin: float = 0.2) -> GridGeometry:
    """A grid covering the odometry's bounding box, the laser's reach and room for drift.

    ``drift_margin`` adds that fraction of the box's larger side on every side: the
    corrected path may leave the odometry's box.
    """
    lo, hi = poses[:, :2].min(axis=0), poses[:, :2].max(axis=0)
    margin = max_range + 1.0 + drift_margin * float(max(hi - lo))
    return GridGeometry.covering(lo[0], lo[1], hi[0], hi[1], resolution, margin=margin)


def replay(log: carmen.CarmenLog, config: RBPFConfig = RBPFConfig(), *, max_range: float | None = None,
           seed: int = 0, progress: bool = False, grow_chunk: float = 10.0,
           every_scan: bool = False, on_update=None) -> ReplayResult:
    """Feed every scan of ``log`` to a fresh RBPF.

    The grids cover the log's odometry (see :func:`log_extent`), so that the joint
    entropy is measured over one extent; they grow in chunks of ``grow_chunk`` metres
    only if the corrected path leaves even that. ``every_scan`` makes each scan an update
    (for logs of keyframes, GMapping's ``-linearUpdate 0 -angularUpdate 0``). Readings
    at or beyond ``max_range`` are taken as no echo. ``on_update(slam)``, if given, is called after
    every update (the first scan's included), as :mod:`.calibration` reads the particles.
    """
    if max_range is not None and not (isinstance(max_range, (int, float)) and 0 < max_range < math.inf):
        raise ValueError(f"max_range must be a finite number of metres above 0, got {max_range!r}")
    if isinstance(seed, bool) or not isinstance(seed, (int, np.integer)) or seed < 0:
        raise ValueError(f"seed must be an integer >= 0, got {seed!r}")
    lasers = log.of_type(carmen.LaserRecord)
    if not lasers:
        raise ValueError("the log has no FLASER, RAWLASER1 or ROBOTLASER1 line")
    if max_range is None:
        ranges_known = [r.max_range for r in lasers if r.max_range is not None]
        if not ranges_known:
            raise ValueError("FLASER lines do not carry the laser's maximum range: pass max_range (--max-range)")
        max_range = max(ranges_known)
    odometry = np.array([pose for _, pose, _ in laser_stream(log) if pose is not None])
    if odometry.size == 0:
        raise ValueError("no scan in the log has odometry (ODOM before RAWLASER1, or a robot pose in the line)")
    if every_scan:
        config = replace(config, linear_update=0.0, angular_update=0.0)
    slam = RBPF(config, max_range=max_range, geometry=log_extent(odometry, max_range, config.resolution),
                grow_chunk=grow_chunk)
    rows, times, odometry_at_update, truths = [], [], [], []
    used = missing = 0
    truth_at = true_pose_at(log)
    stream = laser_stream(log)
    if progress:
        from ...concurrency.progress import progress_bar

        stream = progress_bar(stream, total=len(lasers), unit="scan", desc="replay")
    for position, pose, record in stream:
        if pose is None:
            missing += 1
            continue
        if slam.maps is None:
            slam.reset(pose, np.random.default_rng(seed))
        ranges = np.minimum(record.ranges, max_range)
        metrics = slam.process(pose, ranges, record.angles, record.timestamp)
        used += 1
        if metrics is not None:
            if on_update is not None:
                on_update(slam)
            rows.append(metrics)
            times.append(record.timestamp)
            odometry_at_update.append(pose)
            truths.append(truth_at(record.timestamp, pose, position) if truth_at is not None else None)
    return ReplayResult(rows, slam, np.array(times), np.array(odometry_at_update), truths, used, missing, log)


def tum_problem(result: ReplayResult) -> str | None:
    """Why the updates' timestamps cannot time a trajectory (they are all the same), or None."""
    times = result.timestamps
    if times.size > 1 and np.all(times == times[0]):
        return f"all {times.size} updates have the same timestamp {float(times[0])!r}: the log carries no time"
    return None


def tum_warning(result: ReplayResult) -> str | None:
    """What a TUM trajectory of ``result`` holds that its readers may not expect (timestamps that go
    backwards, as the log's do), or None."""
    steps = np.diff(result.timestamps)
    if np.any(steps < 0):
        k = int(np.argmax(steps < 0))
        return (f"its timestamps are the log's, which go backwards {int(np.sum(steps < 0))} time(s) (first "
                f"{float(result.timestamps[k + 1])!r} after {float(result.timestamps[k])!r}, update {k + 1})")
    return None


def write_tum(result: ReplayResult, path) -> Path:
    """The best particle's trajectory in the TUM format (``timestamp x y z qx qy qz qw``, one pose per
    update, z = 0, the heading as a rotation about z), as the ``evo`` tools read it; ValueError when the
    timestamps cannot time it (see :func:`tum_problem`)."""
    problem = tum_problem(result)
    if problem is not None:
        raise ValueError(f"no TUM trajectory: {problem}")
    path = Path(path)
    poses = result.slam.paths[result.slam.best]
    half = poses[:, 2] / 2.0
    table = np.column_stack([result.timestamps, poses[:, 0], poses[:, 1], np.zeros(len(poses)),
                             np.zeros(len(poses)), np.zeros(len(poses)), np.sin(half), np.cos(half)])
    np.savetxt(path, table, fmt="%.6f", header="timestamp x y z qx qy qz qw", comments="# ")
    return path


def explored_extent(slam: RBPF, margin: float = 1.0) -> tuple[slice, slice, tuple]:
    """Rows, columns and (xmin, xmax, ymin, ymax) of the box of the best map's known cells, with a margin."""
    g = slam.geometry
    rows, cols = np.nonzero(slam.maps.codes[slam.best])
    if rows.size == 0:
        return slice(0, g.rows), slice(0, g.cols), g.extent
    pad = int(round(margin / g.resolution))
    r0, r1 = max(int(rows.min()) - pad, 0), min(int(rows.max()) + 1 + pad, g.rows)
    c0, c1 = max(int(cols.min()) - pad, 0), min(int(cols.max()) + 1 + pad, g.cols)
    return (slice(r0, r1), slice(c0, c1),
            (g.origin_x + c0 * g.resolution, g.origin_x + c1 * g.resolution,
             g.origin_y + r0 * g.resolution, g.origin_y + r1 * g.resolution))


def write_map_png(result: ReplayResult, path, grid: np.ndarray | None = None, title: str = "best particle's map"):
    """A map (default: the best particle's) cropped to the explored area, with the best path in blue."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    slam = result.slam
    grid = slam.best_map() if grid is None else grid
    rows, cols, extent = explored_extent(slam)
    crop = grid[rows, cols]
    fig, ax = plt.subplots(figsize=(7, 7 * crop.shape[0] / max(crop.shape[1], 1) + 0.6))
    ax.imshow(crop, origin="lower", extent=extent, cmap="gray_r", vmin=0, vmax=1, interpolation="nearest")
    path_xy = slam.paths[slam.best]
    ax.plot(path_xy[:, 0], path_xy[:, 1], color="tab:blue", lw=0.8, label="best particle's path")
    ax.set_title(title)
    ax.set_xlabel("x (m)")
    ax.set_ylabel("y (m)")
    ax.legend(loc="upper right", fontsize=8)
    fig.tight_layout()
    write_atomically(path, partial(fig.savefig, dpi=110))
    plt.close(fig)
    return Path(path)


def write_outputs(result: ReplayResult, out_dir) -> dict[str, Path]:
    """Write ``metrics.csv``, ``metrics.png``, ``expected_map.png``, ``best_map.png`` and
    ``best_trajectory.tum`` (unless :func:`tum_problem` says why not) into ``out_dir``."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    paths = {name: out / name for name in ("metrics.csv", "metrics.png", "expected_map.png", "best_map.png")}
    rows = [r.as_row() for r in result.rows]
    write_csv(paths["metrics.csv"], rows)

    steps = [r.step for r in result.rows]
    panels = [("emmi", "EMMI (bits/cell)"), ("mean_information_best", "MI of best map (bits/cell)"),
              ("pose_entropy", "pose entropy (nats)"), ("joint_entropy", "joint entropy (nats)"),
              ("neff", "Neff")]
    fig, axes = plt.subplots(len(panels), 1, figsize=(8, 2.0 * len(panels)), sharex=True)
    for ax, (key, label) in zip(axes, panels, strict=False):
        ax.plot(steps, [getattr(r, key) for r in result.rows], lw=1.2)
        ax.set_ylabel(label, fontsize=8)
        ax.grid(alpha=0.3)
    for r in result.rows:
        if r.resampled:
            for ax in axes:
                ax.axvline(r.step, color="tab:red", lw=0.5, alpha=0.4)
    axes[-1].set_xlabel("RBPF update (red lines: resampling)")
    fig.tight_layout()
    write_atomically(paths["metrics.png"], partial(fig.savefig, dpi=110))
    plt.close(fig)

    write_map_png(result, paths["expected_map.png"], result.slam.expected_map(), "expected map (eq. 6)")
    write_map_png(result, paths["best_map.png"])
    if tum_problem(result) is None:
        paths["best_trajectory.tum"] = write_tum(result, out / "best_trajectory.tum")
    return paths
