"""ROS 1 and ROS 2 bags in, as the records a replay reads from a CARMEN log.

A bag (a ROS 1 ``.bag``; a ROS 2 folder, or its ``.db3`` or ``.mcap`` file) is read with ``rosbags``
(:mod:`.ros_messages`), in one pass over the topics it needs:

- the scans: ``sensor_msgs/LaserScan`` of the ``scan`` topic (default: the bag's only one). Their ranges
  follow REP 117: ``+inf`` and readings above ``range_max`` are no echo (the replay's maximum range), NaN,
  ``-inf`` and readings below ``range_min`` are no reading (left out). A scan whose beams turn clockwise
  (``angle_increment < 0``) is reversed;
- the odometry: ``nav_msgs/Odometry`` of the ``odom`` topic, or the ``odom_frame`` -> ``base_frame``
  transforms of ``/tf`` (REP 105: ``odom`` -> ``base_link``), projected on the plane (REP 103);
- the laser's mounting: the chain of transforms from the base frame to the scans' ``frame_id`` in
  ``/tf_static`` (or, for ROS 1 bags of the older static publishers, in ``/tf``); a laser mounted upside
  down has its beams mirrored. Without one the laser is taken at the robot's centre, with a warning;
- a ground truth (``truth``): ``nav_msgs/Odometry``, ``geometry_msgs/PoseStamped`` or
  ``PoseWithCovarianceStamped``, as the CARMEN logs' TRUEPOS lines.

Every scan gets the odometry pose at its header stamp, interpolated between the two odometry samples
around it (:func:`emmi_gym.geometry.motion.interpolate_poses`); a scan outside the odometry's time span
gets none, and the replay skips it. Time is the messages' header stamps, not the bag's receive times;
odometry whose stamps go back in the bag's order, and odometry or ground truth that is not finite, are
refused, naming the message.
Bad input raises :class:`BagError`, one line naming the bag, the topic, what was expected and what was
found; the records read may take at most ``max_bytes`` of memory, as a CARMEN log's.
"""

from __future__ import annotations

import math
import sqlite3
import struct
from collections.abc import Iterator
from contextlib import contextmanager
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ..geometry.motion import interpolate_poses
from ..inputs.errors import FieldError
from . import carmen
from .ros_messages import (
    LASER_SCAN,
    ODOMETRY,
    POSE_STAMPED,
    POSE_WITH_COVARIANCE_STAMPED,
    TF_MESSAGE,
    planar,
    rosbags,
    seconds,
    stamp_ns,
    typestore,
)

#: What a path must end with to be read as a bag (a ROS 2 bag's folder is one too).
BAG_SUFFIXES = (".bag", ".db3", ".mcap")
TRUTH_TYPES = (ODOMETRY, POSE_STAMPED, POSE_WITH_COVARIANCE_STAMPED)
#: Memory counted per odometry, truth or transform sample held (a tuple of a few floats).
SAMPLE_BYTES = 120


class BagError(FieldError):
    """A bag that cannot be read, or lacks what a replay needs; names the bag and the topic."""


@dataclass(frozen=True)
class BagTopics:
    """Which topics and frames of a bag a replay reads (``replay --scan --odom --odom-frame --base-frame
    --truth``): ``None`` scan is the bag's only LaserScan topic, ``None`` odom reads ``/tf``."""

    scan: str | None = None
    odom: str | None = None
    odom_frame: str = "odom"
    base_frame: str = "base_link"
    truth: str | None = None


def is_bag(path) -> bool:
    """Whether ``path`` names a bag: a ``.bag``, ``.db3`` or ``.mcap`` file, or a folder (a ROS 2 bag)."""
    path = Path(path)
    return path.is_dir() or path.suffix.lower() in BAG_SUFFIXES


def _frame(name: str) -> str:
    return name.lstrip("/")  # ROS 1's tf wrote "/odom"; tf2 and ROS 2 write "odom"


@dataclass
class _Samples:
    """What one pass over a bag collected."""

    scans: list          # (stamp ns, ranges float64, angle_min, angle_increment, range_min, range_max, frame)
    odometry: list       # (stamp ns, x, y, yaw)
    truth: list          # (stamp ns, x, y, yaw)
    links: dict          # child frame -> (parent, x, y, yaw, upside_down); /tf_static over /tf
    base_frame: str
    odometry_message: int = 0  # the message of the latest odometry sample, in its topic

    def add_odometry(self, source: str, topic: str, number: int, stamp: int, pose) -> None:
        """Add the odometry ``pose`` (x, y, yaw) stamped ``stamp`` (ns) of message ``number`` of ``topic``, checked
        finite and stamped no earlier than the odometry before it in the bag (the replay follows odometry in time
        order: a stamp that jumps back would reorder the path); :class:`BagError` naming the message otherwise."""
        _check_finite_pose(source, topic, number, "odometry", pose)
        if self.odometry and stamp < self.odometry[-1][0]:
            raise BagError(source, topic, f"odometry whose stamps never go back in the bag's order (message "
                           f"{self.odometry_message} is stamped {seconds(self.odometry[-1][0])!r} s)",
                           f"message {number} at {seconds(stamp)!r} s")
        self.odometry.append((stamp, *pose))
        self.odometry_message = number

    def add_truth(self, source: str, topic: str, number: int, stamp: int, pose) -> None:
        """Add the true ``pose`` (x, y, yaw) stamped ``stamp`` (ns) of message ``number`` of ``topic``, checked
        finite; :class:`BagError` naming the message otherwise."""
        _check_finite_pose(source, topic, number, "ground-truth", pose)
        self.truth.append((stamp, *pose))


def _check_finite_pose(source: str, topic: str, number: int, what: str, pose) -> None:
    """A :class:`BagError` naming message ``number`` of ``topic`` unless its ``what`` pose (x, y, yaw) is finite."""
    if not all(math.isfinite(value) for value in pose):
        raise BagError(source, topic, f"{what} poses of finite x, y and orientation (message {number}: x "
                       f"{pose[0]!r}, y {pose[1]!r}, yaw {pose[2]!r})")


def read_bag(path, topics: BagTopics = BagTopics(), *, max_bytes: int = carmen.MAX_LOG_BYTES,
             progress: bool = False) -> carmen.CarmenLog:
    """The scans of a bag with their odometry poses and laser mounting, and its ground truth, as a
    :class:`~emmi_gym.formats.carmen.CarmenLog` of ``LaserRecord`` and ``TruePoseRecord``; ``warnings``
    say what the replay should know (no mounting found, readings left out, scans without odometry)."""
    path = Path(path)
    if not path.exists():
        raise FileNotFoundError(f"no bag at {path}")
    source = str(path)
    rb = rosbags()
    with _library_errors(source):
        reader = rb.highlevel.AnyReader([path], default_typestore=typestore(ros1=False))
        with reader:
            chosen, ignored = _choose_topics(source, reader.topics, topics)
            samples = _collect(source, reader, chosen, topics, max_bytes, progress)
    log = _records(source, samples, chosen, topics)
    log.ignored_messages = ignored
    return log


@contextmanager
def _library_errors(source: str) -> Iterator[None]:
    """The library's errors about a damaged or foreign file as :class:`BagError`, one line each (a damaged
    bag's lengths and offsets also fail in the decoding and indexing they drive)."""
    rb = rosbags()
    errors = (rb.highlevel.AnyReaderError, rb.rosbag1.ReaderError, rb.rosbag2.ReaderError, FileNotFoundError,
              sqlite3.DatabaseError, struct.error, EOFError, OverflowError, UnicodeDecodeError, KeyError, IndexError)
    try:
        yield
    except BagError:
        raise
    except errors as exc:
        raise BagError(source, "", "a readable ROS 1 bag or ROS 2 bag (folder, .db3 or .mcap); the reader says: "
                       f"{_one_line(exc)}") from None


def _one_line(exc: BaseException, limit: int = 160) -> str:
    text = " ".join(str(exc).split()) or type(exc).__name__
    return text if len(text) <= limit else text[:limit] + "..."


def _choose_topics(source: str, available: dict, topics: BagTopics) -> tuple[dict[str, str], dict[str, int]]:
    """{role: topic} of the topics read ("scan", "odom", "tf", "tf_static", "truth"), and the others' message
    counts by "topic (type)"."""
    scans = sorted(name for name, info in available.items() if info.msgtype == LASER_SCAN)
    if topics.scan is None:
        if len(scans) != 1:
            found = scans or [f"{name} ({info.msgtype})" for name, info in sorted(available.items())]
            raise BagError(source, "", "one sensor_msgs/LaserScan topic (pass --scan TOPIC to choose)" if scans else
                           "a sensor_msgs/LaserScan topic", found)
        scan = scans[0]
    else:
        scan = _typed(source, available, topics.scan, (LASER_SCAN,), "--scan")
    chosen = {"scan": scan}
    if topics.odom is not None:
        chosen["odom"] = _typed(source, available, topics.odom, (ODOMETRY,), "--odom")
    elif "/tf" not in available:
        odometry = sorted(name for name, info in available.items() if info.msgtype == ODOMETRY)
        raise BagError(source, "/tf", f"odometry: {topics.odom_frame} -> {topics.base_frame} transforms in /tf, or "
                       "an Odometry topic passed with --odom", f"no /tf; Odometry topics {odometry}")
    for role, name in (("tf", "/tf"), ("tf_static", "/tf_static")):
        if name in available:
            chosen[role] = _typed(source, available, name, (TF_MESSAGE,), name)
    if topics.truth is not None:
        chosen["truth"] = _typed(source, available, topics.truth, TRUTH_TYPES, "--truth")
    for role in ("scan", "odom", "truth"):
        if role in chosen and available[chosen[role]].msgcount == 0:
            raise BagError(source, chosen[role], f"{available[chosen[role]].msgtype} messages", "none")
    read = set(chosen.values())
    ignored = {f"{name} ({info.msgtype})": info.msgcount for name, info in available.items()
               if name not in read and info.msgcount}
    return chosen, ignored


def _typed(source: str, available: dict, name: str, types: tuple[str, ...], option: str) -> str:
    """``name``, a topic of the bag of one of ``types``."""
    if name not in available:
        listed = sorted(t for t, info in available.items() if info.msgtype in types)
        raise BagError(source, name, f"a topic of the bag ({option}); its {' or '.join(types)} topics are {listed}",
                       "no such topic")
    if available[name].msgtype not in types:
        raise BagError(source, name, " or ".join(types), available[name].msgtype)
    return name


def _collect(source: str, reader, chosen: dict[str, str], topics: BagTopics, max_bytes: int,
             progress: bool) -> _Samples:
    """One pass over the chosen topics' messages, in the bag's order."""
    role_of = {name: role for role, name in chosen.items()}
    connections = [c for c in reader.connections if c.topic in role_of]
    samples = _Samples([], [], [], {}, _frame(topics.base_frame))
    static: dict = {}
    held, counts = 0, dict.fromkeys(chosen.values(), 0)
    messages = reader.messages(connections=connections)
    if progress:
        from tqdm.auto import tqdm

        messages = tqdm(messages, total=sum(c.msgcount for c in connections), unit="msg", desc="reading bag")
    odom_frame, base_frame = _frame(topics.odom_frame), samples.base_frame
    unreadable = rosbags().highlevel.AnyReaderError
    for connection, _, raw in messages:
        topic = connection.topic
        counts[topic] += 1
        role = role_of[topic]
        try:
            message = reader.deserialize(raw, connection.msgtype)
        except unreadable as exc:  # bytes that are not the type's
            raise BagError(source, topic, f"{connection.msgtype} messages; message {counts[topic]} is not one "
                           f"({_one_line(exc, 100)})") from None
        if role == "scan":
            scan = _scan(source, topic, counts[topic], message)
            held += carmen.RECORD_BYTES + scan[1].nbytes
            samples.scans.append(scan)
        elif role == "odom":
            samples.add_odometry(source, topic, counts[topic], stamp_ns(message.header.stamp),
                                 planar(message.pose.pose.position, message.pose.pose.orientation)[:3])
            samples.base_frame = _frame(message.child_frame_id) or samples.base_frame
            held += SAMPLE_BYTES
        elif role == "truth":
            pose = message.pose.pose if connection.msgtype != POSE_STAMPED else message.pose
            samples.add_truth(source, topic, counts[topic], stamp_ns(message.header.stamp),
                              planar(pose.position, pose.orientation)[:3])
            held += SAMPLE_BYTES
        else:
            for transform in message.transforms:
                parent, child = _frame(transform.header.frame_id), _frame(transform.child_frame_id)
                link = planar(transform.transform.translation, transform.transform.rotation)
                if role == "tf" and parent == odom_frame and child == base_frame and "odom" not in chosen:
                    samples.add_odometry(source, topic, counts[topic], stamp_ns(transform.header.stamp), link[:3])
                elif role == "tf_static":
                    static[child] = (parent, *link)
                else:
                    samples.links.setdefault(child, (parent, *link))
                held += SAMPLE_BYTES
        if held > max_bytes:
            raise BagError(source, topic, f"a bag whose records take at most {max_bytes / 2**20:.3g} MiB of memory "
                           "(a replay holds them all; split it, e.g. with ros2 bag convert or rosbag filter)",
                           f"more after {sum(counts.values()):,} messages")
    samples.links.update(static)
    if not samples.odometry:
        where = chosen.get("odom") or "/tf"
        raise BagError(source, where, f"odometry ({topics.odom_frame} -> {topics.base_frame} transforms)"
                       if where == "/tf" else "Odometry messages",
                       "none" if where != "/tf" else f"transforms {_edges(samples.links)}")
    return samples


def _edges(links: dict) -> list[str]:
    return sorted(f"{parent} -> {child}" for child, (parent, *_) in links.items())


def _scan(source: str, topic: str, number: int, message) -> tuple:
    """(stamp ns, ranges, angle_min, angle_increment, range_min, range_max, frame) of a LaserScan, its beams
    turning counter-clockwise; readings as REP 117 defines them (see the module's docstring)."""
    ranges = np.asarray(message.ranges, dtype=np.float64)
    start, step = float(message.angle_min), float(message.angle_increment)
    low, high = float(message.range_min), float(message.range_max)
    problem = None
    if ranges.size > carmen.MAX_READINGS:
        problem = f"at most {carmen.MAX_READINGS:,} ranges", f"{ranges.size:,}"
    elif not (math.isfinite(step) and step != 0.0 and math.isfinite(start)):
        problem = "a finite angle_min and an angle_increment other than 0", (start, step)
    elif not (0.0 < high < math.inf and 0.0 <= low < high):
        problem = "0 <= range_min < range_max, range_max finite", (low, high)
    if problem is not None:
        raise BagError(source, topic, f"LaserScan messages with {problem[0]}; message {number}", problem[1])
    if step < 0.0:
        ranges, start, step = ranges[::-1], start + (ranges.size - 1) * step, -step
    return (stamp_ns(message.header.stamp), ranges, start, step, low, high, _frame(message.header.frame_id))


def _mounting(frame: str, base: str, links: dict) -> tuple[np.ndarray, bool] | None:
    """The laser frame's planar pose in the base frame (x, y, yaw) along the links child -> parent, and
    whether it is mirrored (mounted upside down); None where no chain of links joins them."""
    matrix, seen = np.eye(3), set()
    while frame != base:
        if frame not in links or frame in seen:
            return None
        seen.add(frame)
        parent, x, y, yaw, upside_down = links[frame]
        c, s, m = math.cos(yaw), math.sin(yaw), -1.0 if upside_down else 1.0
        matrix = np.array([[c, -s * m, x], [s, c * m, y], [0.0, 0.0, 1.0]]) @ matrix
        frame = parent
    offset = np.array([matrix[0, 2], matrix[1, 2], math.atan2(matrix[1, 0], matrix[0, 0])])
    return offset, bool(np.linalg.det(matrix[:2, :2]) < 0.0)


def _series(samples: list) -> tuple[np.ndarray, np.ndarray]:
    """(stamps ns (int64), poses (n, 3)) of (stamp, x, y, yaw) samples, in time order."""
    ordered = sorted(samples, key=lambda sample: sample[0])
    return (np.array([sample[0] for sample in ordered], dtype=np.int64),
            np.array([sample[1:] for sample in ordered], dtype=np.float64).reshape(-1, 3))


def _records(source: str, samples: _Samples, chosen: dict[str, str], topics: BagTopics) -> carmen.CarmenLog:
    """The scans, each with its interpolated odometry pose and its mounting, and the truth, in time order.
    Times are interpolated as nanoseconds from the first odometry stamp (exact in float64 for 100 days)."""
    log = carmen.CarmenLog()
    odometry_ns, odometry = _series(samples.odometry)
    origin = int(odometry_ns[0])
    odometry_times = (odometry_ns - origin).astype(np.float64)
    order = sorted(range(len(samples.scans)), key=lambda k: samples.scans[k][0])
    stamps = np.array([samples.scans[k][0] for k in order], dtype=np.int64)
    poses = interpolate_poses(odometry_times, odometry, (stamps - origin).astype(np.float64))
    if np.isnan(poses[:, 0]).all():
        raise BagError(source, chosen["scan"], f"scans within the odometry's time span ({seconds(origin):g} s to "
                       f"{seconds(odometry_ns[-1]):g} s of {_odometry_source(chosen, topics, samples)})",
                       f"{len(stamps):,} scans from {seconds(stamps[0]):g} s to {seconds(stamps[-1]):g} s")
    mountings = {frame: _mounting(frame or samples.base_frame, samples.base_frame, samples.links)
                 for frame in {scan[6] for scan in samples.scans}}
    left_out = 0
    records = []
    for k, pose in zip(order, poses, strict=True):
        ns, ranges, start, step, low, high, frame = samples.scans[k]
        offset, mirrored = mountings[frame] or (None, False)
        if mirrored:
            ranges, start = ranges[::-1], -(start + (ranges.size - 1) * step)
        no_reading = ~(ranges >= low)  # NaN, -inf, below range_min
        left_out += int(np.count_nonzero(no_reading))
        ranges = np.where(ranges > high, np.inf, np.where(no_reading, 0.0, ranges))
        records.append((ns, 1, carmen.LaserRecord(
            ranges, start, step, high, seconds(ns), None if np.isnan(pose[0]) else pose, offset, "LaserScan")))
    truth_ns, truth = _series(samples.truth)
    if truth_ns.size:  # each true pose with the odometry at its time (or the nearest end), as TRUEPOS lines
        at = np.clip(truth_ns - origin, 0, odometry_ns[-1] - origin).astype(np.float64)
        beside = interpolate_poses(odometry_times, odometry, at)
        records += [(int(t), 0, carmen.TruePoseRecord(pose, near, seconds(int(t))))
                    for t, pose, near in zip(truth_ns, truth, beside, strict=True)]
    log.records = [record for _, _, record in sorted(records, key=lambda r: r[:2])]
    log.warnings = _warnings(samples, chosen, mountings, left_out, int(np.isnan(poses[:, 0]).sum()), topics)
    log.scans_without_echo = sum(1 for record in log.of_type(carmen.LaserRecord) if not np.any(record.ranges > 0))
    return log


def _warnings(samples: _Samples, chosen: dict[str, str], mountings: dict, left_out: int, without_odometry: int,
              topics: BagTopics) -> list[str]:
    scan, sentences = chosen["scan"], []
    for frame, mounting in sorted(mountings.items()):
        if mounting is None:
            sentences.append(f"no transform from {samples.base_frame} to the scans' frame {frame!r} in /tf_static "
                             "or /tf: the laser is taken at the robot's centre, facing forward")
        elif mounting[1]:
            sentences.append(f"the laser frame {frame!r} is mounted upside down: its beams are mirrored")
    if left_out:
        total = sum(scan[1].size for scan in samples.scans)
        sentences.append(f"{left_out:,} of {total:,} readings of {scan} are NaN, -inf or below range_min: left out "
                         "(REP 117: no valid reading)")
    if without_odometry:
        sentences.append(f"{without_odometry:,} of {len(samples.scans):,} scans lie outside the time span of the "
                         f"odometry ({_odometry_source(chosen, topics, samples)}): skipped")
    return sentences


def _odometry_source(chosen: dict[str, str], topics: BagTopics, samples: _Samples) -> str:
    return chosen.get("odom") or f"/tf {_frame(topics.odom_frame)} -> {samples.base_frame}"
