"""The RBPF behaves as a grid SLAM should, and as the paper's figures say."""

import copy

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from emmi_gym import certainty
from emmi_gym.geometry.grid import GridGeometry
from emmi_gym.scoring.scores import absolute_trajectory_error, loop_closure_update, map_accuracy, trajectory_alignment
from emmi_gym.slam import RBPF, CellCodes, ParticleMaps, RBPFConfig
from emmi_gym.slam.occupancy import beam_gaps, open_space_beams
from emmi_gym.slam.resampling import survivors_in_place, systematic_resample
from emmi_gym.slam.revisits import RevisitGrid, revisit_exponent
from emmi_gym.world import LaserConfig, OdometryNoise, Simulator, drive_route, load_world, rasterise
from emmi_gym.world.presets import laser_config, odometry_config

SEEDS = range(6)


def loop_run(seed, config=RBPFConfig(), laser=LaserConfig(), odometry=OdometryNoise()):
    """Drive the loop_corridor loop (start -> decision -> start) and run the RBPF on it."""
    world = load_world("loop_corridor")
    sim = Simulator(world, laser=laser, odometry=odometry)
    rec = drive_route(sim, world.route("to_decision") + world.route("close_loop")[1:], np.random.default_rng(seed))
    geometry = GridGeometry.covering(*world.bounds, config.resolution)
    slam = RBPF(config, max_range=sim.laser.config.max_range, geometry=geometry)
    slam.reset(rec.odometry_poses[0], np.random.default_rng(1000 + seed))
    rows, steps = [], []
    for k, (pose, ranges) in enumerate(zip(rec.odometry_poses, rec.scans, strict=False)):
        metrics = slam.process(pose, ranges, sim.laser.config.angles, rec.times[k])
        if metrics is not None:
            rows.append(metrics)
            steps.append(k)
    return world, rec, slam, rows, np.array(steps), geometry


@pytest.fixture(scope="module")
def loop_runs():
    return [loop_run(seed) for seed in SEEDS]


@pytest.mark.slow
def test_accuracy_after_the_loop_closes(loop_runs):
    """15 particles, after the loop closed: the best path's ATE (frames coincide at the start, as
    for dead reckoning) is < 0.5 m and >= 3x better than dead reckoning's; the best map, registered
    by the path's alignment, agrees with the truth on >= 90% of the cells both know (median)."""
    accuracies = []
    for world, rec, slam, _rows, steps, geometry in loop_runs:
        truth = rec.true_poses[steps]
        best = slam.paths[slam.best]
        ate = absolute_trajectory_error(best, truth, align=False)
        ate_odometry = absolute_trajectory_error(rec.odometry_poses[steps], truth, align=False)
        assert ate < 0.5
        assert ate * 3 <= ate_odometry
        accuracies.append(map_accuracy(slam.best_map(), rasterise(world, 0.1, geometry).grid, geometry=geometry,
                                       transform=trajectory_alignment(best, truth)))
    assert np.median(accuracies) >= 0.90, accuracies
    assert min(accuracies) >= 0.85, accuracies


def _closing_update(rec, steps, angles, max_range, geometry):
    """The first update after the left corridor's lower half whose scan sees again what the bottom
    corridor's first leg saw."""
    xy = rec.true_poses[steps, :2]
    left = np.flatnonzero((xy[:, 0] < 2.0) & (xy[:, 1] < 12.0))[0]
    first_leg = int(np.flatnonzero(xy[:, 1] > 2.0)[0])
    close = loop_closure_update(rec.true_poses[steps], [rec.scans[k] for k in steps], angles, max_range, geometry,
                                first_leg, left + 1)
    assert close is not None, "the robot never saw the start area again"
    return close


@pytest.mark.slow
def test_loop_closure_shows_in_emmi_and_neff(loop_runs):
    """Fig. 6: EMMI higher a few updates after the loop closes; Neff drops there."""
    emmi_up = neff_drop = 0
    angles = LaserConfig().angles
    for _, rec, slam, rows, steps, geometry in loop_runs:
        close = _closing_update(rec, steps, angles, slam.max_range, geometry)
        emmi = np.array([r.emmi for r in rows])
        emmi_up += emmi[min(close + 4, len(rows) - 1)] > emmi[close - 1]
        window = rows[max(close - 3, 0):close + 8]
        neff_drop += any(r.resampled or r.neff < 0.8 * slam.config.particles for r in window)
    assert emmi_up >= 4 and neff_drop >= 4, (emmi_up, neff_drop)


@pytest.fixture(scope="module")
def corridor_env_runs():
    """The loop with the sensors LoopCorridor-v1 registers: a SICK LMS200 at 8 m, poor odometry."""
    laser, odometry = laser_config({"preset": "sick_lms200", "max_range": 8.0}), odometry_config("poor")
    return [(laser,) + loop_run(seed, laser=laser, odometry=odometry) for seed in SEEDS]


@pytest.mark.slow
def test_hypotheses_survive_the_open_loop_and_collapse_when_it_closes(corridor_env_runs):
    """The paper's Fig. 6 with LoopCorridor-v1's sensors (the fast version of ``measurements/slam_accuracy.py
    --laser '{"preset": "sick_lms200", "max_range": 8.0}' --odometry poor``, whose 20 seeds give 15, 20
    and 17 of 20 for the three counts): no resampling before the loop closes, Neff falls or the set
    resamples as it closes, and EMMI's largest rise of the loop's second half comes with the closure."""
    none_before = drop = rise = 0
    for laser, _, rec, slam, rows, steps, geometry in corridor_env_runs:
        close = _closing_update(rec, steps, laser.angles, slam.max_range, geometry)
        left = int(np.flatnonzero((rec.true_poses[steps, 0] < 2.0) & (rec.true_poses[steps, 1] < 12.0))[0])
        none_before += not any(r.resampled for r in rows[:close - 3])
        drop += any(r.resampled or r.neff < 0.8 * slam.config.particles for r in rows[close - 3:close + 8])
        emmi = np.array([r.emmi for r in rows])
        rise += abs(left + 1 + int(np.argmax(np.diff(emmi[left:]))) - close) <= 5
    assert none_before >= 4 and drop == len(SEEDS) and rise >= 4, (none_before, drop, rise)


@pytest.mark.slow
def test_metrics_are_those_of_the_certainty_functions(loop_runs):
    _, _, slam, rows, _, _ = loop_runs[0]
    last = rows[-1]
    w, lut = slam.weights, slam.cell_codes.probability
    histograms = [np.bincount(c.ravel().astype(np.int64) + 128, minlength=256) for c in slam.maps.codes]
    np.testing.assert_array_equal(slam.maps.counts, histograms)
    assert last.emmi == pytest.approx(certainty.emmi(slam.maps.codes, w, lut=lut), abs=1e-12)
    assert last.emmi == pytest.approx(certainty.mean_information(slam.expected_map()), abs=1e-12)
    assert last.joint_entropy == pytest.approx(
        certainty.joint_entropy(slam.paths, slam.cell_codes.to_logodds(slam.maps.codes), w, logodds=True),
        rel=1e-9)
    assert last.mean_information_best == pytest.approx(certainty.mean_information(slam.best_map()), abs=1e-12)
    # the headings' sines and cosines the filter keeps along its paths follow them through its resamplings
    assert any(r.resampled for r in rows)
    assert last.path_entropy == certainty.path_entropy(slam.paths, w)
    assert last.neff == pytest.approx(1 / np.sum(w**2))
    assert 0 < last.emmi < 1 and 1 <= last.neff <= slam.config.particles
    assert all(set(r.phase_ms) == {"scan_matching", "insertion", "weighting", "resampling", "metrics"} for r in rows)


def test_chunks_cover_the_items_once_in_order_the_caller_s_first_and_largest():
    from emmi_gym.concurrency.threads import chunk_bounds, kernel_threads, set_kernel_threads

    threads = kernel_threads()
    try:
        for n_threads in (1, 2, 3, 7):
            set_kernel_threads(n_threads)
            for n, min_chunk in ((15, 1), (5, 1), (1, 1), (0, 1), (100_000, 20_000), (30_000, 20_000)):
                chunks = chunk_bounds(n, min_chunk)
                sizes = [stop - start for start, stop in chunks]
                assert [start for start, _ in chunks] == [0] + [stop for _, stop in chunks[:-1]]
                assert chunks[-1][1] == n and len(chunks) <= n_threads
                assert sizes[0] == max(sizes) and max(sizes) - min(sizes) <= 1
        set_kernel_threads(2)
        assert chunk_bounds(15) == [(0, 8), (8, 15)]
    finally:
        set_kernel_threads(threads)


def test_the_caller_runs_the_calls_no_pool_thread_has_started():
    """With the pool's one thread held in a long call, the caller runs the later calls itself (and
    each call runs once, results in order), instead of waiting for the pool."""
    import threading

    from emmi_gym.concurrency.threads import kernel_threads, run_calls, set_kernel_threads

    started, release = threading.Event(), threading.Event()

    def held():
        started.set()
        release.wait(20)
        return threading.current_thread().name

    def last():
        release.set()
        return threading.current_thread().name

    threads = kernel_threads()
    try:
        set_kernel_threads(2)
        ran = run_calls([(started.wait, 20), (held,), (lambda: threading.current_thread().name,), (last,)])
    finally:
        set_kernel_threads(threads)
    main = threading.current_thread().name
    assert ran[0] is True and ran[1] != main and ran[2:] == [main, main]


def test_same_seed_same_filter_bit_for_bit_on_any_number_of_threads():
    from emmi_gym.concurrency.threads import kernel_threads, set_kernel_threads

    threads = kernel_threads()
    try:
        set_kernel_threads(1)
        a = loop_run(3, RBPFConfig(particles=5))
        set_kernel_threads(3)  # chunks of 2, 2 and 1 particles on three threads
        b = loop_run(3, RBPFConfig(particles=5))
    finally:
        set_kernel_threads(threads)
    np.testing.assert_array_equal(a[2].paths, b[2].paths)
    np.testing.assert_array_equal(a[2].log_weights, b[2].log_weights)
    np.testing.assert_array_equal(a[2].maps.codes, b[2].maps.codes)
    assert [r.emmi for r in a[3]] == [r.emmi for r in b[3]]


# ------------------------------------------------------------------ the paper's Figs. 3 and 4


def _scans_in_office(n_scans, seed=0):
    world = load_world("office")
    sim = Simulator(world, laser=LaserConfig(n_beams=360, drop_probability=0.0))
    rec = drive_route(sim, [world.start.xy, (9.0, 1.0), (10.0, 6.0)], np.random.default_rng(seed))
    picks = np.linspace(0, len(rec.times) - 1, n_scans).astype(int)
    return world, sim.laser.config.angles, rec.true_poses[picks], rec.scans[picks]


def _mi_of(poses, scans, angles, geometry, config=RBPFConfig()):
    maps = ParticleMaps(geometry, 1, CellCodes.from_config(config))
    for pose, ranges in zip(poses, scans, strict=False):
        maps.insert(pose[None], ranges, angles, 8.0, config.max_range_free)
    return certainty.mean_information(maps.probabilities(0))


def test_open_space_beams_are_runs_without_echo_and_a_closed_scan_joins_its_ends():
    no_echo = np.array([True, False, True, True, False, True])
    open_arc = beam_gaps(np.linspace(-1.0, 1.0, 6))
    np.testing.assert_array_equal(open_space_beams(no_echo, open_arc), [False, False, True, True, False, False])
    circle = beam_gaps(np.arange(6) * np.pi / 3)
    np.testing.assert_array_equal(open_space_beams(no_echo, circle), [True, False, True, True, False, True])


def _probabilities_after(ranges, free_range):
    """One scan from (0, 0) heading +x, 91 beams over 90 degrees, with a 8 m sensor, into an empty grid."""
    angles = np.linspace(-np.pi / 4, np.pi / 4, ranges.size)
    geometry = GridGeometry.covering(-1.0, -9.0, 9.0, 9.0, 0.1)
    maps = ParticleMaps(geometry, 1, CellCodes.from_config(RBPFConfig()))
    maps.insert(np.zeros((1, 3)), ranges, angles, 8.0, free_range)
    return geometry, maps.probabilities(0)


@pytest.mark.parametrize("free_range", [0.0, 8.0])
def test_only_runs_of_beams_without_echo_free_cells_a_dropped_echo_frees_nothing(free_range):
    """A wall 3 m ahead with one echo dropped: nothing beyond the wall is freed, whatever ``free_range``;
    an opening where 11 beams in a row read the sensor's range is freed up to ``free_range``."""
    ranges = np.full(91, 3.0)
    ranges[20] = 8.0  # a dropped echo
    ranges[60:71] = 8.0  # an opening: the beams from 15 to 25 degrees left
    geometry, p = _probabilities_after(ranges, free_range)

    def p_at(distance, bearing):
        return p[geometry.cell_of(np.array([distance * np.cos(bearing)]), np.array([distance * np.sin(bearing)]))][0]

    dropped, opening = np.deg2rad(-25.0), np.deg2rad(20.0)
    assert p_at(1.5, dropped) < 0.5  # in front of the wall: freed by the echoes either side
    assert p_at(5.0, dropped) == 0.5  # behind the wall: never freed
    assert (p_at(5.0, opening) < 0.5) == (free_range > 0)
    assert p_at(7.5, opening) == (0.5 if free_range == 0 else p_at(5.0, opening))


def test_fig3_aligned_fusion_raises_mi_misaligned_lowers_it():
    """Fig. 3: two scans 1 m apart; fused where they were taken, the map's MI rises above either
    scan's; fused with the second one misplaced, it is lower, and the lower the larger the error."""
    world, angles, poses, scans = _scans_in_office(12)
    geometry = GridGeometry.covering(*world.bounds, 0.1)
    first, second = poses[0], poses[1]
    one = _mi_of([first], scans[:1], angles, geometry)
    other = _mi_of([second], scans[1:2], angles, geometry)
    fused = [_mi_of([first, second + error], scans[:2], angles, geometry)
             for error in (np.zeros(3), np.array([0.1, 0.0, 0.05]), np.array([0.3, -0.2, 0.15]))]
    # one pass puts a free cell at p = 0.23 (0.22 bits), two agreeing ones at 0.08 (0.60 bits): the
    # cells both scans see gain most, the rest keep their single-scan information
    assert fused[0] > 1.5 * max(one, other)
    assert fused[0] > fused[1] > fused[2]


def test_fig4_mi_is_nearly_resolution_independent_while_entropy_grows():
    world, angles, poses, scans = _scans_in_office(40)
    mi, entropy = [], []
    for resolution in (0.2, 0.1, 0.05, 0.025):
        config = RBPFConfig(resolution=resolution)
        geometry = GridGeometry.covering(*world.bounds, resolution)
        maps = ParticleMaps(geometry, 1, CellCodes.from_config(config))
        for pose, ranges in zip(poses, scans, strict=False):
            maps.insert(pose[None], ranges, angles, 8.0, 0.0)
        p = maps.probabilities(0)
        mi.append(certainty.mean_information(p))
        entropy.append(certainty.map_entropy(p))
    assert (max(mi) - min(mi)) / max(mi) < 0.10, mi
    assert all(a < b for a, b in zip(entropy, entropy[1:], strict=False)), entropy


def test_a_far_wall_seen_at_a_slant_keeps_its_cells():
    """Forty scans of a wall 3 m to the side, its cells between 8 and 30 m ahead seen at 6-36 degrees,
    ranges with 2 cm of noise. Sub-rays between two beams reach only as far as the nearer one: the
    wall keeps 77% of its cells occupied, 15% freed (sub-rays whose lengths were interpolated between
    the two ranges reached past the wall wherever the noise put it further, and freed 55%, leaving 44%
    occupied)."""
    rng = np.random.default_rng(0)
    config = RBPFConfig()
    geometry = GridGeometry.covering(-1.0, -1.0, 40.0, 4.0, 0.05)
    maps = ParticleMaps(geometry, 1, CellCodes.from_config(config))
    angles = np.radians(np.arange(5.0, 175.0, 0.5))
    wall_y = 3.001
    for k in range(40):
        pose = np.array([0.1 * k, 0.0, 0.0])
        ranges = (wall_y - pose[1]) / np.sin(angles) + rng.normal(0.0, 0.02, angles.size)
        maps.insert(pose[None], np.minimum(ranges, 30.0), angles, 30.0, 0.0)
    row, (first, last) = geometry.cell_of(0.0, wall_y)[0], geometry.cell_of(np.array([8.0, 30.0]), wall_y)[1]
    wall = maps.codes[0][row, first:last]
    assert np.mean(wall < 0) < 0.3 and np.mean(wall > 0) > 0.6, (np.mean(wall < 0), np.mean(wall > 0))


# ------------------------------------------------------------------ machinery


def random_scans(rng, maps, n_scans):
    """Insert ``n_scans`` random 60-beam scans, each at its own random pose per particle."""
    angles = np.linspace(-np.pi, np.pi, 60, endpoint=False)
    x0, x1, y0, y1 = maps.geometry.extent
    for _ in range(n_scans):
        poses = np.column_stack([rng.uniform(x0 + 1, x1 - 1, maps.n_particles),
                                 rng.uniform(y0 + 1, y1 - 1, maps.n_particles),
                                 rng.uniform(-np.pi, np.pi, maps.n_particles)])
        maps.insert(poses, rng.uniform(0.3, 2.5, 60), angles, 3.0, 0.0)


def assert_agreement_is_exact(maps):
    """The kept agreement equals one derived from scratch: same disputed cells, same agreed histogram; and
    no grid has a mean hit point where no scan ever ended."""
    assert not np.any(maps.hits[:, ~maps.ever_hit])
    same = np.all(maps.codes == maps.codes[:1], axis=0) & np.all(maps.hits == maps.hits[:1], axis=(0, 3))
    np.testing.assert_array_equal(np.sort(maps.disputed_cells), np.flatnonzero(~same))
    np.testing.assert_array_equal(maps.disputed_codes(),
                                  maps.codes.reshape(maps.n_particles, -1)[:, maps.disputed_cells].T)
    np.testing.assert_array_equal(maps.agreed_counts, np.bincount(maps.codes[0][same].astype(np.int64) + 128,
                                                                   minlength=256))


@pytest.mark.parametrize("seed", range(4))
def test_incremental_emmi_equals_a_full_recomputation(seed):
    """After random insertions, resamplings and a growth of the grids, EMMI from the agreed cells'
    histogram plus the disputed cells equals EMMI over every cell of every grid, and the expected
    map too; resampling copies exactly what np.take of whole grids would."""
    rng = np.random.default_rng(seed)
    maps = ParticleMaps(GridGeometry(0.1, 0.0, 0.0, 60, 70), 5, CellCodes.from_config(RBPFConfig()), block=2)
    lut = maps.cell_codes.probability
    for step in range(6):
        random_scans(rng, maps, 2)
        if step % 2:
            parents = survivors_in_place(rng.integers(0, 5, 5))
            before = maps.codes.copy(), maps.hits.copy(), maps.counts.copy()
            maps.resample(parents)
            np.testing.assert_array_equal(maps.codes, before[0][parents])
            np.testing.assert_array_equal(maps.hits, before[1][parents])
            np.testing.assert_array_equal(maps.counts, before[2][parents])
            assert list(maps.resample_ms) == ["order", "table", "agreement", "copies and unlisting"]
            assert all(ms >= 0.0 for ms in maps.resample_ms.values())
        if step == 3:
            maps.grow_to_contain(-0.5, -0.5, 7.5, 6.5, chunk=1.0)
        assert_agreement_is_exact(maps)
        w = rng.random(5) ** 2
        w /= w.sum()
        full = certainty.emmi(maps.codes, w, lut=lut)
        assert certainty.emmi_of_parts(maps.disputed_codes(), w, maps.agreed_counts, lut=lut) == pytest.approx(
            full, rel=1e-12, abs=1e-12)
        kept = maps.expected_map(w)
        np.testing.assert_allclose(kept, certainty.expected_map(maps.codes, w, lut=lut), rtol=0, atol=1e-12)
        whole = copy.deepcopy(maps)
        whole._forget_expected_map()
        np.testing.assert_array_equal(kept, whole.expected_map(w))  # kept up to date = made whole, bit for bit
        assert not kept.flags.writeable
        np.testing.assert_array_equal(maps.coarse, [[[int((g[r:r + 2, c:c + 2] > 0).sum())
                                                      for c in range(0, g.shape[1], 2)]
                                                     for r in range(0, g.shape[0], 2)] for g in maps.codes])
    assert 0 < maps.disputed_cells.size < maps.codes[0].size


@given(st.integers(0, 2**31), st.integers(1, 30))
def test_survivors_keep_their_slots_and_the_draw_its_copies(seed, m):
    drawn = systematic_resample(np.random.default_rng(seed).random(m) ** 4 + 1e-12, np.random.default_rng(seed))
    arranged = survivors_in_place(drawn)
    np.testing.assert_array_equal(np.sort(arranged), np.sort(drawn))   # as many copies of each parent
    survivors = np.unique(drawn)
    np.testing.assert_array_equal(arranged[survivors], survivors)      # every survivor in its own slot
    assert np.array_equal(arranged[arranged], arranged)


def test_resampling_refuses_parents_that_would_overwrite_a_source():
    maps = ParticleMaps(GridGeometry(0.1, 0.0, 0.0, 10, 10), 3, CellCodes.from_config(RBPFConfig()))
    with pytest.raises(ValueError, match="keep every survivor in its own slot"):
        maps.resample(np.array([1, 0, 0]))  # particle 1's grid is read after slot 1 was overwritten
    with pytest.raises(ValueError, match="3 particle indices"):
        maps.resample(np.array([0, 3, 0]))


def test_resampling_with_nothing_disputed_leaves_maps_and_agreement_as_they_were():
    """Every grid the same (one scan at one pose for all): no span to copy, nothing to re-derive."""
    maps = ParticleMaps(GridGeometry(0.1, 0.0, 0.0, 40, 40), 3, CellCodes.from_config(RBPFConfig()), block=2)
    angles = np.linspace(-np.pi, np.pi, 60, endpoint=False)
    maps.insert(np.tile([2.0, 2.0, 0.3], (3, 1)), np.random.default_rng(0).uniform(0.3, 1.5, 60), angles, 3.0, 0.0)
    before = copy.deepcopy(maps)
    assert maps.disputed_cells.size == 0 and maps.codes.any()
    maps.resample(np.array([0, 0, 2]))
    for name in ("codes", "hits", "coarse", "counts", "status", "agreed_counts"):
        np.testing.assert_array_equal(getattr(maps, name), getattr(before, name))
    assert maps.disputed_cells.size == 0
    assert_agreement_is_exact(maps)


def test_grids_grow_in_chunks_and_keep_cells_aligned():
    maps = ParticleMaps(GridGeometry(0.1, 0.0, 0.0, 10, 10), 2, CellCodes.from_config(RBPFConfig()))
    maps.codes[1, 3, 4] = 7
    maps.counts[1, 128], maps.counts[1, 7 + 128] = 99, 1
    assert maps.grow_to_contain(-0.5, 0.2, 1.5, 0.8, chunk=1.0)
    assert maps.counts[1, 128] == 299 and maps.counts[1].sum() == 300
    g = maps.geometry
    assert (g.origin_x, g.origin_y) == (-1.0, 0.0) and g.cols == 30 and g.rows == 10
    row, col = g.cell_of(0.45, 0.35)
    assert maps.codes[1, row, col] == 7
    assert not maps.grow_to_contain(-0.5, 0.2, 1.5, 0.8, chunk=1.0)


def test_update_policy_waits_for_motion():
    slam = RBPF(RBPFConfig(particles=3, linear_update=0.5, angular_update=0.3), max_range=8.0,
                geometry=GridGeometry(0.1, -5, -5, 100, 100))
    slam.reset([0, 0, 0], np.random.default_rng(0))
    angles = np.linspace(-np.pi, np.pi, 90, endpoint=False)
    ranges = np.full(90, 3.0)
    assert slam.process([0, 0, 0], ranges, angles) is not None  # the first scan initialises
    assert not slam.update_due([0.3, 0, 0]) and slam.update_due([0.55, 0, 0]) and slam.update_due([0, 0, -0.35])
    assert slam.process([0.3, 0, 0], ranges, angles) is None
    assert slam.process([0.3, 0, 0.2], ranges, angles) is None
    assert slam.process([0.55, 0, 0.2], ranges, angles) is not None
    assert slam.process([0.55, 0, 0.55], ranges, angles) is not None  # turned 0.35 rad


def test_measuring_later_gives_the_metrics_of_the_last_update():
    """process(measure=False) leaves the certainty to measure(): the same figures, once per update."""
    filters = []
    for _ in range(2):
        slam = RBPF(RBPFConfig(particles=4), max_range=8.0, geometry=GridGeometry(0.1, -5, -5, 100, 100))
        slam.reset([0, 0, 0], np.random.default_rng(7))
        filters.append(slam)
    eager, lazy = filters
    with pytest.raises(RuntimeError, match="process"):
        lazy.measure()
    angles = np.linspace(-np.pi, np.pi, 90, endpoint=False)
    ranges = 3.0 + 0.5 * np.cos(3 * angles)
    for x in (0.0, 0.6, 1.2):
        now = eager.process([x, 0, 0], ranges, angles)
        assert lazy.process([x, 0, 0], ranges, angles, measure=False) is None
        later = lazy.measure()
        assert later is lazy.measure()  # computed once
        assert now.measures() == later.measures() and now.step == lazy.step - 1


def test_bad_input_is_named():
    slam = RBPF(RBPFConfig(particles=2), max_range=8.0)
    with pytest.raises(RuntimeError, match="reset"):
        slam.process([0, 0, 0], [1.0], [0.0])
    slam.reset([0, 0, 0], np.random.default_rng(0))
    with pytest.raises(ValueError, match="3 ranges but 2 beam angles"):
        slam.process([0, 0, 0], [1.0, 2.0, 3.0], [0.0, 1.0])
    for bad in (dict(particles=0), dict(resolution=-0.1), dict(logodds_free=0.2), dict(likelihood_exponent=0),
                dict(motion_noise=(1, 2)), dict(resample_threshold=2), dict(logodds_clamp=100),
                dict(match_radius=0), dict(coarse_trigger=1.5), dict(insertion_range=-1.0)):
        with pytest.raises(ValueError, match="RBPF|logodds_clamp"):
            RBPFConfig(**bad)


def test_ate_alignment_and_registered_map_accuracy():
    """A trajectory rotated and shifted as a whole has zero aligned ATE; a map registered by
    the same transform is scored as if it had been built in the truth's frame."""
    rng = np.random.default_rng(0)
    truth = np.column_stack([rng.uniform(0, 5, 50), rng.uniform(0, 5, 50), np.zeros(50)])
    angle, shift = 0.1, np.array([0.4, -0.2])
    rot = np.array([[np.cos(angle), -np.sin(angle)], [np.sin(angle), np.cos(angle)]])
    moved = truth.copy()
    moved[:, :2] = truth[:, :2] @ rot.T + shift
    assert absolute_trajectory_error(moved, truth) == pytest.approx(0.0, abs=1e-9)
    assert absolute_trajectory_error(moved, truth, align=False) > 0.2
    r, t = trajectory_alignment(moved, truth)
    np.testing.assert_allclose(r, rot.T, atol=1e-9)
    geometry = GridGeometry(0.1, -2.0, -2.0, 60, 60)
    labels = np.full(geometry.shape, -1)
    labels[20:40, 20:40] = 0
    labels[20:40, 20] = 1
    probabilities = np.where(labels == 1, 0.9, np.where(labels == 0, 0.1, 0.5))
    assert map_accuracy(probabilities, labels) == 1.0
    identity = (np.eye(2), np.zeros(2))
    assert map_accuracy(probabilities, labels, geometry=geometry, transform=identity) == 1.0
    shifted = (np.eye(2), np.array([0.3, 0.0]))  # the truth seen 3 cells off: the wall is missed
    assert map_accuracy(probabilities, labels, geometry=geometry, transform=shifted) < 0.97


def test_the_loop_closes_when_a_scan_sees_the_first_leg_again_not_when_the_robot_is_near():
    """``loop_closure_update``: a forward-looking 180-degree laser closes the loop only once what it
    mapped at the start lies ahead within range; standing near the start looking away does not."""
    geometry = GridGeometry.covering(-10.0, -10.0, 10.0, 10.0, 0.1)
    angles = np.linspace(-np.pi / 2, np.pi / 2, 181)

    def scan_of_walls(pose):
        """Ranges to the walls of a 10 m square room centred on the origin (no echo beyond 8 m)."""
        x, y, theta = pose
        a = theta + angles
        with np.errstate(divide="ignore"):
            tx = np.where(np.cos(a) > 0, (5.0 - x) / np.cos(a), (-5.0 - x) / np.cos(a))
            ty = np.where(np.sin(a) > 0, (5.0 - y) / np.sin(a), (-5.0 - y) / np.sin(a))
        return np.minimum(np.minimum(np.abs(tx), np.abs(ty)), 8.0)

    poses = np.array([[2.0, 0.0, 0.0],        # first leg: facing the east wall
                      [-2.0, 0.0, np.pi],     # the west wall
                      [2.0, 0.5, np.pi],      # back near the start, looking away: not closed
                      [0.0, 0.0, 0.0]])       # facing the east wall again: closed
    scans = [scan_of_walls(p) for p in poses]
    assert all(np.count_nonzero(r < 8.0) > 100 for r in scans)
    assert loop_closure_update(poses, scans, angles, 8.0, geometry, first_leg=1, search_from=1) == 3
    assert loop_closure_update(poses[:3], scans[:3], angles, 8.0, geometry, first_leg=1, search_from=1) is None


def test_a_place_counts_as_revisited_only_after_a_gap_and_stays_so():
    """``RevisitGrid``: blocks seen update after update are not revisited; seen again after ``gap`` updates
    they are, from then on; growing the maps keeps every stamp where it was in the world."""
    geometry = GridGeometry.covering(0.0, 0.0, 10.0, 10.0, 0.1)
    grid = RevisitGrid(geometry, block=2, reach=0.0)
    angles = np.array([0.0, np.pi / 2])
    wall = np.array([3.0, 8.0])  # from (5, 1): an echo at (8, 1), none up the y axis (8 m = max range)
    pose = np.array([5.0, 1.0, 0.0])
    for update in (1, 2, 3):
        assert not grid.revisited(pose, wall, angles, 8.0, update, gap=3).any()
        grid.stamp(pose, wall, angles, 8.0, update, gap=3)
    assert not grid.revisited(pose, wall, angles, 8.0, 5, gap=3).any()  # last seen 2 updates ago
    np.testing.assert_array_equal(grid.revisited(pose, wall, angles, 8.0, 6, gap=3), [True, False])
    grid.stamp(pose, wall, angles, 8.0, 6, gap=3)
    assert grid.revisited(pose, wall, angles, 8.0, 7, gap=3)[0]  # seen again: revisited from then on
    grown = GridGeometry(0.1, -2.0, -4.0, geometry.rows + 60, geometry.cols + 40)
    grid.follow(grown)
    assert grid.revisited(pose, wall, angles, 8.0, 7, gap=3)[0]
    assert not grid.revisited(pose + [0.0, 5.0, 0.0], wall, angles, 8.0, 7, gap=3).any()  # (8, 6): never seen


def test_places_seen_again_count_at_most_revisit_beams_beams():
    """``revisit_beams``: up to that many beams seeing a place again keep ``revisit_exponent``; more share
    that many beams' worth (never below ``likelihood_exponent``); without a bound the exponent stays."""
    config = RBPFConfig(revisit_exponent=0.05, likelihood_exponent=0.004, revisit_beams=30)
    assert revisit_exponent(config, 0) == revisit_exponent(config, 30) == 0.05
    assert revisit_exponent(config, 75) == pytest.approx(0.02)
    assert 75 * revisit_exponent(config, 75) == pytest.approx(30 * 0.05)
    assert revisit_exponent(config, 1000) == 0.004
    assert revisit_exponent(RBPFConfig(revisit_exponent=0.05), 1000) == 0.05
