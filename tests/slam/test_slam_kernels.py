"""Each RBPF kernel against a plain-Python twin on small random cases."""

import math

import numba as nb
import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from emmi_gym.certainty import _kernels as certainty_kernels
from emmi_gym.slam import RBPFConfig
from emmi_gym.slam import _kernels as K
from emmi_gym.slam import _matching as MT
from emmi_gym.slam._memory import copy_rows, prefetch_row
from emmi_gym.slam.occupancy import beam_gaps
from emmi_gym.slam.resampling import systematic_resample

RES = 0.1


def crossed_cells(x0, y0, x1, y1):
    """Cells (row, col) whose interior the segment crosses: brute force over the bounding box.

    An independent way to get the exact traversal (Liang-Barsky clipping per cell),
    in the order of the distance at which the segment enters each cell.
    """
    cells = []
    for col in range(int(math.floor(min(x0, x1))), int(math.floor(max(x0, x1))) + 1):
        for row in range(int(math.floor(min(y0, y1))), int(math.floor(max(y0, y1))) + 1):
            t0, t1 = 0.0, 1.0
            ok = True
            for p, q in ((-(x1 - x0), x0 - col), (x1 - x0, col + 1 - x0), (-(y1 - y0), y0 - row),
                         (y1 - y0, row + 1 - y0)):
                if p == 0:
                    ok &= q > 0
                elif p < 0:
                    t0 = max(t0, q / p)
                else:
                    t1 = min(t1, q / p)
            if ok and t0 < t1:
                cells.append((t0, row, col))
    return [(r, c) for _, r, c in sorted(cells)]


def twin_rays(ranges, angles, gaps, max_range, free_range):
    """(angle, length, kind) of every insertion ray: each beam and the sub-rays across its gap, as long
    as the nearer of the two beams, all from the laser (the kernel starts its sub-rays later, and must
    free the same cells)."""
    n = len(ranges)
    lengths = [r if 0 < r < max_range else (free_range if r > 0 else 0.0) for r in ranges]
    rays = []
    for b in range(n):
        nxt = (b + 1) % n
        count = 1
        if gaps[b] > 0:
            count = min(16, max(1, math.ceil(max(lengths[b], lengths[nxt]) * gaps[b] / RES)))
        for j in range(count):
            if j == 0:
                rays.append((angles[b], lengths[b], K.RAY_HIT if 0 < ranges[b] < max_range else K.RAY_FREE))
            else:
                rays.append((angles[b] + j / count * gaps[b], min(lengths[b], lengths[nxt]), K.RAY_BOUNDED))
    return rays


def twin_insert(codes, poses, rays, inc_occ, inc_free, clamp):
    """Per particle and scan: hit end-point cells +inc_occ once; other crossed cells inc_free once."""
    codes = codes.astype(np.int64).copy()
    m, h, w = codes.shape
    for i in range(m):
        x, y, th = poses[i]
        gx0, gy0 = x / RES, y / RES
        hit_cells, free_cells = set(), set()
        for a, length, kind in rays:
            if kind == K.RAY_HIT:
                hit_cells.add((int(math.floor(gy0 + length * math.sin(th + a) / RES)),
                               int(math.floor(gx0 + length * math.cos(th + a) / RES))))
        for a, length, kind in rays:
            if length <= 0:
                continue
            ex, ey = gx0 + length * math.cos(th + a) / RES, gy0 + length * math.sin(th + a) / RES
            path = crossed_cells(gx0, gy0, ex, ey)
            if kind != K.RAY_FREE:
                path = [c for c in path if c != (int(math.floor(ey)), int(math.floor(ex)))]
            for row, col in path:
                if not (0 <= row < h and 0 <= col < w):
                    break
                free_cells.add((row, col))
        for row, col in hit_cells:
            if 0 <= row < h and 0 <= col < w:
                codes[i, row, col] = np.clip(codes[i, row, col] + inc_occ, -clamp, clamp)
        for row, col in free_cells - hit_cells:
            codes[i, row, col] = np.clip(codes[i, row, col] + inc_free, -clamp, clamp)
    return codes


@given(st.integers(0, 2**31), st.integers(1, 3), st.integers(3, 25), st.booleans(), st.booleans())
def test_insert_scans_matches_twin(seed, m, n_beams, with_max_range, full_circle):
    rng = np.random.default_rng(seed)
    h, w = 30, 40
    codes = rng.integers(-60, 60, size=(m, h, w)).astype(np.int8)
    codes[rng.random((m, h, w)) < 0.5] = -100  # free at the clamp: a crossing leaves them as they are
    codes[:, rng.random((h, w)) < 0.3] = -100  # ... in every grid
    poses = np.column_stack([rng.uniform(0.5, 3.5, m), rng.uniform(0.5, 2.5, m), rng.uniform(-np.pi, np.pi, m)])
    ranges = rng.uniform(0.05, 2.0, n_beams)
    if with_max_range:
        ranges[rng.random(n_beams) < 0.3] = 2.0
    span = 2 * np.pi if full_circle else rng.uniform(0.5, 3.0)
    angles = -span / 2 + np.arange(n_beams) * span / (n_beams if full_circle else n_beams - 1)
    gaps = beam_gaps(angles)
    assert (gaps[-1] > 0) == full_circle
    rays = K.scan_rays(ranges, angles, gaps, 2.0, np.full(n_beams, 0.7), RES)
    want_rays = twin_rays(ranges, angles, gaps, 2.0, 0.7)
    np.testing.assert_allclose(np.column_stack(rays[:3]), np.array(want_rays), atol=1e-12)
    starts, beams = rays[3], rays[2] != K.RAY_BOUNDED
    assert np.all(starts[beams] == 0.0) and np.all(starts >= 0.0)
    expected = twin_insert(codes, poses, want_rays, 17, -8, 100)
    got = codes.copy()
    hits = np.zeros((m, h, w, 3), dtype=np.int8)
    stamp = np.zeros((h, w), dtype=np.int64)
    counts = np.array([np.bincount(c.ravel().astype(np.int64) + 128, minlength=256) for c in codes])
    block = 4
    coarse = np.array([occupied_per_block(c, block) for c in codes])
    touched = np.empty(h * w, dtype=np.int32)
    split = m // 2  # two chunks, as on two threads (each its own stamp and list), then merged
    ever_hit = np.zeros((h, w), dtype=np.bool_)
    serial, n_touched = K.insert_scans(0, split, got, hits, ever_hit, counts, coarse, block, poses, *rays, 17, -8,
                                       100, 0.0, 0.0, RES, stamp, 0, touched)
    other, other_stamp = np.empty(h * w, dtype=np.int32), np.zeros((h, w), dtype=np.int64)
    other_serial, n_other = K.insert_scans(split, m, got, hits, ever_hit, counts, coarse, block, poses, *rays, 17,
                                           -8, 100, 0.0, 0.0, RES, other_stamp, 0, other)
    np.testing.assert_array_equal(ever_hit, np.any(hits[..., 2] > 0, axis=0))  # flagged: where an end point fell
    assert serial == 3 * split and other_serial == 3 * (m - split)
    n_touched = K.merge_touched(touched, n_touched, stamp, 0, other, n_other)
    changed = np.flatnonzero(np.any(got != codes, axis=0) | np.any(hits[..., 2] > 0, axis=0))
    assert len(set(touched[:n_touched])) == n_touched  # each cell once
    assert set(touched[:n_touched]) == set(changed)  # the cells whose code or mean hit point changed, only
    np.testing.assert_array_equal(got, expected)
    np.testing.assert_array_equal(counts, [np.bincount(c.ravel() + 128, minlength=256) for c in expected])
    np.testing.assert_array_equal(coarse, [occupied_per_block(c, block) for c in expected])


@pytest.mark.parametrize("resolution", [0.025, 0.05, 0.1])
def test_sub_rays_started_late_free_what_sub_rays_from_the_laser_free(resolution):
    """A 361-beam scan to 30 m, as the radish logs' (a ragged room, gaps and far walls): the kernel's
    sub-rays, started where they are needed, leave every grid as sub-rays run from the laser."""
    rng = np.random.default_rng(7)
    n = 361
    angles = np.linspace(-np.pi / 2, np.pi / 2, n)
    ranges = np.clip(np.repeat(rng.uniform(1.0, 30.0, n // 10 + 1), 10)[:n] + rng.normal(0.0, 0.3, n), 0.3, 30.0)
    ranges[rng.random(n) < 0.05] = 30.0  # no echo
    rays = K.scan_rays(ranges, angles, beam_gaps(angles), 30.0, np.full(n, 0.0), resolution)
    sub_rays = rays[2] == K.RAY_BOUNDED
    assert np.count_nonzero(rays[3][sub_rays] > 0.0) > 0.5 * np.count_nonzero(sub_rays)  # most start late
    side = int(round(64.0 / resolution))
    m = 3
    poses = np.column_stack([32.0 + rng.uniform(-0.5, 0.5, m), 32.0 + rng.uniform(-0.5, 0.5, m),
                             rng.uniform(-np.pi, np.pi, m)])
    grids = []
    for starts in (rays[3], np.zeros_like(rays[3])):
        codes = np.zeros((m, side, side), dtype=np.int8)
        counts = np.zeros((m, 256), dtype=np.int64)
        counts[:, 128] = side * side
        K.insert_scans(0, m, codes, np.zeros((m, side, side, 3), dtype=np.int8), np.zeros((side, side), bool), counts,
                       np.zeros((m, side // 4, side // 4), dtype=np.int32), 4, poses, *rays[:3], starts, 17, -8, 100,
                       0.0, 0.0, resolution, np.zeros((side, side), dtype=np.int64), 0,
                       np.empty(side * side, dtype=np.int32))
        grids.append(codes)
    assert np.count_nonzero(grids[1] < 0) > 100_000  # the scans freed a large area
    np.testing.assert_array_equal(grids[0], grids[1])


def test_a_laser_off_the_grid_frees_nothing_however_its_sub_rays_start():
    """A pose outside the grid, its scan reaching in: the end points inside are hit, and no cell is freed
    (the rays leave from outside the grid), with sub-rays started late or from the laser."""
    angles = np.linspace(-0.3, 0.3, 7)
    ranges = np.full(7, 3.0)
    rays = K.scan_rays(ranges, angles, beam_gaps(angles), 8.0, np.zeros(7), RES)
    assert np.any(rays[3] > 1.0)  # some sub-rays start inside the grid (its edge is 1 m ahead)
    for starts in (rays[3], np.zeros_like(rays[3])):
        codes = np.zeros((1, 40, 40), dtype=np.int8)
        counts = np.zeros((1, 256), dtype=np.int64)
        counts[0, 128] = 1600
        K.insert_scans(0, 1, codes, np.zeros((1, 40, 40, 3), dtype=np.int8), np.zeros((40, 40), bool), counts,
                       np.zeros((1, 10, 10), dtype=np.int32), 4, np.array([[-1.0, 2.0, 0.0]]), *rays[:3], starts,
                       17, -8, 100, 0.0, 0.0, RES, np.zeros((40, 40), dtype=np.int64), 0,
                       np.empty(1600, dtype=np.int32))
        assert np.count_nonzero(codes > 0) == 7 and not np.any(codes < 0)


def occupied_per_block(grid, block):
    """How many cells of each block x block block are occupied (code > 0), blocks cut at the edges."""
    h, w = grid.shape
    out = np.zeros((-(-h // block), -(-w // block)), dtype=np.int32)
    for row, col in zip(*np.nonzero(grid > 0), strict=False):
        out[row // block, col // block] += 1
    return out


def test_hit_means_follow_the_end_points():
    """One cell hit repeatedly: its stored mean is the mean of the end points (to 1/254 of a cell)."""
    codes = np.zeros((1, 10, 10), dtype=np.int8)
    hits = np.zeros((1, 10, 10, 3), dtype=np.int8)
    stamp = np.zeros((10, 10), dtype=np.int64)
    ends = [(0.52, 0.57), (0.58, 0.51), (0.55, 0.59)]
    serial = 0
    for ex, ey in ends:
        r = math.hypot(ex - 0.05, ey - 0.05)
        a = math.atan2(ey - 0.05, ex - 0.05)
        counts = np.zeros((1, 256), dtype=np.int64)
        counts[0, 128] = 100
        serial, _ = K.insert_scans(0, 1, codes, hits, np.zeros((10, 10), bool), counts,
                                   np.zeros((1, 10, 10), dtype=np.int32), 1,
                                   np.array([[0.05, 0.05, 0.0]]), np.array([a]), np.array([r]),
                                   np.array([K.RAY_HIT]), np.zeros(1), 17, -8, 100, 0.0, 0.0, RES, stamp, serial,
                                   np.empty(100, dtype=np.int32))
    stored = hits[0, 5, 5]
    assert stored[2] == 3
    offset_from_centre = np.mean(ends, axis=0) / RES - 5.5  # in cells, from the centre of cell (5, 5)
    np.testing.assert_allclose(stored[:2] / 254, offset_from_centre, atol=1 / 254 + 1e-9)


def twin_loglik(grid, hits, x, y, theta, ranges, angles, max_range, radius, sigma, null_distance=0.2):
    """Brute force: every cell within the window; a beam with nothing within ``radius`` costs as if
    it were ``null_distance`` off."""
    h, w = grid.shape
    window = math.ceil(radius / RES)
    cap2 = (radius / RES) ** 2
    null2 = (max(null_distance, radius) / RES) ** 2
    scale = RES * RES / (2 * sigma * sigma)
    total, matched = 0.0, 0
    for r, a in zip(ranges, angles, strict=False):
        if not 0 < r < max_range:
            continue
        c, s = math.cos(theta + a), math.sin(theta + a)
        hx, hy = (x + r * c) / RES, (y + r * s) / RES
        sx, sy = -int(np.sign(c)), -int(np.sign(s))  # the laser's side
        hcx, hcy = math.floor(hx), math.floor(hy)
        best = math.inf
        if window + 1 <= hcx < w - window - 1 and window + 1 <= hcy < h - window - 1:
            for row in range(hcy - window, hcy + window + 1):
                for col in range(hcx - window, hcx + window + 1):
                    if grid[row, col] > 0 and (grid[row, col + sx] < 0 or grid[row + sy, col] < 0):
                        mx = col + 0.5 + hits[row, col, 0] / 254
                        my = row + 0.5 + hits[row, col, 1] / 254
                        best = min(best, (mx - hx) ** 2 + (my - hy) ** 2)
        matched += best < cap2
        total -= (best if best < cap2 else null2) * scale
    return total, matched


def random_map(rng, h=40, w=40):
    grid = rng.choice(np.array([-50, 0, 40], dtype=np.int8), size=(h, w), p=[0.5, 0.2, 0.3])
    hits = rng.integers(-127, 128, size=(h, w, 3)).astype(np.int8)
    return grid, hits


def settings(radius=0.15, sigma=0.075, exponent=0.5, min_matched=0.0, trigger=0.0, block=2, revisit_exponent=0.8):
    config = RBPFConfig(resolution=RES, match_radius=radius, likelihood_sigma=sigma, likelihood_exponent=exponent,
                        min_match_fraction=min_matched, coarse_trigger=trigger, match_max_iterations=30,
                        revisit_exponent=revisit_exponent)
    return MT.match_settings(config, 0.0, 0.0, RES, block)


@given(st.integers(0, 2**31), st.sampled_from([0.05, 0.1, 0.15, 0.32]))
def test_scan_loglik_matches_twin(seed, radius):
    """The ring search with early exit finds what a search of the whole window finds."""
    rng = np.random.default_rng(seed)
    grid, hits = random_map(rng)
    grid[rng.random(grid.shape) < 0.6] = -50  # sparser surfaces: the rings go further out
    x, y, theta = rng.uniform(1.2, 2.8), rng.uniform(1.2, 2.8), rng.uniform(-np.pi, np.pi)
    ranges = rng.uniform(0.1, 2.5, 30)
    ranges[::7] = 3.0  # max range: skipped
    angles = np.linspace(-np.pi, np.pi, 30, endpoint=False)
    offsets = np.empty((30, 4))
    n = MT.beam_offsets(theta, ranges, angles, 3.0, RES, offsets)
    s = settings(radius)
    got = MT.scan_loglik(grid, hits, x / RES, y / RES, offsets, n, s, -np.inf)
    want = twin_loglik(grid, hits, x, y, theta, ranges, angles, 3.0, radius, 0.075)
    assert got[1] == want[1]
    assert got[0] == pytest.approx(want[0], rel=1e-9, abs=1e-9)
    # with a floor below the value the whole scan is scored; at or above it the search may stop
    assert MT.scan_loglik(grid, hits, x / RES, y / RES, offsets, n, s, want[0] - 1.0) == got
    cut, flag = MT.scan_loglik(grid, hits, x / RES, y / RES, offsets, n, s, want[0] + 1.0)
    assert cut <= want[0] + 1.0 and flag == -1


@given(st.integers(0, 2**31), st.sampled_from([0.05, 0.1, 0.15, 0.32]), st.sampled_from([0.5, 1.0, 1.5]))
def test_shifted_logliks_are_scan_logliks_bit_for_bit(seed, radius, shift):
    """The stencil's four moves in x and y read each beam's cells once (``_shifted_logliks``): the same
    numbers as four calls of ``scan_loglik``, end points near the grid's edge included."""
    rng = np.random.default_rng(seed)
    grid, hits = random_map(rng)
    grid[rng.random(grid.shape) < 0.5] = -50
    x, y, theta = rng.uniform(0.3, 3.7), rng.uniform(0.3, 3.7), rng.uniform(-np.pi, np.pi)
    ranges = rng.uniform(0.1, 2.5, 30)
    angles = np.linspace(-np.pi, np.pi, 30, endpoint=False)
    offsets = np.empty((30, 4))
    n = MT.beam_offsets(theta, ranges, angles, 3.0, RES, offsets)
    s = settings(radius)
    gxs = x / RES + np.array([-shift, shift, 0.0, 0.0])
    gys = y / RES + np.array([0.0, 0.0, -shift, shift])
    got, matched = np.empty(4), np.empty(4, dtype=np.int64)
    MT._shifted_logliks(grid, hits, gxs, gys, offsets, n, s, got, matched)
    want = [MT.scan_loglik(grid, hits, gxs[k], gys[k], offsets, n, s, -np.inf) for k in range(4)]
    assert got.tolist() == [value for value, _ in want]
    assert matched.tolist() == [count for _, count in want]


def twin_hill_climb(grid, hits, start, ranges, angles, mean, precision, lstep, astep, refinements, iterations):
    def value(p):
        ll, n = twin_loglik(grid, hits, p[0], p[1], p[2], ranges, angles, 3.0, 0.15, 0.075)
        d = p - mean
        d[2] = (d[2] + math.pi) % (2 * math.pi) - math.pi
        return ll - 0.5 * d @ precision @ d, n

    pose = start.copy()
    best, matched = value(pose)
    refinement = 0
    for _ in range(iterations):
        best_pose = None
        for move in range(6):
            cand = pose.copy()
            cand[move // 2] += (1 if move % 2 == 0 else -1) * (astep if move // 2 == 2 else lstep)
            v, n = value(cand)
            if v > best:
                best, matched, best_pose = v, n, cand
        if best_pose is not None:
            pose = best_pose
        else:
            refinement += 1
            if refinement > refinements:
                break
            lstep, astep = lstep / 2, astep / 2
    return pose, best, matched


@given(st.integers(0, 2**31))
def test_hill_climb_matches_twin(seed):
    rng = np.random.default_rng(seed)
    grid, hits = random_map(rng)
    start = np.array([rng.uniform(1.5, 2.5), rng.uniform(1.5, 2.5), rng.uniform(-3, 3)])
    mean = start + rng.normal(0, 0.05, 3)
    precision = np.diag([400.0, 400.0, 1000.0])
    ranges = rng.uniform(0.3, 1.2, 24)
    angles = np.linspace(-np.pi, np.pi, 24, endpoint=False)
    got = MT.hill_climb(grid, hits, start, ranges, angles, 3.0, settings(), mean, precision)
    want = twin_hill_climb(grid, hits, start, ranges, angles, mean, precision, 0.05, 0.05, 3, 30)
    np.testing.assert_allclose(got[0], want[0], atol=1e-9)
    assert got[1] == pytest.approx(want[1], abs=1e-6)
    assert got[2] == want[2]


def test_improved_proposal_matches_twin():
    """The Gaussian fitted on the 7-point stencil around the match, the draw and the weight."""
    rng = np.random.default_rng(4)
    grid, hits = random_map(rng)
    codes, all_hits = grid[None].copy(), hits[None].copy()
    coarse = occupied_per_block(grid, 2)[None]
    sample = np.array([[2.0, 2.1, 0.3]])
    mean = sample + 0.02
    precision = np.diag([400.0, 400.0, 1000.0])[None]
    lognorm = np.array([1.5])
    normals = rng.standard_normal((1, 3))
    ranges = rng.uniform(0.3, 1.2, 24)
    angles = np.linspace(-np.pi, np.pi, 24, endpoint=False)
    new, inc, flags = np.empty((1, 3)), np.empty(1), np.zeros(1, dtype=np.bool_)
    MT.improved_proposal(0, 1, codes, all_hits, coarse, sample, mean, precision, lognorm, normals, ranges, angles,
                         ranges, angles, ranges, False, 3.0, settings(), new, inc, flags)
    best, _, _ = twin_hill_climb(grid, hits, sample[0], ranges, angles, mean[0], precision[0], 0.05, 0.05, 3, 30)
    stencil = np.zeros((7, 3))
    for axis, step in enumerate((0.05, 0.05, 0.05)):
        stencil[1 + 2 * axis, axis], stencil[2 + 2 * axis, axis] = -step, step
    def stencil_scores(beams):
        """log target + log normaliser of the motion prior at each stencil pose, on ``beams``."""
        scores = []
        for off in stencil:
            p = best + off
            ll, _ = twin_loglik(grid, hits, *p, beams, angles, 3.0, 0.15, 0.075)
            d = p - mean[0]
            scores.append(ll - 0.5 * d @ precision[0] @ d + lognorm[0])
        return np.array(scores)

    scores = stencil_scores(ranges)
    weights = np.exp(scores - scores.max())
    mu = weights @ stencil / weights.sum()
    cov = (weights[:, None, None] * np.einsum("ki,kj->kij", stencil - mu, stencil - mu)).sum(0) / weights.sum()
    cov += np.diag([1e-6, 1e-6, 1e-7])
    draw = mu + np.linalg.cholesky(cov) @ normals[0]
    assert flags[0]
    np.testing.assert_allclose(new[0], best + draw, atol=1e-9)
    eta = scores.max() + math.log(weights.sum()) + math.log(0.05**3)
    assert inc[0] == pytest.approx(0.5 * eta, rel=1e-9)

    # beams that see a place again (revisit_gap): the same proposal; the normaliser of those beams
    # only added with the extra exponent (revisit_exponent 0.8 - likelihood_exponent 0.5)
    weighted = ranges.copy()
    weighted[::3] = 3.0  # no echo: left out of the weight
    new2, inc2 = np.empty((1, 3)), np.empty(1)
    MT.improved_proposal(0, 1, codes, all_hits, coarse, sample, mean, precision, lognorm, normals, ranges, angles,
                         ranges, angles, weighted, True, 3.0, settings(), new2, inc2, flags)
    np.testing.assert_array_equal(new2, new)
    subset = stencil_scores(weighted)
    eta_subset = subset.max() + math.log(np.exp(subset - subset.max()).sum()) + math.log(0.05**3)
    assert inc2[0] == pytest.approx(0.5 * eta + 0.3 * eta_subset, rel=1e-9)


@given(st.integers(0, 2**31), st.integers(1, 40))
def test_systematic_resampling_matches_twin(seed, m):
    rng = np.random.default_rng(seed)
    w = rng.random(m) ** 3
    w /= w.sum()
    got = systematic_resample(w, np.random.default_rng(seed))
    u = np.random.default_rng(seed).random()
    cumulative, i, want = np.cumsum(w), 0, []
    for k in range(m):
        pointer = (u + k) / m
        while i < m - 1 and cumulative[i] <= pointer:
            i += 1
        want.append(i)
    np.testing.assert_array_equal(got, want)
    counts = np.bincount(got, minlength=m)
    assert np.all(counts >= np.floor(m * w) - 1e-9) and np.all(counts <= np.ceil(m * w) + 1e-9)


@given(st.integers(0, 2**31), st.integers(0, 50))
def test_code_histogram_matches_bincount(seed, n):
    codes = np.random.default_rng(seed).integers(-128, 128, n).astype(np.int8)
    np.testing.assert_array_equal(certainty_kernels.code_histogram(codes, 256, 128),
                                  np.bincount(codes.astype(np.int64) + 128, minlength=256))


@given(st.lists(st.integers(0, 2**31 - 1), max_size=300, unique=True), st.integers(0, 3))
def test_sorted_cells_is_a_sort(values, scale):
    """The radix sort of the resampling's cells: the same as np.sort, whatever the largest index."""
    cells = (np.array(values, dtype=np.int64) >> (8 * scale)).astype(np.int32)
    np.testing.assert_array_equal(K.sorted_cells(cells), np.sort(cells))


@given(st.lists(st.integers(0, 40 * 37 - 1), max_size=400, unique=True), st.integers(1, 70), st.integers(1, 5))
def test_copy_spans_cover_the_cells_row_by_row_and_the_blocks_they_reach(values, max_gap, block):
    """Every cell in one span, every span within a row from a listed cell to a listed cell, spans of a
    row joined exactly when at most ``max_gap`` apart, and each span's blocks those of its cells."""
    width, cells = 37, np.sort(np.array(values, dtype=np.int32))
    spans = K.copy_spans(cells, width, block, max_gap)
    covered = np.concatenate([np.arange(a, b) for a, b in spans[:, :2]] or [np.empty(0, dtype=np.int64)])
    np.testing.assert_array_equal(np.intersect1d(covered, cells), cells)  # each cell, in one span only:
    assert covered.size == np.unique(covered).size
    assert np.all(np.isin(spans[:, 0], cells)) and np.all(np.isin(spans[:, 1] - 1, cells))
    assert np.all(spans[:, 0] // width == (spans[:, 1] - 1) // width)
    for (a0, b0, *_), (a1, *_) in zip(spans[:-1], spans[1:], strict=False):
        assert a1 // width != a0 // width or a1 - b0 + 1 > max_gap
    for s, inside in enumerate(spans[:, :2]):
        assert np.all(np.diff(cells[(cells >= inside[0]) & (cells < inside[1])]) <= max_gap)
        rows, cols = np.divmod(np.arange(*inside), width)
        blocks = np.unique(rows // block * -(-width // block) + cols // block)
        np.testing.assert_array_equal(np.arange(spans[s, 2], spans[s, 3]), blocks)


def test_copy_rows_copies_whole_rows_start_to_stop_and_nothing_else():
    @nb.njit
    def copy(target, source, start, stop):
        copy_rows(target, source, start, stop)

    rng = np.random.default_rng(0)
    for shape, dtype in (((50,), np.int8), ((50, 3), np.int8), ((50, 2, 2), np.int32)):
        source = rng.integers(-100, 100, shape).astype(dtype)
        for start, stop in ((0, 50), (7, 19), (20, 20), (49, 50)):
            target = np.zeros_like(source)
            copy(target, source, start, stop)
            expected = np.zeros_like(source)
            expected[start:stop] = source[start:stop]
            np.testing.assert_array_equal(target, expected)


def test_prefetch_row_changes_nothing():
    """A cache hint: the kernel that asks for rows ahead reads and returns exactly what it would without."""
    @nb.njit
    def total_with_hints(values, rows):
        total = 0
        for k in range(rows.size):
            if k + 3 < rows.size:
                prefetch_row(values, rows[k + 3])
            total += values[rows[k]].sum()
        return total

    values = np.arange(60, dtype=np.int64).reshape(20, 3)
    rows = np.array([5, 0, 19, 7, 7, 12], dtype=np.int64)
    assert total_with_hints(values, rows) == values[rows].sum()


def test_resample_rows_copy_the_parents_columns_and_name_the_cells_that_agree():
    rng = np.random.default_rng(3)
    table = rng.integers(-3, 3, (500, 6)).astype(np.int8)
    table[::7] = table[::7, :1]  # rows that agree already
    parents = np.array([0, 0, 2, 2, 4, 0])
    cells = rng.permutation(10_000)[:500].astype(np.int32)
    expected, before = table[:, parents], table.copy()
    candidates = np.empty(500, dtype=np.int32)
    n = K.resample_rows(100, 400, table, parents, cells, candidates)  # rows 100-399 only
    np.testing.assert_array_equal(table[100:400], expected[100:400])
    np.testing.assert_array_equal(table[:100], before[:100])
    np.testing.assert_array_equal(table[400:], before[400:])
    np.testing.assert_array_equal(candidates[100:100 + n],
                                  cells[100:400][np.all(expected[100:400] == expected[100:400, :1], axis=1)])


@pytest.mark.parametrize("n_agreed", [3, 40])  # few: holes filled from the end; many: one compacting pass
def test_unlist_agreed_drops_exactly_the_agreed_cells_from_the_list_and_the_table(n_agreed):
    rng = np.random.default_rng(n_agreed)
    n_cells, listed = 500, 60
    disputed = np.empty(n_cells, dtype=np.int32)
    disputed[:listed] = rng.permutation(n_cells)[:listed]
    table = rng.integers(-100, 100, (n_cells, 4)).astype(np.int8)
    status = np.full(n_cells, 7, dtype=np.int16)
    status[disputed[:listed]] = K.DISPUTED
    position = np.full(n_cells, -1, dtype=np.int32)
    position[disputed[:listed]] = np.arange(listed)
    cells = np.sort(rng.choice(disputed[:listed], 45, replace=False))
    agreement = np.full(cells.size, K.DISPUTED, dtype=np.int16)
    agreement[rng.choice(cells.size, n_agreed, replace=False)] = 5
    rows = {int(c): table[k].copy() for k, c in enumerate(disputed[:listed])}
    counts = np.zeros(256, dtype=np.int64)
    n = K.unlist_agreed(cells, agreement, status, counts, disputed, table, listed, position)
    gone = set(cells[agreement != K.DISPUTED].tolist())
    assert n == listed - n_agreed and counts[5 + 128] == n_agreed
    assert sorted(disputed[:n].tolist()) == sorted(set(rows) - gone)
    for k, c in enumerate(disputed[:n]):
        assert position[c] == k and status[c] == K.DISPUTED
        np.testing.assert_array_equal(table[k], rows[int(c)])
    assert all(position[c] == -1 and status[c] == 5 for c in gone)
