"""Worlds from occupancy images (ROS map_server maps, DungeonMaps plans) and map sets."""

from pathlib import Path

import gymnasium as gym
import numpy as np
import pytest
from PIL import Image
from scipy import ndimage

import emmi_gym  # noqa: F401 (registers the ids)
from emmi_gym.world import FREE, OCCUPIED, UNKNOWN, WorldFileError, load_world, rasterise
from emmi_gym.world.images import dungeon_occupancy, map_server_occupancy
from emmi_gym.world.map_sets import WorldSource, builtin_map_sets, map_set_files

PLANS = Path(__file__).resolve().parents[1] / "emmi_gym" / "worlds_data" / "dungeon_maps"
PLAN = PLANS / "test" / "img_10011.png"


def agreement(world, free_mask, resolution):
    """Share of the image's pixels on which the world's rasterised ground truth says free iff the image does."""
    truth = rasterise(world, resolution)
    assert truth.grid.shape == free_mask.shape
    return float(np.mean(truth.reachable == free_mask))


def test_dungeon_plan_loads_as_few_walls_matching_the_image():
    world = load_world(PLAN)
    occupancy = dungeon_occupancy(PLAN)
    assert world.bounds == (0.0, 0.0, 64.0, 48.0)  # 640 x 480 px at the default 0.1 m
    assert len(world.walls) < 200  # traced boundaries, not a shape per pixel (the plan has ~25,000 obstacle px)
    assert agreement(world, occupancy.free, 0.1) >= 0.95
    # the start is the yellow square's centre
    rgb = np.asarray(Image.open(PLAN).convert("RGB"))
    rows, cols = np.nonzero((rgb[..., 0] > 200) & (rgb[..., 1] > 150) & (rgb[..., 2] < 100))
    assert world.start.x == pytest.approx((cols.mean() + 0.5) * 0.1)
    assert world.start.y == pytest.approx((480 - rows.mean() - 0.5) * 0.1)


def test_pixel_size_scales_the_plan():
    world = load_world(PLAN, pixel_size=0.05)
    assert world.bounds == (0.0, 0.0, 32.0, 24.0)
    with pytest.raises(WorldFileError, match="pixel_size"):
        load_world(PLAN, pixel_size=0)


def write_map_server(folder: Path, pixels: np.ndarray, **fields) -> Path:
    """A map_server map: a PGM (top row first, as images are stored) and its YAML file."""
    Image.fromarray(pixels.astype(np.uint8)).save(folder / "map.pgm")
    data = dict(image="map.pgm", resolution=0.05, origin=[-2.0, -1.0, 0.0], negate=0, occupied_thresh=0.65,
                free_thresh=0.196) | fields
    lines = [f"{k}: {v}" for k, v in data.items()]
    (folder / "map.yaml").write_text("\n".join(lines) + "\n")
    return folder / "map.yaml"


def two_rooms() -> np.ndarray:
    """A 120 x 160 px map: a free room with a pillar, unknown grey outside, and a closed-off free pocket."""
    pixels = np.full((120, 160), 205, dtype=np.uint8)  # unknown (p = 0.2)
    pixels[10:110, 10:100] = 0  # occupied block ...
    pixels[12:108, 12:98] = 254  # ... holding a free room
    pixels[50:60, 40:60] = 0  # a pillar
    pixels[20:40, 120:150] = 254  # a pocket the robot cannot reach
    return pixels


def test_map_server_map_loads_with_its_origin_and_only_the_reachable_space(tmp_path):
    path = write_map_server(tmp_path, two_rooms())
    world = load_world(path)
    assert world.bounds == pytest.approx((-2.0, -1.0, -2.0 + 160 * 0.05, -1.0 + 120 * 0.05))
    truth = rasterise(world, 0.05)
    room = np.zeros((120, 160), dtype=bool)
    room[12:108, 12:98] = True
    room[50:60, 40:60] = False
    assert agreement(world, np.flipud(room), 0.05) >= 0.95
    pocket = np.flipud(np.pad(np.ones((20, 30), dtype=bool), ((20, 80), (120, 10))))
    assert np.all(truth.grid[pocket] == UNKNOWN)  # not reachable: neither free nor walled
    assert (truth.grid == OCCUPIED).any() and (truth.grid == FREE).sum() > 0.9 * room.sum()
    assert world.clearance(world.start.x, world.start.y) > 1.0  # the default start: the roomiest free pixel


def test_map_server_negate_and_start(tmp_path):
    path = write_map_server(tmp_path, 255 - two_rooms(), negate=1, start="[1.0, 1.0, 0.5]")
    world = load_world(path)
    assert (world.start.x, world.start.y, world.start.theta) == (1.0, 1.0, 0.5)


@pytest.mark.parametrize("fields, field, expected", [
    (dict(resolution=0), "resolution", r"finite number in \[0.005"),
    (dict(origin="[0, 0, 0.5]"), "origin", "yaw of 0"),
    (dict(free_thresh=0.9), "free_thresh", "below occupied_thresh"),
    (dict(image="missing.pgm"), "image", "does not exist"),
    (dict(image="map.jpg"), "image", "PNG or PGM"),
    (dict(start="[0.5, 2.25, 0.0]"), "start", "point in free space"),  # in the pillar
    (dict(start="[50.0, 0.0, 0.0]"), "start", "inside the map"),
    (dict(colour="red"), "colour", "known options"),
])
def test_bad_map_server_files_name_the_file_and_field(tmp_path, fields, field, expected):
    path = write_map_server(tmp_path, two_rooms(), **fields)
    with pytest.raises(WorldFileError, match=expected) as info:
        load_world(path)
    assert str(path) in str(info.value) and f"'{field}'" in str(info.value)


def test_bad_images_give_clear_errors(tmp_path):
    not_image = tmp_path / "plan.png"
    not_image.write_text("this is not a PNG")
    with pytest.raises(WorldFileError, match="plan.png: expected a PNG or PGM image"):
        load_world(not_image)
    dark = tmp_path / "dark.png"
    Image.fromarray(np.full((40, 40), 127, dtype=np.uint8)).save(dark)
    with pytest.raises(WorldFileError, match="dark.png: expected an image with free space"):
        load_world(dark)
    narrow = np.full((40, 40), 127, dtype=np.uint8)
    narrow[10:30, 19:21] = 195  # a slot 0.2 m wide: the robot (0.4 m across) does not fit
    Image.fromarray(narrow).save(tmp_path / "narrow.png")
    with pytest.raises(WorldFileError, match="robot .* fits"):
        load_world(tmp_path / "narrow.png")
    with pytest.raises(FileNotFoundError):
        load_world(tmp_path / "absent.png")
    Image.new("L", (6000, 5000), 195).save(tmp_path / "huge.png")  # 30 M pixels in a few kB
    with pytest.raises(WorldFileError, match=r"huge.png: expected an image of at most 25,000,000 pixels, got '6000 x 5000'"):
        load_world(tmp_path / "huge.png")


def test_grey_plan_finds_the_start_by_its_grey_level(tmp_path):
    grey = np.asarray(Image.open(PLAN).convert("RGB"), dtype=np.float64) @ [0.2125, 0.7154, 0.0721]
    Image.fromarray(np.round(grey).astype(np.uint8)).save(tmp_path / "grey.png")
    assert load_world(tmp_path / "grey.png").start == load_world(PLAN).start


def test_map_sets_are_drawn_per_seed_and_named_three_ways(tmp_path):
    assert builtin_map_sets() == ["dungeon_maps/test", "dungeon_maps/train"]
    assert len(map_set_files("dungeon_maps/train")) == 50
    source = WorldSource("dungeon_maps/test")
    names = [source.draw(np.random.default_rng(seed)).name for seed in range(6)]
    assert names == [source.draw(np.random.default_rng(seed)).name for seed in range(6)]
    assert len(set(names)) > 1
    for f in sorted(PLANS.joinpath("train").iterdir())[:3]:
        (tmp_path / f.name).write_bytes(f.read_bytes())
    assert len(map_set_files(str(tmp_path))) == 3
    assert len(map_set_files(str(tmp_path / "*.png"))) == 3
    with pytest.raises(ValueError, match="matches no map file"):
        map_set_files(str(tmp_path / "*.gif"))
    assert map_set_files("loop_corridor") is None


def test_explore_draws_plans_from_a_set_deterministically():
    env = gym.make("emmi_gym/Explore-v0", world="dungeon_maps/test", max_decisions=3)
    runs = []
    for _ in range(2):
        _, info = env.reset(seed=11)
        rewards = [env.step(0)[1] for _ in range(2)]
        runs.append((info["world"], rewards, env.unwrapped.true_path.tobytes()))
    assert runs[0] == runs[1]
    assert env.reset(seed=12)[1]["world"] != runs[0][0] or env.reset(seed=13)[1]["world"] != runs[0][0]
    with pytest.raises(ValueError, match="start_at='start'"):
        gym.make("emmi_gym/Explore-v0", world="dungeon_maps/test", start_at="decision")


def test_a_half_circle_scanner_finds_the_frontier_behind_it():
    """With a 180-degree laser the unseen half behind the robot starts at its own position: the frontier's
    centroid is where the robot stands, so the target is its nearest cell at least a metre away."""
    env = gym.make("emmi_gym/Explore-v0", world=str(PLAN), laser="sick_lms200")
    env.reset(seed=0)
    frontiers = [t for t in env.unwrapped.targets if t is not None and t.kind == "frontier"]
    assert frontiers and all(t.travel_cost >= 1.0 for t in frontiers)
    start = env.unwrapped.sim.true_pose
    env.step(0)
    assert np.hypot(*(env.unwrapped.sim.true_pose[:2] - start[:2])) > 0.5  # it drove; it did not stand still


@pytest.mark.parametrize("name", ["intel", "aces", "csail", "fr079"])
def test_real_buildings_load_by_name(name):
    """The worlds built from the corrected logs (scripts/build_building_worlds.py) match their map images: the
    free space reachable from the log's first pose is the building the robot saw."""
    world = load_world(name)
    assert world.source.endswith(f"buildings/{name}.yaml")
    occupancy = map_server_occupancy(world.source)
    labels, _ = ndimage.label(occupancy.free)
    row, col = (int((v - o) / 0.1) for v, o in ((world.start.y, occupancy.origin[1]), (world.start.x,
                                                                                      occupancy.origin[0])))
    reachable = labels == labels[row, col]
    assert reachable.sum() * 0.01 > 300  # m^2
    assert agreement(world, reachable, 0.1) >= 0.95
    assert world.clearance(world.start.x, world.start.y) > 0.2
