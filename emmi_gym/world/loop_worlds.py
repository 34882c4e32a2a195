"""Seeded corridor loops left open at a decision point, with a new area beyond it: the family of worlds where
the order of closing the loop and exploring is put to the test (the paper's Fig. 6, generalised).

A world of the family (centre lines; corridors ``corridor_width`` wide, here w)::

        -D                 0        w                     Lx
         +-----------------+  O1  +-----------------------+ Ly
         |  new area       |  <-  |  decision (heading S) |
         |  (annex)        |      |   old loop, open      |
         |   target_b      |  O2  |                       |
         +-----------------+  ->  +-- start/target_a -----+ 0

The **old loop**: a rectangle ``loop_width`` x ``loop_height`` of corridors, featureless but for
pillars every ``loop_pillar_spacing`` metres (0: none) and two landmarks near the start, so that
the matcher cannot pin the particles along the loop's length, only where it closes. The robot
drives it counter-clockwise from the start (mid-way along the bottom, heading east) to the
decision point on the left side, 5 m below the top (route ``to_decision``).

The **new area** lies west of the loop, ``new_area_length`` metres wide, entered through the
opening O1 beside the decision point: a corridor west then south. With ``new_area_loop`` it turns
east again and rejoins the loop's left corridor through a second opening O2 near the bottom, so
it is a loop of its own (O1, the annex, O2 and the loop's left corridor): the robot that explores
it first sees the left corridor again through O2, a revisit whose weights select particles by
their path through the new area alone. Without, it ends in a dead end. Pillars every
``new_area_pillar_spacing`` metres (0: none) line its outer wall.

Places: ``decision``; ``target_a`` (the start: closing the loop); ``target_b`` (in the new area:
mid-way down its west corridor with ``new_area_loop``, so that from there the way back to the
start runs on through O2; at the dead end without). Routes: ``to_decision``, ``close_loop`` and
``explore``. Sizes are drawn per world, each uniformly within ``size_jitter`` of its value
(rounded to 0.5 m), and so are the pillars' phases.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..inputs.validation import Boolean, Real, check_fields, fail, option
from .loader import parse_world
from .spec import WorldSpec

#: Centre-line distance from the top of the loop down to the decision point, and to the top of O1.
_DECISION_DEPTH = 5.0
_O1_TOP_DEPTH = 6.0
#: Pillars: length along the wall and depth into the corridor (m).
_PILLAR = (0.6, 0.35)
#: Drawn sizes are rounded to this (m).
_GRID = 0.5
#: The longest side of a loop or new area before jitter (m); the env refuses a world whose maps would
#: not fit in memory (``env.memory``) when it is drawn.
MAX_SIDE = 200.0


@dataclass(frozen=True)
class LoopWorldConfig:
    """Parameters of :func:`generate_loop_world` (``gym.make(..., world="loop_order", generator={...})``)."""

    loop_width: float = option(24.0, Real(8.0, MAX_SIDE, unit="m"),
                               help="east-west side of the loop")
    loop_height: float = option(16.0, Real(14.0, MAX_SIDE, unit="m"),
                                help="north-south side of the loop")
    new_area_length: float = option(12.0, Real(4.0, MAX_SIDE, unit="m"),
                                    help="how far west of the loop the new area reaches")
    new_area_loop: bool = option(True, Boolean(),
                                 help="the new area rejoins the loop (a loop of its own); False: a dead end")
    loop_pillar_spacing: float = option(0.0, Real(0.0, MAX_SIDE, unit="m"),
                                        help="pillars this far apart on the loop's outer wall; 0: none")
    new_area_pillar_spacing: float = option(2.0, Real(0.0, MAX_SIDE, unit="m"),
                                            help="pillars this far apart on the new area's outer wall; 0: none")
    corridor_width: float = option(2.0, Real(1.2, 4.0, unit="m"),
                                   help="width of the corridors")
    size_jitter: float = option(0.0, Real(0.0, 0.3),
                                help="sizes drawn uniformly within this share of their values")
    wall_thickness: float = option(0.25, Real(0.05, 1.0, unit="m"),
                                   help="thickness of the walls")

    def __post_init__(self):
        check_fields(self)
        for name, corridors in (("loop_width", 2), ("loop_height", 2), ("new_area_length", 1)):
            lowest = (corridors * self.corridor_width + 1.0) / (1 - self.size_jitter)
            if getattr(self, name) < lowest:
                fail(self, name, f"at least {lowest:.4g} m with size_jitter {self.size_jitter:g} (room for {corridors} "
                     f"corridor(s) {self.corridor_width:g} m wide and a block of 1 m)", getattr(self, name))
        lowest = (_O1_TOP_DEPTH + 3 * self.corridor_width + 1.0) / (1 - self.size_jitter)
        if self.loop_height < lowest:
            fail(self, "loop_height", f"at least {lowest:.4g} m with size_jitter {self.size_jitter:g} and corridors "
                 f"{self.corridor_width:g} m wide (a wall of 1 m between the two openings of the new area)",
                 self.loop_height)


def _drawn(value: float, jitter: float, rng: np.random.Generator) -> float:
    return float(np.round(value * (1 + jitter * rng.uniform(-1.0, 1.0)) / _GRID) * _GRID)


def _pillars(a: tuple[float, float], b: tuple[float, float], inward: tuple[float, float], spacing: float,
             rng: np.random.Generator, margin: float) -> list[dict]:
    """Pillars on the wall from ``a`` to ``b`` (axis-aligned), ``spacing`` apart from a random phase, sticking
    out towards ``inward``, none within ``margin`` of either end."""
    if spacing <= 0:
        return []
    length = abs(b[0] - a[0]) + abs(b[1] - a[1])
    ux, uy = (b[0] - a[0]) / length, (b[1] - a[1]) / length
    out = []
    for s in np.arange(margin + rng.uniform(0.0, spacing), length - margin - _PILLAR[0], spacing):
        x0, y0 = a[0] + ux * s, a[1] + uy * s
        x1 = x0 + ux * _PILLAR[0] + inward[0] * _PILLAR[1]
        y1 = y0 + uy * _PILLAR[0] + inward[1] * _PILLAR[1]
        out.append({"rectangle": {"min": [round(min(x0, x1), 3), round(min(y0, y1), 3)],
                                  "max": [round(max(x0, x1), 3), round(max(y0, y1), 3)]}})
    return out


def loop_world_data(rng: np.random.Generator, config: LoopWorldConfig, name: str) -> dict:
    """The world file (as a dict, :func:`~emmi_gym.world.parse_world`'s input) of one world of the family."""
    c, w = config, config.corridor_width
    lx, ly, d = (_drawn(v, c.size_jitter, rng) for v in (c.loop_width, c.loop_height, c.new_area_length))
    o1_top = ly - _O1_TOP_DEPTH
    o1_bottom, o2_bottom, o2_top = o1_top - w, w, 2 * w
    h = w / 2
    start = (round(lx / 2, 3), h)
    walls = [{"rectangle": {"min": [w, w], "max": [lx - w, ly - w]}},
             # landmarks where the loop closes, seen from the start
             {"rectangle": {"min": [start[0] + 3.0, 0.0], "max": [start[0] + 3.0 + _PILLAR[0], _PILLAR[1]]}},
             {"rectangle": {"min": [start[0] + 5.0, w - _PILLAR[1]], "max": [start[0] + 5.0 + _PILLAR[0], w]}}]
    margin = w + 0.5
    for a, b, inward in (((w, 0.0), (lx - w, 0.0), (0, 1)), ((lx, w), (lx, ly - w), (-1, 0)),
                         ((lx - w, ly), (w, ly), (0, -1)), ((0.0, o1_bottom - 0.5), (0.0, o2_top + 0.5), (1, 0))):
        walls += _pillars(a, b, inward, c.loop_pillar_spacing, rng, margin if a[1] != o1_bottom - 0.5 else 0.0)
    if c.new_area_loop:
        walls += [{"polyline": {"points": [[0, o1_top], [0, ly], [lx, ly], [lx, 0], [0, 0], [0, o2_bottom]]}},
                  {"polyline": {"points": [[0, o1_top], [-d, o1_top], [-d, o2_bottom], [0, o2_bottom]]}},
                  {"polyline": {"points": [[0, o2_top], [-d + w, o2_top], [-d + w, o1_bottom], [0, o1_bottom]]}},
                  {"segment": {"from": [0, o2_top], "to": [0, o1_bottom]}}]
        target_b = (-d + h, round((o1_top + o2_bottom) / 2, 3))
        annex = (((0.0, o1_top), (-d, o1_top), (0, -1)), ((-d, o1_top), (-d, o2_bottom), (1, 0)),
                 ((-d, o2_bottom), (0.0, o2_bottom), (0, 1)))
    else:
        walls += [{"polyline": {"points": [[0, o1_top], [0, ly], [lx, ly], [lx, 0], [0, 0], [0, o1_bottom]]}},
                  {"polyline": {"points": [[0, o1_top], [-d, o1_top], [-d, o2_bottom], [-d + w, o2_bottom],
                                           [-d + w, o1_bottom], [0, o1_bottom]]}}]
        target_b = (-d + h, o2_bottom + h)
        annex = (((0.0, o1_top), (-d, o1_top), (0, -1)), ((-d, o1_top), (-d, o2_bottom), (1, 0)))
    for a, b, inward in annex:
        walls += _pillars(a, b, inward, c.new_area_pillar_spacing, rng, margin)
    explore = ["decision", [h, o1_bottom + h], [-d + h, o1_bottom + h], list(target_b)]
    kind = "a loop of its own" if c.new_area_loop else "a dead end"
    return {
        "name": name,
        "description": f"loop order: a {lx:g} x {ly:g} m corridor loop open at the decision point, a new area "
                       f"{d:g} m wide beyond it with {kind}",
        "bounds": {"xmin": -d - 0.5, "ymin": -0.5, "xmax": lx + 0.5, "ymax": ly + 0.5},
        "wall_thickness": c.wall_thickness,
        "walls": walls,
        "start": {"x": start[0], "y": start[1], "theta": 0.0},
        "places": {"decision": {"x": h, "y": ly - _DECISION_DEPTH, "theta": -np.pi / 2},
                   "target_a": {"x": start[0], "y": start[1], "theta": 0.0},
                   "target_b": {"x": target_b[0], "y": target_b[1]}},
        "routes": {"to_decision": ["start", [lx - h, h], [lx - h, ly - h], [h, ly - h], "decision"],
                   "close_loop": ["decision", [h, h], "target_a"],
                   "explore": explore},
    }


def generate_loop_world(seed: int | np.random.Generator, config: LoopWorldConfig = LoopWorldConfig()) -> WorldSpec:
    """One world of the family; the same seed (or generator state) gives the same world."""
    rng = seed if isinstance(seed, np.random.Generator) else np.random.default_rng(seed)
    name = "loop_order" if isinstance(seed, np.random.Generator) else f"loop_order_{seed}"
    source = f"generate_loop_world({'...' if isinstance(seed, np.random.Generator) else seed})"
    return parse_world(loop_world_data(rng, config, name), source=source)
