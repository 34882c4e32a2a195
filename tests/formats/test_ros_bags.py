"""ROS bags in and out: bags written from a CARMEN log replay as the log does, in ROS 1, ROS 2 sqlite3 and
ROS 2 MCAP alike; ranges, odometry and mounting follow the ROS conventions (REP 103, 105, 117); damaged
bags give one line and exit 2; the maps written load back as worlds, cell for cell."""

from __future__ import annotations

import math
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

pytest.importorskip("rosbags.highlevel")

from helpers import DATA

from emmi_gym.formats import carmen  # noqa: E402
from emmi_gym.formats.map_server import FREE_PERCENT  # noqa: E402
from emmi_gym.formats.ros_bags import BagError, BagTopics, read_bag  # noqa: E402
from emmi_gym.formats.ros_messages import (  # noqa: E402
    LASER_SCAN,
    ODOMETRY,
    TF_MESSAGE,
    header,
    odometry_message,
    transform_stamped,
)
from emmi_gym.formats.ros_writers import STORAGES, open_bag, write_log_bag  # noqa: E402
from emmi_gym.geometry.grid import GridGeometry  # noqa: E402
from emmi_gym.slam import RBPFConfig  # noqa: E402
from emmi_gym.tools.cli import main  # noqa: E402
from emmi_gym.tools.experiments.replay import replay  # noqa: E402
from emmi_gym.world import load_world, rasterise  # noqa: E402
from emmi_gym.world.images import map_server_occupancy  # noqa: E402

INTEL = DATA / "intel-first-loop.log.gz"
SCANS = 40  # the first 40 keyframes of the Intel loop: a few seconds of replay
NAMES = {"ros1": "run.bag", "sqlite3": "run-sqlite3", "mcap": "run-mcap"}


@pytest.fixture(scope="module")
def short_log() -> carmen.CarmenLog:
    log = carmen.read_log(INTEL)
    lasers = [k for k, r in enumerate(log.records) if isinstance(r, carmen.LaserRecord)]
    return replace(log, records=log.records[:lasers[SCANS - 1] + 2])  # with the last scan's TRUEPOS


@pytest.fixture(scope="module")
def bags(short_log, tmp_path_factory) -> dict[str, Path]:
    folder = tmp_path_factory.mktemp("bags")
    return {storage: write_log_bag(short_log, folder / NAMES[storage], storage, max_range=30.0)
            for storage in STORAGES}


def ns(t: float) -> int:
    return int(round(t * 1e9))


def scan_message(store, t, ranges, *, frame="laser", angle_min=-1.0, step=0.5, range_min=0.1, range_max=30.0):
    return store.types[LASER_SCAN](
        header=header(store, ns(t), frame), angle_min=angle_min, angle_max=angle_min + (len(ranges) - 1) * step,
        angle_increment=step, time_increment=0.0, scan_time=0.0, range_min=range_min, range_max=range_max,
        ranges=np.asarray(ranges, dtype=np.float32), intensities=np.zeros(0, dtype=np.float32))


def tf_message(store, t, *links):
    return store.types[TF_MESSAGE](transforms=[transform_stamped(store, ns(t), *link) for link in links])


def write_bag(path, messages, storage="sqlite3") -> Path:
    """A bag of (topic, type, time, make(store)) messages."""
    with open_bag(path, storage) as bag:
        for topic, msgtype, t, make in messages:
            bag.write(topic, msgtype, ns(t), make(bag.store))
    return Path(path)


def replay_cli(*args) -> tuple[int, str, str]:
    import contextlib
    import io

    out, err = io.StringIO(), io.StringIO()
    with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
        try:
            code = main(["replay", *map(str, args), "--quiet"])
        except SystemExit as exc:
            code = exc.code
    return code, out.getvalue(), err.getvalue()


# ----------------------------------------------------------------------------- bags from a log


@pytest.mark.parametrize("storage", STORAGES)
def test_a_bag_written_from_a_log_reads_back_as_the_log(short_log, bags, storage):
    """Per scan the same times and odometry poses, the ranges as float32 (no echo at 30 m as +inf, read back
    as no echo), and every TRUEPOS line as a truth pose."""
    log = read_bag(bags[storage], BagTopics(truth="/truth"))
    mine, theirs = log.of_type(carmen.LaserRecord), short_log.of_type(carmen.LaserRecord)
    assert len(mine) == len(theirs) == SCANS
    for a, b in zip(mine, theirs, strict=True):
        assert a.timestamp == b.timestamp and a.max_range == 30.0
        np.testing.assert_allclose(a.odometry_pose, b.odometry_pose, rtol=0, atol=1e-12)
        np.testing.assert_array_equal(np.minimum(a.ranges, 30.0), np.minimum(b.ranges.astype(np.float32), 30.0))
        np.testing.assert_allclose(a.angles, b.angles, atol=1e-6)
    truth = log.of_type(carmen.TruePoseRecord)
    assert [t.timestamp for t in truth] == [t.timestamp for t in short_log.of_type(carmen.TruePoseRecord)]
    assert log.report() == ["ignored messages: 40 /odom (nav_msgs/msg/Odometry)"]


def test_the_three_formats_replay_alike_and_as_the_log(short_log, bags, tmp_path):
    """The filter gets the same input from every format (the same EMMI curve, bit for bit), and the log's to
    within float32: the same updates, an EMMI curve within 0.01 bits/cell and the ATE within 2 cm."""
    config = RBPFConfig.preset("radish-noisy", particles=5, resolution=0.05)
    results = {s: replay(read_bag(bags[s], BagTopics(truth="/truth")), config, every_scan=True) for s in STORAGES}
    reference = replay(short_log, config, max_range=30.0, every_scan=True)
    curves = {s: np.array([r.emmi for r in result.rows]) for s, result in results.items()}
    np.testing.assert_array_equal(curves["ros1"], curves["sqlite3"])
    np.testing.assert_array_equal(curves["ros1"], curves["mcap"])
    emmi = np.array([r.emmi for r in reference.rows])
    assert curves["mcap"].shape == emmi.shape == (SCANS,)
    assert np.max(np.abs(curves["mcap"] - emmi)) < 0.01
    assert abs(results["mcap"].ate() - reference.ate()) < 0.02


# ----------------------------------------------------------------------------- ROS conventions


def test_ranges_follow_rep_117_and_scans_are_matched_to_odometry_in_time(tmp_path):
    """+inf and readings above range_max are no echo; NaN, -inf and readings below range_min are left out (0, the
    filter's no reading); a clockwise scan is reversed; odometry from /tf is interpolated at the scan's stamp,
    and a scan after the last odometry gets none."""
    ranges = [np.nan, -np.inf, np.inf, 0.05, 5.0, 40.0, 30.0]
    path = write_bag(tmp_path / "rep117", [
        ("/tf", TF_MESSAGE, 0.0, lambda s: tf_message(s, 0.0, ("odom", "base_link", 0.0, 0.0, 0.0))),
        ("/tf", TF_MESSAGE, 1.0, lambda s: tf_message(s, 1.0, ("odom", "base_link", 1.0, 0.0, math.pi / 2))),
        ("/scan", LASER_SCAN, 0.5, lambda s: scan_message(s, 0.5, ranges, frame="base_link")),
        ("/scan", LASER_SCAN, 0.6, lambda s: scan_message(s, 0.6, [1.0, 2.0, 3.0], frame="base_link",
                                                          angle_min=1.0, step=-0.5)),
        ("/scan", LASER_SCAN, 2.0, lambda s: scan_message(s, 2.0, [1.0], frame="base_link")),
    ])
    log = read_bag(path)
    first, clockwise, late = log.of_type(carmen.LaserRecord)
    np.testing.assert_array_equal(first.ranges, [0.0, 0.0, np.inf, 0.0, 5.0, np.inf, 30.0])
    np.testing.assert_allclose(first.odometry_pose, [0.5, 0.0, math.pi / 4], atol=1e-7)
    np.testing.assert_array_equal(clockwise.ranges, [3.0, 2.0, 1.0])
    assert clockwise.start_angle == 0.0 and clockwise.angular_resolution == 0.5
    assert late.odometry_pose is None
    assert "3 of 11 readings of /scan are NaN, -inf or below range_min: left out" in " ".join(log.warnings)
    assert "1 of 3 scans lie outside the time span of the odometry" in " ".join(log.warnings)


def test_the_mounting_is_the_chain_of_static_transforms_and_an_upside_down_laser_is_mirrored(tmp_path):
    """base_link -> mount (0.2 m ahead, turned 90 degrees) -> laser (0.1 m along the mount's x, upside down):
    the laser stands at (0.2, 0.1) facing left, and a beam at +0.5 rad of its frame points at -0.5 rad of it."""
    path = write_bag(tmp_path / "mounted", [
        ("/tf_static", TF_MESSAGE, 0.0, lambda s: tf_message(s, 0.0, ("base_link", "mount", 0.2, 0.0, math.pi / 2))),
        ("/tf_static", TF_MESSAGE, 0.0, lambda s: _upside_down(s, "mount", "laser", 0.1)),
        ("/odom", ODOMETRY, 0.0, lambda s: _odometry(s, 0.0)),
        ("/odom", ODOMETRY, 1.0, lambda s: _odometry(s, 1.0)),
        ("/scan", LASER_SCAN, 0.5, lambda s: scan_message(s, 0.5, [1.0, 2.0, 3.0], angle_min=0.0, step=0.5)),
    ])
    log = read_bag(path, BagTopics(odom="/odom"))
    (scan,) = log.of_type(carmen.LaserRecord)
    np.testing.assert_allclose(scan.laser_offset, [0.2, 0.1, math.pi / 2], atol=1e-12)
    np.testing.assert_array_equal(scan.ranges, [3.0, 2.0, 1.0])
    np.testing.assert_allclose(scan.angles, [-1.0, -0.5, 0.0])
    assert any("mounted upside down" in w for w in log.warnings)
    no_mount = write_bag(tmp_path / "unmounted", [
        ("/odom", ODOMETRY, 0.0, lambda s: _odometry(s, 0.0)),
        ("/scan", LASER_SCAN, 0.0, lambda s: scan_message(s, 0.0, [1.0])),
    ])
    assert "no transform from base_link to the scans' frame 'laser'" in read_bag(no_mount, BagTopics(
        odom="/odom")).warnings[0]


def _odometry(store, t):
    return odometry_message(store, ns(t), "odom", "base_link", (t, 0.0, 0.0))


def _upside_down(store, parent, child, x):
    """A transform rolled by pi about x (z down)."""
    message = tf_message(store, 0.0, (parent, child, x, 0.0, 0.0))
    message.transforms[0].transform.rotation = store.types["geometry_msgs/msg/Quaternion"](x=1.0, y=0.0, z=0.0, w=0.0)
    return message


# ----------------------------------------------------------------------------- damaged bags


def _one_line_exit_2(*args) -> str:
    code, _, err = replay_cli(*args)
    lines = err.strip().splitlines()
    assert code == 2 and len(lines) == 1, (code, err)
    assert "Traceback" not in err
    return lines[0]


@pytest.mark.parametrize("storage", STORAGES)
def test_a_truncated_bag_is_one_line_and_exit_2(bags, tmp_path, storage):
    source = bags[storage]
    file = source if source.is_file() else next(p for p in source.iterdir() if p.suffix in (".db3", ".mcap"))
    data = file.read_bytes()
    cut = tmp_path / f"cut{file.suffix}"
    cut.write_bytes(data[:len(data) // 2])
    line = _one_line_exit_2(cut, "--out", tmp_path / "out")
    assert f"{cut}: expected a readable ROS 1 bag or ROS 2 bag" in line


def test_what_is_not_a_bag_is_one_line_and_exit_2(tmp_path):
    (tmp_path / "notes.bag").write_text("not a bag\n")
    assert "the reader says: File magic is invalid" in _one_line_exit_2(tmp_path / "notes.bag", "--out",
                                                                        tmp_path / "out")
    (tmp_path / "folder").mkdir()
    assert "metadata" in _one_line_exit_2(tmp_path / "folder", "--out", tmp_path / "out")


def test_unknown_types_empty_topics_and_unreadable_messages_are_one_line_and_exit_2(tmp_path):
    from rosbags.typesys import get_types_from_msg

    path = tmp_path / "odd"
    with open_bag(path, "mcap") as bag:
        bag.store.register(get_types_from_msg("float64 x", "my_msgs/msg/Blip"))
        bag.write("/blip", "my_msgs/msg/Blip", 0, bag.store.types["my_msgs/msg/Blip"](x=1.0))
        bag.writer.add_connection("/scan", LASER_SCAN, typestore=bag.store)  # no message
        broken = bag.writer.add_connection("/scan_broken", LASER_SCAN, typestore=bag.store)
        bag.writer.write(broken, 0, b"\x00\x01\x00\x00\xff\xff\xff\xff")
        bag.write("/tf", TF_MESSAGE, 0, tf_message(bag.store, 0.0, ("odom", "base_link", 0.0, 0.0, 0.0)))
    out = ("--out", tmp_path / "out")
    assert "field '/blip': expected sensor_msgs/msg/LaserScan, got 'my_msgs/msg/Blip'" in _one_line_exit_2(
        path, "--scan", "/blip", *out)
    assert "field '/scan': expected sensor_msgs/msg/LaserScan messages, got 'none'" in _one_line_exit_2(
        path, "--scan", "/scan", *out)
    assert "message 1 is not one" in _one_line_exit_2(path, "--scan", "/scan_broken", *out)
    assert "expected one sensor_msgs/LaserScan topic (pass --scan TOPIC to choose), got ['/scan', '/scan_broken']" \
        in _one_line_exit_2(path, *out)
    assert "field '/nope': expected a topic of the bag (--scan)" in _one_line_exit_2(path, "--scan", "/nope", *out)


def test_scans_with_no_odometry_in_range_are_one_line_and_exit_2(tmp_path):
    path = write_bag(tmp_path / "late", [
        ("/scan", LASER_SCAN, 0.0, lambda s: scan_message(s, 0.0, [1.0, 2.0])),
        ("/tf", TF_MESSAGE, 5.0, lambda s: tf_message(s, 5.0, ("odom", "base_link", 0.0, 0.0, 0.0))),
        ("/tf", TF_MESSAGE, 6.0, lambda s: tf_message(s, 6.0, ("odom", "base_link", 1.0, 0.0, 0.0))),
    ])
    assert "field '/scan': expected scans within the odometry's time span (5 s to 6 s of /tf odom -> base_link)" \
        in _one_line_exit_2(path, "--out", tmp_path / "out")
    assert "field '/tf': expected odometry (odom -> base_footprint transforms)" in _one_line_exit_2(
        path, "--base-frame", "base_footprint", "--out", tmp_path / "out")


def test_the_records_held_are_bounded(bags):
    with pytest.raises(BagError, match=r"at most 0\.00954 MiB of memory .*split it"):
        read_bag(bags["sqlite3"], max_bytes=10_000)


def test_bag_options_on_a_carmen_log_are_refused(tmp_path):
    assert "--scan: options of ROS bags" in _one_line_exit_2(INTEL, "--scan", "/scan", "--out", tmp_path / "out")


# ----------------------------------------------------------------------------- maps out


def test_the_map_written_loads_back_as_a_world_cell_for_cell(bags, tmp_path):
    """map.yaml reads back, by map_server's rules, as the free cells of the map the replay wrote (the best
    particle's: percent at most 25), cell for cell on the same cells; as a world, its free space is the part
    of them reachable from its start but for cells on their boundary, where the walls run; --bag-out holds
    the same grid as an OccupancyGrid."""
    from rosbags.highlevel import AnyReader

    out, bag_out = tmp_path / "out", tmp_path / "maps"
    code, stdout, err = replay_cli(bags["mcap"], "--truth", "/truth", "--every-scan", "--preset", "radish-noisy",
                                   "--particles", "3", "--resolution", "0.05", "--out", out, "--bag-out", bag_out)
    assert code == 0, err
    assert "ATE of the best particle against /truth" in stdout
    with AnyReader([bag_out]) as reader:
        grids = {c.topic: reader.deserialize(raw, c.msgtype) for c, _, raw in reader.messages()}
    grid = grids["/map"]
    values = grid.data.reshape(grid.info.height, grid.info.width)
    geometry = GridGeometry(grid.info.resolution, grid.info.origin.position.x, grid.info.origin.position.y,
                            grid.info.height, grid.info.width)
    assert len(grids["/path"].poses) == SCANS
    occupancy = map_server_occupancy(out / "map.yaml")
    assert occupancy.resolution == 0.05 and occupancy.origin == pytest.approx((geometry.origin_x, geometry.origin_y))
    np.testing.assert_array_equal(occupancy.free, (values >= 0) & (values <= FREE_PERCENT))
    world = load_world(out / "map.yaml")
    truth = rasterise(world, 0.05, GridGeometry(0.05, *occupancy.origin, *occupancy.free.shape))
    from scipy import ndimage

    labels, _ = ndimage.label(occupancy.free)
    start = truth.geometry.cell_of(world.start.x, world.start.y)
    region = labels == labels[start]
    # the walls run along the region's boundary (simplified within 0.75 px): the world's free space is the
    # region's but for cells that touch its boundary (their 8 neighbours are not all on one side)
    inner = ndimage.binary_erosion(region, np.ones((3, 3)))
    outer = ndimage.binary_dilation(region, np.ones((3, 3)))
    assert np.all(truth.reachable[inner]) and not np.any(truth.reachable[~outer])
    assert (out / "expected_information.pgm").exists()
    csv = (out / "best_path.csv").read_text().splitlines()
    assert csv[0] == "stamp,x,y,yaw" and len(csv) == SCANS + 1


def test_record_writes_the_world_map_and_a_bag_of_the_run(tmp_path, capsys):
    """The world's free space as a map_server map, cell for cell, and a bag of the run's scans that reads
    without a warning (its mounting in /tf_static, odometry at every scan)."""
    log, bag = tmp_path / "run.log", tmp_path / "run-bag"
    code = main(["record", "loop_corridor", "--route", "to_decision", "--beams", "60", "--out", str(log),
                 "--bag-out", str(bag)])
    assert code == 0
    truth = rasterise(load_world("loop_corridor"), 0.05)
    occupancy = map_server_occupancy(tmp_path / "run_map.yaml")
    assert occupancy.origin == (truth.geometry.origin_x, truth.geometry.origin_y)
    np.testing.assert_array_equal(occupancy.free, truth.reachable)
    assert load_world(tmp_path / "run_map.yaml").bounds == load_world("loop_corridor").bounds
    read = read_bag(bag, BagTopics(truth="/truth"))
    assert len(read.of_type(carmen.LaserRecord)) == len(carmen.read_log(log).of_type(carmen.LaserRecord))
    assert not read.warnings


def test_odometry_whose_stamps_go_back_is_one_line_naming_the_message(tmp_path):
    """The bag's order is the odometry's: a stamp that jumps back would reorder the path the replay follows."""
    path = write_bag(tmp_path / "back", [
        ("/tf", TF_MESSAGE, 0.0, lambda s: tf_message(s, 0.0, ("odom", "base_link", 0.0, 0.0, 0.0))),
        ("/tf", TF_MESSAGE, 1.0, lambda s: tf_message(s, 1.0, ("odom", "base_link", 1.0, 0.0, 0.0))),
        ("/tf", TF_MESSAGE, 2.0, lambda s: tf_message(s, 0.5, ("odom", "base_link", 2.0, 0.0, 0.0))),
        ("/scan", LASER_SCAN, 0.5, lambda s: scan_message(s, 0.5, [1.0, 2.0])),
    ])
    assert (f"{path}: field '/tf': expected odometry whose stamps never go back in the bag's order (message 2 is "
            "stamped 1.0 s), got 'message 3 at 0.5 s'") in _one_line_exit_2(
        path, "--out", tmp_path / "out")


@pytest.mark.parametrize("role, value", [("odom", math.nan), ("odom", math.inf), ("truth", math.nan)])
def test_odometry_or_truth_that_is_not_finite_is_one_line_naming_the_message(tmp_path, role, value):
    def odometry(t, x):
        return lambda s: odometry_message(s, ns(t), "odom", "base_link", (x, 0.0, 0.0))

    messages = [("/odom", ODOMETRY, 0.0, odometry(0.0, 0.0)), ("/truth", ODOMETRY, 0.0, odometry(0.0, 0.0)),
                ("/scan", LASER_SCAN, 0.5, lambda s: scan_message(s, 0.5, [1.0, 2.0])),
                (f"/{role}", ODOMETRY, 1.0, odometry(1.0, value))]
    path = write_bag(tmp_path / "odd", messages)
    what = "odometry" if role == "odom" else "ground-truth"
    assert (f"{path}: field '/{role}': expected {what} poses of finite x, y and orientation (message 2: x "
            f"{value!r}, y 0.0, yaw 0.0)") in _one_line_exit_2(path, "--odom", "/odom", "--truth", "/truth", "--out",
                                                               tmp_path / "out")
