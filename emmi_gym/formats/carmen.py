"""CARMEN log files: the text format of the public 2D laser SLAM datasets.

Reads ``ODOM``, ``FLASER``, ``RAWLASER1``, ``ROBOTLASER1`` and ``TRUEPOS`` lines, plain or
gzipped, and the ``PARAM`` lines that give the front laser's mounting offset; other
message types (``SYNC``, ``NEFF``, other ``PARAM`` names, ...) are counted by type and
passed over, ``#`` lines are comments. Every record must have exactly its fields, then
the timestamp, hostname and logger timestamp: a line with extra tokens (two lines glued
together), NUL bytes or bytes that are not UTF-8 is malformed, an error naming the file
and line (or, with ``skip_bad_lines``, counted). Writes ``ODOM``, ``ROBOTLASER1`` and
``TRUEPOS``. Numbers are written in Python's shortest round-trip form, so a log reads
back bit for bit.

This module is pure format: the simulator's recorder writes through it and the
SLAM's replay reads through it, and neither knows about the other.
"""

from __future__ import annotations

import gzip
import math
from dataclasses import dataclass, field, replace
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
    """The records of a log, in file order, with what was skipped (bad lines by message type)."""

    records: list = field(default_factory=list)
    skipped_bad_lines: dict[str, int] = field(default_factory=dict)
    ignored_messages: dict[str, int] = field(default_factory=dict)
    scans_without_echo: int = 0  # laser lines whose every range is 0 (kept: the motion still counts)

    def of_type(self, cls) -> list:
        return [r for r in self.records if isinstance(r, cls)]

    def report(self) -> list[str]:
        """What was not used, by type and count, one sentence each (empty when every line was read)."""
        lines = []
        if self.skipped_bad_lines:
            lines.append("skipped malformed lines: " + _counts(self.skipped_bad_lines))
        if self.ignored_messages:
            lines.append("ignored messages: " + _counts(self.ignored_messages))
        if self.scans_without_echo:
            lines.append(f"{self.scans_without_echo} scans have no echo (every range 0): they add nothing to the map")
        return lines


def _counts(by_type: dict[str, int]) -> str:
    return ", ".join(f"{count} {name}" for name, count in sorted(by_type.items()))


#: PARAM names of the front laser's mounting offset on the robot (CARMEN's robot module).
LASER_OFFSET_PARAMS = {"robot_frontlaser_offset": 0, "robot_frontlaser_side_offset": 1,
                       "robot_frontlaser_angular_offset": 2}


# ----------------------------------------------------------------------------- reading

#: The most readings a laser line may hold (real scanners have at most a few thousand beams).
MAX_READINGS = 100_000


class _Fields:
    """Cursor over the whitespace-separated fields of one line."""

    def __init__(self, tokens: list[str]):
        self.tokens, self.pos = tokens, 1

    def take(self, what: str, minimum: float = -math.inf, above: bool = False) -> float:
        """The next field as a finite number >= ``minimum`` (> with ``above``)."""
        if self.pos >= len(self.tokens):
            raise ValueError(f"line ends before {what}")
        token = self.tokens[self.pos]
        self.pos += 1
        try:
            value = float(token)
        except ValueError:
            raise ValueError(f"{what}: expected a number, got {token[:40]!r}") from None
        if not math.isfinite(value):
            raise ValueError(f"{what}: expected a finite number, got {token[:40]!r}")
        if value < minimum or (above and value == minimum):
            raise ValueError(f"{what}: expected a number {'>' if above else '>='} {minimum:g}, got {token[:40]!r}")
        return value

    def count(self, what: str, maximum: int = MAX_READINGS) -> int:
        """A count of the fields that follow: a whole number the rest of the line can hold."""
        value = self.take(what, 0.0)
        if value != int(value) or value > maximum:
            raise ValueError(f"{what}: expected a count (an integer in [0, {maximum}]), got {value!r}")
        if value > len(self.tokens) - self.pos:
            raise ValueError(f"{what} is {int(value)}, but the line has only {len(self.tokens) - self.pos} fields "
                             "after it")
        return int(value)

    def numbers_before_host(self) -> int | None:
        """How many fields from here on come before the first that is not a number (the hostname)."""
        for i in range(self.pos, len(self.tokens)):
            try:
                float(self.tokens[i])
            except ValueError:
                return i - self.pos
        return None

    def many(self, n: int, what: str, minimum: float = -math.inf) -> np.ndarray:
        return np.array([self.take(f"{what}[{i}]", minimum) for i in range(n)], dtype=np.float64)

    def pose(self, what: str) -> np.ndarray:
        return self.many(3, what)

    def timestamp(self) -> float:
        """The record's timestamp, which must be followed by the hostname and the logger timestamp only."""
        value = self.take("timestamp")
        rest = self.tokens[self.pos:]
        if len(rest) > 2:
            raise ValueError(f"{len(rest) - 2} tokens after the logger timestamp (expected: timestamp hostname "
                             f"logger_timestamp; two lines glued together?), from {_excerpt(rest[2:])}")
        if len(rest) == 2:
            try:
                float(rest[1])
            except ValueError:
                raise ValueError(f"logger timestamp: expected a number, got {_excerpt(rest[1:])}") from None
        return value


def _excerpt(tokens: list[str], n: int = 3) -> str:
    text = " ".join(tokens[:n])
    return repr(text[:60] + ("..." if len(tokens) > n or len(text) > 60 else ""))


def _parse_odom(f: _Fields) -> OdometryRecord:
    pose = f.pose("odometry pose")
    tv, rv = f.take("tv"), f.take("rv")
    f.take("accel")
    return OdometryRecord(pose, tv, rv, f.timestamp())


def _parse_flaser(f: _Fields, fov: float) -> LaserRecord:
    n = f.count("num_readings")
    numbers = f.numbers_before_host()
    if numbers is not None and numbers != n + 7:  # the ranges, two poses, the timestamp, then the hostname
        raise ValueError(f"num_readings is {n}, but the line has {numbers - 7} ranges before its two poses, "
                         "timestamp and hostname")
    ranges = f.many(n, "range", 0.0)
    f.pose("laser pose")
    odom = f.pose("odometry pose")
    # FLASER lines do not say their field of view: ``fov``, centred, beams evenly spaced
    resolution = fov / (n - 1) if n > 1 else fov
    return LaserRecord(ranges, -fov / 2, resolution, None, f.timestamp(), odom, None, "FLASER")


def _parse_laser_header(f: _Fields):
    f.take("laser_type")
    start, _fov = f.take("start_angle"), f.take("field_of_view")
    # beams must sweep counter-clockwise, and a maximum range must be one
    resolution, max_range = f.take("angular_resolution", 0.0, above=True), f.take("maximum_range", 0.0, above=True)
    f.take("accuracy")
    f.take("remission_mode")
    ranges = f.many(f.count("num_readings"), "range", 0.0)
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


_PARSERS = {"ODOM": _parse_odom, "RAWLASER1": _parse_rawlaser, "ROBOTLASER1": _parse_robotlaser,
            "TRUEPOS": _parse_truepos}


def _tokens(line: str | bytes) -> list[str]:
    """The whitespace-separated tokens of a line; ValueError for bytes that are not text."""
    if isinstance(line, bytes):
        try:
            line = line.decode("utf-8")
        except UnicodeDecodeError as exc:
            raise ValueError(f"bytes that are not UTF-8 text (byte {exc.start}); is this a CARMEN log?") from None
    if "\0" in line:
        raise ValueError(f"NUL bytes (at character {line.index(chr(0))}): a corrupt line")
    return line.split()


def _parse_param(f: _Fields, offset: np.ndarray) -> bool:
    """Fold a PARAM line into the front laser's ``offset`` (x, y, theta); False if it names another parameter."""
    if len(f.tokens) < 2 or f.tokens[1] not in LASER_OFFSET_PARAMS:
        return False
    f.pos = 2
    offset[LASER_OFFSET_PARAMS[f.tokens[1]]] = f.take(f.tokens[1])
    return True


def parse_lines(lines: Iterable[str], source: str = "<log>", *, skip_bad_lines: bool = False,
                flaser_fov: float = math.pi) -> CarmenLog:
    """Parse log lines; a malformed line raises :class:`CarmenFormatError` (or is counted by type, if skipping).

    ``flaser_fov`` (radians) is the field of view of FLASER lines, which do not carry it
    (180 degrees: the SICK LMS of the classic datasets). A front-laser offset from
    ``PARAM`` lines applies to the FLASER lines after it.
    """
    if not 0.0 < flaser_fov <= 2.0 * math.pi:
        raise ValueError(f"flaser_fov must be in (0, 2 pi] radians, got {flaser_fov!r}")
    log = CarmenLog()
    offset = np.zeros(3)
    for number, line in enumerate(lines, start=1):
        try:
            tokens = _tokens(line)
        except ValueError as exc:
            if not skip_bad_lines:
                raise CarmenFormatError(source, number, str(exc)) from None
            log.skipped_bad_lines["unreadable"] = log.skipped_bad_lines.get("unreadable", 0) + 1
            continue
        if not tokens or tokens[0].startswith("#"):
            continue
        kind = tokens[0]
        try:
            record = None
            if kind == "FLASER":
                record = _parse_flaser(_Fields(tokens), flaser_fov)
                if np.any(offset):
                    record = replace(record, laser_offset=offset.copy())
            elif kind in _PARSERS:
                record = _PARSERS[kind](_Fields(tokens))
            elif not (kind == "PARAM" and _parse_param(_Fields(tokens), offset)):
                log.ignored_messages[kind] = log.ignored_messages.get(kind, 0) + 1
            if record is not None:
                log.records.append(record)
                if isinstance(record, LaserRecord) and not np.any(record.ranges > 0):
                    log.scans_without_echo += 1
        except ValueError as exc:
            if not skip_bad_lines:
                raise CarmenFormatError(source, number, f"{kind[:40]}: {exc}") from None
            log.skipped_bad_lines[kind] = log.skipped_bad_lines.get(kind, 0) + 1
    return log


def read_log(path, *, skip_bad_lines: bool = False, flaser_fov: float = math.pi, progress: bool = False) -> CarmenLog:
    """Read a CARMEN log file, plain or gzipped (see :func:`parse_lines`); ``progress`` shows a bar of
    the bytes read (a 250 MB log takes a while)."""
    path = Path(path)
    if path.is_dir():
        raise ValueError(f"{path}: is a folder, expected a CARMEN log file")
    with path.open("rb") as raw:
        gzipped = raw.read(2) == b"\x1f\x8b"
        raw.seek(0)
        fh = gzip.GzipFile(fileobj=raw) if gzipped else raw
        lines = _with_progress(fh, raw, path) if progress else fh
        try:
            return parse_lines(lines, str(path), skip_bad_lines=skip_bad_lines, flaser_fov=flaser_fov)
        except (OSError, EOFError) as exc:  # a truncated or corrupt gzip stream
            raise ValueError(f"{path}: cannot be read as gzip ({exc})") from None


def _with_progress(lines, raw, path: Path, every: int = 2000):
    """The lines, with a tqdm bar of the bytes of the file read so far (compressed ones for gzip)."""
    from tqdm.auto import tqdm

    with tqdm(total=path.stat().st_size, unit="B", unit_scale=True, desc=f"reading {path.name}") as bar:
        for number, line in enumerate(lines):
            if number % every == 0:
                bar.update(raw.tell() - bar.n)
            yield line
        bar.update(raw.tell() - bar.n)


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
