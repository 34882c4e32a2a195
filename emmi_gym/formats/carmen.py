"""CARMEN log files: the text format of the public 2D laser SLAM datasets.

Reads ``ODOM``, ``FLASER``, ``RAWLASER1``, ``ROBOTLASER1`` and ``TRUEPOS`` lines, plain or
gzipped, and the ``PARAM`` lines that give the front laser's mounting offset; other
message types (``SYNC``, ``NEFF``, other ``PARAM`` names, ...) are counted by type and
passed over, ``#`` lines are comments. Every record must have exactly its fields, then
the timestamp, hostname and logger timestamp: a line with extra tokens (two lines glued
together), NUL bytes, bytes that are not UTF-8, characters that are not ASCII (a digit or
space of another script) or numbers Python reads but C does not (``1_000``) is malformed, an
error naming the file and line (or, with ``skip_bad_lines``, counted); so is a number that is
not finite. Laser and odometry lines whose timestamps go backwards, and laser lines whose
timestamps are all the same, are reported with the line.

Reading is bounded by what a log can hold, not by what a file can: lines are read at most
:data:`MAX_LINE_BYTES` long (a stream without newlines is refused at that length, a binary
one at its first line), :data:`MAX_IDLE_LINES` lines in a row that hold no message end the
reading, and the records read may take at most :data:`MAX_LOG_BYTES` of memory.

Writes ``ODOM``, ``ROBOTLASER1`` and ``TRUEPOS``. Numbers are written in Python's shortest
round-trip form, so a log reads back bit for bit.

This module is pure format: the simulator's recorder writes through it and the
SLAM's replay reads through it, and neither knows about the other.
"""

from __future__ import annotations

import gzip
import math
import unicodedata
from collections.abc import Iterable
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import TextIO

import numpy as np

from ..inputs.errors import FieldError
from ..inputs.user_paths import input_file


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


class CarmenFileError(FieldError):
    """A log file cannot be read as one (a folder, a device, not text); names the file."""


@dataclass
class CarmenLog:
    """The records of a log, in file order, with what was skipped (bad lines by message type), what is
    wrong with its laser lines' timestamps (sentences naming the lines) and, from readers of other
    formats (:mod:`.ros_bags`), other warnings a replay should print before it starts."""

    records: list = field(default_factory=list)
    skipped_bad_lines: dict[str, int] = field(default_factory=dict)
    ignored_messages: dict[str, int] = field(default_factory=dict)
    scans_without_echo: int = 0  # laser lines whose every range is 0 (kept: the motion still counts)
    timing: list[str] = field(default_factory=list)
    warnings: list[str] = field(default_factory=list)

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
        return lines + self.timing + self.warnings


def _counts(by_type: dict[str, int]) -> str:
    return ", ".join(f"{count} {name}" for name, count in sorted(by_type.items()))


#: PARAM names of the front laser's mounting offset on the robot (CARMEN's robot module).
LASER_OFFSET_PARAMS = {"robot_frontlaser_offset": 0, "robot_frontlaser_side_offset": 1,
                       "robot_frontlaser_angular_offset": 2}


# ----------------------------------------------------------------------------- reading

#: The most readings a laser line may hold (real scanners have at most a few thousand beams).
MAX_READINGS = 100_000
#: The longest line read, bytes: a laser line of :data:`MAX_READINGS` ranges and as many remissions, each
#: written in at most 20 characters (a line of 10,000 beams takes a few hundred kB).
MAX_LINE_BYTES = 2 * MAX_READINGS * 20
#: Lines in a row that hold no message (empty, comments, unreadable ones skipped) after which a stream is not
#: taken for a log (real logs have a header of a few dozen comments).
MAX_IDLE_LINES = 100_000
#: The most memory the records read may take (counted as :data:`RECORD_BYTES` per record plus its ranges):
#: 270,000 scans of 180 beams, from a log of about 250 MB of text.
MAX_LOG_BYTES = 512 * 2**20
RECORD_BYTES = 500


class _Fields:
    """Cursor over the whitespace-separated fields of one line."""

    def __init__(self, tokens: list[str]):
        self.tokens, self.pos = tokens, 1

    def number(self, what: str, minimum: float = -math.inf, above: bool = False) -> float:
        """The next field as a finite number >= ``minimum`` (> with ``above``)."""
        if self.pos >= len(self.tokens):
            raise ValueError(f"line ends before {what}")
        token = self.tokens[self.pos]
        self.pos += 1
        try:
            if "_" in token:  # Python reads 1_000 as a number; C, and the logs' writers, do not
                raise ValueError
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
        value = self.number(what, 0.0)
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

    def numbers(self, n: int, what: str, minimum: float = -math.inf) -> np.ndarray:
        """The next ``n`` fields as finite numbers >= ``minimum`` (``what[i]`` names each in an error)."""
        return np.array([self.number(f"{what}[{i}]", minimum) for i in range(n)], dtype=np.float64)

    def pose(self, what: str) -> np.ndarray:
        return self.numbers(3, what)

    def timestamp(self) -> float:
        """The record's timestamp, which must be followed by the hostname and the logger timestamp only."""
        value = self.number("timestamp")
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
    tv, rv = f.number("tv"), f.number("rv")
    f.number("accel")
    return OdometryRecord(pose, tv, rv, f.timestamp())


def _parse_flaser(f: _Fields, fov: float) -> LaserRecord:
    n = f.count("num_readings")
    numbers = f.numbers_before_host()
    if numbers is not None and numbers != n + 7:  # the ranges, two poses, the timestamp, then the hostname
        raise ValueError(f"num_readings is {n}, but the line has {numbers - 7} ranges before its two poses, "
                         "timestamp and hostname")
    ranges = f.numbers(n, "range", 0.0)
    f.pose("laser pose")
    odom = f.pose("odometry pose")
    # FLASER lines do not say their field of view: ``fov``, centred, beams evenly spaced
    resolution = fov / (n - 1) if n > 1 else fov
    return LaserRecord(ranges, -fov / 2, resolution, None, f.timestamp(), odom, None, "FLASER")


def _parse_laser_header(f: _Fields):
    f.number("laser_type")
    start, _fov = f.number("start_angle"), f.number("field_of_view")
    # beams must sweep counter-clockwise, and a maximum range must be one
    resolution, max_range = f.number("angular_resolution", 0.0, above=True), f.number("maximum_range", 0.0, above=True)
    f.number("accuracy")
    f.number("remission_mode")
    ranges = f.numbers(f.count("num_readings"), "range", 0.0)
    f.numbers(f.count("num_remissions"), "remission")
    return ranges, start, resolution, max_range


def _parse_rawlaser(f: _Fields) -> LaserRecord:
    ranges, start, resolution, max_range = _parse_laser_header(f)
    return LaserRecord(ranges, start, resolution, max_range, f.timestamp(), None, None, "RAWLASER1")


def _parse_robotlaser(f: _Fields) -> LaserRecord:
    ranges, start, resolution, max_range = _parse_laser_header(f)
    laser_pose, robot_pose = f.pose("laser pose"), f.pose("robot pose")
    for what in ("laser_tv", "laser_rv", "forward_safety_dist", "side_safety_dist", "turn_axis"):
        f.number(what)
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


def _text(line: str | bytes) -> str:
    """A line as text; ValueError for bytes that are not text."""
    if isinstance(line, bytes):
        try:
            line = line.decode("utf-8")
        except UnicodeDecodeError as exc:
            raise ValueError(f"bytes that are not UTF-8 text (byte {exc.start}); is this a CARMEN log?") from None
    if "\0" in line:
        raise ValueError(f"NUL bytes (at character {line.index(chr(0))}): a corrupt line")
    return line


def _check_ascii(line: str) -> None:
    """ValueError naming the first character that is not ASCII (a record's fields are ASCII numbers and names;
    Python would read other scripts' digits as numbers and their spaces as separators)."""
    if not line.isascii():
        column, char = next((k, c) for k, c in enumerate(line) if not c.isascii())
        raise ValueError(f"the character U+{ord(char):04X} ({unicodedata.name(char, 'unnamed')}) at column "
                         f"{column + 1}: expected ASCII digits, signs and spaces")


def _parse_param(f: _Fields, offset: np.ndarray) -> None:
    """Fold a PARAM line of :data:`LASER_OFFSET_PARAMS` into the front laser's ``offset`` (x, y, theta)."""
    f.pos = 2
    offset[LASER_OFFSET_PARAMS[f.tokens[1]]] = f.number(f.tokens[1])


def parse_lines(lines: Iterable[str], source: str = "<log>", *, skip_bad_lines: bool = False,
                flaser_fov: float = math.pi, max_bytes: int = MAX_LOG_BYTES) -> CarmenLog:
    """Parse log lines; a malformed line raises :class:`CarmenFormatError` (or is counted by type, if skipping).

    ``flaser_fov`` (radians) is the field of view of FLASER lines, which do not carry it
    (180 degrees: the SICK LMS of the classic datasets). A front-laser offset from
    ``PARAM`` lines applies to the FLASER lines after it. What is not a log is refused, whether
    skipping or not: a line longer than :data:`MAX_LINE_BYTES`, :data:`MAX_IDLE_LINES` lines in a
    row without a message, records taking more than ``max_bytes`` of memory.
    """
    if not 0.0 < flaser_fov <= 2.0 * math.pi:
        raise ValueError(f"flaser_fov must be in (0, 2 pi] radians, got {flaser_fov!r}")
    log = CarmenLog()
    offset = np.zeros(3)
    held = idle = 0
    times = {LaserRecord: _Timestamps("laser"), OdometryRecord: _Timestamps("odometry", frozen_reported=False)}
    for number, line in enumerate(lines, start=1):
        if len(line) > MAX_LINE_BYTES:
            raise CarmenFormatError(source, number, _too_long())
        try:
            text = _text(line)
        except ValueError as exc:
            if not skip_bad_lines:
                raise CarmenFormatError(source, number, str(exc)) from None
            log.skipped_bad_lines["unreadable"] = log.skipped_bad_lines.get("unreadable", 0) + 1
            idle = _idle(idle, source, number)
            continue
        tokens = text.split()
        if not tokens or tokens[0].startswith("#"):
            idle = _idle(idle, source, number)
            continue
        idle = 0
        kind = tokens[0]
        try:
            record = None
            if kind == "FLASER":
                _check_ascii(text)
                record = _parse_flaser(_Fields(tokens), flaser_fov)
                if np.any(offset):
                    record = replace(record, laser_offset=offset.copy())
            elif kind in _PARSERS:
                _check_ascii(text)
                record = _PARSERS[kind](_Fields(tokens))
            elif kind == "PARAM" and len(tokens) > 1 and tokens[1] in LASER_OFFSET_PARAMS:
                _check_ascii(text)
                _parse_param(_Fields(tokens), offset)
            else:
                log.ignored_messages[kind] = log.ignored_messages.get(kind, 0) + 1
        except ValueError as exc:
            if not skip_bad_lines:
                raise CarmenFormatError(source, number, f"{kind[:40]}: {exc}") from None
            log.skipped_bad_lines[kind] = log.skipped_bad_lines.get(kind, 0) + 1
            continue
        if record is None:
            continue
        log.records.append(record)
        held += RECORD_BYTES + (record.ranges.nbytes if isinstance(record, LaserRecord) else 0)
        if held > max_bytes:
            raise CarmenFormatError(source, number, f"the records read so far take more than {max_bytes / 2**20:.3g} "
                                    f"MiB of memory ({len(log.records):,} records): a replay holds the whole log; "
                                    "split it")
        if type(record) in times:
            times[type(record)].add(record.timestamp, number)
        if isinstance(record, LaserRecord) and not np.any(record.ranges > 0):
            log.scans_without_echo += 1
    log.timing = [sentence for kind in times.values() for sentence in kind.report()]
    return log


def _too_long() -> str:
    return (f"a line longer than {MAX_LINE_BYTES:,} bytes (a laser line of {MAX_READINGS:,} readings takes less): "
            "not a CARMEN log?")


def _idle(idle: int, source: str, number: int) -> int:
    """One more line without a message; :class:`CarmenFormatError` once there are :data:`MAX_IDLE_LINES`."""
    if idle + 1 >= MAX_IDLE_LINES:
        raise CarmenFormatError(source, number, f"{MAX_IDLE_LINES:,} lines in a row hold no message (empty lines, "
                                "comments or unreadable lines): not a CARMEN log?")
    return idle + 1


class _Timestamps:
    """Whether the timestamps of one kind of line (``what``: "laser", "odometry") go forward: the steps back (the
    first one's lines) and, if ``frozen_reported``, whether all are the same."""

    def __init__(self, what: str, frozen_reported: bool = True):
        self.what, self.frozen_reported = what, frozen_reported
        self.count = self.back = 0
        self.first = self.last = None  # (timestamp, line)
        self.first_back = None
        self.varies = False

    def add(self, timestamp: float, line: int) -> None:
        self.count += 1
        if self.last is None:
            self.first = (timestamp, line)
        else:
            if timestamp < self.last[0]:
                self.back += 1
                self.first_back = self.first_back or (line, timestamp, self.last)
            self.varies = self.varies or timestamp != self.first[0]
        self.last = (timestamp, line)

    def report(self) -> list[str]:
        sentences = []
        if self.back:
            line, timestamp, (previous, previous_line) = self.first_back
            sentences.append(f"{self.what} timestamps go backwards {self.back} time(s), first at line {line} "
                             f"({timestamp!r} after {previous!r} at line {previous_line}): times and rates from them "
                             "are not trustworthy")
        if self.frozen_reported and self.count > 1 and not self.varies:
            sentences.append(f"all {self.count} {self.what} lines have the same timestamp {self.first[0]!r} (lines "
                             f"{self.first[1]} to {self.last[1]}): the log carries no time")
        return sentences


def read_log(path, *, skip_bad_lines: bool = False, flaser_fov: float = math.pi, progress: bool = False,
             max_bytes: int = MAX_LOG_BYTES) -> CarmenLog:
    """Read a CARMEN log file, plain or gzipped, or a pipe (see :func:`parse_lines`); ``progress`` shows a bar
    of the bytes read (a 250 MB log takes a while)."""
    path = input_file(path, "CARMEN log file", CarmenFileError, pipes=True)
    with path.open("rb") as raw:
        head = raw.peek(2)[:2]
        fh = gzip.GzipFile(fileobj=raw) if head == b"\x1f\x8b" else raw
        lines = _log_lines(fh, str(path))
        if progress:
            lines = _with_progress(lines, raw, path)
        try:
            return parse_lines(lines, str(path), skip_bad_lines=skip_bad_lines, flaser_fov=flaser_fov,
                               max_bytes=max_bytes)
        except (OSError, EOFError) as exc:  # a truncated or corrupt gzip stream
            raise ValueError(f"{path}: cannot be read as gzip ({exc})") from None
        finally:
            lines.close()  # ends the progress bar's line now, not after the error's message


def _log_lines(stream, source: str):
    """The lines of a log stream, each read at most :data:`MAX_LINE_BYTES` long (a stream without newlines
    takes no more memory than that); binary data is refused at its first line."""
    number = 0
    while True:
        line = stream.readline(MAX_LINE_BYTES + 1)
        if not line:
            return
        number += 1
        if number == 1 and b"\0" in line:
            nul = line.index(b"\0")
            raise CarmenFileError(source, "",
                                  f"a CARMEN log, which is text, not binary data (NUL bytes from byte {nul})")
        if len(line) > MAX_LINE_BYTES:
            raise CarmenFormatError(source, number, _too_long())
        yield line


def _with_progress(lines, raw, path: Path, every: int = 2000):
    """The lines, with a tqdm bar of the bytes of the file read so far (compressed ones for gzip; none for a
    pipe, whose size is not known)."""
    from tqdm.auto import tqdm

    size = path.stat().st_size if path.is_file() else None
    with tqdm(total=size, unit="B", unit_scale=True, desc=f"reading {path.name}") as bar:
        for number, line in enumerate(lines):
            if number % every == 0:
                bar.update(_position(raw) - bar.n)
            yield line
        bar.update(_position(raw) - bar.n)


def _position(raw) -> int:
    try:
        return raw.tell()
    except OSError:  # a pipe
        return 0


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
