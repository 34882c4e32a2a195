"""Build the worlds of the four real buildings from their corrected CARMEN logs.

    python measurements/build_building_worlds.py [--data ../shared/datasets/carmen] [--resolution 0.1]
                                                 [--buildings intel aces csail fr079] [--out DIR]

For each of intel, aces, csail and fr079 (or the ``--buildings`` given): every scan of the corrected
log is inserted at its corrected pose into one occupancy grid (the filter's sensor model; echoes beyond
``--insertion-range`` only free space up to it, no-echo readings free nothing); cells that end
free (p < 0.3) are the building's free space, cleaned of one-cell spurs (a morphological opening)
and of unseen holes smaller than ``--hole-area`` m^2 that hold no wall (gaps between distant
beams). The result is written as a ROS map_server map (PNG: 254 free, 0 occupied, 205 unknown,
and its YAML with the log's first pose as ``start``) into ``emmi_gym/worlds_data/buildings/``,
where ``load_world("intel")`` finds it (or into ``--out``); it prints each world's size and wall count.
"""

from __future__ import annotations

import argparse
from pathlib import Path

import _arguments as arguments
import numpy as np
from _data import require_files
from PIL import Image
from scipy import ndimage

from emmi_gym.formats import carmen
from emmi_gym.slam import CellCodes, ParticleMaps, RBPFConfig
from emmi_gym.tools.experiments.replay import laser_stream, log_extent
from emmi_gym.world import load_world

BUILDINGS = {"intel": "intel", "aces": "aces", "csail": "csail", "fr079": "freiburg-079"}
OUT = Path(__file__).resolve().parents[1] / "emmi_gym" / "worlds_data" / "buildings"
FREE_P, WALL_P = 0.3, 0.6


def building_map(log_path: Path, resolution: float, insertion_range: float):
    """(free mask, occupied mask, geometry, first pose) of the corrected log's scans at their poses."""
    log = carmen.read_log(log_path)
    scans = [(pose, record) for _, pose, record in laser_stream(log) if pose is not None]
    poses = np.array([pose for pose, _ in scans])
    geometry = log_extent(poses, insertion_range, resolution, drift_margin=0.0)
    config = RBPFConfig(particles=1, resolution=resolution)
    maps = ParticleMaps(geometry, 1, CellCodes.from_config(config))
    for pose, record in scans:
        max_range = record.max_range or float(np.max(record.ranges))
        ranges = np.ascontiguousarray(record.ranges, dtype=np.float64)
        maps.insert(np.asarray(pose, dtype=np.float64)[None, :], ranges, np.ascontiguousarray(record.angles),
                    max_range, 0.0, insertion_range)
    p = maps.probabilities(0)
    return p < FREE_P, p > WALL_P, geometry, poses[0]


def clean(free: np.ndarray, occupied: np.ndarray, resolution: float, hole_area: float) -> np.ndarray:
    free = ndimage.binary_opening(free)
    holes, n = ndimage.label(~free)
    sizes = ndimage.sum_labels(np.ones_like(free), holes, index=np.arange(1, n + 1))
    walled = ndimage.maximum(occupied, holes, index=np.arange(1, n + 1)).astype(bool)
    small = np.concatenate([[False], (sizes * resolution ** 2 < hole_area) & ~walled])
    return free | small[holes]


def write_map_server(out: Path, name: str, free: np.ndarray, occupied: np.ndarray, geometry, start,
                     source: str) -> Path:
    rows, cols = np.nonzero(free)
    r0, r1, c0, c1 = rows.min() - 2, rows.max() + 3, cols.min() - 2, cols.max() + 3
    free, occupied = free[r0:r1, c0:c1], occupied[r0:r1, c0:c1]
    pixels = np.where(free, 254, np.where(occupied, 0, 205)).astype(np.uint8)
    Image.fromarray(np.flipud(pixels)).save(out / f"{name}.png", optimize=True)
    x0, y0 = geometry.origin_x + c0 * geometry.resolution, geometry.origin_y + r0 * geometry.resolution
    (out / f"{name}.yaml").write_text(
        f"# built by measurements/build_building_worlds.py from {source} (corrected poses)\n"
        f"name: {name}\nimage: {name}.png\nresolution: {geometry.resolution}\n"
        f"origin: [{x0:.3f}, {y0:.3f}, 0.0]\nnegate: 0\noccupied_thresh: 0.65\nfree_thresh: 0.196\n"
        f"start: [{start[0]:.3f}, {start[1]:.3f}, {start[2]:.4f}]\n")
    return out / f"{name}.yaml"


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--data", type=Path, default=Path(__file__).resolve().parents[2] / "shared" / "datasets" /
                        "carmen")
    parser.add_argument("--resolution", type=arguments.number(0.0, unit="m"), default=0.1)
    parser.add_argument("--insertion-range", type=arguments.number(0.0, unit="m"), default=15.0)
    parser.add_argument("--hole-area", type=arguments.number(0.0, unit="m^2"), default=1.0, help="m^2")
    parser.add_argument("--buildings", nargs="+", choices=list(BUILDINGS), default=list(BUILDINGS),
                        help="which worlds to build (default: all four)")
    parser.add_argument("--out", type=Path, default=OUT, help="where the worlds go (default: the package's, where "
                        "load_world finds them)")
    args = parser.parse_args()
    buildings = {name: BUILDINGS[name] for name in args.buildings}
    require_files(parser, args.data, [f"{log_name}-corrected.log.gz" for log_name in buildings.values()], "carmen")
    args.out.mkdir(parents=True, exist_ok=True)
    print("| building | size | free area | walls |")
    print("| --- | --- | --- | --- |")
    for name, log_name in buildings.items():
        log_path = args.data / f"{log_name}-corrected.log.gz"
        free, occupied, geometry, start = building_map(log_path, args.resolution, args.insertion_range)
        free = clean(free, occupied, args.resolution, args.hole_area)
        path = write_map_server(args.out, name, free, occupied, geometry, start, log_path.name)
        world = load_world(path)
        xmin, ymin, xmax, ymax = world.bounds
        print(f"| {name} | {xmax - xmin:.0f} x {ymax - ymin:.0f} m | {free.sum() * args.resolution ** 2:.0f} m^2 | "
              f"{len(world.walls)} |")


if __name__ == "__main__":
    main()
