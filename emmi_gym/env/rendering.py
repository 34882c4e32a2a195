"""Frames of the environment: the true world and robot beside the expected map with the particles.

Drawn with NumPy into an RGB array (no display needed); ``human`` mode shows the
same frame in a pygame window.
"""

from __future__ import annotations

import math

import numpy as np

from ..geometry.clipping import clip_segment
from ..inputs.extras import missing_extra

PIXELS_PER_METRE = 16
_WALL, _FREE, _UNKNOWN = (60, 60, 60), (255, 255, 255), (200, 200, 200)


class Canvas:
    """An RGB panel over a world box, with world -> pixel drawing of points, lines and discs."""

    def __init__(self, bounds, ppm: int = PIXELS_PER_METRE):
        self.xmin, self.ymin, xmax, ymax = bounds
        self.ppm = ppm
        self.width = int(math.ceil((xmax - self.xmin) * ppm))
        self.height = int(math.ceil((ymax - self.ymin) * ppm))
        self.image = np.zeros((self.height, self.width, 3), dtype=np.uint8)

    def pixels(self, x, y):
        col = np.floor((np.asarray(x) - self.xmin) * self.ppm).astype(int)
        row = self.height - 1 - np.floor((np.asarray(y) - self.ymin) * self.ppm).astype(int)
        return row, col

    def points(self, x, y, colour, radius: int = 0):
        rows, cols = self.pixels(np.atleast_1d(x), np.atleast_1d(y))
        for dr in range(-radius, radius + 1):
            for dc in range(-radius, radius + 1):
                if dr * dr + dc * dc <= radius * radius:
                    r, c = rows + dr, cols + dc
                    ok = (r >= 0) & (r < self.height) & (c >= 0) & (c < self.width)
                    self.image[r[ok], c[ok]] = colour

    def polyline(self, xy: np.ndarray, colour):
        """Each segment sampled twice a pixel over the part of it that crosses the panel (clipped first:
        an estimated path far off the map costs what the panel holds)."""
        xmax, ymax = self.xmin + self.width / self.ppm, self.ymin + self.height / self.ppm
        for (x0, y0), (x1, y1) in zip(xy[:-1], xy[1:], strict=False):
            t0, t1 = clip_segment(float(x0), float(y0), float(x1 - x0), float(y1 - y0), 0.0, 1.0,
                                  self.xmin, xmax, self.ymin, ymax)
            if t0 > t1:
                continue
            n = max(2, int(math.hypot(x1 - x0, y1 - y0) * (t1 - t0) * self.ppm * 2))
            t = np.linspace(t0, t1, n)
            self.points(x0 + t * (x1 - x0), y0 + t * (y1 - y0), colour)

    def robot(self, pose, colour, radius_m: float):
        self.points(pose[0], pose[1], colour, radius=max(1, int(radius_m * self.ppm)))
        ahead = np.array([pose[0], pose[1]]) + 2 * radius_m * np.array([math.cos(pose[2]), math.sin(pose[2])])
        self.polyline(np.array([pose[:2], ahead]), (0, 0, 0))

    def grid(self, values_rgb: np.ndarray, geometry):
        """Paint a (H, W, 3) image of a grid with ``geometry`` under the canvas's pixels."""
        rows = np.arange(self.height)
        cols = np.arange(self.width)
        ys = self.ymin + (self.height - 1 - rows + 0.5) / self.ppm
        xs = self.xmin + (cols + 0.5) / self.ppm
        gr, gc = geometry.cell_of(xs[None, :].repeat(self.height, 0), ys[:, None].repeat(self.width, 1))
        ok = geometry.inside(gr, gc)
        self.image[ok] = values_rgb[gr[ok], gc[ok]]


def truth_rgb(truth_grid: np.ndarray) -> np.ndarray:
    rgb = np.empty(truth_grid.shape + (3,), dtype=np.uint8)
    rgb[:] = _UNKNOWN
    rgb[truth_grid == 0] = _FREE
    rgb[truth_grid == 1] = _WALL
    return rgb


def map_rgb(expected_map: np.ndarray) -> np.ndarray:
    grey = (255 * (1.0 - expected_map)).astype(np.uint8)
    return np.repeat(grey[:, :, None], 3, axis=2)


_TRUE_PATH, _ROBOT, _BEST_PATH, _PARTICLES = (0, 160, 0), (220, 30, 30), (255, 140, 0), (30, 60, 220)
CAPTION_HEIGHT = 16


def caption(width: int, segments) -> np.ndarray:
    """A white strip ``width`` pixels wide with (text, colour) segments in Pillow's built-in font: the
    panel's title and legend (which colour is what)."""
    from PIL import Image, ImageDraw, ImageFont

    strip = Image.new("RGB", (width, CAPTION_HEIGHT), (255, 255, 255))
    draw, font = ImageDraw.Draw(strip), ImageFont.load_default()
    draw.fontmode = "1"  # no anti-aliasing: each legend word in exactly its colour
    x = 3
    for text, colour in segments:
        draw.text((x, 2), text, fill=colour, font=font)
        x += int(draw.textlength(text, font=font))
    return np.asarray(strip)


def render_frame(bounds, truth_grid, geometry, expected_map, true_pose, true_path, particle_poses, best_path,
                 robot_radius: float) -> np.ndarray:
    """Left: the true world, the true path (green) and robot (red). Right: the expected map,
    the particles (blue) and the best particle's path (orange). Each panel has a caption saying
    so. Returns (H, W, 3) uint8."""
    left = Canvas(bounds)
    left.image[:] = _UNKNOWN
    left.grid(truth_rgb(truth_grid), geometry)
    if len(true_path) > 1:
        left.polyline(np.asarray(true_path)[:, :2], _TRUE_PATH)
    left.robot(true_pose, _ROBOT, robot_radius)
    right = Canvas(bounds)
    right.image[:] = 127
    right.grid(map_rgb(expected_map), geometry)
    if len(best_path) > 1:
        right.polyline(best_path[:, :2], _BEST_PATH)
    right.points(particle_poses[:, 0], particle_poses[:, 1], _PARTICLES, radius=1)
    black = (0, 0, 0)
    left_panel = np.concatenate([caption(left.width, [("truth: ", black), ("path", _TRUE_PATH), (", ", black),
                                                      ("robot", _ROBOT)]), left.image])
    right_panel = np.concatenate([caption(right.width, [("expected map: ", black), ("best path", _BEST_PATH),
                                                        (", ", black), ("particles", _PARTICLES)]), right.image])
    gap = np.full((left_panel.shape[0], 8, 3), 255, dtype=np.uint8)
    return np.concatenate([left_panel, gap, right_panel], axis=1)


class HumanWindow:
    """A pygame window that shows frames at the environment's frame rate."""

    def __init__(self, fps: int):
        try:
            import pygame
        except ModuleNotFoundError as error:
            raise missing_extra(error, 'render_mode="human"') or error from None

        self.pygame = pygame
        pygame.init()
        pygame.display.init()
        self.window = None
        self.clock = pygame.time.Clock()
        self.fps = fps

    def show(self, frame: np.ndarray) -> None:
        pg = self.pygame
        if self.window is None:
            self.window = pg.display.set_mode((frame.shape[1], frame.shape[0]))
            pg.display.set_caption("emmi-gym")
        pg.event.pump()
        surface = pg.surfarray.make_surface(np.transpose(frame, (1, 0, 2)))
        self.window.blit(surface, (0, 0))
        pg.display.flip()
        self.clock.tick(self.fps)

    def close(self) -> None:
        self.pygame.display.quit()
        self.pygame.quit()
