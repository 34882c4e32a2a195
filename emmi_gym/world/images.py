"""Worlds from occupancy images: ROS map_server maps and plain floor-plan images (DungeonMaps).

An image becomes a :class:`WorldSpec` in three steps:

1. **Classify the pixels** free / not free, and find the start. A map_server map follows
   ROS's ``map_server`` rules (trinary mode): a pixel's occupancy is ``p = (255 - v) / 255``
   (``v / 255`` with ``negate: 1``; colour channels averaged), free below ``free_thresh``,
   occupied above ``occupied_thresh``, unknown between; unknown counts as not free. A plain
   image follows the DungeonMaps colour rules: light pixels (grey level >= 160) are free, dark
   ones obstacles, and the yellow square (RGB: red and green high, blue low; in a grey image the
   level 208 that yellow becomes) is the start. 16-bit grey images (PNG, or PGM of maxval above
   255) are read at their full range: 65535 is white, and the levels above are 257 times theirs.
2. **Keep the free space reachable from the start** (4-connected); everything else is obstacle,
   so closed-off pockets neither get walls nor count as area to explore.
3. **Trace its boundary** with scikit-image's marching squares and simplify each contour with
   Douglas-Peucker (``approximate_polygon``, tolerance :data:`CONTOUR_TOLERANCE` pixels): the
   walls are a few segments half a pixel thick, not a shape per pixel. They are traced at level
   :data:`WALL_LEVEL` of the free mask, a quarter pixel inside the obstacle pixels, so that their
   free-side face lies on the pixel edge: the laser sees the image's boundary, and the ground
   truth rasterised at the image's resolution gives back the image's free pixels.

Without a start (a map_server map gives none unless its YAML adds ``start: [x, y, theta]``, an
image without yellow), the robot starts at the free pixel farthest from any obstacle.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from PIL import Image, PngImagePlugin, PpmImagePlugin
from scipy import ndimage

from ..inputs.errors import excerpt
from ..inputs.user_paths import input_file
from ..inputs.validation import (
    Choice,
    Integer,
    Maybe,
    Real,
    Text,
    Tuple,
    build,
    check_fields,
    check_value,
    fail,
    option,
)
from ..inputs.yaml_files import read_yaml_file
from .spec import ROBOT_RADIUS, Place, WorldFileError, WorldSpec

IMAGE_SUFFIXES = (".png", ".pgm")
#: Metres per pixel of a plain image unless the user gives ``pixel_size`` (DungeonMaps' corridors,
#: 32 px, become 3.2 m; a 640 x 480 plan 64 x 48 m).
DEFAULT_PIXEL_SIZE = 0.1
#: The largest image read (pixels; 500 m square at 0.1 m, 250 m at 0.05 m), checked from the header before
#: decoding. Making a world of one takes at most about 20 bytes per pixel (its levels, the free mask, the
#: nearest obstacle of each pixel that finds the default start, the labels of the free regions, the float
#: copy marching squares reads; measured peaks: 12 bytes per pixel for grey images, 18 for colour ones):
#: 500 MB at the bound. An environment on the world takes far more per cell (see
#: :mod:`emmi_gym.env.memory`), checked when it is made.
MAX_IMAGE_PIXELS = 5_000 * 5_000
#: The longest boundary of the reachable free space traced, in pixel edges: marching squares lists each
#: edge's segment as Python tuples before joining them (about 350 bytes and 20 us per edge). The real
#: buildings' maps have 7,000 to 13,000; a plan of noise or a fine maze has millions.
MAX_BOUNDARY_EDGES = 250_000
#: Formats read, by their first bytes: PNG, and the Netpbm family of PGM (its binary and plain
#: variants, and PBM and PPM, which share Pillow's reader).
_PNG_SIGNATURE = b"\x89PNG\r\n\x1a\n"
_NETPBM_MAGIC = (b"P1", b"P2", b"P3", b"P4", b"P5", b"P6")
#: Pillow's modes of 16-bit grey images (levels 0-65535): 16-bit PNGs and PGMs of maxval above 255.
_SIXTEEN_BIT_MODES = ("I", "I;16", "I;16B", "I;16L", "I;16N")
#: Level of the free mask (1 free, 0 obstacle) at which walls are traced: 0.75 px from a free pixel's centre,
#: which with walls half a pixel thick puts their faces on the pixel edges.
WALL_LEVEL = 0.25
#: Douglas-Peucker tolerance of the traced walls, pixels (the walls stay within it of the boundary).
CONTOUR_TOLERANCE = 0.75
#: DungeonMaps colour rules: grey level (ITU-R 601 luma) from which a pixel is free; the grey level of the
#: start square in a grey image (skimage's luma of yellow), with its tolerance.
FREE_LEVEL = 160
START_GREY, START_GREY_TOLERANCE = 208, 3
PIXEL_SIZE = Real(0.005, 5.0, unit="m per pixel")


@dataclass(frozen=True)
class OccupancyImage:
    """Free pixels of a map image in the world frame: ``free[row, col]``, row 0 at the bottom (y up),
    pixel (r, c) covers ``[x0 + c*res, x0 + (c+1)*res) x [y0 + r*res, ...)``; ``start`` in metres or None."""

    free: np.ndarray
    resolution: float
    origin: tuple[float, float]
    start: Place | None
    name: str
    source: str


@dataclass(frozen=True)
class MapServerFile:
    """The fields of a ROS map_server YAML file (plus emmi-gym's optional ``start`` and ``name``)."""

    image: str = option(None, Text())
    resolution: float = option(None, Real(0.005, 5.0, unit="m per pixel"))
    origin: tuple = option(None, Tuple(Real(-1e4, 1e4, unit="m"), 3))
    negate: int = option(0, Integer(0, 1))
    occupied_thresh: float = option(0.65, Real(0.0, 1.0))
    free_thresh: float = option(0.196, Real(0.0, 1.0))
    mode: str = option("trinary", Choice(("trinary", "scale")))  # the free / not-free split is the same in both
    start: tuple | None = option(None, Maybe(Tuple(Real(-1e4, 1e4), 3), "the free pixel farthest from obstacles"))
    name: str | None = option(None, Maybe(Text(), "the file's name"))

    def __post_init__(self):
        for key in ("image", "resolution", "origin"):
            if getattr(self, key) is None:
                fail(self, key, "a value (the field is required)")
        check_fields(self)
        if self.free_thresh >= self.occupied_thresh:
            fail(self, "free_thresh", f"a threshold below occupied_thresh = {self.occupied_thresh}", self.free_thresh)
        if self.origin[2] != 0.0:
            fail(self, "origin", "a yaw of 0 (rotated maps are not supported; most of ROS ignores the yaw too)",
                 list(self.origin))


#: The fields only a map_server file has (a world file has none of them).
_MAP_SERVER_ONLY = ("image", "resolution", "origin", "negate", "occupied_thresh", "free_thresh", "mode")


def is_map_server_file(data) -> bool:
    """Whether YAML data is a map_server map (it has one of map_server's own fields, such as ``image`` or
    ``resolution``) rather than a world file."""
    return isinstance(data, dict) and any(key in data for key in _MAP_SERVER_ONLY)


def open_image(path) -> Image.Image:
    """Open a PNG or PGM image (its header only), with clear errors naming the file for what is not one, is
    broken, or is larger than :data:`MAX_IMAGE_PIXELS` (checked before any pixel is decoded)."""
    path = input_file(path, "map image", WorldFileError)
    with path.open("rb") as fh:
        head = fh.read(8)
    if head.startswith(_PNG_SIGNATURE):
        kind, reader = "PNG", PngImagePlugin.PngImageFile
    elif head[:2] in _NETPBM_MAGIC:
        kind, reader = "PGM", PpmImagePlugin.PpmImageFile
    else:
        raise WorldFileError(str(path), "", f"a PNG or PGM image, not {_what_file(path, head)}")
    try:  # the format's own reader: Pillow's decompression-bomb check would fire before the bound below
        image = reader(str(path))
    except (SyntaxError, ValueError, OSError, EOFError, MemoryError) as exc:
        raise WorldFileError(str(path), "", f"a {kind} image with a valid header (Pillow: {_pillow_says(exc)})") \
            from None
    width, height = image.size
    if width * height > MAX_IMAGE_PIXELS:
        image.close()
        raise WorldFileError(str(path), "", f"an image of at most {MAX_IMAGE_PIXELS:,} pixels",
                             f"{width} x {height}")
    return image


def read_levels(path) -> tuple[np.ndarray, int]:
    """The pixels of a PNG or PGM image and the level of white: ``(rows, cols)`` grey levels (uint8, white
    255; uint16, white 65535, for 16-bit images, read at their full range) or ``(rows, cols, 3)`` uint8 RGB
    for a colour image. Errors name the file (see :func:`open_image`)."""
    image = open_image(path)
    try:
        with image:
            image.load()
            if image.mode == "F":
                raise WorldFileError(str(path), "", "a PGM image of integer levels", "a floating-point PFM image")
            if image.mode in _SIXTEEN_BIT_MODES:
                levels = np.asarray(image)
                if levels.size and (levels.min() < 0 or levels.max() > 65535):
                    raise WorldFileError(str(path), "", "16-bit levels (0-65535)",
                                         f"levels up to {int(levels.max())}")
                return levels.astype(np.uint16), 65535
            if image.mode in ("1", "L", "LA", "La"):
                return np.asarray(image.convert("L")), 255
            return np.asarray(image.convert("RGB")), 255
    except (SyntaxError, ValueError, OSError, EOFError, MemoryError) as exc:
        if isinstance(exc, WorldFileError):
            raise
        kind = "PNG" if image.format == "PNG" else "PGM"
        raise WorldFileError(str(path), "", f"a {kind} image whose pixel data is complete and valid (Pillow: "
                             f"{_pillow_says(exc)})") from None


def _pillow_says(exc: BaseException) -> str:
    text = (str(exc) or type(exc).__name__)[:160]
    if "buffer is not large enough" in text or "truncated" in text:
        text += ": the file is shorter than its header says"
    return text


def _what_file(path: Path, head: bytes) -> str:
    """What a file that is not a PNG or PGM is, for the error: the image format Pillow finds, if any."""
    try:
        with Image.open(path) as other:
            return f"a {other.format} image"
    except Exception:  # noqa: BLE001  (only naming what the file is; any failure means: not an image)
        return f"any image format Pillow reads (the file starts with {excerpt(head)})"


def dungeon_occupancy(path, pixel_size: float = DEFAULT_PIXEL_SIZE) -> OccupancyImage:
    """A plain floor-plan image read with the DungeonMaps colour rules, ``pixel_size`` metres per pixel,
    its lower-left corner at (0, 0)."""
    path = Path(path)
    pixel_size = check_value(pixel_size, PIXEL_SIZE, "load_world", "pixel_size", WorldFileError)
    levels, white = read_levels(path)
    if levels.ndim == 3:
        rgb = levels
        grey = (rgb @ np.array([299, 587, 114], dtype=np.int32)) // 1000  # ITU-R 601 luma, as Pillow's "L"
        if np.any(rgb[..., 0] != rgb[..., 2]):  # a colour image: the start square is yellow
            start_mask = (rgb[..., 0] > 200) & (rgb[..., 1] > 150) & (rgb[..., 2] < 100)
        else:  # a grey image: yellow became START_GREY
            start_mask = np.abs(grey - START_GREY) <= START_GREY_TOLERANCE
        light = grey >= FREE_LEVEL
    else:  # grey levels: 8-bit as they are, 16-bit at 257 per 8-bit level (65535 = 255 x 257)
        scale = white // 255
        light = levels >= FREE_LEVEL * scale
        start_mask = ((levels >= (START_GREY - START_GREY_TOLERANCE) * scale) &
                      (levels <= (START_GREY + START_GREY_TOLERANCE) * scale))
    free = np.flipud(light) | np.flipud(start_mask)
    start = None
    if start_mask.any():
        rows, cols = np.nonzero(np.flipud(start_mask))
        start = Place(float((cols.mean() + 0.5) * pixel_size), float((rows.mean() + 0.5) * pixel_size), 0.0)
    return OccupancyImage(free, pixel_size, (0.0, 0.0), start, path.stem, str(path))


def map_server_image(path, image: str) -> Path:
    """The image file that the map_server YAML file ``path`` names as ``image``: absolute, or beside the file."""
    return Path(image) if Path(image).is_absolute() else Path(path).parent / image


def map_server_occupancy(path, data: dict | None = None) -> OccupancyImage:
    """A ROS map_server map (its YAML file and the image it names), classified by map_server's rules."""
    path = Path(path)
    if data is None:
        data = read_yaml_file(path, "map_server map", WorldFileError)
    spec = build(MapServerFile, data, "", source=str(path), error=WorldFileError)
    image_path = map_server_image(path, spec.image)
    if image_path.suffix.lower() not in IMAGE_SUFFIXES:
        raise WorldFileError(str(path), "image", f"a PNG or PGM image (*{' or *'.join(IMAGE_SUFFIXES)})", spec.image)
    if not image_path.exists():
        raise WorldFileError(str(path), "image", f"an image file beside the YAML file; {image_path} does not exist",
                             spec.image)
    levels, white = read_levels(image_path)
    # a pixel's value is its grey level or the mean of its colour channels; classified through a table of
    # every value it can take (colour: every channel sum), computed as map_server computes it
    if levels.ndim == 3:
        values, index = np.arange(3 * white + 1) / 3.0, levels.sum(axis=2, dtype=np.uint16)
    else:
        values, index = np.arange(white + 1, dtype=np.float64), levels
    occupancy = values / white if spec.negate else (white - values) / white
    free = np.flipud((occupancy < spec.free_thresh)[index])
    start = Place(*spec.start) if spec.start is not None else None
    return OccupancyImage(free, spec.resolution, (spec.origin[0], spec.origin[1]), start, spec.name or path.stem,
                          str(path))


def world_from_occupancy(occupancy: OccupancyImage) -> WorldSpec:
    """The world of an occupancy image: walls along the boundary of the free space reachable from the start."""
    free, res, (x0, y0) = occupancy.free, occupancy.resolution, occupancy.origin
    source = occupancy.source
    rows, cols = free.shape
    if max(rows, cols) * res > 2000.0:
        raise WorldFileError(source, "", "a world at most 2000 m across (its ground truth and every particle's map "
                             f"cover it), here {cols * res:g} x {rows * res:g} m")
    if not free.any():
        raise WorldFileError(source, "", "an image with free space (none of its pixels reads as free)")
    start = occupancy.start or _roomiest_point(free, res, x0, y0)
    r, c = int(math.floor((start.y - y0) / res)), int(math.floor((start.x - x0) / res))
    if not (0 <= r < rows and 0 <= c < cols):
        raise WorldFileError(source, "start", f"a point inside the map [{x0:g}, {x0 + cols * res:g}] x "
                             f"[{y0:g}, {y0 + rows * res:g}]", [start.x, start.y])
    if not free[r, c]:
        raise WorldFileError(source, "start", f"a point in free space; pixel (row {rows - 1 - r}, column {c} from "
                             "the top left) is an obstacle", [start.x, start.y])
    labels, _ = ndimage.label(free)
    reachable = labels == labels[r, c]
    del labels
    edges = boundary_edges(reachable)
    if edges > MAX_BOUNDARY_EDGES:
        raise WorldFileError(source, "", f"free space reachable from the start whose boundary is at most "
                             f"{MAX_BOUNDARY_EDGES:,} pixel edges long (the walls are traced along it; real "
                             "buildings' maps have about 10,000: is this a plan of noise?)", f"{edges:,} edges")
    walls = boundary_walls(reachable, res, x0, y0)
    spec = WorldSpec(name=occupancy.name, bounds=(x0, y0, x0 + cols * res, y0 + rows * res), walls=walls,
                     start=start, places={"start": start}, source=source,
                     description=f"from the occupancy image {Path(source).name}: {cols} x {rows} pixels of {res:g} m")
    if spec.clearance(start.x, start.y) < ROBOT_RADIUS:
        raise WorldFileError(source, "start", f"a point where the robot (radius {ROBOT_RADIUS} m) fits clear of "
                             f"the walls; it is {max(0.0, spec.clearance(start.x, start.y)):.2f} m from one",
                             [round(start.x, 3), round(start.y, 3)])
    return spec


def boundary_edges(region: np.ndarray, chunk: int = 1024) -> int:
    """How many pixel edges separate the boolean region from the rest (the image's border counts as the rest):
    what marching squares will list (counted in chunks of rows, a few bytes per pixel at a time)."""
    padded = np.pad(region, 1)
    edges = 0
    for r0 in range(0, padded.shape[0], chunk):
        rows, below = padded[r0:r0 + chunk], padded[r0 + 1:r0 + chunk + 1]
        edges += int(np.count_nonzero(rows[:, 1:] != rows[:, :-1]))  # neighbours in a row
        edges += int(np.count_nonzero(rows[:len(below)] != below))  # neighbours in a column
    return edges


def boundary_walls(region: np.ndarray, res: float, x0: float, y0: float) -> np.ndarray:
    """(K, 5) walls half a pixel thick along the boundary of a boolean region (rows = y up), simplified."""
    # here, not at the top: skimage.measure pulls in scipy.signal and scipy.stats (1 s to import)
    from skimage.measure import approximate_polygon, find_contours

    padded = np.pad(region, 1).view(np.uint8)  # find_contours reads it as float64 (a copy of its own)
    thickness = res / 2
    rows = []
    for contour in find_contours(padded, WALL_LEVEL):
        polygon = approximate_polygon(contour, CONTOUR_TOLERANCE)
        xy = np.column_stack([x0 + (polygon[:, 1] - 0.5) * res, y0 + (polygon[:, 0] - 0.5) * res])
        a, b = xy[:-1], xy[1:]
        keep = np.hypot(*(b - a).T) > 1e-9
        rows.append(np.column_stack([a[keep], b[keep], np.full(int(keep.sum()), thickness)]))
    return np.concatenate(rows) if rows else np.zeros((0, 5))


def _roomiest_point(free: np.ndarray, res: float, x0: float, y0: float) -> Place:
    """The centre of the free pixel farthest from any non-free pixel (the default start)."""
    rows, cols = free.shape
    # the nearest obstacle pixel of every pixel; the distances squared are taken from it a few rows at a time
    # (scipy's distances are their square roots: the same first maximum, without two float arrays per pixel)
    nearest = ndimage.distance_transform_edt(np.pad(free, 1), return_distances=False, return_indices=True)
    best, best_square = 0, -1
    columns = np.arange(1, cols + 1, dtype=np.int64)
    for r0 in range(0, rows, 256):
        r1 = min(r0 + 256, rows)
        dr = nearest[0, r0 + 1:r1 + 1, 1:-1] - np.arange(r0 + 1, r1 + 1, dtype=np.int64)[:, None]
        dc = nearest[1, r0 + 1:r1 + 1, 1:-1] - columns
        square = dr * dr + dc * dc
        k = int(np.argmax(square))
        if square.flat[k] > best_square:
            best, best_square = r0 * cols + k, int(square.flat[k])
    r, c = divmod(best, cols)
    return Place(float(x0 + (c + 0.5) * res), float(y0 + (r + 0.5) * res), 0.0)
