"""Worlds, loader errors, generator, simulator, laser, odometry, ground truth."""

import copy
import math

import numpy as np
import pymunk
import pytest
import yaml
from helpers import ROOT, independent_loops
from hypothesis import given
from hypothesis import strategies as st

from emmi_gym.geometry.motion import compose_local, compose_motion, relative_motion, wrap_angle
from emmi_gym.world.generator import GeneratorConfig, generate_world
from emmi_gym.world.ground_truth import FREE, OCCUPIED, UNKNOWN, is_reachable, rasterise
from emmi_gym.world.laser import LaserConfig
from emmi_gym.world.loader import builtin_worlds, load_world, parse_world
from emmi_gym.world.odometry import OdometryNoise, noisy_motion
from emmi_gym.world.simulator import RobotConfig, Simulator
from emmi_gym.world.spec import ROBOT_RADIUS, WorldFileError

PLANS = ROOT / "emmi_gym" / "worlds_data" / "dungeon_maps"

BOX = {
    "name": "box",
    "bounds": {"xmin": -3, "ymin": -3, "xmax": 3, "ymax": 3},
    "walls": [{"rectangle": {"min": [-2, -2], "max": [2, 2], "thickness": 0.2}}],
    "start": {"x": 0, "y": 0, "theta": 0},
}


def box(**changes):
    data = copy.deepcopy(BOX)
    data.update(changes)
    return data


# ------------------------------------------------------------------ built-in and generated worlds


def assert_connected_with_free_start(world):
    """The robot fits at the start, and every place is in the free space reachable from it."""
    assert world.clearance(world.start.x, world.start.y) > ROBOT_RADIUS
    truth = rasterise(world, 0.1)
    for name, place in world.places.items():
        assert is_reachable(truth, *place.xy), name
    return truth


@pytest.mark.parametrize("name", builtin_worlds())
def test_builtin_world_loads_connected_with_free_start(name):
    world = load_world(name)
    truth = assert_connected_with_free_start(world)
    for route in world.routes.values():
        for waypoint in route:
            assert is_reachable(truth, *waypoint)
    again = load_world(name)
    np.testing.assert_array_equal(world.walls, again.walls)


def test_builtin_worlds_are_the_expected_ones():
    assert {"loop_corridor", "office"} <= set(builtin_worlds())
    loop = load_world("loop_corridor")
    assert {"start", "decision", "target_a", "target_b"} <= set(loop.places)
    # a single loop of ~70 m: the to_decision + close_loop routes go round it once
    route = loop.route("to_decision") + loop.route("close_loop")[1:]
    length = sum(math.dist(a, b) for a, b in zip(route[:-1], route[1:], strict=False))
    assert 65 < length < 80
    assert loop.route("close_loop")[-1] == loop.place("start").xy


def test_office_has_twoindependent_loops():
    assert independent_loops(load_world("office")) >= 2
    assert independent_loops(load_world("loop_corridor")) == 1


@pytest.mark.parametrize("seed", range(50))
def test_generated_world_connected_free_start_deterministic(seed):
    world = generate_world(seed)
    assert_connected_with_free_start(world)
    np.testing.assert_array_equal(world.walls, generate_world(seed).walls)


def test_generated_worlds_have_the_asked_loops_and_differ_by_seed():
    for n_loops in (0, 1, 3):
        assert independent_loops(generate_world(5, GeneratorConfig(n_loops=n_loops))) == n_loops
    assert not np.array_equal(generate_world(1).walls, generate_world(2).walls)


def test_generator_rejects_bad_parameters():
    with pytest.raises(ValueError, match="loops"):
        GeneratorConfig(nx=2, ny=2, n_loops=5)
    with pytest.raises(ValueError, match="corridor_width"):
        GeneratorConfig(corridor_width=5.0)
    with pytest.raises(ValueError, match=r"field 'spacing': expected a lattice at most 400 m across .* GB"):
        GeneratorConfig(nx=20, spacing=30.0, corridor_width=2.0)


# ------------------------------------------------------------------ loader errors


@pytest.mark.parametrize("data, field, expected", [
    ({k: v for k, v in BOX.items() if k != "start"}, "start", "required"),
    ({k: v for k, v in BOX.items() if k != "walls"}, "walls", "required"),
    (box(colour="red"), "colour", "known keys"),
    (box(start={"x": 0, "y": 0, "heading": 1}), "start.heading", "known keys"),
    (box(walls=[{"segment": {"from": [0, 0], "to": [1, 1], "thickness": 0}}]), "walls[0].segment.thickness",
     r"in \[0.01, 5\] m"),
    (box(walls=[{"segment": {"from": [0, 0], "to": [1, 1], "thickness": -0.1}}]), "walls[0].segment.thickness",
     r"in \[0.01, 5\] m"),
    (box(wall_thickness=0), "wall_thickness", r"in \[0.01, 5\] m"),
    (box(wall_thickness=float("nan")), "wall_thickness", r"in \[0.01, 5\] m, got nan"),
    (box(bounds={"xmin": -3, "ymin": -3, "xmax": 1e5, "ymax": 3}), "bounds.xmax", r"in \[-10000, 10000\] m"),
    (box(bounds={"xmin": -3000, "ymin": -3, "xmax": 3, "ymax": 3}), "bounds.xmax", "at most 2000 m across"),
    (box(start={"x": 1e300, "y": 0}), "start.x", r"in \[-10000, 10000\] m"),
    (box(start={"x": "1.0e5", "y": 0}), "start.x", "write exponents with a sign or a dot"),
    (box(routes={"r": ["start", [1, 1], [1, 2.5]]}), "routes.r[2]",
     r"drive to straight from the one before; at \(1.00, 1.75\) it would overlap the wall from"),
    (box(bounds={"xmin": 3, "ymin": -3, "xmax": 3, "ymax": 3}), "bounds.xmax", "greater than"),
    (box(walls=[{"rectangle": {"min": [1, 1], "max": [0, 2]}}]), "walls[0].rectangle.max", "positive width"),
    (box(walls=[{"segment": {"from": [1, 1], "to": [1, 1]}}]), "walls[0].segment", "positive length"),
    (box(start={"x": 2, "y": 0}), "start", "clear of every wall"),
    (box(start={"x": 10, "y": 0}), "start", "inside the bounds"),
    (box(start={"x": "zero", "y": 0}), "start.x", "finite number"),
    (box(start={"x": True, "y": 0}), "start.x", "finite number"),
    (box(bounds={"xmin": -3, "ymin": -3, "xmax": float("inf"), "ymax": 3}), "bounds.xmax", "finite number"),
    (box(walls=[{"segment": {"from": [0, "a"], "to": [1, 1]}}]), "walls[0].segment.from[1]", "finite number"),
    (box(walls=[{"segment": {"from": [0], "to": [1, 1]}}]), "walls[0].segment.from", r"point \[x, y\]"),
    (box(walls=[{"circle": {"r": 1}}]), "walls[0]", "exactly one of"),
    (box(walls=[]), "walls", "non-empty list"),
    (box(routes={"r": ["start", "nowhere"]}), "routes.r[1]", "place name"),
    (box(routes={"r": ["start", [9000, 1]]}), "routes.r[1]", r"a waypoint inside the bounds \[-3, 3\]"),
    ([1, 2, 3], "", "a mapping"),
])
def test_malformed_world_names_the_field(data, field, expected):
    with pytest.raises(WorldFileError, match=expected) as info:
        parse_world(data, source="bad.yaml")
    assert info.value.field == field
    assert str(info.value).startswith(f"bad.yaml: field '{field}': " if field else "bad.yaml: expected")


def test_world_file_errors_name_the_file(tmp_path):
    path = tmp_path / "mine.yaml"
    path.write_text(yaml.safe_dump(box(start={"x": 0, "y": 0, "theta": "north"})))
    with pytest.raises(WorldFileError, match=r"mine\.yaml: field 'start.theta': expected a finite number"):
        load_world(path)
    path.write_text("name: [unclosed")
    with pytest.raises(WorldFileError, match="valid YAML"):
        load_world(path)
    with pytest.raises(ValueError, match="unknown world 'nowhere'.*loop_corridor"):
        load_world("nowhere")


def test_unsafe_yaml_tags_are_refused(tmp_path):
    path = tmp_path / "evil.yaml"
    path.write_text("!!python/object/apply:os.system ['echo hi']\n")
    with pytest.raises(WorldFileError, match="valid YAML"):
        load_world(path)


_junk = st.one_of(st.none(), st.booleans(), st.integers(-5, 5), st.floats(allow_nan=True), st.text(max_size=3),
                  st.lists(st.integers(-3, 3), max_size=3),
                  st.dictionaries(st.text(max_size=3), st.integers(), max_size=2))


def _leaf_paths(obj, prefix=()):
    if isinstance(obj, dict):
        for k, v in obj.items():
            yield from _leaf_paths(v, prefix + (k,))
    elif isinstance(obj, list):
        for i, v in enumerate(obj):
            yield from _leaf_paths(v, prefix + (i,))
    yield prefix


@given(st.data())
def test_fuzzed_world_files_raise_only_the_loader_error(data):
    world = yaml.safe_load(_builtin_path("loop_corridor").read_text())
    paths = [p for p in _leaf_paths(world) if p]
    for _ in range(data.draw(st.integers(1, 3))):
        path = data.draw(st.sampled_from(paths))
        target = world
        try:
            for key in path[:-1]:
                target = target[key]
            if data.draw(st.booleans()) and isinstance(target, dict):
                target.pop(path[-1], None)
            else:
                target[path[-1]] = data.draw(_junk)
        except (KeyError, IndexError, TypeError):
            continue
    try:
        parse_world(world)
    except WorldFileError:
        pass


def _builtin_path(name):
    from importlib import resources

    return resources.files("emmi_gym.worlds_data").joinpath(f"{name}.yaml")


# ------------------------------------------------------------------ laser


def _pymunk_ranges(sim, pose, config):
    ranges = []
    for a in config.angles + pose[2]:
        end = (pose[0] + config.max_range * math.cos(a), pose[1] + config.max_range * math.sin(a))
        hit = sim.space.segment_query_first(tuple(pose[:2]), end, 0.0,
                                            pymunk.ShapeFilter(mask=pymunk.ShapeFilter.ALL_MASKS() ^ 1))
        hit = None if hit is None or hit.shape is sim.shape else hit
        ranges.append(config.max_range if hit is None else hit.alpha * config.max_range)
    return np.array(ranges)


@pytest.mark.parametrize("world_name", ["loop_corridor", "dungeon_maps/test/img_10011.png", "intel"])
def test_laser_kernel_matches_pymunk_segment_queries(world_name):
    world = load_world(PLANS / world_name.split("/", 1)[1] if world_name.endswith(".png") else world_name)
    config = LaserConfig(n_beams=360)
    sim = Simulator(world, laser=config)
    sim.shape.filter = pymunk.ShapeFilter(categories=1)
    rng = np.random.default_rng(0)
    truth = rasterise(world, 0.1)
    checked = 0
    while checked < 20:
        x, y = rng.uniform(world.bounds[0], world.bounds[2]), rng.uniform(world.bounds[1], world.bounds[3])
        if not is_reachable(truth, x, y) or world.clearance(x, y) < 0.05:
            continue
        pose = np.array([x, y, rng.uniform(-np.pi, np.pi)])
        np.testing.assert_allclose(sim.laser.true_ranges(pose), _pymunk_ranges(sim, pose, config), atol=1e-6)
        checked += 1


def test_laser_in_a_known_box():
    """Robot at the centre of a 4 m box with 0.2 m walls: the inner faces are 1.9 m away."""
    world = parse_world(BOX)
    sim = Simulator(world, laser=LaserConfig(n_beams=8, drop_probability=0.0))
    sim.reset(np.random.default_rng(1))
    angles = sim.laser.config.angles
    expected = 1.9 / np.maximum(np.abs(np.cos(angles)), np.abs(np.sin(angles)))
    np.testing.assert_allclose(sim.laser.true_ranges(sim.true_pose), expected, atol=1e-9)
    scans = np.array([sim.scan() for _ in range(400)])
    errors = scans - expected
    assert abs(errors.mean()) < 0.003
    assert errors.std() == pytest.approx(0.02, rel=0.1)


def test_beams_past_max_range_read_max_range_and_drops():
    world = parse_world(BOX)
    sim = Simulator(world, laser=LaserConfig(n_beams=90, max_range=1.5, drop_probability=0.0))
    sim.reset(np.random.default_rng(2))
    assert (sim.scan() == 1.5).all()  # every wall is 1.9 m or more away
    sim = Simulator(world, laser=LaserConfig(n_beams=1000, drop_probability=0.2))
    sim.reset(np.random.default_rng(3))
    dropped = (sim.scan() == 8.0).mean()
    assert dropped == pytest.approx(0.2, abs=0.04)


def test_noisy_ranges_kernel_matches_its_numpy_twin():
    from emmi_gym.world.laser import _noisy_ranges

    rng = np.random.default_rng(4)
    true = np.concatenate([rng.uniform(0.0, 8.0, 200), np.full(20, 8.0), [0.01, 7.99]])
    normals, uniforms = rng.standard_normal(true.size) * 3, rng.random(true.size)
    twin = np.where(true < 8.0, np.clip(true + 0.05 * normals, 0.0, 8.0), 8.0)
    twin[uniforms < 0.1] = 8.0
    assert np.array_equal(_noisy_ranges(true, normals, uniforms, 0.05, 0.1, 8.0), twin)
    assert np.array_equal(_noisy_ranges(true, np.zeros(0), np.zeros(0), 0.05, 0.1, 8.0), np.minimum(true, 8.0))


def test_laser_config_rejects_bad_values():
    for bad in (dict(fov=0), dict(n_beams=0), dict(max_range=-1), dict(range_sigma=-0.1), dict(drop_probability=1)):
        with pytest.raises(ValueError, match=f"LaserConfig: field '{next(iter(bad))}'"):
            LaserConfig(**bad)


# ------------------------------------------------------------------ robot and physics


def test_robot_stops_at_a_wall_and_reports_the_collision():
    world = parse_world(BOX)
    sim = Simulator(world)
    sim.reset(np.random.default_rng(0))
    collided = [sim.step(0.6, 0.0).collided for _ in range(60)]  # 6 s at 0.6 m/s toward the wall at x = 1.9
    assert any(collided) and not collided[0]
    assert sim.true_pose[0] <= 1.9 - ROBOT_RADIUS + 0.02
    assert sim.true_pose[0] > 1.9 - ROBOT_RADIUS - 0.05


def test_commands_are_clipped_to_the_robot_limits():
    sim = Simulator(parse_world(BOX), robot=RobotConfig(max_speed=0.5, max_turn_rate=1.0))
    sim.reset(np.random.default_rng(0))
    xs = [sim.step(10.0, 0.0).true_pose[0] for _ in range(4)]
    assert np.diff(xs)[-1] == pytest.approx(0.5 * 0.1, abs=1e-6)  # 0.5 m/s for 0.1 s, once up to speed
    headings = [sim.step(0.0, -10.0).true_pose[2] for _ in range(4)]
    assert np.diff(headings)[-1] == pytest.approx(-1.0 * 0.1, abs=1e-6)


# ------------------------------------------------------------------ odometry


def test_relative_and_composed_motion_are_inverse():
    rng = np.random.default_rng(0)
    for _ in range(100):
        a = rng.uniform(-5, 5, 3)
        b = a + rng.uniform(-0.3, 0.3, 3)
        b[2] = (b[2] + np.pi) % (2 * np.pi) - np.pi
        np.testing.assert_allclose(compose_motion(a, *relative_motion(a, b)), b, atol=1e-9)


def test_one_pose_in_floats_gives_the_numbers_of_the_array_form():
    """compose_motion, compose_local and wrap_angle take a float path for one pose (the simulator's and the
    pose estimate's, every step): the same arithmetic as on a batch of poses. wrap_angle's is exact anywhere;
    the compositions' cos and sin come from the C library, not NumPy's vectorised loops, which may differ
    in the last bit on some processors (not on this project's machines, where the episodes stayed the same)."""
    rng = np.random.default_rng(1)
    poses, motions = rng.uniform(-20, 20, (2000, 3)), rng.uniform(-4, 4, (2000, 3))
    batch_motion = compose_motion(poses, motions[:, 0], motions[:, 1], motions[:, 2])
    batch_local = compose_local(poses, motions)
    for k in range(len(poses)):
        np.testing.assert_array_max_ulp(compose_motion(poses[k], *map(float, motions[k])), batch_motion[k], 1)
        np.testing.assert_array_max_ulp(compose_local(poses[k], motions[k]), batch_local[k], 1)
        angle = float(motions[k, 0] * 7)
        assert isinstance(wrap_angle(angle), float) and wrap_angle(angle) == wrap_angle(np.array([angle]))[0]


def test_noise_free_odometry_is_exact():
    sim = Simulator(load_world("office"), odometry=OdometryNoise(0, 0, 0, 0, 0))
    sim.reset(np.random.default_rng(0))
    for v, w in [(0.5, 0.0)] * 20 + [(0.3, 0.8)] * 20 + [(-0.2, 0.0)] * 5:
        step = sim.step(v, w)
    np.testing.assert_allclose(step.odometry_pose, step.true_pose, atol=1e-9)


def test_odometry_noise_has_the_model_variances():
    noise = OdometryNoise(0.1, 0.05, 0.02, 0.01, heading_drift=0.01)
    rng = np.random.default_rng(0)
    rot1, trans, rot2 = 0.2, 0.5, -0.1
    samples = np.array([noisy_motion(rot1, trans, rot2, noise, rng) for _ in range(20000)])
    assert samples.mean(axis=0) == pytest.approx([rot1, trans, rot2 + 0.01 * trans], abs=0.005)
    expected_var = [0.1 * rot1**2 + 0.05 * trans**2, 0.02 * trans**2 + 0.01 * (rot1**2 + rot2**2),
                    0.1 * rot2**2 + 0.05 * trans**2]
    np.testing.assert_allclose(samples.var(axis=0), expected_var, rtol=0.05)


def test_dead_reckoning_drift_matches_the_documented_defaults():
    """Fast version of measurements/odometry_drift.py: round the loop_corridor loop on 8 seeds."""
    from emmi_gym.world.recording import drive_route

    world = load_world("loop_corridor")
    sim = Simulator(world, laser=LaserConfig(n_beams=4))
    route = world.route("to_decision") + world.route("close_loop")[1:]
    errors = []
    for seed in range(8):
        rec = drive_route(sim, route, np.random.default_rng(seed))
        assert rec.reached and not rec.collisions.any()
        errors.append(np.hypot(*(rec.true_poses[-1, :2] - rec.odometry_poses[-1, :2])))
    assert np.mean(np.array(errors) > 1.0) >= 0.75
    assert 1.0 < np.median(errors) < 4.0


# ------------------------------------------------------------------ ground truth


def test_ground_truth_of_the_box():
    truth = rasterise(parse_world(BOX), 0.1)
    g, geo = truth.grid, truth.geometry
    r, c = geo.cell_of(0.0, 0.0)
    assert g[r, c] == FREE
    r, c = geo.cell_of(-2.0, 0.0)
    assert g[r, c] == OCCUPIED
    r, c = geo.cell_of(-2.8, -2.8)
    assert g[r, c] == UNKNOWN
    # the free interior is the 3.8 m x 3.8 m inner square, less the half-cell wall margin
    assert truth.reachable.sum() * 0.01 == pytest.approx(3.7 ** 2, rel=0.06)


def test_ground_truth_at_any_resolution():
    """The reachable area converges as cells shrink: walls claim half a cell more on each side, so
    halving the cell adds about (wall length x cell / 2) of free space, and nothing leaks or closes."""
    world = load_world("loop_corridor")
    areas = [rasterise(world, res).reachable.sum() * res**2 for res in (0.2, 0.1, 0.05)]
    assert areas[0] < areas[1] < areas[2]
    assert areas[1] / areas[0] < 1.2 and areas[2] / areas[1] < areas[1] / areas[0]


def test_resting_against_a_wall_is_not_a_collision():
    sim = Simulator(parse_world(BOX))
    sim.reset(np.random.default_rng(0))
    for _ in range(60):
        sim.step(0.6, 0.0)  # drive into the wall at x = 1.9 and keep pushing
    assert sim.step(0.6, 0.0).collided
    assert not any(sim.step(0.0, 0.0).collided for _ in range(5))  # then stand still against it


def test_turning_on_the_spot_is_all_rot2():
    """A few microns of jitter must not become rot1 (its arbitrary angle would scale the noise)."""
    from emmi_gym.geometry.motion import MIN_TRANSLATION, motion_std

    before, after = np.array([1.0, 2.0, 0.3]), np.array([1.0 + 3e-6, 2.0 - 2e-6, 0.45])
    rot1, trans, rot2 = relative_motion(before, after)
    assert rot1 == 0.0 and abs(trans) < MIN_TRANSLATION and rot2 == pytest.approx(0.15)
    sd_rot1, _, sd_rot2 = motion_std(rot1, trans, rot2, OdometryNoise().alphas)
    assert sd_rot1 < 1e-6 and sd_rot2 == pytest.approx(np.sqrt(0.02) * 0.15, rel=1e-3)


# ------------------------------------------------------------------ presets


def test_sensor_presets_follow_the_datasheets_and_take_overrides():
    from emmi_gym.world.presets import laser_config, odometry_config

    sick = laser_config("sick_lms200")
    assert (sick.n_beams, sick.max_range) == (181, 30.0)
    assert math.degrees(sick.fov) == pytest.approx(180) and math.degrees(sick.angular_resolution) == pytest.approx(1)
    hokuyo = laser_config({"preset": "hokuyo_urg04lx", "max_range": 4.0})
    assert hokuyo.max_range == 4.0 and math.degrees(hokuyo.angular_resolution) == pytest.approx(0.352, abs=1e-3)
    assert laser_config("default") == LaserConfig() == laser_config({})
    assert odometry_config("typical") == OdometryNoise()
    assert odometry_config("poor").trans_from_trans == 4 * OdometryNoise().trans_from_trans
    with pytest.raises(ValueError, match=r"laser.preset': expected one of \['default'"):
        laser_config({"preset": "lms"})
    with pytest.raises(ValueError, match="odometry_noise': expected a preset name"):
        odometry_config(3)


def test_odometry_presets_drift_in_their_order():
    """Fast version of measurements/odometry_drift.py --preset all: one loop (74 m), 6 seeds."""
    from emmi_gym.world.presets import odometry_config
    from emmi_gym.world.recording import drive_route

    world = load_world("loop_corridor")
    route = world.route("to_decision") + world.route("close_loop")[1:]
    medians = {}
    for preset in ("good", "poor"):
        sim = Simulator(world, laser=LaserConfig(n_beams=4), odometry=odometry_config(preset))
        medians[preset] = np.median([np.hypot(*(rec.true_poses[-1, :2] - rec.odometry_poses[-1, :2])) for rec in
                                     (drive_route(sim, route, np.random.default_rng(s)) for s in range(6))])
    assert medians["good"] < 1.5 < 2.5 < medians["poor"]
