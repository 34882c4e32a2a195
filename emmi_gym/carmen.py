"""CARMEN log files: the text format of the public 2D laser SLAM datasets.

Reads ``ODOM``, ``FLASER``, ``RAWLASER1``, ``ROBOTLASER1`` and ``TRUEPOS`` lines (other
message types such as ``PARAM`` or ``SYNC`` are counted and passed over, ``#`` lines
are comments) and writes ``ODOM``, ``ROBOTLASER1`` and ``TRUEPOS``. Numbers are
written in Python's shortest round-trip form, so a log reads back bit for bit.

This module is pure format: the simulator's recorder writes through it and the
SLAM's replay reads through it, and neither knows about the other.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from pathlib import Path
from typing import Iterable, TextIO

import numpy as np


class CarmenFormatError(ValueError):
    """A malformed log line; names the file and the line number."""

    def __init__(self, source: str, line_number: int, message: str):
        self.source, self.line_number = source, line_number
        super().__init__(f"{source}:{line_number}: {message}")


@dataclass(frozen=True)
class OdometryRecord:
    pose: np.ndarray          # x, y, theta of the odometry
    tv: float
    rv: float
    timestamp: float


@dataclass(frozen=True)
class LaserRecord:
    """One scan: beam i points at ``start_angle + i * angular_resolution`` in the laser frame."""

    ranges: np.ndarray
    start_angle: float
    angular_resolution: float
    max_range: float | None   # None for FLASER, whose lines do not carry it
    timestamp: float
    odometry_pose: np.ndarray | None = None   # robot pose by odometry when the scan was taken
    laser_offset: np.ndarray | None = None    # laser pose relative to the robot (x, y, theta)
    kind: str = "ROBOTLASER1"

    @property
    def angles(self) -> np.ndarray:
        return self.start_angle + np.arange(self.ranges.size) * self.angular_resolution


@dataclass(frozen=True)
class TruePoseRecord:
    true_pose: np.ndarray
    odometry_pose: np.ndarray
    timestamp: float


@dataclass
class CarmenLog:
    """The records of a log, in file order, with what was skipped."""

    records: list = field(default_factory=list)
    skipped_bad_lines: int = 0
    ignored_messages: dict[str, int] = field(default_factory=dict)

    def of_type(self, cls) -> list:
        return [r for r in self.records if isinstance(r, cls)]


# ----------------------------------------------------------------------------- reading


class _Fields:
    """Cursor over the whitespace-separated fields of one line."""

    def __init__(self, tokens: list[str]):
        self.tokens, self.pos = tokens, 1

    def take(self, what: str) -> float:
        if self.pos >= len(self.tokens):
            raise ValueError(f"line ends before {what}")
        token = self.tokens[self.pos]
        self.pos += 1
        try:
            value = float(token)
        except ValueError:
            raise ValueError(f"{what}: expected a number, got {token!r}") from None
        if math.isnan(value):
            raise ValueError(f"{what}: NaN is not a valid value")
        return value

    def count(self, what: str) -> int:
        value = self.take(what)
        if value < 0 or value != int(value):
            raise ValueError(f"{what}: expected a count (integer >= 0), got {value!r}")
        return int(value)

    def many(self, n: int, what: str) -> np.ndarray:
        return np.array([self.take(f"{what}[{i}]") for i in range(n)], dtype=np.float64)

    def pose(self, what: str) -> np.ndarray:
        return self.many(3, what)

    def timestamp(self) -> float:
        return self.take("timestamp")  # hostname and logger timestamp follow; not needed


def _parse_odom(f: _Fields) -> OdometryRecord:
    pose = f.pose("odometry pose")
    tv, rv = f.take("tv"), f.take("rv")
    f.take("accel")
    return OdometryRecord(pose, tv, rv, f.timestamp())


def _parse_flaser(f: _Fields) -> LaserRecord:
    n = f.count("num_readings")
    ranges = f.many(n, "range")
    f.pose("laser pose")
    odom = f.pose("odometry pose")
    # FLASER is the classic 180 deg front laser: beams from -90 deg, evenly spaced
    resolution = math.pi / (n - 1) if n > 1 else math.pi
    return LaserRecord(ranges, -math.pi / 2, resolution, None, f.timestamp(), odom, None, "FLASER")


def _parse_laser_header(f: _Fields):
    f.take("laser_type")
    start, _fov, resolution, max_range = f.take("start_angle"), f.take("field_of_view"), \
        f.take("angular_resolution"), f.take("maximum_range")
    f.take("accuracy")
    f.take("remission_mode")
    ranges = f.many(f.count("num_readings"), "range")
    f.many(f.count("num_remissions"), "remission")
    return ranges, start, resolution, max_range


def _parse_rawlaser(f: _Fields) -> LaserRecord:
    ranges, start, resolution, max_range = _parse_laser_header(f)
    return LaserRecord(ranges, start, resolution, max_range, f.timestamp(), None, None, "RAWLASER1")


def _parse_robotlaser(f: _Fields) -> LaserRecord:
    ranges, start, resolution, max_range = _parse_laser_header(f)
    laser_pose, robot_pose = f.pose("laser pose"), f.pose("robot pose")
    for what in ("laser_tv", "laser_rv", "forward_safety_dist", "side_safety_dist", "turn_axis"):
        f.take(what)
    dx, dy = laser_pose[0] - robot_pose[0], laser_pose[1] - robot_pose[1]
    c, s = math.cos(robot_pose[2]), math.sin(robot_pose[2])
    offset = np.array([c * dx + s * dy, -s * dx + c * dy,
                       (laser_pose[2] - robot_pose[2] + math.pi) % (2 * math.pi) - math.pi])
    return LaserRecord(ranges, start, resolution, max_range, f.timestamp(), robot_pose, offset, "ROBOTLASER1")


def _parse_truepos(f: _Fields) -> TruePoseRecord:
    true_pose, odom = f.pose("true pose"), f.pose("odometry pose")
    return TruePoseRecord(true_pose, odom, f.timestamp())


_PARSERS = {"ODOM": _parse_odom, "FLASER": _parse_flaser, "RAWLASER1": _parse_rawlaser,
            "ROBOTLASER1": _parse_robotlaser, "TRUEPOS": _parse_truepos}


def parse_lines(lines: Iterable[str], source: str = "<log>", *, skip_bad_lines: bool = False) -> CarmenLog:
    """Parse log lines; a malformed line raises :class:`CarmenFormatError` (or is counted, if skipping)."""
    log = CarmenLog()
    for number, line in enumerate(lines, start=1):
        tokens = line.split()
        if not tokens or tokens[0].startswith("#"):
            continue
        parser = _PARSERS.get(tokens[0])
        if parser is None:
            log.ignored_messages[tokens[0]] = log.ignored_messages.get(tokens[0], 0) + 1
            continue
        try:
            log.records.append(parser(_Fields(tokens)))
        except ValueError as exc:
            if not skip_bad_lines:
                raise CarmenFormatError(source, number, f"{tokens[0]}: {exc}") from None
            log.skipped_bad_lines += 1
    return log


def read_log(path, *, skip_bad_lines: bool = False) -> CarmenLog:
    """Read a CARMEN log file (see :func:`parse_lines`)."""
    path = Path(path)
    with path.open() as fh:
        return parse_lines(fh, str(path), skip_bad_lines=skip_bad_lines)


# ----------------------------------------------------------------------------- writing

_HOST = "emmi-gym"


def _token(v) -> str:
    if isinstance(v, str):
        return v
    if isinstance(v, (int, np.integer)):
        return str(int(v))
    return repr(float(v))  # shortest round-trip form


def _join(*parts) -> str:
    return " ".join(map(_token, parts))


def write_odometry(fh: TextIO, pose, tv: float, rv: float, timestamp: float) -> None:
    fh.write(_join("ODOM", *pose, tv, rv, 0, timestamp, _HOST, timestamp) + "\n")


def write_robotlaser(fh: TextIO, ranges, start_angle: float, fov: float, angular_resolution: float,
                     max_range: float, robot_pose, timestamp: float, range_accuracy: float = 0.01) -> None:
    """A ROBOTLASER1 line for a laser mounted at the robot's centre (laser pose = robot pose)."""
    fh.write(_join("ROBOTLASER1", 0, start_angle, fov, angular_resolution, max_range, range_accuracy, 0,
                   len(ranges), *ranges, 0, *robot_pose, *robot_pose, 0, 0, 0, 0, 0,
                   timestamp, _HOST, timestamp) + "\n")


def write_truepos(fh: TextIO, true_pose, odometry_pose, timestamp: float) -> None:
    fh.write(_join("TRUEPOS", *true_pose, *odometry_pose, timestamp, _HOST, timestamp) + "\n")
