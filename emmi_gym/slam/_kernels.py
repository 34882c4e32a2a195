"""Numba kernels of the RBPF: scan insertion, scan likelihood, scan matching, improved proposal.

Hot loops only; each has a plain-Python twin in ``tests/test_slam_kernels.py``.
Grid coordinates: ``g = (world - origin) / resolution``; cell (row, col) = (floor(gy), floor(gx)).
Maps are int8 codes of log-odds (see ``sensor_model``): > 0 occupied, < 0 free, 0 unknown.
Beside them, ``hits`` (M, H, W, 3) int8 keeps for each cell the mean position of the beam
end points that fell in it (x and y offsets from the cell centre in 1/254 of a cell)
and how many (capped), as GMapping's point accumulators do: the scan matcher measures
distances to these means, not to cell centres, so its accuracy is not that of the grid.
"""


from __future__ import annotations

import math

import numba as nb
import numpy as np

#: Cells remember the mean of their last this-many hits (a running mean with a capped count).
HIT_COUNT_CAP = 32
_OFFSET_SCALE = 254.0


@nb.njit(cache=True, inline="always")
def _add_clamped(grid, counts, row, col, increment, clamp):
    """grid[row, col] += increment within +-clamp, keeping the grid's code histogram ``counts`` current."""
    old = np.int16(grid[row, col])
    v = old + increment
    if v > clamp:
        v = clamp
    elif v < -clamp:
        v = -clamp
    grid[row, col] = v
    counts[old + 128] -= 1
    counts[v + 128] += 1


#: Kinds of insertion rays: a beam's hit (end cell occupied), a ray that frees its whole
#: length (max-range reading), a ray that frees up to but not its end cell (a sub-ray).
RAY_HIT, RAY_FREE, RAY_BOUNDED = 0, 1, 2


@nb.njit(cache=True)
def scan_rays(ranges, angles, gaps, max_range, free_range, resolution, jump):
    """The rays that insert one scan as its polygon: each beam, plus sub-rays across the gap to the next.

    A gap of ``gaps[b]`` radians after beam b (0 for a last beam without neighbour) gets
    sub-rays no more than one cell apart at the far end (at most 16), so that every cell
    of the scanned area is crossed whatever the resolution (MRPT's widened beams). Across
    a continuous surface (both beams hit, ranges within ``jump`` metres plus 10%) a
    sub-ray's length is interpolated; across a depth jump it takes the nearer one, never
    entering the shadow. Sub-rays only free cells, up to but not their end cell: only
    real end points claim occupancy. Returns (angle offsets, lengths, kinds) of all rays,
    relative to the laser heading; kinds are RAY_HIT, RAY_FREE or RAY_BOUNDED.
    """
    n = ranges.size
    total = 0
    counts = np.ones(n, dtype=np.int64)
    lengths = np.empty(n)
    for b in range(n):
        lengths[b] = ranges[b] if 0.0 < ranges[b] < max_range else (free_range if ranges[b] > 0.0 else 0.0)
    for b in range(n):
        if gaps[b] > 0.0:
            far = max(lengths[b], lengths[(b + 1) % n])
            counts[b] = min(16, max(1, int(math.ceil(far * gaps[b] / resolution))))
        total += counts[b]
    ray_angles = np.empty(total)
    ray_lengths = np.empty(total)
    ray_kinds = np.empty(total, dtype=np.int64)
    k = 0
    for b in range(n):
        nb_ = (b + 1) % n
        r0, r1 = ranges[b], ranges[nb_]
        hit0 = 0.0 < r0 < max_range
        smooth = hit0 and 0.0 < r1 < max_range and abs(r0 - r1) <= jump + 0.1 * min(r0, r1)
        for j in range(counts[b]):
            f = j / counts[b]
            ray_angles[k] = angles[b] + f * gaps[b]
            if j == 0:
                ray_lengths[k] = lengths[b]
                ray_kinds[k] = RAY_HIT if hit0 else RAY_FREE
            else:
                ray_lengths[k] = (1.0 - f) * r0 + f * r1 if smooth else min(lengths[b], lengths[nb_])
                ray_kinds[k] = RAY_BOUNDED
            k += 1
    return ray_angles, ray_lengths, ray_kinds


@nb.njit(cache=True, inline="always")
def _accumulate_hit(cell, gx, gy, col, row):
    """Fold an end point at grid coordinates (gx, gy) into its cell's running mean."""
    n = np.int32(cell[2]) + 1
    if n > HIT_COUNT_CAP:
        n = HIT_COUNT_CAP
    for axis in range(2):
        offset = (gx - col - 0.5) if axis == 0 else (gy - row - 0.5)
        old = np.float64(cell[axis]) / _OFFSET_SCALE
        new = old + (offset - old) / n
        cell[axis] = np.int8(round(max(-0.5, min(0.5, new)) * _OFFSET_SCALE))
    cell[2] = n


@nb.njit(cache=True)
def insert_scans(codes, hits, counts, poses, ray_angles, ray_lengths, ray_kinds, inc_occupied, inc_free, clamp,
                 origin_x, origin_y, resolution, stamp, serial):
    """Insert one scan, given as rays (see :func:`scan_rays`), into each particle's grid at its pose.

    Eq. (4) in log-odds with the paper's peaked model (Fig. 2): per particle and scan a
    cell is updated at most once, ``inc_occupied`` if some hit ray ends in it, else
    ``inc_free`` if some ray crosses it before its end (exact cell traversal, Amanatides
    & Woo; a RAY_FREE ray frees its end cell too). ``stamp`` (H, W) int64
    remembers which cells this scan already touched; ``serial`` grows by 2 per particle
    and is returned. Hit end points also update their cell's mean hit position, and
    ``counts`` (M, 256), how many cells of each grid hold each code (index code + 128),
    follows every change.
    """
    m, h, w = codes.shape
    n_rays = ray_angles.size
    for i in range(m):
        grid = codes[i]
        hit_id = serial + 1
        free_id = serial + 2
        serial += 2
        gx0 = (poses[i, 0] - origin_x) / resolution
        gy0 = (poses[i, 1] - origin_y) / resolution
        for b in range(n_rays):  # end points first: they win over crossings
            if ray_kinds[b] != RAY_HIT:
                continue
            a = poses[i, 2] + ray_angles[b]
            gx = gx0 + ray_lengths[b] * math.cos(a) / resolution
            gy = gy0 + ray_lengths[b] * math.sin(a) / resolution
            col, row = int(math.floor(gx)), int(math.floor(gy))
            if not (0 <= row < h and 0 <= col < w):
                continue
            _accumulate_hit(hits[i, row, col], gx, gy, col, row)
            if stamp[row, col] != hit_id:
                stamp[row, col] = hit_id
                _add_clamped(grid, counts[i], row, col, inc_occupied, clamp)
        for b in range(n_rays):
            length = ray_lengths[b]
            if length <= 0.0:
                continue
            keep_end = ray_kinds[b] != RAY_FREE
            a = poses[i, 2] + ray_angles[b]
            ex = gx0 + length * math.cos(a) / resolution
            ey = gy0 + length * math.sin(a) / resolution
            cx, cy = int(math.floor(gx0)), int(math.floor(gy0))
            end_x, end_y = int(math.floor(ex)), int(math.floor(ey))
            dx, dy = ex - gx0, ey - gy0
            step_x = 1 if dx > 0 else -1
            step_y = 1 if dy > 0 else -1
            t_dx = abs(1.0 / dx) if dx != 0.0 else np.inf
            t_dy = abs(1.0 / dy) if dy != 0.0 else np.inf
            t_x = ((cx + 1 - gx0) if dx > 0 else (gx0 - cx)) * t_dx if dx != 0.0 else np.inf
            t_y = ((cy + 1 - gy0) if dy > 0 else (gy0 - cy)) * t_dy if dy != 0.0 else np.inf
            n_steps = abs(end_x - cx) + abs(end_y - cy)
            for k in range(n_steps + 1):
                if k == n_steps and keep_end:
                    break
                if not (0 <= cy < h and 0 <= cx < w):
                    break
                if stamp[cy, cx] < hit_id:
                    stamp[cy, cx] = free_id
                    _add_clamped(grid, counts[i], cy, cx, inc_free, clamp)
                if t_x < t_y:
                    cx += step_x
                    t_x += t_dx
                else:
                    cy += step_y
                    t_y += t_dy
    return serial


@nb.njit(cache=True)
def beam_offsets(theta, ranges, angles, max_range, resolution, out):
    """End-point offsets of the beams that hit something, for a laser heading ``theta``.

    Fills ``out[k] = (dx, dy, back_x, back_y)`` in grid cells for the k-th hit beam:
    the end point is the laser's grid position plus (dx, dy); (back_x, back_y) is the
    whole-cell step back towards the laser, sqrt(2) cells along the beam rounded
    (GMapping's freeCellRatio), so never (0, 0). Returns the number of hit beams.
    Depends on the heading only, so moves in x and y reuse it.
    """
    n = 0
    for b in range(ranges.size):
        r = ranges[b]
        if r >= max_range or r <= 0.0:
            continue
        a = theta + angles[b]
        c, s = math.cos(a), math.sin(a)
        out[n, 0] = r * c / resolution
        out[n, 1] = r * s / resolution
        out[n, 2] = round(-math.sqrt(2.0) * c)
        out[n, 3] = round(-math.sqrt(2.0) * s)
        n += 1
    return n


@nb.njit(cache=True)
def scan_loglik(grid, hits, gx, gy, offsets, n_beams, window, scale, null_loglik):
    """Log-likelihood of a scan on one grid, the laser at grid position (gx, gy) (GMapping's score).

    ``offsets`` come from :func:`beam_offsets`. For each hit beam, search the
    ``window`` cells around its end point for a cell that is occupied while its
    neighbour back towards the laser is free; the nearest such cell's mean hit point,
    at distance d cells, scores ``-d^2 * scale`` (scale = resolution^2 / (2 sigma^2));
    a beam with none, or ending within ``window + 1`` cells of the grid's edge, scores
    ``null_loglik``. Returns (log-likelihood, matched beams).
    """
    h, w = grid.shape
    total = 0.0
    matched = 0
    for b in range(n_beams):
        hx = gx + offsets[b, 0]
        hy = gy + offsets[b, 1]
        back_x = int(offsets[b, 2])
        back_y = int(offsets[b, 3])
        hcx, hcy = int(math.floor(hx)), int(math.floor(hy))
        best = np.inf
        reach = window + 1  # the window and the step back stay inside: no per-cell checks
        if not (reach <= hcx < w - reach and reach <= hcy < h - reach):
            total += null_loglik
            continue
        for oy in range(-window, window + 1):
            row = hcy + oy
            frow = row + back_y
            for ox in range(-window, window + 1):
                col = hcx + ox
                if grid[row, col] > 0 and grid[frow, col + back_x] < 0:
                    cell = hits[row, col]
                    mx = col + 0.5 + np.float64(cell[0]) / _OFFSET_SCALE
                    my = row + 0.5 + np.float64(cell[1]) / _OFFSET_SCALE
                    d2 = (mx - hx) ** 2 + (my - hy) ** 2
                    if d2 < best:
                        best = d2
        if best < np.inf:
            total -= best * scale
            matched += 1
        else:
            total += null_loglik
    return total, matched


@nb.njit(cache=True, inline="always")
def _prior_quadratic(x, y, theta, mean, precision):
    """(x - mean)^T P (x - mean) with the heading difference wrapped."""
    d0 = x - mean[0]
    d1 = y - mean[1]
    d2 = (theta - mean[2] + math.pi) % (2.0 * math.pi) - math.pi
    p = precision
    return (d0 * (p[0, 0] * d0 + p[0, 1] * d1 + p[0, 2] * d2)
            + d1 * (p[1, 0] * d0 + p[1, 1] * d1 + p[1, 2] * d2)
            + d2 * (p[2, 0] * d0 + p[2, 1] * d1 + p[2, 2] * d2))


@nb.njit(cache=True)
def log_target(grid, hits, pose, offsets, n_beams, geo, window, scale, null_loglik, mean, precision):
    """log p(z | m, x) + log p(x | x_{t-1}, u) up to a constant: the optimal proposal's log-density.

    ``offsets`` must be those of ``pose[2]``; ``geo`` = (origin_x, origin_y, resolution).
    Returns (value, matched beams). The motion term keeps the estimate where the scan
    says nothing (along a plain corridor), as the optimal proposal does.
    """
    gx = (pose[0] - geo[0]) / geo[2]
    gy = (pose[1] - geo[1]) / geo[2]
    ll, matched = scan_loglik(grid, hits, gx, gy, offsets, n_beams, window, scale, null_loglik)
    return ll - 0.5 * _prior_quadratic(pose[0], pose[1], pose[2], mean, precision), matched


@nb.njit(cache=True)
def hill_climb(grid, hits, start, ranges, angles, max_range, geo, window, scale, null_loglik, mean, precision,
               linear_step, angular_step, refinements, max_iterations):
    """GMapping's scan matcher on the proposal's log-density: greedy moves of +-step in x, y, theta;
    halve the steps when none helps.

    Returns (best pose, its log-density, its matched beams).
    """
    resolution = geo[2]
    current = np.empty((ranges.size, 4))
    turned = np.empty((ranges.size, 4))
    pose = start.copy()
    n = beam_offsets(pose[2], ranges, angles, max_range, resolution, current)
    best, matched = log_target(grid, hits, pose, current, n, geo, window, scale, null_loglik, mean, precision)
    lstep, astep = linear_step, angular_step
    refinement = 0
    candidate = np.empty(3)
    best_pose = pose.copy()
    for _ in range(max_iterations):
        improved = False
        for move in range(6):
            candidate[:] = pose
            axis = move // 2
            sign = 1.0 if move % 2 == 0 else -1.0
            if axis == 2:
                candidate[2] += sign * astep
                beam_offsets(candidate[2], ranges, angles, max_range, resolution, turned)
                value, hit = log_target(grid, hits, candidate, turned, n, geo, window, scale, null_loglik, mean,
                                        precision)
            else:
                candidate[axis] += sign * lstep
                value, hit = log_target(grid, hits, candidate, current, n, geo, window, scale, null_loglik, mean,
                                        precision)
            if value > best:
                best, matched = value, hit
                best_pose[:] = candidate
                improved = True
        if improved:
            if best_pose[2] != pose[2]:
                beam_offsets(best_pose[2], ranges, angles, max_range, resolution, current)
            pose[:] = best_pose
        else:
            refinement += 1
            if refinement > refinements:
                break
            lstep *= 0.5
            astep *= 0.5
    return pose, best, matched


@nb.njit(cache=True)
def improved_proposal(codes, hits, motion_samples, motion_means, motion_precisions, motion_lognorms, normals,
                      ranges, angles, climb_skip, max_range, origin_x, origin_y, resolution, window, sigma,
                      linear_step, angular_step, refinements, max_iterations, exponent, min_matched,
                      new_poses, log_increments, matched_flags):
    """The improved proposal of GMapping (Grisetti et al. 2007, eqs. 18-20), for every particle.

    From each particle's motion sample x' (odometry noise already applied), hill-climb
    to the mode x* of ``loglik(x) + log p(x | x_{t-1}, u)`` on the particle's own grid. If at least ``min_matched``
    beams match there, evaluate ``L(x) = loglik(x) + log p(x | x_{t-1}, u)`` on the 7
    poses x* and x* +- one step along x, y and theta, fit a Gaussian (mean, covariance)
    weighted by exp(L), draw the new pose from it with ``normals``, and add
    ``exponent * log(eta)``, eta = sum exp(L) * cell volume, to the log-weight.
    Otherwise keep x' and add ``exponent * loglik(x')`` (the same integral, estimated by
    one sample). ``exponent`` tempers the weights only (GMapping's ogain, MRPT's
    powFactor), not the proposal.
    """
    m = codes.shape[0]
    geo = np.array([origin_x, origin_y, resolution])
    scale = resolution * resolution / (2.0 * sigma * sigma)
    null_loglik = -((window + 1.0) ** 2) * scale
    log_volume = math.log(linear_step * linear_step * angular_step)
    offsets = np.empty((3, ranges.size, 4))  # beam offsets at headings x*, -step, +step
    stencil = np.zeros((7, 3))
    for axis in range(3):
        step = angular_step if axis == 2 else linear_step
        stencil[1 + 2 * axis, axis] = -step
        stencil[2 + 2 * axis, axis] = step
    scores = np.empty(7)
    pose = np.empty(3)
    for i in range(m):
        grid, cell_hits = codes[i], hits[i]
        climb_ranges = np.ascontiguousarray(ranges[::climb_skip])
        climb_angles = np.ascontiguousarray(angles[::climb_skip])
        best_pose, _, _ = hill_climb(grid, cell_hits, motion_samples[i], climb_ranges, climb_angles, max_range,
                                     geo, window, scale, null_loglik, motion_means[i], motion_precisions[i],
                                     linear_step, angular_step, refinements, max_iterations)
        for t in range(3):
            n = beam_offsets(best_pose[2] + (t - 1) * angular_step, ranges, angles, max_range, resolution, offsets[t])
        _, matched = scan_loglik(grid, cell_hits, (best_pose[0] - origin_x) / resolution,
                                 (best_pose[1] - origin_y) / resolution, offsets[1], n, window, scale, null_loglik)
        matched_flags[i] = matched >= min_matched
        if not matched_flags[i]:
            n = beam_offsets(motion_samples[i, 2], ranges, angles, max_range, resolution, offsets[0])
            gx = (motion_samples[i, 0] - origin_x) / resolution
            gy = (motion_samples[i, 1] - origin_y) / resolution
            ll, _ = scan_loglik(grid, cell_hits, gx, gy, offsets[0], n, window, scale, null_loglik)
            new_poses[i] = motion_samples[i]
            log_increments[i] = exponent * ll
            continue
        top = -np.inf
        for k in range(7):
            for axis in range(3):
                pose[axis] = best_pose[axis] + stencil[k, axis]
            t = 0 if stencil[k, 2] < 0 else (2 if stencil[k, 2] > 0 else 1)
            value, _ = log_target(grid, cell_hits, pose, offsets[t], n, geo, window, scale, null_loglik,
                                  motion_means[i], motion_precisions[i])
            scores[k] = value + motion_lognorms[i]
            if scores[k] > top:
                top = scores[k]
        total = 0.0
        mean = np.zeros(3)
        for k in range(7):
            scores[k] = math.exp(scores[k] - top)
            total += scores[k]
            mean += scores[k] * stencil[k]
        mean /= total
        cov = np.zeros((3, 3))
        for k in range(7):
            d = stencil[k] - mean
            cov += (scores[k] / total) * np.outer(d, d)
        cov[0, 0] += 1e-6
        cov[1, 1] += 1e-6
        cov[2, 2] += 1e-7
        chol = np.linalg.cholesky(cov)
        draw = mean + chol @ normals[i]
        new_poses[i, 0] = best_pose[0] + draw[0]
        new_poses[i, 1] = best_pose[1] + draw[1]
        new_poses[i, 2] = (best_pose[2] + draw[2] + math.pi) % (2.0 * math.pi) - math.pi
        log_increments[i] = exponent * (top + math.log(total) + log_volume)
