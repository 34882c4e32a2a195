"""Observations: the expected map as an image with the estimated pose, for SB3's MultiInputPolicy / CnnPolicy.

Each observation type gives the observation space (:meth:`ObservationType.space`) and the
observation now (:meth:`ObservationType.observe`); :func:`observation_factory` picks the type
the option ``observation`` names: ``"dict"`` (:class:`DictObservation`) or ``"image"``
(:class:`ImageObservation`). The functions below draw their parts.
"""

from __future__ import annotations

import math

import gymnasium as gym
import numba as nb
import numpy as np
from gymnasium import spaces

from ..geometry.grid import GridGeometry
from ..navigation.planner import FREE_P, OCCUPIED_P
from .actions import by_name

UNKNOWN_PIXEL = 127
PATH_PIXEL = 128
ROBOT_PIXEL = 255
POSE_ENTROPY_RANGE = 20.0  # nats: the certainty vector carries pose_entropy / 20, clipped to [-1, 1]
FRONTIER_LENGTH_RANGE = 10.0  # m: a frontier's length / 10 m, clipped to 1
LOOP_SPREAD_RANGE = 0.5  # m: a revisit's loop displacement spread / 0.5 m, clipped to 1
TARGET_FEATURES = ("valid", "revisit", "dx", "dy", "travel_cost", "frontier_length", "loop_strength", "loop_spread")


class ObservationType:
    """What an observation is (:meth:`space`) and how the environment makes it (:meth:`observe`).

    The environment calls :meth:`refresh` whenever the filter updated (after the expected map and
    its measures were recomputed) and :meth:`observe` at every reset and step. A type reads the
    environment's public state only (``env.expected_map``, ``env.metrics``, ``env.estimated_pose``,
    ``env.slam``, ``env.action_type``), as HighwayEnv's observation types read the env's road
    and vehicle.
    """

    def __init__(self, env: gym.Env):
        self.env = env

    def space(self) -> spaces.Space:
        """The observation space."""
        raise NotImplementedError

    def observe(self):
        """The observation now."""
        raise NotImplementedError

    def refresh(self) -> None:
        """The filter updated: what depends on the expected map is out of date."""


class ImageObservation(ObservationType):
    """``Box(0, 255, (2, obs_size, obs_size), uint8)``, for CnnPolicy: channel 0 the expected map
    pooled to pixels (0 free, 255 occupied, 127 unknown; :class:`MapPooling`), channel 1 the
    estimated path (128) and the robot with its heading (255); north up. The whole world, or with
    ``egocentric`` a square of ``egocentric_extent`` metres round the estimated pose
    (:func:`view_window`). The map and the path are drawn again only when the filter updated (or
    at every step when egocentric), the robot at every step (:func:`map_and_path`,
    :func:`with_robot`)."""

    def __init__(self, env: gym.Env):
        super().__init__(env)
        self._pooling = MapPooling()
        self._map_image: np.ndarray | None = None
        self._stale = True  # the filter updated since the map and path were drawn

    def space(self) -> spaces.Box:
        size = self.env.config.obs_size
        return spaces.Box(0, 255, (2, size, size), dtype=np.uint8)

    def refresh(self) -> None:
        self._stale = True

    def image(self, pose) -> np.ndarray:
        """The image with the robot at ``pose`` (the estimated pose now)."""
        env, cfg = self.env, self.env.config
        window = view_window(env.world.bounds, pose, cfg.obs_size, cfg.egocentric, cfg.egocentric_extent)
        if cfg.egocentric or self._stale:  # the map and the path change only at filter updates
            map_channel = self._pooling(env.expected_map, env.geometry, window, cfg.obs_size)
            self._map_image = map_and_path(map_channel, env.slam.paths[env.slam.best], window, cfg.obs_size)
            self._stale = False
        return with_robot(self._map_image, pose, window, cfg.obs_size)

    def observe(self) -> np.ndarray:
        return self.image(self.env.estimated_pose)


class DictObservation(ImageObservation):
    """``Dict``, for MultiInputPolicy: ``map``, the :class:`ImageObservation`; ``pose``, (x, y)
    scaled to [-1, 1] over the world's bounds and (cos, sin) of the heading (:func:`pose_vector`);
    ``certainty``, (EMMI in bits/cell, pose entropy / 20 nats) (:func:`certainty_vector`); and,
    when the action type has target slots (waypoint actions), ``targets``: one row of
    :data:`TARGET_FEATURES` per slot (:func:`target_features`)."""

    def __init__(self, env: gym.Env):
        super().__init__(env)
        self._certainty = np.zeros(2, dtype=np.float32)

    def space(self) -> spaces.Dict:
        parts = {
            "map": super().space(),
            "pose": spaces.Box(-1.0, 1.0, (4,), dtype=np.float32),
            "certainty": spaces.Box(-1.0, 1.0, (2,), dtype=np.float32),
        }
        n_slots = self.env.action_type.n_slots
        if n_slots:
            parts["targets"] = spaces.Box(-1.0, 1.0, (n_slots, len(TARGET_FEATURES)), dtype=np.float32)
        return spaces.Dict(parts)

    def refresh(self) -> None:
        super().refresh()
        metrics = self.env.metrics
        self._certainty = certainty_vector(metrics.emmi, metrics.pose_entropy)

    def observe(self) -> dict:
        env = self.env
        pose = env.estimated_pose
        observation = {"map": self.image(pose), "pose": pose_vector(pose, env.world.bounds),
                       "certainty": self._certainty.copy()}
        actions = env.action_type
        if actions.n_slots:
            observation["targets"] = target_features(actions.targets, actions.loop_spreads, pose, env.world.bounds,
                                                     env.geometry.resolution)
        return observation


#: The observation types by the option ``observation``.
OBSERVATION_TYPES: dict[str, type[ObservationType]] = {"dict": DictObservation, "image": ImageObservation}


def observation_factory(env: gym.Env, config) -> ObservationType:
    """The observation type the option ``observation`` of ``config`` names, for ``env``."""
    return by_name(OBSERVATION_TYPES, "observation", config.observation)(env)


def view_window(bounds, pose, size: int, egocentric: bool, extent: float) -> tuple[float, float, float]:
    """(x0, y0, metres per pixel) of the square the image shows: the world's bounds, or a crop round the pose."""
    if egocentric:
        return pose[0] - extent / 2, pose[1] - extent / 2, extent / size
    xmin, ymin, xmax, ymax = bounds
    side = max(xmax - xmin, ymax - ymin)
    return (xmin + xmax - side) / 2, (ymin + ymax - side) / 2, side / size


class MapPooling:
    """Downsampling of the expected map to image pixels that keeps thin walls.

    Each pixel shows its cells' most occupied value if any cell is an obstacle
    (p > 0.65), else their least occupied value if any is known free (p < 0.47), else
    127 (unknown). Picking one cell per pixel would miss walls a few cells thick
    whenever a pixel spans several cells. The cells of each pixel are listed once per
    (grid, window) and a kernel pools them in one pass (:func:`_pool`).
    """

    def __init__(self):
        self._key = None  # the (grid, window, size) the index below was made for
        self._cells = self._pixels = self._bounds = np.empty(0, dtype=np.int64)

    def _prepare(self, geometry: GridGeometry, window, size: int) -> None:
        x0, y0, mpp = window
        xs, ys = geometry.cell_centres()
        col = np.floor((xs - x0) / mpp).astype(np.int64).ravel()
        row = (size - 1 - np.floor((ys - y0) / mpp)).astype(np.int64).ravel()
        inside = (row >= 0) & (row < size) & (col >= 0) & (col < size)
        pixel = (row * size + col)[inside]
        cells = np.flatnonzero(inside)
        order = np.argsort(pixel, kind="stable")
        self._cells = cells[order]
        self._pixels, starts = np.unique(pixel[order], return_index=True)
        self._bounds = np.append(starts, self._cells.size)  # pixel k's cells: _cells[_bounds[k]:_bounds[k + 1]]
        self._key = (geometry, tuple(window), size)

    def __call__(self, expected_map: np.ndarray, geometry: GridGeometry, window, size: int) -> np.ndarray:
        if self._key != (geometry, tuple(window), size):
            self._prepare(geometry, window, size)
        image = np.full(size * size, UNKNOWN_PIXEL, dtype=np.uint8)
        _pool(expected_map.ravel(), self._cells, self._bounds, self._pixels, OCCUPIED_P, FREE_P, image)
        return image.reshape(size, size)


@nb.njit(cache=True)
def _pool(p, cells, bounds, pixels, occupied_p, free_p, image):
    """Into ``image[pixels[k]]`` the pooled value of the cells ``cells[bounds[k]:bounds[k + 1]]`` of ``p``
    (see :class:`MapPooling`), as floor(255 p) clipped to [0, 255]."""
    for k in range(pixels.size):
        most, least = -np.inf, np.inf
        for j in range(bounds[k], bounds[k + 1]):
            value = p[cells[j]]
            most = max(most, value)
            least = min(least, value)
        pooled = most if most > occupied_p else (least if least < free_p else 0.5)
        image[pixels[k]] = min(max(math.floor(pooled * 255.0), 0.0), 255.0)


def _pixel(x, y, window, size: int):
    """(row, column) of the image pixels holding the points (x, y), arrays or scalars; row 0 is the top
    (north up)."""
    x0, y0, mpp = window
    if isinstance(x, float) and isinstance(y, float) and math.isfinite(x) and math.isfinite(y):  # one point
        return size - 1 - math.floor((y - y0) / mpp), math.floor((x - x0) / mpp)
    return (size - 1 - np.floor((y - y0) / mpp)).astype(int), np.floor((x - x0) / mpp).astype(int)


def map_and_path(map_channel: np.ndarray, path: np.ndarray, window, size: int) -> np.ndarray:
    """(2, size, size) uint8 without the robot: channel 0 the pooled expected map (see :class:`MapPooling`:
    0 free, 255 occupied, 127 unknown or outside), channel 1 the estimated path (128). Both change only
    when the filter updates, so the environment keeps this image between updates and draws the robot
    on a copy (:func:`with_robot`) at every step."""
    image = np.zeros((2, size, size), dtype=np.uint8)
    image[0] = map_channel
    if len(path):
        rows, cols = _pixel(path[:, 0], path[:, 1], window, size)
        inside = (rows >= 0) & (rows < size) & (cols >= 0) & (cols < size)
        image[1][rows[inside], cols[inside]] = PATH_PIXEL
    return image


def with_robot(image: np.ndarray, pose, window, size: int) -> np.ndarray:
    """A copy of a :func:`map_and_path` image with the robot in channel 1: 255 on the 3 x 3 pixels round
    its position and on one pixel 2.5 pixels ahead, for its heading."""
    image = image.copy()
    robot = image[1]
    r, c = _pixel(pose[0], pose[1], window, size)
    robot[max(r - 1, 0):max(r + 2, 0), max(c - 1, 0):max(c + 2, 0)] = ROBOT_PIXEL
    ahead = 2.5 * window[2]
    hr, hc = _pixel(pose[0] + ahead * math.cos(pose[2]), pose[1] + ahead * math.sin(pose[2]), window, size)
    if 0 <= hr < size and 0 <= hc < size:
        robot[hr, hc] = ROBOT_PIXEL
    return image


def pose_vector(pose, bounds) -> np.ndarray:
    """(x, y) scaled to [-1, 1] over the world's bounds, and (cos, sin) of the heading; float32."""
    xmin, ymin, xmax, ymax = bounds
    x = 2.0 * (pose[0] - xmin) / (xmax - xmin) - 1.0
    y = 2.0 * (pose[1] - ymin) / (ymax - ymin) - 1.0
    return np.array([min(max(v, -1.0), 1.0) for v in (x, y, math.cos(pose[2]), math.sin(pose[2]))], dtype=np.float32)


def target_features(slots, loop_spreads, pose, bounds, resolution: float) -> np.ndarray:
    """(n_slots, 8) float32 in [-1, 1], one row per action slot, so the policy sees what each action means.

    Columns (:data:`TARGET_FEATURES`): 1 if the slot holds a target; 1 if it is a revisit
    (loop-closing) target; its offset from the estimated pose, (dx, dy) / the world's
    larger side; its travel cost / twice that side; a frontier's length (cells times
    ``resolution``) / 10 m; a revisit's loop strength 1 - route length / path length
    closed (at least 1/3, see :data:`~emmi_gym.navigation.candidates.LOOP_RATIO`) and
    its ``loop_spreads`` entry / 0.5 m (the particles' disagreement about the
    robot's position relative to the revisited pose,
    :func:`~emmi_gym.certainty.loop_displacement_spread`: what closing the loop can
    resolve), both 0 for a frontier. Empty slots are all zeros.
    """
    xmin, ymin, xmax, ymax = bounds
    side = max(xmax - xmin, ymax - ymin)
    rows = np.zeros((len(slots), len(TARGET_FEATURES)), dtype=np.float32)
    for k, (target, spread) in enumerate(zip(slots, loop_spreads, strict=False)):
        if target is None:
            continue
        revisit = target.kind == "revisit"
        rows[k] = (1.0, float(revisit), (target.x - pose[0]) / side, (target.y - pose[1]) / side,
                   target.travel_cost / (2.0 * side),
                   0.0 if revisit else target.gain * resolution / FRONTIER_LENGTH_RANGE,
                   1.0 - 1.0 / target.gain if revisit else 0.0,
                   spread / LOOP_SPREAD_RANGE if revisit else 0.0)
    return np.clip(rows, -1.0, 1.0)


def certainty_vector(emmi: float, pose_entropy: float) -> np.ndarray:
    """(EMMI in bits/cell, pose entropy / 20 nats) clipped to [-1, 1]; float32."""
    return np.clip(np.array([emmi, pose_entropy / POSE_ENTROPY_RANGE], dtype=np.float32), -1.0, 1.0)
