"""Numba kernels of the scan matcher and the improved proposal.

GMapping's design (Grisetti, Stachniss, Burgard 2007): each particle hill-climbs from
its motion sample to the mode of ``log p(z | m, x) + log p(x | x_{t-1}, u)`` on its own
grid, by moves of +-step in x, y and theta with the steps halved when no move helps;
the new pose is drawn from a Gaussian fitted around that mode, and the weight grows by
the proposal's normaliser (eqs. 18-20). Two changes make it independent of the cell
size and widen its capture basin to about 0.5 m and 5 degrees:

- **A search radius in metres.** A beam's end point looks for the nearest obstacle point
  within ``radius`` metres (ring by ring, stopping once no farther ring can hold a nearer
  one), not within one cell as GMapping's kernelSize 1. Its log-likelihood is
  ``-min(d, radius)^2 / (2 sigma^2)``: a Gaussian truncated by an outlier floor, so one
  beam can cost no more than the floor whatever the cell size.
- **A coarse stage** (multi-resolution matching, as Olson 2009 and Cartographer). Each grid
  keeps, per block of ``block x block`` cells, how many of its cells are occupied
  (``coarse``, updated by the insertion). When the fine climb from the motion sample
  matches too few beams, a climb on the blocks, each beam scoring ``exp(-d^2 / 2)`` with
  d its distance in blocks to the nearest occupied block within two, moves the sample
  into the fine basin first.

Grid coordinates: ``g = (world - origin) / resolution``; cell (row, col) = (floor(gy), floor(gx)).
Codes: > 0 occupied, < 0 free, 0 unknown; ``hits`` hold each cell's mean end point
(see ``_kernels``).
"""

from __future__ import annotations

import math
from collections import namedtuple

import numba as nb
import numpy as np

from ._kernels import OFFSET_SCALE

#: A mean hit point's offset in its cell for each int8 code, indexed by code + 128: the quotients a
#: division by ``OFFSET_SCALE`` gives, read from a table (an L1 load, not a division, per cell looked at).
HIT_OFFSET = np.arange(-128, 128) / OFFSET_SCALE

#: Scan-matching settings in grid units, built by :func:`match_settings`.
MatchSettings = namedtuple("MatchSettings", [
    "origin_x", "origin_y", "resolution",
    "window",            # cells searched around an end point (ceil(radius / resolution))
    "cap2",              # (radius / resolution)^2: beams farther than this from a surface are unmatched
    "null2",             # (null distance / resolution)^2: what an unmatched beam scores
    "scale",             # resolution^2 / (2 sigma^2): log-likelihood per squared cell
    "linear_step", "angular_step", "refinements", "max_iterations",
    "block",             # cells per coarse block side
    "coarse_linear_step", "coarse_angular_step", "coarse_trigger",
    "exponent",          # tempering of the weights
    "revisit_extra",     # revisit_exponent - exponent: the extra tempering of beams that see a place again
    "min_matched",       # fraction of the likelihood beams that must match
    "proposal_inflation",  # factor on the covariance of the proposal's fitted Gaussian
])


def match_settings(config, origin_x: float, origin_y: float, resolution: float, block: int,
                   revisit_exponent: float | None = None) -> MatchSettings:
    """The kernel settings of an :class:`~emmi_gym.slam.config.RBPFConfig` on a grid of ``resolution``
    (``revisit_exponent``: this update's, if not the configuration's)."""
    if revisit_exponent is None:
        revisit_exponent = config.revisit_exponent
    radius_cells = config.match_radius / resolution
    return MatchSettings(
        float(origin_x), float(origin_y), float(resolution), int(math.ceil(radius_cells)), radius_cells ** 2,
        (max(config.likelihood_null_distance, config.match_radius) / resolution) ** 2,
        resolution * resolution / (2.0 * config.likelihood_sigma ** 2),
        config.match_linear_step, config.match_angular_step, config.match_refinements,
        config.match_max_iterations, int(block), block * resolution, config.coarse_angular_step,
        config.coarse_trigger, config.likelihood_exponent, revisit_exponent - config.likelihood_exponent,
        config.min_match_fraction, config.proposal_inflation)


@nb.njit(cache=True)
def beam_offsets(theta, ranges, angles, max_range, resolution, out):
    """End-point offsets of the beams that hit something, for a laser heading ``theta``.

    Fills ``out[k] = (dx, dy, side_x, side_y)`` in grid cells for the k-th hit beam:
    the end point is the laser's grid position plus (dx, dy); (side_x, side_y) are the
    signs of the direction back towards the laser (0 for a beam exactly along an axis),
    which name the 4-neighbours of a cell on the laser's side (see :func:`_try_cell`).
    Returns the number of hit beams. Depends on the heading only, so moves in x and y
    reuse it.
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
        out[n, 2] = -np.sign(c)
        out[n, 3] = -np.sign(s)
        n += 1
    return n


@nb.njit(cache=True, inline="always")
def _try_cell(grid, hits, row, col, side_x, side_y, hx, hy, best):
    """Squared distance from (hx, hy) to the cell's mean hit point if the cell is a surface seen
    from the laser, else ``best``.

    A surface cell is occupied with a free 4-neighbour on the laser's side (``side_x``,
    ``side_y``: the signs of the direction back to the laser; a sign of 0 names the cell
    itself, which is occupied). GMapping asks for the one cell straight back along the beam
    to be free, which a beam grazing a wall often does not find (that cell is the wall's
    next cell): about a tenth of a corridor scan's beams then scored as misses, differently
    from particle to particle. The far face of a thick wall still does not count: its free
    neighbours face away from the laser.

    Written without branches on the cells' codes (whether a cell near a wall is a surface is
    a coin toss to the branch predictor): half the time of the branching form per beam.
    """
    surface, mx, my = _surface_point(grid, hits, row, col, side_x, side_y)
    d2 = (mx - hx) ** 2 + (my - hy) ** 2
    return d2 if surface and d2 < best else best


@nb.njit(cache=True, inline="always")
def _surface_point(grid, hits, row, col, side_x, side_y):
    """(whether the cell is a surface seen from the laser (see :func:`_try_cell`), its mean hit point x, y)."""
    surface = (grid[row, col] > 0) & ((grid[row, col + side_x] < 0) | (grid[row + side_y, col] < 0))
    mx = col + 0.5 + HIT_OFFSET[np.int64(hits[row, col, 0]) + 128]
    my = row + 0.5 + HIT_OFFSET[np.int64(hits[row, col, 1]) + 128]
    return surface, mx, my


@nb.njit(cache=True, inline="always")
def nearest_surface_d2(grid, hits, hx, hy, side_x, side_y, window):
    """Squared distance (cells^2) from the end point (hx, hy) to the nearest surface point within
    ``window`` cells (Chebyshev), inf if none; the caller keeps window + 1 cells from the edge.

    Rings of growing Chebyshev radius k are searched in turn. Every mean hit point lies
    inside its cell, so a point of ring k is at least k - 1 + e cells away, e the end
    point's distance to the nearest side of its own cell (0 to 0.5): the search stops as
    soon as (k - 1 + e)^2 >= the best distance found (e less a rounding slack, so that the
    result is the exhaustive search's). An end point near its cell's middle that has a
    surface point in its own cell is settled without ring 1.
    """
    hcx, hcy = int(math.floor(hx)), int(math.floor(hy))
    fx, fy = hx - hcx, hy - hcy
    edge = min(fx, 1.0 - fx, fy, 1.0 - fy) - 1e-9
    best = _try_cell(grid, hits, hcy, hcx, side_x, side_y, hx, hy, np.inf)
    for k in range(1, window + 1):
        if (k - 1 + edge) * (k - 1 + edge) >= best:
            break
        for j in range(-k, k + 1):
            best = _try_cell(grid, hits, hcy - k, hcx + j, side_x, side_y, hx, hy, best)
            best = _try_cell(grid, hits, hcy + k, hcx + j, side_x, side_y, hx, hy, best)
        for j in range(-k + 1, k):
            best = _try_cell(grid, hits, hcy + j, hcx - k, side_x, side_y, hx, hy, best)
            best = _try_cell(grid, hits, hcy + j, hcx + k, side_x, side_y, hx, hy, best)
    return best


@nb.njit(cache=True)
def scan_loglik(grid, hits, gx, gy, offsets, n_beams, s, floor):
    """Log-likelihood of a scan on one grid, the laser at grid position (gx, gy).

    Each hit beam whose end point has a surface point within ``match_radius``
    (:func:`nearest_surface_d2`, d in cells) scores ``-d^2 * scale``; any other beam, or
    one ending within ``window + 1`` cells of the grid's edge, scores ``-null2 * scale``,
    as if it were ``likelihood_null_distance`` off (GMapping's nullLikelihood: a fixed cost
    for a beam that finds nothing, whatever the cell size). Returns (log-likelihood,
    matched beams).

    Every beam lowers the sum, so once it is at or below ``floor`` no later beam can lift
    it back: the search stops there and returns (the partial sum, -1). A climb passes the
    value to beat (a bound, as in branch and bound) and skips most of the beams of the
    moves that do not help; ``-inf`` scores every beam.
    """
    h, w = grid.shape
    total = 0.0
    matched = 0
    reach = s.window + 1
    for b in range(n_beams):
        hx = gx + offsets[b, 0]
        hy = gy + offsets[b, 1]
        hcx, hcy = int(math.floor(hx)), int(math.floor(hy))
        d2 = np.inf
        if reach <= hcx < w - reach and reach <= hcy < h - reach:
            d2 = nearest_surface_d2(grid, hits, hx, hy, int(offsets[b, 2]), int(offsets[b, 3]), s.window)
        if d2 < s.cap2:
            matched += 1
            total -= d2 * s.scale
        else:
            total -= s.null2 * s.scale
        if total <= floor:
            return total, -1
    return total, matched


@nb.njit(cache=True)
def coarse_score(coarse, block, gx, gy, offsets, n_beams):
    """Sum over hit beams of exp(-d^2 / 2), d the distance in blocks from the end point to the centre
    of the nearest block within two that holds an occupied cell (0 when none)."""
    h, w = coarse.shape
    total = 0.0
    for b in range(n_beams):
        bx = (gx + offsets[b, 0]) / block
        by = (gy + offsets[b, 1]) / block
        cx, cy = int(math.floor(bx)), int(math.floor(by))
        if not (2 <= cx < w - 2 and 2 <= cy < h - 2):
            continue
        best = np.inf
        for row in range(cy - 2, cy + 3):
            for col in range(cx - 2, cx + 3):
                if coarse[row, col] > 0:
                    d2 = (col + 0.5 - bx) ** 2 + (row + 0.5 - by) ** 2
                    if d2 < best:
                        best = d2
        if best < np.inf:
            total += math.exp(-0.5 * best)
    return total


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


@nb.njit(cache=True, inline="always")
def log_target(grid, hits, pose, offsets, n_beams, s, mean, precision, floor):
    """log p(z | m, x) + log p(x | x_{t-1}, u) up to a constant: the optimal proposal's log-density.

    ``offsets`` must be those of ``pose[2]``. Returns (value, matched beams), or (a value
    at or below ``floor``, -1) as soon as the value cannot exceed ``floor``
    (:func:`scan_loglik`). The motion term keeps the estimate where the scan says nothing
    (along a plain corridor).
    """
    gx = (pose[0] - s.origin_x) / s.resolution
    gy = (pose[1] - s.origin_y) / s.resolution
    prior = 0.5 * _prior_quadratic(pose[0], pose[1], pose[2], mean, precision)
    ll, matched = scan_loglik(grid, hits, gx, gy, offsets, n_beams, s, floor + prior)
    return ll - prior, matched


@nb.njit(cache=True, inline="always")
def _objective(coarse_stage, grid, hits, coarse, pose, offsets, n_beams, s, mean, precision, floor):
    """What a climb maximises: :func:`coarse_score` in the coarse stage, else :func:`log_target`
    (cut short at ``floor``). Returns (value, matched beams; 0 in the coarse stage)."""
    if coarse_stage:
        return coarse_score(coarse, s.block, (pose[0] - s.origin_x) / s.resolution,
                            (pose[1] - s.origin_y) / s.resolution, offsets, n_beams), 0
    return log_target(grid, hits, pose, offsets, n_beams, s, mean, precision, floor)


@nb.njit(cache=True)
def _climb(coarse_stage, grid, hits, coarse, start, ranges, angles, max_range, s, mean, precision, linear_step,
           angular_step, refinements):
    """GMapping's scan matcher: greedy moves of +-step in x, y, theta on :func:`_objective`; halve the
    steps when none helps, at most ``refinements`` times. The move straight back to where the last
    step came from is not scored again (it scored less), and the beams turned by +-astep are computed
    once per heading and step (a move in x or y keeps them; a turn taken makes them the current ones).
    In the fine stage the four moves in x and y, which share the heading's beams, are scored at once
    (:func:`_shifted_logliks`) and taken or not as scoring them one by one with the bound would: the same
    climb.
    Returns (best pose, its value, its matched beams)."""
    current = np.empty((ranges.size, 4))
    plus = np.empty((ranges.size, 4))   # the beams at heading + astep, valid while plus_ok
    minus = np.empty((ranges.size, 4))  # ... - astep
    plus_ok = minus_ok = False
    pose = start.copy()
    n = beam_offsets(pose[2], ranges, angles, max_range, s.resolution, current)
    best, matched = _objective(coarse_stage, grid, hits, coarse, pose, current, n, s, mean, precision, -np.inf)
    lstep, astep = linear_step, angular_step
    refinement = 0
    candidate = np.empty(3)
    best_pose = pose.copy()
    back = -1  # the move that would return to the pose before the last step: known to be worse
    gxs, gys, shifted, shifted_matched = np.empty(4), np.empty(4), np.empty(4), np.empty(4, dtype=np.int64)
    for _ in range(s.max_iterations):
        improved = False
        taken = -1
        if not coarse_stage:  # the four moves in x and y keep the heading: scored at once (_shifted_logliks)
            for move in range(4):
                candidate[:] = pose
                candidate[move // 2] += (1.0 if move % 2 == 0 else -1.0) * lstep
                gxs[move] = (candidate[0] - s.origin_x) / s.resolution
                gys[move] = (candidate[1] - s.origin_y) / s.resolution
            _shifted_logliks(grid, hits, gxs, gys, current, n, s, shifted, shifted_matched)
        for move in range(6):
            if move == back:
                continue
            candidate[:] = pose
            axis = move // 2
            sign = 1.0 if move % 2 == 0 else -1.0
            offsets = current
            if axis < 2 and not coarse_stage:
                candidate[axis] += sign * lstep
                # what log_target with the floor ``best`` gives: cut short (hit -1) where the whole sum ends
                # at or below best + prior, since each beam lowers it
                prior = 0.5 * _prior_quadratic(candidate[0], candidate[1], candidate[2], mean, precision)
                value = shifted[move] - prior
                hit = shifted_matched[move] if shifted[move] > best + prior else -1
            else:
                if axis == 2:
                    candidate[2] += sign * astep
                    if move == 4:
                        if not plus_ok:
                            beam_offsets(candidate[2], ranges, angles, max_range, s.resolution, plus)
                            plus_ok = True
                        offsets = plus
                    else:
                        if not minus_ok:
                            beam_offsets(candidate[2], ranges, angles, max_range, s.resolution, minus)
                            minus_ok = True
                        offsets = minus
                else:
                    candidate[axis] += sign * lstep
                value, hit = _objective(coarse_stage, grid, hits, coarse, candidate, offsets, n, s, mean, precision,
                                        best)
            if hit >= 0 and value > best:  # hit < 0: cut short, not better
                best, matched = value, hit
                best_pose[:] = candidate
                improved = True
                taken = move
        back = taken ^ 1 if improved else -1
        if improved:
            if taken == 4:  # the turned beams are those of the new heading: keep them, not recompute
                current, plus = plus, current
            elif taken == 5:
                current, minus = minus, current
            if taken >= 4:
                plus_ok = minus_ok = False
            pose[:] = best_pose
        else:
            refinement += 1
            if refinement > refinements:
                break
            lstep *= 0.5
            astep *= 0.5
            plus_ok = minus_ok = False
    return pose, best, matched


@nb.njit(cache=True)
def hill_climb(grid, hits, start, ranges, angles, max_range, s, mean, precision):
    """The fine climb on the proposal's log-density. Returns (best pose, its log-density, its matched beams)."""
    return _climb(False, grid, hits, np.zeros((1, 1), dtype=np.int32), start, ranges, angles, max_range, s, mean,
                  precision, s.linear_step, s.angular_step, s.refinements)


@nb.njit(cache=True)
def coarse_climb(coarse, start, ranges, angles, max_range, s):
    """The coarse climb on :func:`coarse_score` (no motion prior), steps halved twice; returns the pose."""
    pose, _, _ = _climb(True, np.zeros((1, 1), dtype=np.int8), np.zeros((1, 1, 3), dtype=np.int8), coarse, start,
                        ranges, angles, max_range, s, start, np.zeros((3, 3)), s.coarse_linear_step,
                        s.coarse_angular_step, 2)
    return pose


@nb.njit(cache=True)
def match(grid, hits, coarse, start, climb_ranges, climb_angles, max_range, s, mean, precision):
    """The mode of the proposal near ``start``: the fine climb, and where it matches fewer than
    ``coarse_trigger`` of the climbing beams, a coarse climb then a fine one from there; the
    better of the two. Returns (pose, log-density)."""
    pose, best, matched = hill_climb(grid, hits, start, climb_ranges, climb_angles, max_range, s, mean, precision)
    n = 0
    for b in range(climb_ranges.size):
        if 0.0 < climb_ranges[b] < max_range:
            n += 1
    if matched >= s.coarse_trigger * n:
        return pose, best
    coarse_pose = coarse_climb(coarse, start, climb_ranges, climb_angles, max_range, s)
    refined, value, _ = hill_climb(grid, hits, coarse_pose, climb_ranges, climb_angles, max_range, s, mean,
                                   precision)
    if value > best:
        return refined, value
    return pose, best


@nb.njit(cache=True, nogil=True)
def improved_proposal(start, stop, codes, hits, coarse, motion_samples, motion_means, motion_precisions,
                      motion_lognorms, normals, climb_ranges, climb_angles, ranges, angles, weight_ranges,
                      separate_weights, max_range, s, new_poses, log_increments, matched_flags):
    """The improved proposal of GMapping (Grisetti et al. 2007, eqs. 18-20), for every particle.

    From each particle's motion sample x' (odometry noise applied), :func:`match` finds the
    mode x* of ``L(x) = loglik(x) + log p(x | x_{t-1}, u)`` on the particle's own grid
    (``climb_*``: the beams used while climbing). If at least ``min_matched`` of the
    likelihood beams (``ranges``, ``angles``: decimated, since neighbouring beams' errors
    are not independent) match there, evaluate L on x* and x* +- one step along x, y and
    theta, fit a Gaussian weighted by exp(L), widen its covariance by ``proposal_inflation``,
    draw the new pose from it with ``normals``,
    and add ``exponent * log(eta)`` to the log-weight, eta = sum exp(L) * step volume
    (eq. 20). Otherwise keep x' and add ``exponent * loglik(x')``: the same integral
    estimated by the one sample drawn from the motion model. With ``separate_weights``,
    ``weight_ranges`` are the beams that see a place again (the others set to ``max_range``,
    i.e. no echo; see :mod:`emmi_gym.slam.revisits`): the same normaliser of those beams
    only, on the same seven poses (or at x'), is added times ``revisit_extra``, so that they
    count with ``revisit_exponent`` in all. The proposal uses every beam either way.

    Proposes particles ``start`` to ``stop`` - 1: the particles are independent, so chunks of
    them run at once on threads (:mod:`emmi_gym.concurrency.threads`; the GIL is released), with the
    same result whatever the number of threads.
    """
    lstep, astep = s.linear_step, s.angular_step
    stencil = np.zeros((7, 3))
    for axis in range(3):
        step = astep if axis == 2 else lstep
        stencil[1 + 2 * axis, axis] = -step
        stencil[2 + 2 * axis, axis] = step
    n_likelihood = 0
    for b in range(ranges.size):
        if 0.0 < ranges[b] < max_range:
            n_likelihood += 1
    min_matched = max(1, int(math.ceil(s.min_matched * n_likelihood)))
    for i in range(start, stop):
        _propose(i, codes[i], hits[i], coarse[i], motion_samples, motion_means, motion_precisions, motion_lognorms,
                 normals, climb_ranges, climb_angles, ranges, angles, weight_ranges, separate_weights, max_range, s,
                 stencil, min_matched, new_poses, log_increments, matched_flags)


@nb.njit(cache=True, nogil=True)
def _propose(i, grid, cell_hits, coarse, motion_samples, motion_means, motion_precisions, motion_lognorms,
             normals, climb_ranges, climb_angles, ranges, angles, weight_ranges, separate_weights, max_range, s,
             stencil, min_matched, new_poses, log_increments, matched_flags):
    """Particle ``i`` of :func:`improved_proposal`: its mode, its Gaussian, its draw and its weight."""
    astep = s.angular_step
    log_volume = math.log(s.linear_step * s.linear_step * astep)
    offsets = np.empty((3, ranges.size, 4))  # beam offsets at headings x* - step, x*, x* + step
    scores = np.empty(7)
    pose = np.empty(3)
    best_pose, _ = match(grid, cell_hits, coarse, motion_samples[i], climb_ranges, climb_angles,
                         max_range, s, motion_means[i], motion_precisions[i])
    n = beam_offsets(best_pose[2], ranges, angles, max_range, s.resolution, offsets[1])
    centre, matched = log_target(grid, cell_hits, best_pose, offsets[1], n, s, motion_means[i],
                                 motion_precisions[i], -np.inf)
    matched_flags[i] = matched >= min_matched
    if not matched_flags[i]:
        n = beam_offsets(motion_samples[i, 2], ranges, angles, max_range, s.resolution, offsets[0])
        gx = (motion_samples[i, 0] - s.origin_x) / s.resolution
        gy = (motion_samples[i, 1] - s.origin_y) / s.resolution
        ll, _ = scan_loglik(grid, cell_hits, gx, gy, offsets[0], n, s, -np.inf)
        new_poses[i] = motion_samples[i]
        log_increments[i] = s.exponent * ll
        if separate_weights:
            n = beam_offsets(motion_samples[i, 2], weight_ranges, angles, max_range, s.resolution, offsets[0])
            ll, _ = scan_loglik(grid, cell_hits, gx, gy, offsets[0], n, s, -np.inf)
            log_increments[i] += s.revisit_extra * ll
        return
    beam_offsets(best_pose[2] - astep, ranges, angles, max_range, s.resolution, offsets[0])
    beam_offsets(best_pose[2] + astep, ranges, angles, max_range, s.resolution, offsets[2])
    top, total = _stencil_scores(grid, cell_hits, best_pose, centre, offsets, n, s, stencil, motion_means[i],
                                 motion_precisions[i], motion_lognorms[i], scores, pose)
    mean = np.zeros(3)
    for k in range(7):
        scores[k] = math.exp(scores[k] - top)
        mean += scores[k] * stencil[k]
    mean /= total
    cov = np.zeros((3, 3))
    for k in range(7):
        d = stencil[k] - mean
        cov += (scores[k] / total) * np.outer(d, d)
    cov *= s.proposal_inflation
    cov[0, 0] += 1e-6
    cov[1, 1] += 1e-6
    cov[2, 2] += 1e-7
    chol = np.linalg.cholesky(cov)
    draw = mean + chol @ normals[i]
    new_poses[i, 0] = best_pose[0] + draw[0]
    new_poses[i, 1] = best_pose[1] + draw[1]
    new_poses[i, 2] = (best_pose[2] + draw[2] + math.pi) % (2.0 * math.pi) - math.pi
    log_increments[i] = s.exponent * (top + math.log(total) + log_volume)
    if separate_weights:  # the proposal is drawn: its offsets take those of the weighted beams
        n = beam_offsets(best_pose[2], weight_ranges, angles, max_range, s.resolution, offsets[1])
        beam_offsets(best_pose[2] - astep, weight_ranges, angles, max_range, s.resolution, offsets[0])
        beam_offsets(best_pose[2] + astep, weight_ranges, angles, max_range, s.resolution, offsets[2])
        centre, _ = log_target(grid, cell_hits, best_pose, offsets[1], n, s, motion_means[i],
                               motion_precisions[i], -np.inf)
        top, total = _stencil_scores(grid, cell_hits, best_pose, centre, offsets, n, s, stencil,
                                     motion_means[i], motion_precisions[i], motion_lognorms[i], scores, pose)
        log_increments[i] += s.revisit_extra * (top + math.log(total) + log_volume)


@nb.njit(cache=True)
def _stencil_scores(grid, cell_hits, best_pose, centre, offsets, n, s, stencil, mean, precision, lognorm, scores,
                    pose):
    """The proposal's log-density plus the motion prior's log-normaliser on the seven poses round the mode,
    into ``scores`` (``centre``: the log-density at the mode; ``offsets``: the beams at headings mode - step,
    mode, mode + step). Returns (the largest score, the sum of exp(score - largest))."""
    scores[0] = centre + lognorm
    top = scores[0]
    gxs, gys, shifted, matched = np.empty(4), np.empty(4), np.empty(4), np.empty(4, dtype=np.int64)
    for k in range(1, 5):  # the moves in x and y keep the heading: their beams share one look at the cells
        gxs[k - 1] = (best_pose[0] + stencil[k, 0] - s.origin_x) / s.resolution
        gys[k - 1] = (best_pose[1] + stencil[k, 1] - s.origin_y) / s.resolution
    _shifted_logliks(grid, cell_hits, gxs, gys, offsets[1], n, s, shifted, matched)
    for k in range(1, 7):
        for axis in range(3):
            pose[axis] = best_pose[axis] + stencil[k, axis]
        if k <= 4:
            value = shifted[k - 1] - 0.5 * _prior_quadratic(pose[0], pose[1], pose[2], mean, precision)
        else:
            t = 0 if stencil[k, 2] < 0 else (2 if stencil[k, 2] > 0 else 1)
            value, _ = log_target(grid, cell_hits, pose, offsets[t], n, s, mean, precision, -np.inf)
        scores[k] = value + lognorm
        if scores[k] > top:
            top = scores[k]
    total = 0.0
    for k in range(7):
        total += math.exp(scores[k] - top)
    return top, total


@nb.njit(cache=True)
def _shifted_logliks(grid, hits, gxs, gys, offsets, n_beams, s, out, matched):
    """:func:`scan_loglik` (every beam scored) with the laser at each of the four grid positions (gxs[k],
    gys[k]), the same numbers into ``out``: each beam's surface points are read once from the cells
    round its four end points, not searched four times. A cell outside a point's window holds no
    surface point within the match radius of it, so taking it in changes nothing. The matched beams of
    each go to ``matched``."""
    h, w = grid.shape
    reach = s.window + 1
    hxs, hys, best = np.empty(4), np.empty(4), np.empty(4)
    out[:] = 0.0
    matched[:] = 0
    for b in range(n_beams):
        side_x, side_y = int(offsets[b, 2]), int(offsets[b, 3])
        lo_x = lo_y = w + h
        hi_x = hi_y = -1
        inside = True
        for k in range(4):
            hxs[k] = gxs[k] + offsets[b, 0]
            hys[k] = gys[k] + offsets[b, 1]
            cx, cy = int(math.floor(hxs[k])), int(math.floor(hys[k]))
            inside = inside and reach <= cx < w - reach and reach <= cy < h - reach
            lo_x, hi_x, lo_y, hi_y = min(lo_x, cx), max(hi_x, cx), min(lo_y, cy), max(hi_y, cy)
            best[k] = np.inf
        if inside:
            for row in range(lo_y - s.window, hi_y + s.window + 1):
                for col in range(lo_x - s.window, hi_x + s.window + 1):
                    surface, mx, my = _surface_point(grid, hits, row, col, side_x, side_y)
                    if surface:
                        for k in range(4):
                            d2 = (mx - hxs[k]) ** 2 + (my - hys[k]) ** 2
                            if d2 < best[k]:
                                best[k] = d2
        else:
            for k in range(4):
                cx, cy = int(math.floor(hxs[k])), int(math.floor(hys[k]))
                if reach <= cx < w - reach and reach <= cy < h - reach:
                    best[k] = nearest_surface_d2(grid, hits, hxs[k], hys[k], side_x, side_y, s.window)
        for k in range(4):
            if best[k] < s.cap2:
                out[k] -= best[k] * s.scale
                matched[k] += 1
            else:
                out[k] -= s.null2 * s.scale
