"""What an environment takes per cell of its world's grid, checked before a world's grids are made.

An environment keeps, on one grid over its world, the filter's maps (:class:`ParticleMaps`, what
the filter alone would check), the oracle's map (the same maps for one particle) and, while it
refreshes its products and builds the observation's pooling index for a world, arrays of a few
words per cell. A world drawn from an image or a map set is checked before any of it is built, and
the error names the world and says what size is allowed. A replan's search, over what the robot has seen,
is counted as if that were the whole world.
"""

from __future__ import annotations

import math

from ..geometry.grid import GridGeometry
from ..slam.occupancy import MAX_MAP_BYTES, MapTooLarge, ParticleMaps

#: Bytes per cell the environment adds to its filter's and oracle's maps at their peak (tracemalloc over a
#: reset and a step on a blank 2000 x 2000 plan: 260 bytes per cell with 15 particles, 170 of them the maps):
#: the expected map's copy, the map labels and the observation's pooling index and what builds it.
ENV_BYTES_PER_CELL = 96
#: Bytes per cell of the planning window a replan takes at its peak, once the robot has seen the whole world
#: and the window covers it (tracemalloc over ``travel_costs`` on a 1000 x 1000 map of corridors: 42 bytes
#: per cell, 9 of them held by the costs it returns): the clearance, the step costs, the search's distances,
#: traceback and bucket queue.
PLANNING_BYTES_PER_CELL = 42


def env_bytes_per_cell(particles: int) -> int:
    """Bytes an environment with ``particles`` particles takes per cell of its grid: the filter's and the
    oracle's maps, the environment's own arrays and a replan over the whole grid."""
    return (ParticleMaps.bytes_per_cell(particles) + ParticleMaps.bytes_per_cell(1) + ENV_BYTES_PER_CELL
            + PLANNING_BYTES_PER_CELL)


def check_env_memory(geometry: GridGeometry, particles: int, world: str) -> None:
    """Raise :class:`MapTooLarge` naming ``world`` if an environment on ``geometry`` would take more than
    :data:`MAX_MAP_BYTES` (the filter's maps first, with the filter's own message)."""
    ParticleMaps.check_memory(geometry.rows, geometry.cols, particles, geometry.resolution)
    per_cell = env_bytes_per_cell(particles)
    needed = float(geometry.rows) * geometry.cols * per_cell
    if needed > MAX_MAP_BYTES:
        most = MAX_MAP_BYTES // per_cell
        side = math.sqrt(most) * geometry.resolution
        raise MapTooLarge(f"world {world}: {geometry.cols} x {geometry.rows} cells of {geometry.resolution:g} m "
                          f"would take {needed / 2**30:.1f} GiB in an environment with {particles} particles "
                          f"({per_cell} bytes per cell: the filter's maps, the oracle's map, the observation, "
                          f"planning), above the bound of {MAX_MAP_BYTES / 2**30:.0f} GiB; at most {most:,} cells "
                          f"(a square of {side:.0f} m at {geometry.resolution:g} m): use coarser cells (resolution), "
                          "fewer particles or a smaller world")
