"""Where an episode's world comes from: one fixed world, a generated world per reset, or a set of maps.

A **map set** is drawn from at every reset, deterministically per seed (the index comes from
the episode's generator). It is named by

- a set shipped with the package: ``"dungeon_maps/train"`` or ``"dungeon_maps/test"``;
- a folder: its map_server maps (``*.yaml``) if it has any, else its images (``*.png``, ``*.pgm``);
  a folder with ``train/`` and ``test/`` subfolders gives its splits as ``"folder/train"``...;
- a glob pattern: ``"plans/*.png"``.

Loaded worlds are cached (a plan loads in about 20 ms, and the next reset may draw it again).
"""

from __future__ import annotations

import glob
from collections import OrderedDict
from pathlib import Path

import numpy as np

from ..inputs.errors import excerpt
from ..inputs.yaml_files import YAML_SUFFIXES
from .generator import GeneratorConfig, generate_world
from .images import DEFAULT_PIXEL_SIZE, IMAGE_SUFFIXES
from .loader import load_world, worlds_data_root
from .loop_worlds import LoopWorldConfig, generate_loop_world
from .spec import WorldSpec

#: Families of generated worlds, by the ``world`` name that draws one per reset: their options' class and
#: their generator. ``world=None`` draws the lattice worlds of :func:`generate_world`.
WORLD_FAMILIES = {"loop_order": (LoopWorldConfig, generate_loop_world)}

#: The folder of the package's shipped worlds, as it appears in a path to one of them wherever it is installed.
_SHIPPED_FOLDER = "emmi_gym/worlds_data/"

#: Worlds of a set kept loaded (a plan's spec takes a few kB).
CACHED_WORLDS = 512
_GLOB_CHARS = set("*?[")


def builtin_map_sets() -> list[str]:
    """Names of the map sets shipped with the package (folders of maps under ``worlds_data``)."""
    root = worlds_data_root()
    return sorted(str(folder.relative_to(root)) for folder in root.glob("*/*") if folder.is_dir() and
                  _map_files(folder))


def world_name(world) -> str:
    """How episode records name ``world``: a map of a shipped set by its name in the set
    (``"dungeon_maps/test/img_10011.png"``, which :func:`~emmi_gym.world.loader.load_world` loads), wherever the
    package is installed, so that evaluations made from two installs pair by world; anything else as given. A path
    into another install's shipped worlds, as records of earlier versions hold, gets the same name."""
    text = str(world)
    shipped = text.replace("\\", "/").rpartition(_SHIPPED_FOLDER)
    return shipped[2] if shipped[1] and shipped[2] else text


def _map_files(folder: Path) -> list[Path]:
    yaml_files = sorted(p for p in folder.iterdir() if p.suffix.lower() in YAML_SUFFIXES)
    return yaml_files or sorted(p for p in folder.iterdir() if p.suffix.lower() in IMAGE_SUFFIXES)


def map_set_files(name: str) -> list[Path] | None:
    """The map files of the set ``name``, or None if ``name`` does not name a set (a folder, a glob, a
    shipped set); a set that matches no map file is an error."""
    if name in builtin_map_sets():
        return _map_files(worlds_data_root() / name)
    if _GLOB_CHARS & set(name):
        files = sorted(Path(p) for p in glob.glob(name) if Path(p).suffix.lower() in IMAGE_SUFFIXES + YAML_SUFFIXES)
        if not files:
            raise ValueError(f"the map set {excerpt(name)} matches no map file "
                             f"({', '.join(IMAGE_SUFFIXES + YAML_SUFFIXES)})")
        return files
    if Path(name).is_dir():
        files = _map_files(Path(name))
        if not files:
            raise ValueError(f"the folder {excerpt(name)} holds no map file "
                             f"({', '.join(IMAGE_SUFFIXES + YAML_SUFFIXES)}); give a folder of maps, a glob or one map")
        return files
    return None


class WorldSource:
    """Draws the world of each episode: :meth:`draw` takes the episode's generator.

    ``world``: a world name or file (always the same world), a map set (one of its maps per
    reset), a family of :data:`WORLD_FAMILIES` (one of its worlds per reset, from ``generator``, the
    family's options) or None (a generated lattice world per reset, from ``generator``).
    """

    def __init__(self, world: str | None, generator: GeneratorConfig | LoopWorldConfig = GeneratorConfig(),
                 pixel_size: float = DEFAULT_PIXEL_SIZE):
        self.generator = generator
        self.pixel_size = pixel_size
        self.generate = WORLD_FAMILIES[world][1] if world in WORLD_FAMILIES else generate_world
        generated = world is None or world in WORLD_FAMILIES
        self.files = map_set_files(world) if not generated else None
        self.fixed: WorldSpec | None = None
        if not generated and self.files is None:
            self.fixed = load_world(world, pixel_size)
        self._cache: OrderedDict[Path, WorldSpec] = OrderedDict()

    def draw(self, rng: np.random.Generator) -> WorldSpec:
        if self.fixed is not None:
            return self.fixed
        if self.files is None:
            return self.generate(rng, self.generator)
        return self.load(self.files[int(rng.integers(len(self.files)))])

    def load(self, path: Path) -> WorldSpec:
        """The world of one map of the set (cached)."""
        if path not in self._cache:
            self._cache[path] = load_world(path, self.pixel_size)
            if len(self._cache) > CACHED_WORLDS:
                self._cache.popitem(last=False)
        self._cache.move_to_end(path)
        return self._cache[path]
