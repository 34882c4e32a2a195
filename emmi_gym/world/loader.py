"""Read and validate world files (YAML, ``yaml.safe_load`` only).

A world file::

    name: loop_corridor
    description: free text
    bounds: {xmin: -10.5, ymin: -0.5, xmax: 24.5, ymax: 16.5}
    wall_thickness: 0.2            # default for walls that give none
    walls:
      - segment: {from: [0, 0], to: [24, 0]}
      - polyline: {points: [[0, 10], [0, 16], [24, 16]], closed: false, thickness: 0.2}
      - rectangle: {min: [2, 2], max: [22, 14]}      # the outline, as four walls
    start: {x: 12, y: 1, theta: 0}
    places:                        # optional named poses
      decision: {x: 1, y: 11, theta: -1.5708}
    routes:                        # optional: waypoint lists of places or [x, y]
      to_decision: [start, [23, 1], [23, 15], [1, 15], decision]

Every problem raises :class:`WorldFileError` naming the file, the field and what
was expected.
"""

from __future__ import annotations

import math
from importlib import resources
from pathlib import Path

import numpy as np

from ..inputs.errors import excerpt
from ..inputs.validation import Invalid, Real
from ..inputs.yaml_files import YAML_SUFFIXES, read_yaml_file
from .images import (
    DEFAULT_PIXEL_SIZE,
    IMAGE_SUFFIXES,
    dungeon_occupancy,
    is_map_server_file,
    map_server_image,
    map_server_occupancy,
    world_from_occupancy,
)
from .spec import ROBOT_RADIUS, Place, WorldFileError, WorldSpec, point_segment_distance

_TOP_KEYS = {"name", "description", "bounds", "wall_thickness", "walls", "start", "places", "routes"}
_REQUIRED = ("name", "bounds", "walls", "start")
_WALL_KINDS = {"segment": {"from", "to", "thickness"},
               "polyline": {"points", "closed", "thickness"},
               "rectangle": {"min", "max", "thickness"}}
_DEFAULT_THICKNESS = 0.2
#: Bounds of the numbers in a world file: coordinates (m), wall thickness, the world's size (the
#: ground truth and every particle's map cover it: 2 km at 0.1 m are 400 M cells per map).
COORDINATE = Real(-1e4, 1e4, unit="m")
THICKNESS = Real(0.01, 5.0, unit="m")
MAX_WORLD_SIZE = 2000.0
#: Spacing (m) of the points at which a route's legs are checked against the walls.
ROUTE_CHECK_STEP = 0.05


def _looks_numeric(text: str) -> bool:
    try:
        float(text)
    except ValueError:
        return False
    return True


#: Folders of ``worlds_data`` whose YAML files are built-in worlds: hand-made world files at the top,
#: map_server maps of real buildings (``measurements/build_building_worlds.py``) in ``buildings/``.
_BUILTIN_FOLDERS = (".", "buildings")


def worlds_data_root() -> Path:
    """The folder of the worlds and map sets shipped with the package."""
    return Path(str(resources.files("emmi_gym.worlds_data")))


def _builtin_files() -> dict[str, Path]:
    root = worlds_data_root()
    return {path.stem: path for folder in _BUILTIN_FOLDERS for path in sorted((root / folder).glob("*.yaml"))}


def builtin_worlds() -> list[str]:
    """Names of the worlds shipped with the package: ``loop_corridor``, ``office`` and the buildings
    ``intel``, ``aces``, ``csail``, ``fr079``."""
    return sorted(_builtin_files())


def load_world(name_or_path, pixel_size: float = DEFAULT_PIXEL_SIZE) -> WorldSpec:
    """Load a world: a built-in name (``"loop_corridor"``, ``"intel"``), a world file (``.yaml``), a
    ROS map_server map (its ``.yaml``) or a floor-plan image (``.png``/``.pgm``, DungeonMaps colour
    rules, ``pixel_size`` metres per pixel; see :mod:`emmi_gym.world.images`); a map of a shipped map set
    by its name in the set (``"dungeon_maps/test/img_10011.png"``) where no such file is in the working folder."""
    path = world_path(name_or_path)
    if path.suffix.lower() in IMAGE_SUFFIXES:
        return world_from_occupancy(dungeon_occupancy(path, pixel_size))
    data = read_yaml_file(path, "world file", WorldFileError)
    if is_map_server_file(data):
        return world_from_occupancy(map_server_occupancy(path, data))
    return parse_world(data, source=path.name if str(name_or_path) in _builtin_files() else str(path))


def world_path(name_or_path) -> Path:
    """The file :func:`load_world` reads for ``name_or_path`` (a path, a map of a shipped map set, a built-in name);
    ValueError for a name that is none of them."""
    name = str(name_or_path)
    path = Path(name)
    if not path.exists() and not path.is_absolute() and (worlds_data_root() / path).is_file():
        path = worlds_data_root() / path
    builtin = _builtin_files()
    if path.suffix.lower() not in IMAGE_SUFFIXES + YAML_SUFFIXES and not path.exists():
        if name not in builtin:
            raise ValueError(f"unknown world {excerpt(name)}: give a path to a world file or map_server map (.yaml), "
                             f"an image ({'/'.join(IMAGE_SUFFIXES)}) or one of {sorted(builtin)}")
        path = builtin[name]
    return path


def world_files(name_or_path) -> dict[str, Path]:
    """The files a world is read from, ``{what: path}``: ``"the world file"`` (:func:`world_path`) and, for a
    map_server map, ``"the world's image"`` that its YAML file names; for a command that must not write over them."""
    path = world_path(name_or_path)
    files = {"the world file": path}
    if path.suffix.lower() in YAML_SUFFIXES and path.is_file():
        data = read_yaml_file(path, "world file", WorldFileError)
        if is_map_server_file(data) and isinstance(data.get("image"), str):
            files["the world's image"] = map_server_image(path, data["image"])
    return files


class _Reader:
    """Field-by-field validation with the path of each field in the messages."""

    def __init__(self, source: str):
        self.source = source

    def fail(self, path: str, expected: str, got=WorldFileError.NOTHING):
        raise WorldFileError(self.source, path, expected, got)

    def mapping(self, value, path: str, allowed: set[str], required=()) -> dict:
        if not isinstance(value, dict):
            if not path:  # the whole file: its type, not its content (which may be any file's)
                self.fail("", f"a mapping of world fields, not a {type(value).__name__}")
            self.fail(path, "a mapping", value)
        unknown = sorted(set(map(str, value)) - allowed)
        if unknown:
            self.fail(f"{path}.{unknown[0]}" if path else unknown[0], f"one of the known keys {sorted(allowed)}")
        for key in required:
            if key not in value:
                self.fail(f"{path}.{key}" if path else key, "a value (the field is required)")
        return value

    def number(self, value, path: str, check: Real = COORDINATE) -> float:
        try:
            return check(value)
        except Invalid as exc:
            hint = " (write exponents with a sign or a dot: 1.0e+5)" if isinstance(value, str) and _looks_numeric(
                value) else ""
            self.fail(path, f"{exc}{hint}", value)

    def point(self, value, path: str) -> tuple[float, float]:
        if not isinstance(value, (list, tuple)) or len(value) != 2:
            self.fail(path, "a point [x, y]", value)
        return (self.number(value[0], f"{path}[0]"), self.number(value[1], f"{path}[1]"))

    def string(self, value, path: str) -> str:
        if not isinstance(value, str) or not value:
            self.fail(path, "a non-empty string", value)
        return value


def parse_world(data, source: str = "<dict>") -> WorldSpec:
    """Validate a world given as a dict (as read from YAML) and build its :class:`WorldSpec`."""
    r = _Reader(source)
    data = r.mapping(data, "", _TOP_KEYS, _REQUIRED)
    name = r.string(data["name"], "name")
    description = data.get("description", "")
    if not isinstance(description, str):
        r.fail("description", "a string", description)

    b = r.mapping(data["bounds"], "bounds", {"xmin", "ymin", "xmax", "ymax"}, ("xmin", "ymin", "xmax", "ymax"))
    bounds = tuple(r.number(b[k], f"bounds.{k}") for k in ("xmin", "ymin", "xmax", "ymax"))
    if bounds[2] <= bounds[0]:
        r.fail("bounds.xmax", f"a number greater than bounds.xmin = {bounds[0]}", bounds[2])
    if bounds[3] <= bounds[1]:
        r.fail("bounds.ymax", f"a number greater than bounds.ymin = {bounds[1]}", bounds[3])

    for axis, lo, hi in (("x", bounds[0], bounds[2]), ("y", bounds[1], bounds[3])):
        if hi - lo > MAX_WORLD_SIZE:
            r.fail(f"bounds.{axis}max", f"a world at most {MAX_WORLD_SIZE:g} m across (its ground truth and every "
                   f"particle's map cover the bounds), here {hi - lo:g} m", hi)
    default_thickness = r.number(data.get("wall_thickness", _DEFAULT_THICKNESS), "wall_thickness", THICKNESS)
    walls = _parse_walls(r, data["walls"], default_thickness)
    start = _parse_place(r, data["start"], "start")
    _check_start(r, start, bounds, walls)

    places_data = data.get("places") or {}
    if not isinstance(places_data, dict):
        r.fail("places", "a mapping of names to {x, y[, theta]}", places_data)
    places = {"start": start}
    for key, value in places_data.items():
        places[str(key)] = _parse_place(r, value, f"places.{key}")

    routes_data = data.get("routes") or {}
    if not isinstance(routes_data, dict):
        r.fail("routes", "a mapping of names to waypoint lists", routes_data)
    routes = {}
    for key, waypoints in routes_data.items():
        path = f"routes.{key}"
        if not isinstance(waypoints, list) or len(waypoints) < 2:
            r.fail(path, "a list of at least two waypoints (place names or [x, y])", waypoints)
        routes[str(key)] = [_waypoint(r, w, f"{path}[{i}]", places) for i, w in enumerate(waypoints)]
        _check_route(r, path, routes[str(key)], bounds, walls)

    return WorldSpec(name=name, bounds=bounds, walls=walls, start=start, places=places, routes=routes,
                     description=description, source=source)


def _parse_walls(r: _Reader, walls_data, default_thickness: float) -> np.ndarray:
    if not isinstance(walls_data, list) or not walls_data:
        r.fail("walls", "a non-empty list of segment / polyline / rectangle entries", walls_data)
    rows = []
    for i, entry in enumerate(walls_data):
        path = f"walls[{i}]"
        if not isinstance(entry, dict) or len(entry) != 1 or next(iter(entry)) not in _WALL_KINDS:
            r.fail(path, f"a mapping with exactly one of {sorted(_WALL_KINDS)}", entry)
        kind, body = next(iter(entry.items()))
        path = f"{path}.{kind}"
        required = {"segment": ("from", "to"), "polyline": ("points",), "rectangle": ("min", "max")}[kind]
        body = r.mapping(body, path, _WALL_KINDS[kind], required)
        t = r.number(body.get("thickness", default_thickness), f"{path}.thickness", THICKNESS)
        if kind == "segment":
            points = [r.point(body["from"], f"{path}.from"), r.point(body["to"], f"{path}.to")]
        elif kind == "polyline":
            pts = body["points"]
            if not isinstance(pts, list) or len(pts) < 2:
                r.fail(f"{path}.points", "a list of at least two points [x, y]", pts)
            points = [r.point(p, f"{path}.points[{k}]") for k, p in enumerate(pts)]
            closed = body.get("closed", False)
            if not isinstance(closed, bool):
                r.fail(f"{path}.closed", "true or false", closed)
            if closed:
                points.append(points[0])
        else:
            (x0, y0), (x1, y1) = r.point(body["min"], f"{path}.min"), r.point(body["max"], f"{path}.max")
            if x1 <= x0 or y1 <= y0:
                r.fail(f"{path}.max", f"a corner above and right of min = [{x0}, {y0}] (positive width and height)",
                       [x1, y1])
            points = [(x0, y0), (x1, y0), (x1, y1), (x0, y1), (x0, y0)]
        for k, (a, b) in enumerate(zip(points[:-1], points[1:], strict=False)):
            if math.hypot(b[0] - a[0], b[1] - a[1]) <= 1e-9:
                r.fail(path, f"walls of positive length (points {k} and {k + 1} coincide)", [list(a), list(b)])
            rows.append((*a, *b, t))
    return np.array(rows, dtype=np.float64)


def _parse_place(r: _Reader, value, path: str) -> Place:
    v = r.mapping(value, path, {"x", "y", "theta"}, ("x", "y"))
    theta = r.number(v["theta"], f"{path}.theta") if "theta" in v else None
    return Place(r.number(v["x"], f"{path}.x"), r.number(v["y"], f"{path}.y"), theta)


def _first_collision(points: np.ndarray, bounds, walls: np.ndarray):
    """The index of the first point (N, 2) where the robot's body leaves the bounds or touches a wall, and
    what it touches (None if the robot fits everywhere)."""
    xmin, ymin, xmax, ymax = bounds
    for i0 in range(0, len(points), 4096):  # chunks keep the (points x walls) distances small
        chunk = points[i0:i0 + 4096]
        outside = ~((xmin + ROBOT_RADIUS <= chunk[:, 0]) & (chunk[:, 0] <= xmax - ROBOT_RADIUS) &
                    (ymin + ROBOT_RADIUS <= chunk[:, 1]) & (chunk[:, 1] <= ymax - ROBOT_RADIUS))
        gaps = point_segment_distance(chunk[:, 0], chunk[:, 1], walls) - walls[None, :, 4] / 2
        bad = outside | (gaps.min(axis=1) < ROBOT_RADIUS)
        if bad.any():
            i = int(np.argmax(bad))
            if outside[i]:
                return i0 + i, f"the bounds [{xmin:g}, {xmax:g}] x [{ymin:g}, {ymax:g}]"
            w = walls[int(np.argmin(gaps[i]))]
            return i0 + i, f"the wall from ({w[0]:g}, {w[1]:g}) to ({w[2]:g}, {w[3]:g})"
    return None


def _check_start(r: _Reader, start: Place, bounds, walls: np.ndarray) -> None:
    collision = _first_collision(np.array([start.xy]), bounds, walls)
    if collision is not None:
        r.fail("start", f"a pose where the robot (radius {ROBOT_RADIUS} m) is inside the bounds and clear of every "
                        f"wall; it overlaps {collision[1]}", [start.x, start.y])


def _check_route(r: _Reader, path: str, waypoints: list, bounds, walls: np.ndarray) -> None:
    """A route is driven straight from waypoint to waypoint: every waypoint inside the bounds (so that the legs'
    checks cost what the world holds), and the robot must fit along every leg."""
    xmin, ymin, xmax, ymax = bounds
    for i, (x, y) in enumerate(waypoints):
        if not (xmin <= x <= xmax and ymin <= y <= ymax):
            r.fail(f"{path}[{i}]", f"a waypoint inside the bounds [{xmin:g}, {xmax:g}] x [{ymin:g}, {ymax:g}]", [x, y])
    for i, (a, b) in enumerate(zip(waypoints[:-1], waypoints[1:], strict=False)):
        length = math.hypot(b[0] - a[0], b[1] - a[1])
        t = np.linspace(0.0, 1.0, max(2, int(math.ceil(length / ROUTE_CHECK_STEP)) + 1))
        points = np.column_stack([a[0] + t * (b[0] - a[0]), a[1] + t * (b[1] - a[1])])
        collision = _first_collision(points, bounds, walls)
        if collision is not None:
            x, y = points[collision[0]]
            r.fail(f"{path}[{i + 1}]", f"a waypoint the robot (radius {ROBOT_RADIUS} m) can drive to straight from "
                   f"the one before; at ({x:.2f}, {y:.2f}) it would overlap {collision[1]}", list(b))


def _waypoint(r: _Reader, value, path: str, places: dict[str, Place]) -> tuple[float, float]:
    if isinstance(value, str):
        if value not in places:
            r.fail(path, f"a place name (one of {sorted(places)}) or a point [x, y]", value)
        return places[value].xy
    return r.point(value, path)
