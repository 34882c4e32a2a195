"""The scan matcher's capture basin is set in metres and radians, not in cells."""

import math

import numpy as np
import pytest

from emmi_gym.grid import GridGeometry
from emmi_gym.slam import CellCodes, ParticleMaps, RBPFConfig
from emmi_gym.slam import _matching as MT
from emmi_gym.world import LaserConfig, Simulator, load_world

TRUE_POSE = np.array([5.5, 4.5, 0.5])  # in a room: the scan pins x, y and heading


@pytest.fixture(scope="module")
def scans():
    """A 180-degree, 181-beam scan of the office world (lower left room) at TRUE_POSE and two taken nearby for the map."""
    world = load_world("office")
    laser = Simulator(world, laser=LaserConfig(fov=math.pi, n_beams=181, max_range=15.0,
                                               range_sigma=0.0, drop_probability=0.0)).laser
    poses = [TRUE_POSE + d for d in ([0.0, 0.0, 0.0], [-0.3, 0.1, -0.1], [0.3, -0.1, 0.1])]
    return world, laser, poses, [laser.true_ranges(p) for p in poses]


@pytest.mark.parametrize("resolution", [0.025, 0.05, 0.1])
@pytest.mark.parametrize("offset", [(0.4, 0.0, 4.0), (-0.28, 0.28, -4.0), (0.0, -0.4, 4.0)])
def test_matcher_recovers_a_pose_displaced_by_40_cm_and_4_degrees(scans, resolution, offset):
    world, laser, poses, ranges = scans
    config = RBPFConfig(resolution=resolution)
    geometry = GridGeometry.covering(*world.bounds, resolution, margin=2.0)
    maps = ParticleMaps(geometry, 1, CellCodes.from_config(config), config.coarse_block())
    for pose, r in zip(poses, ranges):
        maps.insert(pose[None], r, laser.config.angles, laser.config.max_range, 0.0)
    start = TRUE_POSE + np.array([offset[0], offset[1], math.radians(offset[2])])
    settings = MT.match_settings(config, geometry.origin_x, geometry.origin_y, resolution, maps.block)
    flat_prior = np.zeros((3, 3))
    climb = slice(None, None, 6)
    pose, _ = MT.match(maps.codes[0], maps.hits[0], maps.coarse[0], start, ranges[0][climb],
                       laser.config.angles[climb], laser.config.max_range, settings, start, flat_prior)
    assert math.hypot(*(pose[:2] - TRUE_POSE[:2])) < 0.05
    assert abs(pose[2] - TRUE_POSE[2]) < math.radians(1.0)
