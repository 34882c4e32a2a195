"""The scan matcher's capture basin is set in metres and radians, not in cells."""

import math

import numpy as np
import pytest

from emmi_gym.geometry.grid import GridGeometry
from emmi_gym.slam import CellCodes, ParticleMaps, RBPFConfig
from emmi_gym.slam import _matching as MT
from emmi_gym.world import LaserConfig, Simulator, load_world

TRUE_POSE = np.array([5.5, 4.5, 0.5])  # in a room: the scan pins x, y and heading


@pytest.fixture(scope="module")
def scans():
    """A 180-degree, 181-beam scan of the office world (lower left room) at TRUE_POSE and two taken nearby for the
    map."""
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
    for pose, r in zip(poses, ranges, strict=False):
        maps.insert(pose[None], r, laser.config.angles, laser.config.max_range, 0.0)
    start = TRUE_POSE + np.array([offset[0], offset[1], math.radians(offset[2])])
    settings = MT.match_settings(config, geometry.origin_x, geometry.origin_y, resolution, maps.block)
    flat_prior = np.zeros((3, 3))
    climb = slice(None, None, 6)
    pose, _ = MT.match(maps.codes[0], maps.hits[0], maps.coarse[0], start, ranges[0][climb],
                       laser.config.angles[climb], laser.config.max_range, settings, start, flat_prior)
    assert math.hypot(*(pose[:2] - TRUE_POSE[:2])) < 0.05
    assert abs(pose[2] - TRUE_POSE[2]) < math.radians(1.0)


def _scan_matched_fraction(grid, hits, geometry, pose, ranges, angles, max_range):
    """The share of the echoes whose end point finds a surface within the match radius."""
    settings = MT.match_settings(RBPFConfig(resolution=geometry.resolution), geometry.origin_x, geometry.origin_y,
                                 geometry.resolution, 1)
    offsets = np.empty((ranges.size, 4))
    n = MT.beam_offsets(pose[2], ranges, angles, max_range, geometry.resolution, offsets)
    gx, gy = (pose[0] - geometry.origin_x) / geometry.resolution, (pose[1] - geometry.origin_y) / geometry.resolution
    _, matched = MT.scan_loglik(grid, hits, gx, gy, offsets, n, settings, -np.inf)
    return matched / n


@pytest.mark.parametrize("resolution", [0.05, 0.1])
def test_beams_grazing_a_wall_match_it(resolution):
    """Down a corridor many beams meet the walls at a glancing angle. With a map made from scans
    every 0.5 m along the corridor, a noiseless scan taken in between must find its walls with
    nearly every echo; with GMapping's test (the one cell straight back along the beam must be free)
    a grazing beam often does not: 88-94% of the echoes here, a tenth of each scan scored as misses."""
    world = load_world("loop_corridor")
    laser = Simulator(world, laser=LaserConfig(fov=2 * math.pi, n_beams=360, max_range=8.0, range_sigma=0.0,
                                               drop_probability=0.0)).laser
    config = RBPFConfig(resolution=resolution)
    geometry = GridGeometry.covering(*world.bounds, resolution, margin=2.0)
    maps = ParticleMaps(geometry, 1, CellCodes.from_config(config), 1)
    for x in np.arange(5.0, 16.0, 0.5):  # along the start corridor
        pose = np.array([x, 1.0, 0.0])
        maps.insert(pose[None], laser.true_ranges(pose), laser.config.angles, 8.0, 0.0)
    for x in (9.25, 10.1, 11.37):
        pose = np.array([x, 1.03, 0.01])
        fraction = _scan_matched_fraction(maps.codes[0], maps.hits[0], geometry, pose, laser.true_ranges(pose),
                                          laser.config.angles, 8.0)
        assert fraction > 0.99


def test_the_far_face_of_a_thick_wall_is_not_a_surface():
    """A beam that ends inside a wall, past its middle, is not matched to the far face (seen only
    from the other side): its nearest surface seen from the laser is the near face, 0.2 m back."""
    resolution = 0.05
    grid = np.full((60, 60), -40, dtype=np.int8)
    grid[:, 20:25] = 40  # a 0.25 m wall, free on both sides
    hits = np.zeros((60, 60, 3), dtype=np.int8)
    pose = np.array([0.5, 1.5, 0.0])  # left of the wall, looking at it
    wall_x = 20 * resolution
    beyond = np.array([wall_x - pose[0] + 4.5 * resolution])  # ends in the far face's cell
    at_face = np.array([wall_x - pose[0] + 0.5 * resolution])
    angles = np.zeros(1)
    geometry = GridGeometry(resolution, 0.0, 0.0, 60, 60)
    assert _scan_matched_fraction(grid, hits, geometry, pose, at_face, angles, 8.0) == 1.0
    assert _scan_matched_fraction(grid, hits, geometry, pose, beyond, angles, 8.0) == 0.0


@pytest.mark.parametrize("inflation", [4.0, 9.0])
def test_proposal_inflation_widens_the_fitted_gaussian_s_draws_by_its_root(scans, inflation):
    """Two particles on one map, drawn with opposite normals: their midpoint is the fitted Gaussian's mean, and
    each draw's offset from it grows by sqrt(proposal_inflation); the weights, which the fit's normaliser
    sets before the covariance is widened, stay as they were. A flat likelihood (sigma 1 m) gives the fit
    a width of about the stencil's step, far above its numerical floor of 1 mm."""
    world, laser, poses, ranges = scans
    geometry = GridGeometry.covering(*world.bounds, 0.05, margin=2.0)

    def propose(config):
        maps = ParticleMaps(geometry, 2, CellCodes.from_config(config), config.coarse_block())
        for pose, r in zip(poses[1:], ranges[1:], strict=False):
            maps.insert(np.stack([pose, pose]), r, laser.config.angles, laser.config.max_range, 0.0)
        settings = MT.match_settings(config, geometry.origin_x, geometry.origin_y, 0.05, maps.block)
        start = np.stack([TRUE_POSE + [0.03, -0.02, 0.01]] * 2)
        normals = np.array([[0.8, -1.1, 0.6], [-0.8, 1.1, -0.6]])
        precisions = np.stack([np.diag([1 / 0.1 ** 2, 1 / 0.1 ** 2, 1 / 0.05 ** 2])] * 2)
        beams = laser.config.angles
        new_poses, increments, matched = np.empty((2, 3)), np.empty(2), np.zeros(2, dtype=np.bool_)
        MT.improved_proposal(0, 2, maps.codes, maps.hits, maps.coarse, start, start, precisions, np.zeros(2),
                             normals, ranges[0][::3], beams[::3], ranges[0][::2], beams[::2], ranges[0][::2],
                             False, laser.config.max_range, settings, new_poses, increments, matched)
        assert matched.all()
        centre = new_poses.mean(axis=0)
        return new_poses[0] - centre, increments

    offset, weights = propose(RBPFConfig(resolution=0.05, likelihood_sigma=1.0))
    wide_offset, wide_weights = propose(RBPFConfig(resolution=0.05, likelihood_sigma=1.0,
                                                   proposal_inflation=inflation))
    assert np.linalg.norm(offset[:2]) > 0.01
    np.testing.assert_allclose(wide_offset, math.sqrt(inflation) * offset, rtol=0.01)
    np.testing.assert_array_equal(wide_weights, weights)
