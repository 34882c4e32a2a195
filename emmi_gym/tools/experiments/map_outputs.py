"""A replay's maps and path for ROS tools: map_server maps, a CSV of stamped poses, a ROS 2 bag.

The best particle's map is the filter's answer (``map.yaml``, trinary: free, occupied, unknown); the
information of the expected map (paper eq. 9 of eq. 6, ``1 - H`` bits per cell, as percent) is how sure
the particles are together (``expected_information.yaml``, scale: black is one bit). Both are cropped to
the explored area, as the PNGs. ``best_path.csv`` holds the best particle's pose at every update, stamped
with its scan's time.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from ...certainty.information import cell_information
from ...formats.map_server import occupancy_values, write_map_server
from ...formats.ros_writers import write_map_bag
from ...geometry.grid import GridGeometry
from .replay import ReplayResult, explored_extent
from .report import write_csv

#: What ``emmi-gym replay`` writes into its ``--out`` folder (:func:`~.replay.write_outputs` and
#: :func:`write_map_files`): all that its ``--overwrite`` removes.
REPLAY_FILES = ("metrics.csv", "metrics.png", "expected_map.png", "best_map.png", "best_trajectory.tum", "map.yaml",
                "map.pgm", "expected_information.yaml", "expected_information.pgm", "best_path.csv")


def map_layers(result: ReplayResult) -> dict[str, tuple[np.ndarray, GridGeometry]]:
    """{"map": best particle's occupancy values, "expected_information": the expected map's information in
    percent}, each with the geometry of the explored area they are cropped to."""
    slam = result.slam
    rows, cols, _ = explored_extent(slam)
    g = slam.geometry
    crop = GridGeometry(g.resolution, g.origin_x + cols.start * g.resolution, g.origin_y + rows.start * g.resolution,
                        rows.stop - rows.start, cols.stop - cols.start)
    best = occupancy_values(slam.best_map()[rows, cols], slam.maps.codes[slam.best][rows, cols] != 0)
    information = np.rint(100.0 * cell_information(slam.expected_map()[rows, cols])).astype(np.int8)
    return {"map": (best, crop), "expected_information": (information, crop)}


def write_path_csv(path, times: np.ndarray, poses: np.ndarray) -> Path:
    """Stamped planar poses as CSV: ``stamp`` (seconds), ``x``, ``y`` (m), ``yaw`` (rad)."""
    write_csv(Path(path), [{"stamp": float(t), "x": float(p[0]), "y": float(p[1]), "yaw": float(p[2])}
                           for t, p in zip(times, poses, strict=True)])
    return Path(path)


def write_map_files(result: ReplayResult, out_dir) -> dict[str, Path]:
    """``map.yaml`` + ``map.pgm``, ``expected_information.yaml`` + ``.pgm`` and ``best_path.csv`` in
    ``out_dir``."""
    out = Path(out_dir)
    layers = map_layers(result)
    files = {}
    for name, (values, geometry) in layers.items():
        files[f"{name}.yaml"] = write_map_server(out / f"{name}.yaml", values, geometry,
                                                 mode="trinary" if name == "map" else "scale")
        files[f"{name}.pgm"] = files[f"{name}.yaml"].with_suffix(".pgm")
    files["best_path.csv"] = write_path_csv(out / "best_path.csv", result.timestamps,
                                            result.slam.paths[result.slam.best])
    return files


def write_replay_bag(result: ReplayResult, path, storage: str = "sqlite3") -> Path:
    """The layers of :func:`map_layers` on ``/map`` and ``/expected_information`` and the best particle's
    path on ``/path``, as a ROS 2 bag."""
    grids = {f"/{name}": layer for name, layer in map_layers(result).items()}
    return write_map_bag(path, grids, result.timestamps, result.slam.paths[result.slam.best], storage=storage)
