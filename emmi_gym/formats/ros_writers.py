"""ROS bags out: a log's scans, odometry and truth as a ROS 1 or ROS 2 bag, and maps and a path as a ROS 2
bag for RViz.

:func:`write_log_bag` writes what a robot's driver and ``ros2 bag record /scan /odom /tf /tf_static``
would have left (REP 105 frames ``odom`` -> ``base_link`` -> ``laser``): per scan a ``sensor_msgs/LaserScan``
on ``/scan``, the odometry pose at its time as ``nav_msgs/Odometry`` on ``/odom`` and as a transform on
``/tf``, the laser's mounting once on ``/tf_static``, and every true pose as ``geometry_msgs/PoseStamped``
on ``/truth``. Ranges follow REP 117: readings at or beyond the maximum range become ``+inf`` (no echo),
readings of 0 (no reading, in CARMEN logs) NaN. :func:`write_map_bag` writes occupancy grids
(``nav_msgs/OccupancyGrid``) and a path (``nav_msgs/Path``) in the ``map`` frame.
"""

from __future__ import annotations

from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path

import numpy as np

from ..geometry.grid import GridGeometry
from . import carmen
from .ros_messages import (
    LASER_SCAN,
    OCCUPANCY_GRID,
    ODOMETRY,
    PATH,
    POSE_STAMPED,
    TF_MESSAGE,
    header,
    odometry_message,
    pose_message,
    rosbags,
    time_message,
    to_ns,
    transform_stamped,
    typestore,
)

#: Bag formats written: ROS 1 (a ``.bag`` file), ROS 2 with the sqlite3 or the MCAP storage (a folder).
STORAGES = ("ros1", "sqlite3", "mcap")


class _Bag:
    """A bag open for writing: topics added on first use, messages serialised for the bag's ROS version."""

    def __init__(self, writer, ros1: bool):
        self.writer, self.ros1, self.store = writer, ros1, typestore(ros1)
        self.connections: dict[str, object] = {}

    def write(self, topic: str, msgtype: str, ns: int, message) -> None:
        if topic not in self.connections:
            self.connections[topic] = self.writer.add_connection(topic, msgtype, typestore=self.store)
        serialize = self.store.serialize_ros1 if self.ros1 else self.store.serialize_cdr
        self.writer.write(self.connections[topic], ns, serialize(message, msgtype))


def check_new_bag(path, option: str = "--bag-out") -> Path:
    """``path``, where a new ROS 2 bag can be written (nothing there yet, in an existing folder), before the
    work that fills it; ValueError otherwise, or :class:`~.ros_messages.RosExtraMissing`."""
    rosbags()
    path = Path(path)
    if path.exists():
        raise ValueError(f"{option} {path}: exists (a ROS 2 bag is written into a new folder)")
    if not path.parent.is_dir():
        raise ValueError(f"{option} {path}: {path.parent} is not a folder")
    return path


@contextmanager
def open_bag(path, storage: str = "sqlite3") -> Iterator[_Bag]:
    """A new bag at ``path`` (ROS 1: a file; ROS 2: a folder, which must not exist) of ``storage``."""
    if storage not in STORAGES:
        raise ValueError(f"storage: expected one of {list(STORAGES)}, got {storage!r}")
    rb = rosbags()
    path = Path(path)
    if storage == "ros1":
        writer = rb.rosbag1.Writer(path)
    else:
        plugin = rb.rosbag2.StoragePlugin.MCAP if storage == "mcap" else rb.rosbag2.StoragePlugin.SQLITE3
        writer = rb.rosbag2.Writer(path, version=rb.rosbag2.Writer.VERSION_LATEST, storage_plugin=plugin)
    with writer:
        yield _Bag(writer, storage == "ros1")


def write_log_bag(log: carmen.CarmenLog, path, storage: str = "sqlite3", *, max_range: float | None = None,
                  frames: tuple[str, str, str] = ("odom", "base_link", "laser")) -> Path:
    """Write the scans, odometry and truth of ``log`` as a bag (see the module's docstring); each scan's
    odometry pose is the one a CARMEN replay gives it (its line's, else the latest ODOM before it), so that
    the bag replays as the log does. ``max_range`` is for lines that do not carry it (FLASER). Scans before
    any odometry are left out."""
    odom_frame, base_frame, laser_frame = frames
    written = 0
    with open_bag(path, storage) as bag:
        types, odometry = bag.store.types, None
        for record in log.records:
            if isinstance(record, carmen.OdometryRecord):
                odometry = record.pose
            elif isinstance(record, carmen.TruePoseRecord):
                ns = to_ns(record.timestamp)
                truth = types[POSE_STAMPED](header=header(bag.store, ns, "map"),
                                            pose=pose_message(bag.store, *record.true_pose))
                bag.write("/truth", POSE_STAMPED, ns, truth)
            elif isinstance(record, carmen.LaserRecord):
                pose = record.odometry_pose if record.odometry_pose is not None else odometry
                if pose is None:
                    continue
                ns = to_ns(record.timestamp)
                if not written:
                    offset = record.laser_offset if record.laser_offset is not None else np.zeros(3)
                    bag.write("/tf_static", TF_MESSAGE, ns, types[TF_MESSAGE](
                        transforms=[transform_stamped(bag.store, ns, base_frame, laser_frame, *offset)]))
                bag.write("/odom", ODOMETRY, ns, odometry_message(bag.store, ns, odom_frame, base_frame, pose))
                bag.write("/tf", TF_MESSAGE, ns, types[TF_MESSAGE](
                    transforms=[transform_stamped(bag.store, ns, odom_frame, base_frame, *pose)]))
                bag.write("/scan", LASER_SCAN, ns, _laser_scan(bag.store, ns, laser_frame, record, max_range))
                written += 1
    if not written:
        raise ValueError("the log has no scan with odometry to write")
    return Path(path)


def _laser_scan(store, ns: int, frame: str, record: carmen.LaserRecord, max_range: float | None):
    limit = record.max_range if record.max_range is not None else max_range
    if limit is None:
        raise ValueError(f"{record.kind} lines do not carry the laser's maximum range: pass max_range")
    ranges = np.where(record.ranges >= limit, np.inf, np.where(record.ranges > 0.0, record.ranges, np.nan))
    n = record.ranges.size
    return store.types[LASER_SCAN](
        header=header(store, ns, frame), angle_min=record.start_angle,
        angle_max=record.start_angle + (n - 1) * record.angular_resolution,
        angle_increment=record.angular_resolution, time_increment=0.0, scan_time=0.0, range_min=0.0,
        range_max=float(limit), ranges=ranges.astype(np.float32), intensities=np.zeros(0, dtype=np.float32))


def occupancy_grid(store, ns: int, values: np.ndarray, geometry: GridGeometry, frame: str = "map"):
    """A ``nav_msgs/OccupancyGrid`` of int8 ``values`` (-1 unknown, 0-100; row 0 at the bottom, as ROS's
    row-major data from the origin cell) on ``geometry``."""
    types = store.types
    info = types["nav_msgs/msg/MapMetaData"](
        map_load_time=time_message(store, ns), resolution=geometry.resolution, width=geometry.cols,
        height=geometry.rows, origin=pose_message(store, geometry.origin_x, geometry.origin_y, 0.0))
    return types[OCCUPANCY_GRID](header=header(store, ns, frame), info=info,
                                 data=np.ascontiguousarray(values, dtype=np.int8).ravel())


def write_map_bag(path, grids: dict[str, tuple[np.ndarray, GridGeometry]], times: np.ndarray, poses: np.ndarray,
                  *, path_topic: str = "/path", storage: str = "sqlite3") -> Path:
    """A ROS 2 bag of occupancy grids ({topic: (values, geometry)}, see :func:`occupancy_grid`) and a path
    (poses (T, 3) at ``times``, seconds) in the ``map`` frame, all stamped with the last time."""
    if storage == "ros1":
        raise ValueError("maps are written to ROS 2 bags (sqlite3 or mcap)")
    end = to_ns(float(times[-1])) if len(times) else 0
    with open_bag(path, storage) as bag:
        for topic, (values, geometry) in grids.items():
            bag.write(topic, OCCUPANCY_GRID, end, occupancy_grid(bag.store, end, values, geometry))
        stamped = [bag.store.types[POSE_STAMPED](header=header(bag.store, to_ns(float(t)), "map"),
                                                 pose=pose_message(bag.store, *pose))
                   for t, pose in zip(times, poses, strict=True)]
        bag.write(path_topic, PATH, end, bag.store.types[PATH](header=header(bag.store, end, "map"), poses=stamped))
    return Path(path)
