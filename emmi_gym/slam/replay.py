"""Run the RBPF on a CARMEN log and write what it measured: CSV, metric plot, map images."""

from __future__ import annotations

import csv
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from .. import carmen
from ..evaluation import absolute_trajectory_error
from ..grid import GridGeometry
from ..motion import compose_motion
from .config import RBPFConfig
from .rbpf import RBPF, UpdateMetrics


@dataclass
class ReplayResult:
    """What a replay produced: per-update metrics, the filter at the end, the true poses if logged."""

    rows: list[UpdateMetrics]
    slam: RBPF
    true_poses: np.ndarray | None          # (updates, 3) latest TRUEPOS before each update, if any
    scans_used: int = 0
    scans_without_odometry: int = 0
    log: carmen.CarmenLog | None = None
    notes: list[str] = field(default_factory=list)

    def ate(self) -> float | None:
        """ATE (m, aligned) of the best particle's path against TRUEPOS, when the log has it."""
        if self.true_poses is None:
            return None
        return absolute_trajectory_error(self.slam.paths[self.slam.best], self.true_poses)


def laser_stream(log: carmen.CarmenLog):
    """(laser pose by odometry, scan record, latest true pose or None) for every scan that has odometry.

    ROBOTLASER1 and FLASER lines carry the robot's odometry pose; a RAWLASER1 line takes
    the latest ODOM before it. The laser's mounting offset (ROBOTLASER1) is applied, so
    the filter tracks the laser itself.
    """
    odometry = None
    truth = None
    for record in log.records:
        if isinstance(record, carmen.OdometryRecord):
            odometry = record.pose
        elif isinstance(record, carmen.TruePoseRecord):
            truth = record.true_pose
        elif isinstance(record, carmen.LaserRecord):
            pose = record.odometry_pose if record.odometry_pose is not None else odometry
            if pose is None:
                yield None, record, truth
                continue
            if record.laser_offset is not None and np.any(record.laser_offset):
                ox, oy, otheta = record.laser_offset
                pose = compose_motion(pose, np.arctan2(oy, ox), np.hypot(ox, oy), otheta - np.arctan2(oy, ox))
            yield pose, record, truth


def log_extent(poses: np.ndarray, max_range: float, resolution: float, drift_margin: float = 0.2) -> GridGeometry:
    """A grid covering the odometry's bounding box, the laser's reach and room for drift.

    ``drift_margin`` adds that fraction of the box's larger side on every side: the
    corrected path may leave the odometry's box.
    """
    lo, hi = poses[:, :2].min(axis=0), poses[:, :2].max(axis=0)
    margin = max_range + 1.0 + drift_margin * float(max(hi - lo))
    return GridGeometry.covering(lo[0], lo[1], hi[0], hi[1], resolution, margin=margin)


def replay(log: carmen.CarmenLog, config: RBPFConfig = RBPFConfig(), *, max_range: float | None = None,
           seed: int = 0, progress: bool = False, grow_chunk: float = 10.0) -> ReplayResult:
    """Feed every scan of ``log`` to a fresh RBPF.

    The grids cover the log's odometry (see :func:`log_extent`), so that the joint
    entropy is measured over one extent; they grow in chunks of ``grow_chunk`` metres
    only if the corrected path leaves even that.
    """
    lasers = log.of_type(carmen.LaserRecord)
    if not lasers:
        raise ValueError("the log has no FLASER, RAWLASER1 or ROBOTLASER1 line")
    if max_range is None:
        ranges_known = [r.max_range for r in lasers if r.max_range is not None]
        if not ranges_known:
            raise ValueError("FLASER lines do not carry the laser's maximum range: pass max_range (--max-range)")
        max_range = max(ranges_known)
    odometry = np.array([pose for pose, _, _ in laser_stream(log) if pose is not None])
    if odometry.size == 0:
        raise ValueError("no scan in the log has odometry (ODOM before RAWLASER1, or a robot pose in the line)")
    slam = RBPF(config, max_range=max_range, geometry=log_extent(odometry, max_range, config.resolution),
                grow_chunk=grow_chunk)
    rows, truths = [], []
    used = missing = 0
    stream = laser_stream(log)
    if progress:
        from tqdm import tqdm

        stream = tqdm(stream, total=len(lasers), unit="scan", desc="replay")
    for pose, record, truth in stream:
        if pose is None:
            missing += 1
            continue
        if slam.maps is None:
            slam.reset(pose, np.random.default_rng(seed))
        ranges = np.minimum(record.ranges, max_range)
        metrics = slam.process(pose, ranges, record.angles, record.timestamp)
        used += 1
        if metrics is not None:
            rows.append(metrics)
            truths.append(truth)
    true_poses = np.array(truths) if truths and all(t is not None for t in truths) else None
    return ReplayResult(rows, slam, true_poses, used, missing, log)


def write_outputs(result: ReplayResult, out_dir) -> dict[str, Path]:
    """Write ``metrics.csv``, ``metrics.png``, ``expected_map.png`` and ``best_map.png`` into ``out_dir``."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    paths = {name: out / name for name in ("metrics.csv", "metrics.png", "expected_map.png", "best_map.png")}
    rows = [r.as_row() for r in result.rows]
    with paths["metrics.csv"].open("w", newline="") as fh:
        writer = csv.DictWriter(fh, fieldnames=list(rows[0]))
        writer.writeheader()
        writer.writerows(rows)

    steps = [r.step for r in result.rows]
    panels = [("emmi", "EMMI (bits/cell)"), ("mean_information_best", "MI of best map (bits/cell)"),
              ("pose_entropy", "pose entropy (nats)"), ("joint_entropy", "joint entropy (nats)"),
              ("neff", "Neff")]
    fig, axes = plt.subplots(len(panels), 1, figsize=(8, 2.0 * len(panels)), sharex=True)
    for ax, (key, label) in zip(axes, panels):
        ax.plot(steps, [getattr(r, key) for r in result.rows], lw=1.2)
        ax.set_ylabel(label, fontsize=8)
        ax.grid(alpha=0.3)
    for r in result.rows:
        if r.resampled:
            for ax in axes:
                ax.axvline(r.step, color="tab:red", lw=0.5, alpha=0.4)
    axes[-1].set_xlabel("RBPF update (red lines: resampling)")
    fig.tight_layout()
    fig.savefig(paths["metrics.png"], dpi=110)
    plt.close(fig)

    slam = result.slam
    for name, grid, title in (("expected_map.png", slam.expected_map(), "expected map (eq. 6)"),
                              ("best_map.png", slam.best_map(), "best particle's map")):
        fig, ax = plt.subplots(figsize=(7, 7 * grid.shape[0] / max(grid.shape[1], 1) + 0.5))
        ax.imshow(grid, origin="lower", extent=slam.geometry.extent, cmap="gray_r", vmin=0, vmax=1)
        ax.plot(slam.paths[slam.best, :, 0], slam.paths[slam.best, :, 1], color="tab:blue", lw=0.8)
        ax.set_title(title)
        ax.set_xlabel("x (m)")
        ax.set_ylabel("y (m)")
        fig.tight_layout()
        fig.savefig(paths[name], dpi=110)
        plt.close(fig)
    return paths
