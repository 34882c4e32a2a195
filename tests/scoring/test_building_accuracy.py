"""The building accuracy: the share of the building's cells mapped correctly, unmapped cells counting as wrong."""

import gymnasium as gym
import numpy as np
import pytest
from scipy import ndimage

import emmi_gym  # noqa: F401 (registers the ids)
from emmi_gym.scoring.scores import building_accuracy, building_cells, map_accuracy
from emmi_gym.world import FREE, OCCUPIED, UNKNOWN, LaserConfig, Simulator, drive_route, load_world, rasterise


@pytest.fixture(scope="module")
def truth() -> np.ndarray:
    """A room of 8 x 10 free cells inside walls two cells thick, in an outside of unknown cells, and a closed-off
    pocket of unknown cells inside the walls."""
    grid = np.full((16, 18), UNKNOWN, dtype=np.int8)
    grid[2:14, 2:16] = OCCUPIED
    grid[4:12, 4:14] = FREE
    grid[6, 8] = OCCUPIED  # a pillar
    return grid


def probabilities_of(labels: np.ndarray) -> np.ndarray:
    """A map that says ``labels`` (-1 unobserved, 0 free, 1 occupied) with certainty."""
    return np.select([labels == 0, labels == 1], [0.02, 0.98], 0.5)


def test_the_building_is_the_free_space_and_the_wall_faces_around_it(truth):
    cells = building_cells(truth)
    faces = cells & (truth == OCCUPIED)
    assert np.array_equal(cells & (truth != OCCUPIED), truth == FREE)
    # the inner face of the outer walls (a ring of 10 x 12 cells: corners touch the free space diagonally) and
    # the pillar; the wall's outer layer and the outside are never seen
    assert np.count_nonzero(faces) == 10 * 12 - 8 * 10 + 1
    assert not cells[2, :].any() and not cells[:, 2].any() and not cells[0].any()
    assert faces[3, 3] and faces[6, 8]


def test_a_complete_correct_map_scores_one_and_an_empty_map_zero(truth):
    assert building_accuracy(probabilities_of(truth), truth) == 1.0
    assert building_accuracy(np.full(truth.shape, 0.5), truth) == 0.0
    # what lies outside the building does not count, right or wrong
    outside = np.where(building_cells(truth), truth, 1 - np.abs(truth))
    assert building_accuracy(probabilities_of(outside), truth) == 1.0


def test_a_half_mapped_correct_map_scores_the_share_mapped_where_map_accuracy_says_perfect(truth):
    cells = building_cells(truth)
    half = truth.copy()
    half[:, 9:] = UNKNOWN  # the right half never seen
    share = np.count_nonzero(cells[:, :9]) / np.count_nonzero(cells)
    assert building_accuracy(probabilities_of(half), truth) == pytest.approx(share)
    assert 0.4 < share < 0.6
    assert map_accuracy(probabilities_of(half), truth) == 1.0  # mapping less reads as perfect there


def test_a_wrong_cell_lowers_it_by_one_cell_of_the_building(truth):
    n = np.count_nonzero(building_cells(truth))
    for row, col in ((5, 5), (3, 3)):  # a free cell drawn occupied, a wall face drawn free
        wrong = truth.copy()
        wrong[row, col] = 1 - wrong[row, col]
        assert building_accuracy(probabilities_of(wrong), truth) == pytest.approx(1.0 - 1.0 / n)


def test_a_map_on_another_grid_or_a_truth_with_no_building_is_refused_or_scores_zero(truth):
    with pytest.raises(ValueError, match="must share one grid"):
        building_accuracy(np.full((3, 3), 0.5), truth)
    assert building_accuracy(np.full((3, 3), 0.02), np.full((3, 3), UNKNOWN, dtype=np.int8)) == 0.0


def test_the_building_holds_every_cell_a_laser_sees_on_a_shipped_world():
    """The loop corridor driven once: nearly every echo ends in a cell of the building, and every one within a cell
    of it (the range noise carries a few a cell deeper into the wall); the insides of the walls are left out."""
    world = load_world("loop_corridor")
    laser = LaserConfig()
    record = drive_route(Simulator(world, laser=laser), world.route("to_decision") + world.route("close_loop")[1:],
                         np.random.default_rng(3))
    truth = rasterise(world, 0.1)
    cells = building_cells(truth.grid)
    near = ndimage.binary_dilation(cells, structure=np.ones((3, 3), dtype=bool))
    echoes = inside = 0
    for (x, y, theta), ranges in zip(record.true_poses[::20], record.scans[::20], strict=True):
        hit = ranges < laser.max_range
        angle = theta + laser.angles[hit]
        row, col = truth.geometry.cell_of(x + ranges[hit] * np.cos(angle), y + ranges[hit] * np.sin(angle))
        assert near[row, col].all()
        echoes, inside = echoes + row.size, inside + np.count_nonzero(cells[row, col])
    assert echoes > 1000 and inside > 0.9 * echoes
    assert cells[truth.reachable].all()
    assert np.count_nonzero(cells) < np.count_nonzero(truth.grid != UNKNOWN)


def test_the_env_reports_the_building_accuracy_growing_with_what_it_has_mapped():
    env = gym.make("emmi_gym/LoopCorridor-v1", max_decisions=3, info_scores="always")
    _, info = env.reset(seed=0)
    scores = [info["building_accuracy"]]
    for _ in range(3):
        _, _, _, _, info = env.step(0)
        scores.append(info["building_accuracy"])
    core = env.unwrapped
    assert scores[-1] == building_accuracy(core.expected_map, core.truth.grid)
    assert 0.0 < scores[0] < scores[-1] <= 1.0
    assert scores[-1] <= info["coverage"] + 0.1  # unmapped cells count: it cannot run far ahead of coverage
