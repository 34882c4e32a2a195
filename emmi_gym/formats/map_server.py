"""ROS map_server maps out: a PGM image and the YAML file that describes it.

The convention is the one ROS's ``map_saver`` writes and :mod:`emmi_gym.world.images` reads: occupancy
values as in ``nav_msgs/OccupancyGrid`` (-1 unknown, 0-100 percent) become, in ``trinary`` mode, 254
(free: at most :data:`FREE_PERCENT`), 0 (occupied: at least :data:`OCCUPIED_PERCENT`) or 205 (unknown and
in between), and the YAML's ``free_thresh`` 0.196 and ``occupied_thresh`` 0.65 read them back so. In
``scale`` mode (a quantity in [0, 100] shown as grey, as the information of a map) the level is
``255 (1 - v / 100)`` and the thresholds 0 and 1 make map_server read ``99 v / 100`` back. The image's top
row is the map's highest y; ``origin`` is the lower-left corner of the bottom-left pixel, yaw 0.
"""

from __future__ import annotations

from functools import partial
from pathlib import Path

import numpy as np
from PIL import Image

from ..formats.atomic_files import write_atomically, write_text_atomically
from ..geometry.grid import GridGeometry

#: map_saver's thresholds (percent) and levels, and the YAML thresholds that read the levels back.
FREE_PERCENT, OCCUPIED_PERCENT = 25, 65
FREE_LEVEL, OCCUPIED_LEVEL, UNKNOWN_LEVEL = 254, 0, 205
FREE_THRESH, OCCUPIED_THRESH = 0.196, 0.65


def occupancy_values(probabilities: np.ndarray, known: np.ndarray) -> np.ndarray:
    """int8 occupancy values: the percent of each known cell's occupancy probability, -1 elsewhere."""
    return np.where(known, np.rint(100.0 * np.asarray(probabilities)), -1).astype(np.int8)


def trinary_levels(values: np.ndarray) -> np.ndarray:
    """map_saver's grey levels of occupancy values (rows as the grid's: bottom first)."""
    return np.where((values >= 0) & (values <= FREE_PERCENT), FREE_LEVEL,
                    np.where(values >= OCCUPIED_PERCENT, OCCUPIED_LEVEL, UNKNOWN_LEVEL)).astype(np.uint8)


def write_map_server(yaml_path, values: np.ndarray, geometry: GridGeometry, *, mode: str = "trinary") -> Path:
    """Write ``values`` (int8, -1 or 0-100, on ``geometry``) as ``<name>.pgm`` and ``<name>.yaml``; returns
    the YAML's path (what ``load_world`` and ``map_server`` take)."""
    if mode not in ("trinary", "scale"):
        raise ValueError(f"mode: expected 'trinary' or 'scale', got {mode!r}")
    yaml_path = Path(yaml_path)
    image_path = yaml_path.with_suffix(".pgm")
    if mode == "trinary":
        levels, free, occupied = trinary_levels(values), FREE_THRESH, OCCUPIED_THRESH
    else:
        levels, free, occupied = np.rint(2.55 * (100 - np.clip(values, 0, 100))).astype(np.uint8), 0.0, 1.0
    write_atomically(image_path, partial(_save_pgm, np.flipud(levels)))
    text = (f"image: {image_path.name}\nresolution: {geometry.resolution!r}\n"
            f"origin: [{geometry.origin_x!r}, {geometry.origin_y!r}, 0.0]\nnegate: 0\n"
            f"occupied_thresh: {occupied!r}\nfree_thresh: {free!r}\nmode: {mode}\n")
    write_text_atomically(yaml_path, text)
    return yaml_path


def _save_pgm(levels: np.ndarray, path) -> None:
    Image.fromarray(np.ascontiguousarray(levels, dtype=np.uint8)).save(path, format="PPM")
