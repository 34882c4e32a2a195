"""Worlds from occupancy images (ROS map_server maps, DungeonMaps plans) and map sets."""

import struct
import zlib
from pathlib import Path

import gymnasium as gym
import numpy as np
import pytest
from helpers import ROOT
from PIL import Image
from scipy import ndimage

import emmi_gym  # noqa: F401 (registers the ids)
from emmi_gym.world import FREE, OCCUPIED, UNKNOWN, WorldFileError, load_world, rasterise
from emmi_gym.world.images import dungeon_occupancy, map_server_occupancy
from emmi_gym.world.map_sets import WorldSource, builtin_map_sets, map_set_files, world_name

PLANS = ROOT / "emmi_gym" / "worlds_data" / "dungeon_maps"
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
    with pytest.raises(WorldFileError,
                       match=r"huge.png: expected an image of at most 25,000,000 pixels, got '6000 x 5000'"):
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


def test_a_shipped_plan_is_named_by_its_set_wherever_installed_and_loads_by_that_name(tmp_path, monkeypatch):
    """Evaluations made from two installs (a clone and a worktree, two machines) pair by world: a shipped plan's
    records name it in its set, not by the install's path, and that name loads it."""
    plan = map_set_files("dungeon_maps/test")[0]
    assert world_name(plan) == f"dungeon_maps/test/{plan.name}"
    assert world_name(f"/elsewhere/site-packages/emmi_gym/worlds_data/dungeon_maps/test/{plan.name}") == \
        world_name(plan)
    assert world_name(tmp_path / "own.png") == str(tmp_path / "own.png") and world_name(None) == "None"
    monkeypatch.chdir(tmp_path)
    np.testing.assert_array_equal(load_world(world_name(plan)).walls, load_world(plan).walls)


def test_explore_draws_plans_from_a_set_deterministically():
    env = gym.make("emmi_gym/Explore-v1", world="dungeon_maps/test", max_decisions=3)
    runs = []
    for _ in range(2):
        _, info = env.reset(seed=11)
        rewards = [env.step(0)[1] for _ in range(2)]
        runs.append((info["world"], rewards, env.unwrapped.true_path.tobytes()))
    assert runs[0] == runs[1]
    assert env.reset(seed=12)[1]["world"] != runs[0][0] or env.reset(seed=13)[1]["world"] != runs[0][0]
    with pytest.raises(ValueError, match="start_at='start'"):
        gym.make("emmi_gym/Explore-v1", world="dungeon_maps/test", start_at="decision")


def test_a_half_circle_scanner_finds_the_frontier_behind_it():
    """With a 180-degree laser the unseen half behind the robot starts at its own position: the frontier's
    centroid is where the robot stands, so the target is its nearest cell at least a metre away."""
    env = gym.make("emmi_gym/Explore-v1", world=str(PLAN), laser="sick_lms200")
    env.reset(seed=0)
    frontiers = [t for t in env.unwrapped.targets if t is not None and t.kind == "frontier"]
    assert frontiers and all(t.travel_cost >= 1.0 for t in frontiers)
    start = env.unwrapped.sim.true_pose
    env.step(0)
    assert np.hypot(*(env.unwrapped.sim.true_pose[:2] - start[:2])) > 0.5  # it drove; it did not stand still


@pytest.mark.parametrize("name", ["intel", "aces", "csail", "fr079"])
def test_real_buildings_load_by_name(name):
    """The worlds built from the corrected logs (measurements/build_building_worlds.py) match their map images: the
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


def room(wall: int, free: int) -> np.ndarray:
    """A 60 x 80 px room at two grey levels: walls 4 px thick round it and a pillar inside."""
    pixels = np.full((60, 80), wall)
    pixels[4:-4, 4:-4] = free
    pixels[25:35, 30:45] = wall
    return pixels


def test_16_bit_maps_load_with_their_walls(tmp_path):
    """The same plan as an 8-bit and a 16-bit image (walls at 20000 of 65535) gives the same free cells and walls,
    as a plain plan and as a map_server map (PGM)."""
    Image.fromarray(room(78, 255).astype(np.uint8)).save(tmp_path / "plan8.png")
    Image.fromarray(room(20000, 65535).astype(np.uint16)).save(tmp_path / "plan16.png")
    eight, sixteen = dungeon_occupancy(tmp_path / "plan8.png"), dungeon_occupancy(tmp_path / "plan16.png")
    assert 0.5 < eight.free.mean() < 0.9
    np.testing.assert_array_equal(sixteen.free, eight.free)
    np.testing.assert_array_equal(load_world(tmp_path / "plan16.png").walls, load_world(tmp_path / "plan8.png").walls)
    eight_bit_map = write_map_server(tmp_path, room(0, 254))
    reference = map_server_occupancy(eight_bit_map).free
    Image.fromarray(room(0, 65278).astype(np.uint16)).save(tmp_path / "map.pgm")  # 254 x 257
    assert Image.open(tmp_path / "map.pgm").mode == "I"  # maxval 65535
    np.testing.assert_array_equal(map_server_occupancy(eight_bit_map).free, reference)
    Image.fromarray(room(20000, 65535).astype(np.uint16)).save(tmp_path / "map.pgm")
    assert 0.5 < map_server_occupancy(eight_bit_map).free.mean() < 0.9


def _png_chunk(kind: bytes, data: bytes) -> bytes:
    return struct.pack(">I", len(data)) + kind + data + struct.pack(">I", zlib.crc32(kind + data))


def _png(width: int, height: int, before_image: bytes = b"", rows: bytes | None = None) -> bytes:
    """An 8-bit grey PNG (white unless ``rows`` are given) with ``before_image`` chunks ahead of its pixels."""
    pixels = zlib.compress(rows if rows is not None else (b"\0" + b"\xff" * width) * height)
    return (b"\x89PNG\r\n\x1a\n" + _png_chunk(b"IHDR", struct.pack(">IIBBBBB", width, height, 8, 0, 0, 0, 0)) +
            before_image + _png_chunk(b"IDAT", pixels) + _png_chunk(b"IEND", b""))


def _jpeg(path):
    Image.fromarray(room(78, 255).astype(np.uint8)).save(path, format="JPEG")


@pytest.mark.parametrize("name, content, expected", [
    # a text chunk that inflates to 2 MB (Pillow stops at 1 MB; a real one could inflate to gigabytes)
    ("ztxt.png", _png(40, 40, _png_chunk(b"zTXt", b"Comment\0\0" + zlib.compress(b"\0" * (2 << 20)))),
     r"ztxt\.png: expected a PNG image with a valid header \(Pillow: Decompressed data too large"),
    ("truncated.pgm", b"P5\n100 100\n255\n" + b"\xff" * 500,
     r"truncated\.pgm: expected a PGM image whose pixel data is complete and valid \(Pillow: .*shorter than"),
    ("maxval0.pgm", b"P5\n10 10\n0\n" + b"\0" * 100,
     r"maxval0\.pgm: expected a PGM image with a valid header \(Pillow: maxval must be greater than 0"),
    # 400 M pixels in its header, a few bytes of pixels: refused by the package's bound before decoding
    ("huge.png", _png(20000, 20000, rows=b"\0" * 100),
     r"huge\.png: expected an image of at most 25,000,000 pixels, got '20000 x 20000'"),
    ("photo.png", _jpeg, r"photo\.png: expected a PNG or PGM image, not a JPEG image"),
    ("x.png", "folder", r"x\.png: expected a map image, not a folder"),
], ids=["ztxt-bomb", "truncated", "maxval-0", "20000x20000", "jpeg", "folder"])
def test_broken_images_name_the_file_and_what_is_wrong(tmp_path, name, content, expected):
    path = tmp_path / name
    if content == "folder":
        path.mkdir()
    elif callable(content):
        content(path)
    else:
        path.write_bytes(content)
    with pytest.raises(WorldFileError, match=expected):
        load_world(path)


def test_images_and_world_files_that_are_devices_are_named_as_such(tmp_path, capsys):
    from emmi_gym.tools.cli import main

    with pytest.raises(WorldFileError, match=r"/dev/zero: expected a world file, not a character device"):
        load_world("/dev/zero")
    (tmp_path / "map.pgm").symlink_to("/dev/zero")
    (tmp_path / "map.yaml").write_text("image: map.pgm\nresolution: 0.1\norigin: [0, 0, 0]\n")
    with pytest.raises(WorldFileError, match=r"map\.pgm: expected a map image, not a character device"):
        load_world(tmp_path / "map.yaml")
    (tmp_path / "ztxt.png").write_bytes(_png(40, 40, _png_chunk(b"zTXt", b"C\0\0" + zlib.compress(b"\0" * (2 << 20)))))
    with pytest.raises(SystemExit) as exit_info:
        main(["record", str(tmp_path / "ztxt.png"), "--out", str(tmp_path / "run.log")])
    assert exit_info.value.code == 2
    assert f"{tmp_path / 'ztxt.png'}: expected a PNG image with a valid header" in capsys.readouterr().err


def test_a_map_server_file_without_its_image_is_read_as_one(tmp_path):
    path = tmp_path / "map.yaml"
    path.write_text("resolution: 0.05\norigin: [0.0, 0.0, 0.0]\nnegate: 0\noccupied_thresh: 0.65\nfree_thresh: 0.2\n")
    with pytest.raises(WorldFileError, match=r"map\.yaml: field 'image': expected a value \(the field is required\)"):
        load_world(path)


def test_environments_too_large_for_memory_are_refused_with_the_size_allowed(tmp_path):
    """Maps within the filter's bound, but not with what the environment adds per cell (the oracle's map, the
    observation): refused when the env is made (a fixed world) or draws the world (a map set), naming it."""
    from emmi_gym.concurrency.threads import kernel_threads, set_kernel_threads
    from emmi_gym.env.memory import env_bytes_per_cell
    from emmi_gym.slam.occupancy import MapTooLarge

    Image.new("L", (1500, 1500), 255).save(tmp_path / "plan.png")  # 2.25 M cells at 0.1 m
    threads = kernel_threads()
    try:
        set_kernel_threads(1)  # each insertion thread adds its own working memory
        per_cell = env_bytes_per_cell(300)  # the filter's maps for 300 particles, the oracle's, the env's, planning
        expected = (rf"plan\.png: 1500 x 1500 cells of 0\.1 m would take {1500 * 1500 * per_cell / 2**30:.1f} GiB in "
                    rf"an environment with 300 particles \({per_cell} bytes per cell: .*\), above the bound of 4 GiB; "
                    f"at most {4 * 2**30 // per_cell:,} cells")
        with pytest.raises(MapTooLarge, match=expected):
            gym.make("emmi_gym/Explore-v1", world=str(tmp_path / "plan.png"), particles=300)
        (tmp_path / "set").mkdir()
        (tmp_path / "plan.png").rename(tmp_path / "set" / "plan.png")
        env = gym.make("emmi_gym/Explore-v1", world=str(tmp_path / "set"), particles=300)
        with pytest.raises(MapTooLarge, match=expected.replace("plan", "set/plan")):
            env.reset(seed=0)
    finally:
        set_kernel_threads(threads)
