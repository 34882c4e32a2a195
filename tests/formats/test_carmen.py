"""CARMEN logs: a recorded route reads back bit for bit; malformed lines are named by number."""

import math

import numpy as np
import pytest

from emmi_gym.formats import carmen
from emmi_gym.world.laser import LaserConfig
from emmi_gym.world.loader import load_world
from emmi_gym.world.recording import drive_route, write_carmen
from emmi_gym.world.simulator import Simulator


@pytest.fixture(scope="module")
def recorded(tmp_path_factory):
    world = load_world("office")
    sim = Simulator(world, laser=LaserConfig(n_beams=90))
    rec = drive_route(sim, [world.start.xy, (9.5, 1.0), (10.0, 6.0)], np.random.default_rng(7))
    path = write_carmen(rec, sim, tmp_path_factory.mktemp("logs") / "office.log")
    return sim, rec, path


def test_recorded_log_reads_back_the_same_numbers(recorded):
    sim, rec, path = recorded
    log = carmen.read_log(path)
    odom = log.of_type(carmen.OdometryRecord)
    lasers = log.of_type(carmen.LaserRecord)
    truth = log.of_type(carmen.TruePoseRecord)
    assert len(odom) == len(lasers) == len(truth) == len(rec.times) > 50
    np.testing.assert_array_equal([o.pose for o in odom], rec.odometry_poses)
    np.testing.assert_array_equal([t.true_pose for t in truth], rec.true_poses)
    np.testing.assert_array_equal([scan.ranges for scan in lasers], rec.scans)
    np.testing.assert_array_equal([scan.timestamp for scan in lasers], rec.times)
    np.testing.assert_array_equal([scan.odometry_pose for scan in lasers], rec.odometry_poses)
    first = lasers[0]
    np.testing.assert_allclose(first.angles, sim.laser.config.angles, atol=1e-12)
    assert first.max_range == sim.laser.config.max_range
    np.testing.assert_array_equal(first.laser_offset, [0.0, 0.0, 0.0])


def test_same_seed_same_recording_bit_for_bit():
    world = load_world("loop_corridor")
    sim = Simulator(world, laser=LaserConfig(n_beams=60))
    route = world.route("explore")
    a = drive_route(sim, route, np.random.default_rng(11), max_steps=200)
    b = drive_route(sim, route, np.random.default_rng(11), max_steps=200)
    c = drive_route(sim, route, np.random.default_rng(12), max_steps=200)
    for field in ("true_poses", "odometry_poses", "scans", "collisions"):
        np.testing.assert_array_equal(getattr(a, field), getattr(b, field))
    assert not np.array_equal(a.scans, c.scans)


def test_malformed_lines_give_their_line_number(recorded):
    _, _, path = recorded
    lines = path.read_text().splitlines()
    lines[5] = lines[5].replace(lines[5].split()[3], "abc", 1)
    with pytest.raises(carmen.CarmenFormatError, match=r"bad\.log:6: .*expected a number, got 'abc'"):
        carmen.parse_lines(lines, "bad.log")
    lines[9] = "ODOM 1.0 2.0"
    log = carmen.parse_lines(lines, "bad.log", skip_bad_lines=True)
    kinds = (lines[5].split()[0], "ODOM")
    assert sum(log.skipped_bad_lines.values()) == 2 and set(log.skipped_bad_lines) == set(kinds)
    with pytest.raises(carmen.CarmenFormatError, match=r"bad\.log:10: ODOM: line ends before"):
        carmen.parse_lines(["# comment"] * 9 + [lines[9]], "bad.log")


def test_other_laser_formats_and_messages():
    ranges = " ".join(["1.5"] * 181)
    lines = [
        "PARAM robot_front_laser_max 8.0 nohost 0",
        f"FLASER 181 {ranges} 1 2 0.5 1.1 2.1 0.4 12.5 host 12.5",
        f"RAWLASER1 0 -1.5708 3.1416 0.017453 80.0 0.01 0 181 {ranges} 0 13.0 host 13.0",
        f"ROBOTLASER1 0 -1.5708 3.1416 0.017453 80.0 0.01 0 181 {ranges} 0 "
        "1.1 2.0 0.5 1.0 2.0 0.5 0 0 0 0 0 14.0 host 14.0",
        "TRUEPOS 1 2 3 4 5 6 15.0 host 15.0",
        "SYNC 1 2",
    ]
    log = carmen.parse_lines(lines)
    flaser, raw, robot = log.of_type(carmen.LaserRecord)
    assert flaser.kind == "FLASER" and flaser.max_range is None
    assert flaser.angles[0] == pytest.approx(-math.pi / 2) and flaser.angles[-1] == pytest.approx(math.pi / 2)
    np.testing.assert_array_equal(flaser.odometry_pose, [1.1, 2.1, 0.4])
    assert raw.odometry_pose is None and raw.max_range == 80.0 and raw.ranges.size == 181
    # the laser sits 0.1 m along world x from the robot, which faces 0.5 rad: in the robot frame
    np.testing.assert_allclose(robot.laser_offset, [0.1 * math.cos(0.5), -0.1 * math.sin(0.5), 0.0], atol=1e-12)
    assert log.ignored_messages == {"PARAM": 1, "SYNC": 1}
    assert log.report() == ["ignored messages: 1 PARAM, 1 SYNC"]
    truth = log.of_type(carmen.TruePoseRecord)[0]
    np.testing.assert_array_equal(truth.odometry_pose, [4, 5, 6])
    with pytest.raises(carmen.CarmenFormatError, match="<log>:1: FLASER: num_readings: expected a count"):
        carmen.parse_lines(["FLASER 1.5 1"])


def test_record_command_writes_a_readable_log(tmp_path, capsys):
    from emmi_gym.tools.cli import main

    out = tmp_path / "explore.log"
    assert main(["record", "loop_corridor", "--route", "explore", "--beams", "30", "--out", str(out)]) == 0
    assert "reached the end of the route" in capsys.readouterr().out
    log = carmen.read_log(out)
    assert len(log.of_type(carmen.LaserRecord)) > 50
    with pytest.raises(SystemExit) as exit_info:
        main(["record", "office", "--route", "nope", "--out", str(out)])
    assert exit_info.value.code == 2
    assert "has no route 'nope'; it has ['left_loop', 'right_loop']" in capsys.readouterr().err


SCAN = " ".join(["2.5"] * 180)


def test_replay_command_names_the_log_that_lacks_what_it_needs(tmp_path, capsys):
    from emmi_gym.tools.cli import main

    for name, content, says in [("empty.log", "", "has no FLASER, RAWLASER1 or ROBOTLASER1 line"),
                                ("no_odometry.log", "RAWLASER1 0 -1.57 3.1415 0.0174 30 0.01 0 2 2.5 2.5 0 1.0 h 1.0\n",
                                 "no scan in the log has odometry")]:
        path = tmp_path / name
        path.write_text(content)
        with pytest.raises(SystemExit) as exit_info:
            main(["replay", str(path), "--out", str(tmp_path / "out"), "--quiet"])
        assert exit_info.value.code == 2
        err = capsys.readouterr().err
        assert f"{path}: " in err and says in err, err


def test_glued_nul_and_binary_lines_are_errors_with_their_line_number():
    good = f"FLASER 180 {SCAN} 0 0 0 0 0 0 1.0 host 1.0"
    glued = "ODOM 0 0 0 0 0 0 1.0 host 1.0" + good  # the newline lost: the scan must not vanish
    with pytest.raises(carmen.CarmenFormatError, match=r"x\.log:2: ODOM: .*tokens after the logger timestamp"):
        carmen.parse_lines([good, glued], "x.log")
    with pytest.raises(carmen.CarmenFormatError, match=r"x\.log:1: NUL bytes"):
        carmen.parse_lines(["\0\0" + good], "x.log")
    with pytest.raises(carmen.CarmenFormatError, match=r"x\.log:2: bytes that are not UTF-8"):
        carmen.parse_lines([good.encode(), b"\xff\xfe\x00garbage"], "x.log")
    with pytest.raises(carmen.CarmenFormatError, match=r"x\.log:1: FLASER: .*tokens after"):
        carmen.parse_lines([good + " 7 8 9"], "x.log")
    log = carmen.parse_lines([glued, "\0" + good, good], "x.log", skip_bad_lines=True)
    assert log.skipped_bad_lines == {"ODOM": 1, "unreadable": 1}
    assert log.report() == ["skipped malformed lines: 1 ODOM, 1 unreadable"]


RAW = "RAWLASER1 0 -1.5708 3.1416 {res} {max_range} 0.01 0 3 {ranges} 0 13.0 host 13.0"


@pytest.mark.parametrize("line, expected", [
    (RAW.format(res=0.017, max_range="inf", ranges="1 1 1"), r"maximum_range: expected a finite number, got 'inf'"),
    (RAW.format(res=0.017, max_range=0, ranges="1 1 1"), r"maximum_range: expected a number > 0, got '0'"),
    (RAW.format(res=-0.017, max_range=8, ranges="1 1 1"), r"angular_resolution: expected a number > 0"),
    (RAW.format(res=0.017, max_range=8, ranges="1 -1 1"), r"range\[1\]: expected a number >= 0, got '-1'"),
    (f"FLASER 180 {SCAN} 0 0 0 1e999 0 0 1.0 host 1.0", r"odometry pose\[0\]: expected a finite number"),
    ("FLASER 5 1 1 1 0 0 0 0 0 0 1.0 emmi-gym 1.0",
     r"num_readings is 5, but the line has 3 ranges before its two poses"),
    ("FLASER 1e9 1 1", r"num_readings: expected a count \(an integer in \[0, 100000\]\)"),
])
def test_bad_laser_fields_name_line_and_field(line, expected):
    with pytest.raises(carmen.CarmenFormatError, match=rf"<log>:2: \w+: {expected}"):
        carmen.parse_lines(["# a header line", line])


def test_scans_without_echo_are_reported_and_parsing_shows_progress(tmp_path, capsys):
    zeros = " ".join(["0"] * 180)
    log = carmen.parse_lines([f"FLASER 180 {zeros} 0 0 0 0 0 0 1.0 host 1.0", f"FLASER 180 {SCAN} 0 0 0 0 0 0 2.0 h 2"])
    assert log.report() == ["1 scans have no echo (every range 0): they add nothing to the map"]
    path = tmp_path / "run.log"
    path.write_text(f"FLASER 180 {SCAN} 0 0 0 0 0 0 2.0 h 2\n" * 50)
    assert len(carmen.read_log(path, progress=True).records) == 50
    assert "reading run.log" in capsys.readouterr().err


def test_replay_of_a_straight_drive_and_of_a_pose_far_away():
    from emmi_gym.slam import RBPFConfig
    from emmi_gym.slam.occupancy import MapTooLarge
    from emmi_gym.tools.experiments.replay import replay

    straight = [f"FLASER 180 {SCAN} 0 0 0 {0.5 * k} 0 0 {k}.0 h {k}.0" for k in range(5)]
    result = replay(carmen.parse_lines(straight), RBPFConfig(particles=2), max_range=8.0)
    assert len(result.rows) >= 2
    far = straight[:2] + [f"FLASER 180 {SCAN} 0 0 0 1e6 0 0 9.0 h 9.0"]
    with pytest.raises(MapTooLarge, match=r"for 2 particles would take [\d.]+ GiB, above the bound of 4 GiB"):
        replay(carmen.parse_lines(far), RBPFConfig(particles=2), max_range=8.0)


@pytest.mark.parametrize("n", [180, 181, 361, 541])
def test_flaser_of_any_width_spans_the_field_of_view(n):
    line = f"FLASER {n} {' '.join(['1.0'] * n)} 0 0 0 0 0 0 1.0 host 1.0"
    scan = carmen.parse_lines([line]).of_type(carmen.LaserRecord)[0]
    assert scan.ranges.size == n
    assert scan.angles[0] == pytest.approx(-math.pi / 2) and scan.angles[-1] == pytest.approx(math.pi / 2)
    wide = carmen.parse_lines([line], flaser_fov=math.radians(240)).of_type(carmen.LaserRecord)[0]
    assert wide.angles[-1] - wide.angles[0] == pytest.approx(math.radians(240))
    with pytest.raises(ValueError, match="flaser_fov"):
        carmen.parse_lines([line], flaser_fov=7.0)


def test_gzipped_logs_and_laser_offsets_from_param_lines(tmp_path):
    import gzip

    lines = ["PARAM robot_frontlaser_offset 0.25 nohost 0", "PARAM robot_frontlaser_side_offset -0.05 nohost 0",
             "PARAM robot_max_velocity 1.0 nohost 0", f"FLASER 180 {SCAN} 0 0 0 0 0 0 1.0 host 1.0"]
    path = tmp_path / "run.log.gz"
    with gzip.open(path, "wt") as fh:
        fh.write("\n".join(lines) + "\n")
    log = carmen.read_log(path)
    scan = log.of_type(carmen.LaserRecord)[0]
    np.testing.assert_array_equal(scan.laser_offset, [0.25, -0.05, 0.0])
    assert log.ignored_messages == {"PARAM": 1}
    with pytest.raises(ValueError, match="expected a CARMEN log file, not a folder"):
        carmen.read_log(tmp_path)
    broken = tmp_path / "broken.log.gz"
    broken.write_bytes(path.read_bytes()[:40])
    with pytest.raises(ValueError, match="broken.log.gz: cannot be read as gzip"):
        carmen.read_log(broken)


def test_replay_matches_truth_by_time_and_writes_tum(tmp_path):
    """TRUEPOS lines after their scans (as the radish-noisy logs have them) still give an ATE, and the
    best path is written in the TUM format."""
    from emmi_gym.slam import RBPFConfig
    from emmi_gym.tools.experiments.replay import replay, write_tum

    lines = []
    for k in range(6):
        x = 0.3 * k
        ranges = " ".join(f"{2.0 + 0.01 * b:.2f}" for b in range(180))
        lines += [f"FLASER 180 {ranges} {x} 0 0 {x} 0 0 {k}.0 host {k}.0",
                  f"TRUEPOS {x} 0.01 0 {x} 0 0 {k}.0 host {k}.0"]
    result = replay(carmen.parse_lines(lines), RBPFConfig(particles=2), max_range=30.0, every_scan=True)
    assert len(result.rows) == 6 and all(t is not None for t in result.true_poses)
    assert result.ate() is not None and result.dead_reckoning_ate() == pytest.approx(0.0, abs=1e-9)
    rounded = [" ".join(line.split()[:-3] + ["1134860000.0", "host", "1134860000.0"]) for line in lines]
    tied = replay(carmen.parse_lines(rounded), RBPFConfig(particles=2), max_range=30.0, every_scan=True)
    assert tied.dead_reckoning_ate() == pytest.approx(0.0, abs=1e-9)  # rounded timestamps: the truth next to each scan
    table = np.loadtxt(write_tum(result, tmp_path / "best.tum"))
    assert table.shape == (6, 8)
    np.testing.assert_allclose(table[:, 0], np.arange(6.0))
    np.testing.assert_allclose(table[:, 6] ** 2 + table[:, 7] ** 2, 1.0, atol=1e-6)


def test_help_is_plain_text(capsys):
    from emmi_gym.tools.cli import main

    with pytest.raises(SystemExit):
        main(["--help"])
    out = capsys.readouterr().out
    assert "Active SLAM" in out and "``" not in out


def flaser(x: float, t: float, x_text: str | None = None, sep: str = " ") -> str:
    """A FLASER line at odometry x, time t (``x_text`` written in place of x; fields joined by ``sep``)."""
    return sep.join(["FLASER", "180", SCAN.replace(" ", sep), "0", "0", "0", x_text or repr(x), "0", "0", repr(t),
                     "host", repr(t)])


def test_timestamps_that_go_backwards_or_never_change_are_reported_with_their_lines(tmp_path, capsys):
    from emmi_gym.tools.cli import main

    backwards = carmen.parse_lines(["# header", *(flaser(0.5 * k, [1.0, 2.0, 1.5, 3.0][k]) for k in range(4))])
    assert backwards.report() == ["laser timestamps go backwards 1 time(s), first at line 4 (1.5 after 2.0 at line 3): "
                                  "times and rates from them are not trustworthy"]
    frozen = [flaser(0.5 * k, 7.0) for k in range(5)]
    assert carmen.parse_lines(frozen).report() == ["all 5 laser lines have the same timestamp 7.0 (lines 1 to 5): "
                                                   "the log carries no time"]
    assert carmen.parse_lines([flaser(0.5 * k, float(k // 2)) for k in range(4)]).report() == []  # rounded: fine
    path = tmp_path / "frozen.log"
    path.write_text("\n".join(frozen) + "\n")
    assert main(["replay", str(path), "--max-range", "8", "--particles", "2", "--out", str(tmp_path / "out"),
                 "--quiet"]) == 0
    out, err = capsys.readouterr()
    assert f"{path}: warning: all 5 laser lines have the same timestamp 7.0 (lines 1 to 5)" in err
    assert "no best_trajectory.tum: all 5 updates have the same timestamp 7.0" in out  # no timed trajectory pretended
    assert not (tmp_path / "out" / "best_trajectory.tum").exists() and (tmp_path / "out" / "metrics.csv").exists()


@pytest.mark.parametrize("line, expected", [
    (flaser(1.0, 2.0, "\u0661.\u0665"),
     r"x\.log:2: FLASER: the character U\+0661 \(ARABIC-INDIC DIGIT ONE\) at column"),
    (flaser(1.0, 2.0, "\uff11"), r"x\.log:2: FLASER: the character U\+FF11 \(FULLWIDTH DIGIT ONE\)"),
    (flaser(1.0, 2.0, sep="\u00a0"), r"x\.log:2: FLASER: the character U\+00A0 \(NO-BREAK SPACE\) at column 7"),
    (flaser(1.0, 2.0, "1_0"), r"x\.log:2: FLASER: odometry pose\[0\]: expected a number, got '1_0'"),
    ("ODOM 1 2 3 0 0 0 1\u00a0h 1", r"x\.log:2: ODOM: the character U\+00A0"),
])
def test_numbers_python_reads_but_logs_do_not_hold_are_malformed(line, expected):
    with pytest.raises(carmen.CarmenFormatError, match=expected):
        carmen.parse_lines([flaser(0.0, 1.0), line], "x.log")


def _peak(action) -> float:
    """Peak memory (MB) Python allocated while running ``action``."""
    import tracemalloc

    tracemalloc.start()
    try:
        action()
    finally:
        peak = tracemalloc.get_traced_memory()[1] / 1e6
        tracemalloc.stop()
    return peak


def test_streams_that_are_not_logs_are_refused_early_and_in_little_memory(tmp_path):
    import gzip

    def refused(path, expected):
        def action():
            with pytest.raises(ValueError, match=expected):
                carmen.read_log(path, progress=True)
        return action

    assert _peak(refused("/dev/zero", r"/dev/zero: expected a CARMEN log file, not a character device")) < 10
    zeros = tmp_path / "zeros.log.gz"
    zeros.write_bytes(gzip.compress(b"\0" * (64 << 20)))  # 64 KB that unpack to 64 MB of NUL bytes
    assert _peak(refused(zeros, r"zeros\.log\.gz: expected a CARMEN log, which is text, not binary data")) < 10
    long_line = tmp_path / "long.log"
    long_line.write_text(flaser(0.0, 1.0) + "\nFLASER " + "1 " * 5_000_000 + "\n")  # a 10 MB line
    assert _peak(refused(long_line, r"long\.log:2: a line longer than 4,000,000 bytes")) < 12
    newlines = tmp_path / "newlines.log.gz"
    newlines.write_bytes(gzip.compress(b"# a comment\n" + b"\n" * 10**6))
    assert _peak(refused(newlines, r"newlines\.log\.gz:100000: 100,000 lines in a row hold no message")) < 10


def test_the_records_of_a_log_are_bounded_in_memory():
    lines = [flaser(0.01 * (k % 2), float(k)) for k in range(1000)]
    assert len(carmen.parse_lines(lines, max_bytes=2 * 10**6).records) == 1000  # 1940 bytes each
    for skip in (False, True):
        with pytest.raises(carmen.CarmenFormatError, match=r"x\.log:516: the records read so far take more than "
                                                           r"0\.954 MiB of memory \(516 records\): a replay holds"):
            carmen.parse_lines(lines, "x.log", max_bytes=10**6, skip_bad_lines=skip)


def test_a_pose_far_off_asks_for_too_large_maps_not_an_overflow(tmp_path, capsys):
    from emmi_gym.tools.cli import main

    path = tmp_path / "far.log"
    path.write_text("\n".join([flaser(0.5 * k, float(k)) for k in range(3)] + [flaser(1e300, 3.0)]) + "\n")
    with pytest.raises(SystemExit) as exit_info:
        main(["replay", str(path), "--max-range", "8", "--particles", "2", "--out", str(tmp_path / "out"), "--quiet"])
    assert exit_info.value.code == 2
    assert f"{path}: maps of " in capsys.readouterr().err


@pytest.mark.parametrize("options, expected", [
    (["--max-range", "inf"], "argument --max-range: expected a finite number above 0 (m), got 'inf'"),
    (["--max-range", "nan"], "argument --max-range: expected a finite number above 0 (m), got 'nan'"),
    (["--max-range", "-5"], "argument --max-range: expected a finite number above 0 (m), got '-5'"),
    (["--seed", "-1"], "argument --seed: expected an integer in [0, 4294967295], got '-1'"),
    (["--flaser-fov", "0"], "argument --flaser-fov: expected a finite number in (0, 360] (degrees), got '0'"),
    (["--out", "{file}/sub"], "--out {file}/sub: expected a folder that can be made and written to; {file} is a "
                              "regular file, not a folder"),
])
def test_replay_options_name_themselves_before_any_work(tmp_path, capsys, options, expected):
    from emmi_gym.tools.cli import main

    log, file = tmp_path / "run.log", tmp_path / "a_file"
    log.write_text("\n".join(flaser(0.5 * k, float(k)) for k in range(3)) + "\n")
    file.write_text("x")
    options = [option.format(file=file) for option in options]
    with pytest.raises(SystemExit) as exit_info:
        main(["replay", str(log), "--max-range", "8", "--particles", "2", "--out", str(tmp_path / "out"), "--quiet",
              *options])
    assert exit_info.value.code == 2
    err = capsys.readouterr().err
    assert expected.format(file=file) in err and "run.log" not in err


def test_replay_refuses_a_folder_in_use_unless_overwritten(tmp_path, capsys):
    from emmi_gym.tools.cli import main

    log = tmp_path / "short.log"
    log.write_text("\n".join(flaser(0.5 * k, float(k)) for k in range(4)) + "\n")
    out = tmp_path / "out"
    replay = ["replay", str(log), "--max-range", "8", "--particles", "2", "--out", str(out), "--quiet"]
    assert main(replay) == 0
    (out / "notes.txt").write_text("mine")
    before = {path: path.read_bytes() for path in out.iterdir()}
    with pytest.raises(SystemExit) as exit_info:
        main(replay)
    assert exit_info.value.code == 2
    err = capsys.readouterr().err
    assert f"{out} is not empty (it holds best_map.png," in err and "replace it with --overwrite" in err
    assert "--resume" not in err and {path: path.read_bytes() for path in out.iterdir()} == before
    (out / "best_trajectory.tum").write_text("an earlier replay's")
    assert main([*replay, "--overwrite"]) == 0
    assert (out / "notes.txt").read_text() == "mine" and (out / "metrics.csv").exists()
    assert "an earlier replay's" not in (out / "best_trajectory.tum").read_text()


def map_server_world(folder):
    """A map_server map of a walled 4 m room, ``room_map.yaml`` and ``.pgm`` in ``folder`` (as ``record --out
    room.log`` names its map): a world to record in."""
    from emmi_gym.formats.map_server import write_map_server
    from emmi_gym.geometry.grid import GridGeometry

    values = np.zeros((40, 40), dtype=np.int8)
    values[[0, -1], :] = values[:, [0, -1]] = 100
    return write_map_server(folder / "room_map.yaml", values, GridGeometry(0.1, 0.0, 0.0, 40, 40))


def test_record_refuses_to_write_over_its_world_or_one_output_over_another(tmp_path, capsys):
    from emmi_gym.tools.cli import main
    from emmi_gym.world.loader import world_path

    world = tmp_path / "w.yaml"
    world.write_bytes(world_path("loop_corridor").read_bytes())
    (tmp_path / "link.log").symlink_to(world)
    room = map_server_world(tmp_path)
    before = {path: path.read_bytes() for path in tmp_path.iterdir() if path.is_file()}
    for argv, says in (
        ([str(world), "--out", str(world)], f"--out {world}: expected a file apart from the world file {world}"),
        ([str(world), "--out", str(tmp_path / "link.log")], "which it is (links resolved) and would be overwritten"),
        ([str(room), "--out", str(tmp_path / "room.log")],
         f"the map of --out {tmp_path / 'room_map.yaml'}: expected a file apart from the world file {room}"),
        ([str(world), "--out", str(tmp_path / "run.log"), "--bag-out", str(tmp_path / "run.log")],
         f"--bag-out {tmp_path / 'run.log'}: expected a file apart from --out {tmp_path / 'run.log'}, which it is "
         "(links resolved) and would be written over; give another --bag-out"),
    ):
        with pytest.raises(SystemExit) as exit_info:
            main(["record", *argv, "--route", "explore", "--beams", "30"])
        assert exit_info.value.code == 2
        err = capsys.readouterr().err
        assert says in err and len(err.strip().splitlines()) == 1, err
    assert {path: path.read_bytes() for path in tmp_path.iterdir() if path.is_file()} == before
    assert not (tmp_path / "run.log").exists()


def test_odometry_timestamps_that_go_backwards_are_reported_with_their_lines():
    odometry = [f"ODOM {0.1 * k!r} 0 0 0 0 0 {t!r} host {t!r}" for k, t in enumerate([1.0, 2.0, 1.5, 3.0])]
    assert carmen.parse_lines(["# header", *odometry]).report()[-1] == (
        "odometry timestamps go backwards 1 time(s), first at line 4 (1.5 after 2.0 at line 3): times and rates "
        "from them are not trustworthy")
    assert carmen.parse_lines(odometry[:1] * 3).timing == []  # odometry at one time: no sentence of its own
