"""The oracle map (scans at the true poses) and the map scores measured against it."""

import gymnasium as gym
import numpy as np
import pytest

import emmi_gym  # noqa: F401 (registers the ids)
from emmi_gym.geometry.grid import GridGeometry
from emmi_gym.scoring.oracle import OracleMap
from emmi_gym.scoring.scores import map_labels, oracle_accuracy, wall_consistency
from emmi_gym.slam import RBPF, RBPFConfig
from emmi_gym.world import LaserConfig, Simulator, drive_route, load_world


@pytest.fixture(scope="module")
def loop_run():
    """The loop_corridor loop driven once: true poses and scans every 0.5 m."""
    world = load_world("loop_corridor")
    laser = LaserConfig()
    sim = Simulator(world, laser=laser)
    rec = drive_route(sim, world.route("to_decision") + world.route("close_loop")[1:], np.random.default_rng(3))
    steps = np.concatenate([[0], np.nonzero(np.diff(np.floor(np.cumsum(
        np.hypot(*np.diff(rec.true_poses[:, :2], axis=0).T)) / 0.5)))[0] + 1])
    geometry = GridGeometry.covering(*world.bounds, 0.1)
    return rec.true_poses[steps], rec.scans[steps], laser.angles, geometry


def oracle_from(poses, scans, angles, geometry) -> OracleMap:
    rbpf = RBPF(RBPFConfig(particles=1), max_range=LaserConfig().max_range, geometry=geometry)
    rbpf.reset(poses[0], np.random.default_rng(0))
    oracle = OracleMap(rbpf)
    for pose, scan in zip(poses, scans, strict=False):
        oracle.insert(pose, scan, angles)
    return oracle


def map_from(poses, scans, angles, geometry) -> np.ndarray:
    return oracle_from(poses, scans, angles, geometry).probabilities()


def test_labels_read_off_the_codes_are_those_of_the_probabilities(loop_run):
    poses, scans, angles, geometry = loop_run
    oracle = oracle_from(poses, scans, angles, geometry)
    labels = oracle.labels()
    assert np.array_equal(labels, map_labels(oracle.probabilities()))
    assert set(np.unique(labels)) == {-1, 0, 1}  # all three kinds occur, so the table's order is tested


def test_a_perfectly_localised_map_scores_one_and_a_rotated_one_lower(loop_run):
    poses, scans, angles, geometry = loop_run
    truth = map_from(poses, scans, angles, geometry)
    assert oracle_accuracy(truth, truth) == 1.0 and wall_consistency(truth, truth, 0.1) == 1.0
    # a heading error that grows by 0.2 degrees per metre (as an uncorrected gyro drift): the loop's end
    # overlaps its start with walls ~0.25 m apart, the revisited walls drawn twice
    travelled = np.concatenate([[0.0], np.cumsum(np.hypot(*np.diff(poses[:, :2], axis=0).T))])
    drifted = [poses[0]]
    for k in range(1, len(poses)):
        step = np.array(poses[k]) - poses[k - 1]
        c, s = np.cos(drifted[-1][2] - poses[k - 1][2]), np.sin(drifted[-1][2] - poses[k - 1][2])
        local = np.array([c * step[0] - s * step[1], s * step[0] + c * step[1], step[2] + np.radians(0.2) * (
            travelled[k] - travelled[k - 1])])
        drifted.append(drifted[-1] + local)
    skewed = map_from(np.array(drifted), scans, angles, geometry)
    accuracy, consistency = oracle_accuracy(skewed, truth), wall_consistency(skewed, truth, 0.1)
    assert accuracy < 0.97 and consistency < 0.9
    # and the error grows with the drift
    assert oracle_accuracy(map_from(np.array(drifted[:len(drifted) // 2]), scans[:len(drifted) // 2], angles,
                                    geometry), map_from(poses[:len(poses) // 2], scans[:len(poses) // 2], angles,
                                                        geometry)) > accuracy


def test_a_doubled_wall_lowers_wall_consistency_not_just_accuracy():
    oracle = np.full((40, 40), 0.5)
    oracle[5:35, 5:35] = 0.1
    oracle[5:35, 20] = 0.95  # one wall
    doubled = oracle.copy()
    doubled[5:35, 26] = 0.95  # drawn again 0.6 m off
    assert wall_consistency(doubled, oracle, 0.1) == pytest.approx(0.5)
    assert oracle_accuracy(doubled, oracle) == pytest.approx(1 - 30 / (30 * 30))
    assert wall_consistency(oracle, oracle, 0.1, tolerance=0.0) == 1.0
    assert map_labels(np.array([0.5, 0.1, 0.9])).tolist() == [-1, 0, 1]
    with pytest.raises(ValueError, match="one grid"):
        oracle_accuracy(oracle, oracle[:-1])


def test_env_reports_oracle_scores():
    env = gym.make("emmi_gym/LoopCorridor-v1", max_decisions=2, info_scores="always")
    _, info = env.reset(seed=0)
    for _ in range(2):
        _, _, _, _, info = env.step(0)
        assert 0.0 <= info["oracle_accuracy"] <= 1.0 and 0.0 <= info["wall_consistency"] <= 1.0
    # before the robot moves, every particle and the oracle inserted the one scan at the same pose
    _, info = env.reset(seed=0, options={"start_at": "start"})
    assert info["oracle_accuracy"] == 1.0 and info["wall_consistency"] == 1.0


@pytest.mark.parametrize("resolution, tolerance", [(0.1, 0.2), (0.05, 0.2), (0.1, 0.0), (0.025, 0.1), (0.1, 0.45)])
def test_wall_consistency_counts_the_walls_within_the_tolerance_centre_to_centre(resolution, tolerance):
    rng = np.random.default_rng(int(tolerance * 100) + int(1 / resolution))
    for _ in range(20):
        shape = tuple(rng.integers(1, 30, 2))
        mine = np.where(rng.random(shape) < 0.2, 0.95, np.where(rng.random(shape) < 0.5, 0.1, 0.5))
        oracle = np.where(rng.random(shape) < 0.1, 0.95, 0.1)
        walls, true_walls = np.argwhere(mine > 0.5), np.argwhere(oracle > 0.5)
        if not len(walls):
            expected = 1.0
        elif not len(true_walls):
            expected = 0.0
        else:
            distance = np.hypot(*(walls[:, None, :] - true_walls[None, :, :]).transpose(2, 0, 1)).min(axis=1)
            expected = float(np.mean(distance * resolution <= tolerance + 1e-9))
        assert wall_consistency(mine, oracle, resolution, tolerance=tolerance) == pytest.approx(expected)
