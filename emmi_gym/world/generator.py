"""Seeded generator of indoor worlds with loops: corridor lattices, dead ends and rooms.

Corridors run along the edges of a random connected subgraph of an ``nx`` x ``ny``
lattice of junctions ``spacing`` metres apart: a random spanning tree (so every
junction is reachable) plus ``n_loops`` extra edges, each closing one independent
loop. Some dead ends open into square rooms. The free space is drawn on a 0.1 m
layout raster and the walls are traced along its outline, merged into straight runs.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ..inputs.validation import Integer, Real, check_fields, fail, option
from .spec import Place, WorldSpec

_LAYOUT = 0.1  # metres per layout cell; sizes are rounded to it
#: Upper bounds of the lattice: junctions per side, their spacing, and the world's width (whose
#: layout raster, one byte per 0.1 m cell, is then at most 16 MB).
MAX_JUNCTIONS = 20
MAX_SPACING = 50.0
MAX_EXTENT = 400.0


@dataclass(frozen=True)
class GeneratorConfig:
    """Parameters of :func:`generate_world`."""

    nx: int = option(4, Integer(2, MAX_JUNCTIONS),
                     help="junctions of the lattice along x")
    ny: int = option(3, Integer(2, MAX_JUNCTIONS),
                     help="junctions of the lattice along y")
    spacing: float = option(6.0, Real(1.6, MAX_SPACING, unit="m"),
                            help="distance between neighbouring junctions")
    corridor_width: float = option(2.0, Real(0.8, MAX_SPACING / 2, unit="m"),
                                   help="width of the corridors (at most spacing / 2)")
    n_loops: int = option(2, Integer(0, 2 * MAX_JUNCTIONS**2),
                          help="corridors added to a random spanning tree, each closing one independent loop")
    room_probability: float = option(0.6, Real(0.0, 1.0),
                                     help="chance that a dead end opens into a square room")
    room_size: float = option(4.0, Real(0.0, 2 * MAX_SPACING, open_lo=True, unit="m"),
                              help="side of a room")
    wall_thickness: float = option(0.25, Real(0.05, 2.0, unit="m"),
                                   help="thickness of the walls")

    def __post_init__(self):
        check_fields(self)
        if not self.corridor_width <= self.spacing / 2:
            fail(self, "corridor_width", f"at most spacing / 2 = {self.spacing / 2:g} m", self.corridor_width)
        max_loops = (self.nx - 1) * self.ny + self.nx * (self.ny - 1) - (self.nx * self.ny - 1)
        if not self.n_loops <= max_loops:
            fail(self, "n_loops", f"0 to {max_loops} (the loops a {self.nx} x {self.ny} lattice has room for)",
                 self.n_loops)
        if not self.corridor_width < self.room_size < 2 * (self.spacing - self.corridor_width):
            fail(self, "room_size", f"above the corridor width and below {2 * (self.spacing - self.corridor_width):g}"
                 " m, so rooms do not touch other corridors", self.room_size)
        extent = max(self.nx, self.ny) * self.spacing
        if extent > MAX_EXTENT:
            fail(self, "spacing", f"a lattice at most {MAX_EXTENT:g} m across (max(nx, ny) * spacing = {extent:g} m; "
                 f"its {_LAYOUT} m layout raster would take {(extent / _LAYOUT) ** 2 / 1e9:.1f} GB)", self.spacing)


def _lattice_graph(cfg: GeneratorConfig, rng: np.random.Generator) -> set[tuple[tuple[int, int], tuple[int, int]]]:
    """A random spanning tree of the lattice (randomised depth-first search) plus n_loops extra edges."""
    def neighbours(node):
        i, j = node
        for di, dj in ((1, 0), (-1, 0), (0, 1), (0, -1)):
            if 0 <= i + di < cfg.nx and 0 <= j + dj < cfg.ny:
                yield (i + di, j + dj)

    edges: set = set()
    visited = {(0, 0)}
    stack = [(0, 0)]
    while stack:
        node = stack[-1]
        options = [n for n in neighbours(node) if n not in visited]
        if not options:
            stack.pop()
            continue
        nxt = options[int(rng.integers(len(options)))]
        edges.add(tuple(sorted((node, nxt))))
        visited.add(nxt)
        stack.append(nxt)
    all_edges = sorted({tuple(sorted((a, b))) for a in np.ndindex(cfg.nx, cfg.ny) for b in neighbours(a)})
    spare = [e for e in all_edges if e not in edges]
    for k in rng.permutation(len(spare))[:cfg.n_loops]:
        edges.add(spare[k])
    return edges


def _outline_segments(free: np.ndarray, x0: float, y0: float) -> list[tuple[float, float, float, float]]:
    """Maximal straight runs of the boundary between free and other layout cells."""
    segments = []
    padded = np.pad(free, 1)
    horizontal = padded[1:, 1:-1] != padded[:-1, 1:-1]   # edge below row r (r = 0..H)
    vertical = padded[1:-1, 1:] != padded[1:-1, :-1]     # edge left of column c (c = 0..W)
    for r, row in enumerate(horizontal):
        for start, stop in _runs(row):
            segments.append((x0 + start * _LAYOUT, y0 + r * _LAYOUT, x0 + stop * _LAYOUT, y0 + r * _LAYOUT))
    for c, col in enumerate(vertical.T):
        for start, stop in _runs(col):
            segments.append((x0 + c * _LAYOUT, y0 + start * _LAYOUT, x0 + c * _LAYOUT, y0 + stop * _LAYOUT))
    return segments


def _runs(mask: np.ndarray):
    """(start, stop) index pairs of the runs of True in a 1-D mask."""
    d = np.diff(np.concatenate([[0], mask.astype(np.int8), [0]]))
    return zip(np.flatnonzero(d == 1), np.flatnonzero(d == -1), strict=False)


def generate_world(seed: int | np.random.Generator, config: GeneratorConfig = GeneratorConfig()) -> WorldSpec:
    """A connected world with ``config.n_loops`` independent loops; the same seed gives the same world.

    Places: ``start`` (junction (0, 0), facing its first corridor), ``junction_i_j``
    for every junction and ``room_k`` for every room.
    """
    rng = seed if isinstance(seed, np.random.Generator) else np.random.default_rng(seed)
    cfg = config
    edges = _lattice_graph(cfg, rng)
    half_w = round(cfg.corridor_width / 2 / _LAYOUT)
    step = round(cfg.spacing / _LAYOUT)
    margin = round(cfg.room_size / _LAYOUT) + 2
    shape = ((cfg.ny - 1) * step + 2 * margin, (cfg.nx - 1) * step + 2 * margin)
    free = np.zeros(shape, dtype=bool)

    def cell(node):  # layout (row, col) of a junction
        return margin + node[1] * step, margin + node[0] * step

    for a, b in edges:
        (ra, ca), (rb, cb) = cell(a), cell(b)
        free[min(ra, rb) - half_w:max(ra, rb) + half_w, min(ca, cb) - half_w:max(ca, cb) + half_w] = True

    degree: dict = {}
    for a, b in edges:
        degree[a] = degree.get(a, 0) + 1
        degree[b] = degree.get(b, 0) + 1
    places = {}
    half_room = round(cfg.room_size / 2 / _LAYOUT)
    rooms = 0
    for node in sorted(degree):
        if degree[node] == 1 and node != (0, 0) and rng.random() < cfg.room_probability:
            r, c = cell(node)
            free[r - half_room:r + half_room, c - half_room:c + half_room] = True
            places[f"room_{rooms}"] = node
            rooms += 1

    x0 = y0 = -margin * _LAYOUT
    walls = np.round([(*s, cfg.wall_thickness) for s in _outline_segments(free, x0, y0)], 6)
    rows, cols = np.nonzero(free)
    pad = 1.0
    bounds = tuple(round(float(v), 6) for v in (
        x0 + cols.min() * _LAYOUT - pad, y0 + rows.min() * _LAYOUT - pad,
        x0 + (cols.max() + 1) * _LAYOUT + pad, y0 + (rows.max() + 1) * _LAYOUT + pad))

    def xy(node):
        return (node[0] * cfg.spacing, node[1] * cfg.spacing)

    first = min(b for a, b in edges if a == (0, 0))
    heading = math.atan2(first[1], first[0])
    all_places = {"start": Place(0.0, 0.0, heading)}
    all_places.update({f"junction_{i}_{j}": Place(*xy((i, j))) for i, j in sorted(degree)})
    all_places.update({name: Place(*xy(node)) for name, node in places.items()})
    name = f"generated_{seed}" if not isinstance(seed, np.random.Generator) else "generated"
    return WorldSpec(name=name, bounds=bounds, walls=walls, start=all_places["start"], places=all_places,
                     description=f"generated: {cfg.nx}x{cfg.ny} junctions, {cfg.n_loops} loops, {rooms} rooms",
                     source=f"generate_world({seed if not isinstance(seed, np.random.Generator) else '...'})")
