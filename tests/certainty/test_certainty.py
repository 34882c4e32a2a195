"""Certainty metrics against plain float64 references, and the paper's properties."""

import math

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st
from hypothesis.extra import numpy as hnp

from emmi_gym import certainty as C

# ---------------------------------------------------------------- plain references


def ref_weights(w, log=False):
    w = np.asarray(w, dtype=np.float64)
    if log:
        w = np.exp(w - w.max())
    return w / w.sum()


def ref_h2(p):
    p = float(p)
    if p <= 0.0 or p >= 1.0:
        return 0.0
    return -(p * math.log2(p) + (1 - p) * math.log2(1 - p))


def ref_mi(p, tol=1e-3):
    info, n = 0.0, 0
    for v in np.asarray(p, dtype=np.float64).ravel():
        h = ref_h2(v)
        if h * math.log(2) < math.log(2) - tol:
            info += 1 - h
            n += 1
    return info / n if n else 0.0


def ref_em(p, w):
    return sum(wi * pi.astype(np.float64) for wi, pi in zip(w, p, strict=False))


def ref_pose_entropy(poses, w):
    poses = np.asarray(poses, dtype=np.float64)
    mx, my = (w * poses[:, 0]).sum(), (w * poses[:, 1]).sum()
    mt = math.atan2((w * np.sin(poses[:, 2])).sum(), (w * np.cos(poses[:, 2])).sum())
    cov = np.zeros((3, 3))
    for wi, (x, y, t) in zip(w, poses, strict=False):
        dt = (t - mt + math.pi) % (2 * math.pi) - math.pi
        d = np.array([x - mx, y - my, dt])
        cov += wi * np.outer(d, d)
    det = max(np.linalg.det(cov), C.DEFAULT_DET_FLOOR)
    return 0.5 * math.log((2 * math.pi * math.e) ** 3 * det)


# ---------------------------------------------------------------- strategies

probs = st.floats(0.0, 1.0, allow_nan=False, width=32)
# Values on both sides of the observed threshold, and exactly 0, 0.5 and 1.
cell_values = st.one_of(probs, st.sampled_from([0.0, 0.5, 1.0, 0.47, 0.53, 0.4776, 0.5224]))


@st.composite
def particle_grids(draw, max_m=6, max_side=12):
    m = draw(st.integers(1, max_m))
    h = draw(st.integers(1, max_side))
    w_ = draw(st.integers(1, max_side))
    dtype = draw(st.sampled_from([np.float32, np.float64]))
    grids = draw(hnp.arrays(dtype, (m, h, w_), elements=cell_values))
    weights = draw(hnp.arrays(np.float64, (m,), elements=st.floats(0.0, 10.0)))
    if weights.sum() == 0:
        weights[0] = 1.0
    return grids, weights


# ---------------------------------------------------------------- against the references


@given(particle_grids())
def test_expected_map_matches_reference(case):
    grids, weights = case
    np.testing.assert_allclose(C.expected_map(grids, weights), ref_em(grids, ref_weights(weights)), atol=1e-12)


@given(particle_grids())
def test_emmi_matches_reference(case):
    grids, weights = case
    em = ref_em(grids, ref_weights(weights))
    assert C.emmi(grids, weights) == pytest.approx(ref_mi(em), abs=1e-9)


@given(particle_grids(), st.floats(-40, 40))
def test_logodds_input_matches_probability_input(case, shift):
    grids, weights = case
    p = np.clip(grids.astype(np.float64), 1e-6, 1 - 1e-6)
    logodds = np.log(p / (1 - p))
    assert C.emmi(logodds, weights, logodds=True) == pytest.approx(C.emmi(p, weights), abs=1e-9)
    np.testing.assert_allclose(C.expected_map(logodds, weights, logodds=True), C.expected_map(p, weights), atol=1e-9)


@given(hnp.arrays(np.float64, st.integers(1, 200), elements=cell_values))
def test_cell_and_map_information_match_reference(p):
    h = np.array([ref_h2(v) for v in p])
    np.testing.assert_allclose(C.cell_entropy(p), h, atol=1e-12)
    np.testing.assert_allclose(C.cell_information(p), 1 - h, atol=1e-12)
    assert C.map_information(p) == pytest.approx((1 - h).sum(), abs=1e-9)
    assert C.map_entropy(p) == pytest.approx(h.sum(), abs=1e-9)
    assert C.mean_information(p) == pytest.approx(ref_mi(p), abs=1e-12)


@given(hnp.arrays(np.float64, st.integers(1, 50), elements=cell_values), st.floats(0.0, 0.5))
def test_observed_tolerance_is_in_nats(p, tol):
    assert C.mean_information(p, observed_tol=tol) == pytest.approx(ref_mi(p, tol), abs=1e-12)


@given(particle_grids(max_side=6))
def test_weighted_map_entropy_matches_reference(case):
    grids, weights = case
    w = ref_weights(weights)
    expected = sum(wi * sum(ref_h2(v) for v in g.ravel()) for wi, g in zip(w, grids, strict=False))
    assert C.weighted_map_entropy(grids, weights) == pytest.approx(expected, rel=1e-9, abs=1e-9)


# Particle sets of at least 5 spread poses: with fewer, Sigma is singular and the
# entropy is the floor (tested on its own below), where round-off decides det.
@given(st.integers(5, 30), st.floats(0.01, 10.0), st.floats(0.001, 3.0), st.integers(0, 2**31))
def test_pose_entropy_matches_reference(m, spread_xy, spread_theta, seed):
    rng = np.random.default_rng(seed)
    poses = rng.normal(size=(m, 3)) * [spread_xy, spread_xy, spread_theta] + rng.normal(size=3) * 5
    weights = rng.random(m) + 0.01
    assert C.pose_entropy(poses, weights) == pytest.approx(ref_pose_entropy(poses, ref_weights(weights)), abs=1e-6)


@given(st.integers(5, 12), st.integers(1, 7), st.integers(0, 2**31))
def test_path_and_joint_entropy_match_reference(m, t, seed):
    rng = np.random.default_rng(seed)
    paths = rng.normal(size=(m, t, 3))
    grids = rng.random((m, 5, 4))
    w = rng.random(m) + 0.01
    wn = ref_weights(w)
    h_path = np.mean([ref_pose_entropy(paths[:, k], wn) for k in range(t)])
    assert C.path_entropy(paths, w) == pytest.approx(h_path, abs=1e-6)
    h_maps = sum(wi * sum(ref_h2(v) for v in g.ravel()) for wi, g in zip(wn, grids, strict=False)) * math.log(2)
    assert C.joint_entropy(paths, grids, w) == pytest.approx(h_path + h_maps, abs=1e-6)


@given(hnp.arrays(np.float64, st.integers(1, 20), elements=st.floats(-1e9, 50)))
def test_weight_entropy_and_neff_match_reference(logw):
    w = ref_weights(logw, log=True)
    nz = w[w > 0]
    assert C.weight_entropy(logw, log=True) == pytest.approx(-(nz * np.log(nz)).sum(), abs=1e-9)
    assert C.effective_sample_size(logw, log=True) == pytest.approx(1 / (w**2).sum(), rel=1e-9)


def test_kernels_agree_with_numpy_on_large_odd_sizes():
    """Sizes around SIMD widths and a large odd one, where a vectorised tail could slip."""
    rng = np.random.default_rng(1)
    for n in (7, 8, 9, 4095, 65537):
        grids = rng.random((3, n)).astype(np.float32)
        w = np.array([0.2, 0.3, 0.5])
        em = ref_em(grids, w)
        np.testing.assert_allclose(C.expected_map(grids, w), em, atol=1e-12)
        assert C.emmi(grids, w) == pytest.approx(ref_mi(em), abs=1e-9)


# ---------------------------------------------------------------- the paper's properties


def test_empty_map_has_zero_mean_information():
    assert C.mean_information(np.full((30, 30), 0.5)) == 0.0
    assert C.emmi(np.full((4, 30, 30), 0.5), np.ones(4)) == 0.0
    assert C.emmi(np.zeros((2, 10, 10)), np.ones(2), logodds=True) == 0.0


@given(hnp.arrays(np.float64, st.integers(1, 300), elements=cell_values))
def test_mean_information_lies_in_unit_interval(p):
    assert 0.0 <= C.mean_information(p) <= 1.0


def test_certain_map_has_mean_information_one():
    rng = np.random.default_rng(0)
    p = (rng.random((20, 20)) < 0.3).astype(float)
    assert C.mean_information(p) == 1.0
    assert C.emmi(np.stack([p, p]), [1, 3]) == 1.0


def test_fig5_contradicting_particles():
    """Fig. 5: p = 0.01 vs 0.99, equal weights: EM = 0.5, EMMI ~ 0 there, joint entropy low."""
    a = np.full((8, 8), 0.01)
    b = np.full((8, 8), 0.99)
    grids, w = np.stack([a, b]), np.array([0.5, 0.5])
    np.testing.assert_allclose(C.expected_map(grids, w), 0.5)
    assert C.emmi(grids, w) == 0.0
    agree = np.stack([a, a])
    assert C.emmi(agree, w) > 0.9
    # Each particle's own map is certain: the map term of eq. (12) is as low as when they agree.
    h_cell = C.weighted_map_entropy(grids, w) / a.size
    assert h_cell == pytest.approx(ref_h2(0.01), rel=1e-9)
    assert h_cell < 0.1
    assert C.weighted_map_entropy(grids, w) == pytest.approx(C.weighted_map_entropy(agree, w))


def test_fig5_example_rows():
    from emmi_gym.certainty.examples import fig5_contrast

    agree, disagree = fig5_contrast()
    assert disagree["emmi_bits"] < agree["emmi_bits"] - 0.01
    assert disagree["joint_entropy_nats"] == pytest.approx(agree["joint_entropy_nats"])


# ---------------------------------------------------------------- numerics and weight handling


def test_no_nan_or_inf_at_the_edges():
    p = np.array([[[0.0, 1.0], [0.5, 1.0]], [[1.0, 0.0], [0.0, 0.0]]])
    for w, log in ([1.0, 0.0], False), ([0.0, -1e9], True), ([3.0, 1.0], False):
        values = [C.emmi(p, w, log_weights=log), C.expected_map(p, w, log_weights=log).sum(),
                  C.weighted_map_entropy(p, w, log_weights=log),
                  C.joint_entropy(np.zeros((2, 3, 3)), p, w, log_weights=log),
                  C.pose_entropy(np.zeros((2, 3)), w, log_weights=log),
                  C.weight_entropy(w, log=log), C.effective_sample_size(w, log=log)]
        assert np.isfinite(values).all()
    big = np.array([[1e6, -1e6, 0.0]])
    assert C.emmi(big, [1.0], logodds=True) == 1.0


def test_log_weights_of_minus_1e9_vanish():
    grids = np.stack([np.full((3, 3), 0.9), np.full((3, 3), 0.1)])
    np.testing.assert_allclose(C.expected_map(grids, [0.0, -1e9], log_weights=True), 0.9)
    assert C.weight_entropy([0.0, -1e9], log=True) == 0.0
    assert C.effective_sample_size([0.0, -1e9], log=True) == 1.0


def test_unnormalised_and_log_weights_agree():
    rng = np.random.default_rng(3)
    grids = rng.random((5, 16, 16))
    w = rng.random(5) * 100
    assert C.emmi(grids, w) == pytest.approx(C.emmi(grids, np.log(w), log_weights=True), abs=1e-12)
    assert C.emmi(grids, w) == pytest.approx(C.emmi(grids, w / w.sum()), abs=1e-12)


def test_single_particle():
    p = np.random.default_rng(4).random((1, 10, 10))
    assert C.emmi(p, [7.0]) == pytest.approx(C.mean_information(p[0]))
    assert C.pose_entropy([[1.0, 2.0, 3.0]], [1.0]) == pytest.approx(
        0.5 * math.log((2 * math.pi * math.e) ** 3 * C.DEFAULT_DET_FLOOR))
    assert C.weight_entropy([2.0]) == 0.0


def test_pose_entropy_wraps_heading():
    w = np.ones(2)
    across_pi = C.pose_entropy([[0, 0, math.pi - 0.05], [0.1, 0, -math.pi + 0.05]], w)
    near_zero = C.pose_entropy([[0, 0, -0.05], [0.1, 0, 0.05]], w)
    assert across_pi == pytest.approx(near_zero)


def test_pose_entropy_grows_with_spread():
    rng = np.random.default_rng(5)
    base = rng.normal(size=(50, 3))
    w = np.ones(50)
    assert C.pose_entropy(base * 0.5, w) < C.pose_entropy(base, w)
    # a Gaussian scaled by s in all three axes gains 3 ln s nats
    assert C.pose_entropy(base * 0.1, w) - C.pose_entropy(base * 0.05, w) == pytest.approx(3 * math.log(2), abs=0.2)


def test_loop_displacement_spread():
    """The spread of x_T - x_k over particles: a shared offset or a shared drift does not count."""
    rng = np.random.default_rng(6)
    common = np.cumsum(rng.normal(size=(1, 30, 3)), axis=1)
    paths = np.repeat(common, 400, axis=0) + np.array([5.0, -2.0, 0.0])  # all particles agree
    assert C.loop_displacement_spread(paths, np.ones(400), since=3) == pytest.approx(0.0, abs=1e-9)
    drifted = paths.copy()
    drifted[:, 10:, :2] += rng.normal(scale=0.3, size=(400, 1, 2))  # the particles split after update 10
    assert C.loop_displacement_spread(drifted, np.ones(400), since=12) == pytest.approx(0.0, abs=1e-9)
    assert C.loop_displacement_spread(drifted, np.ones(400), since=3) == pytest.approx(0.3 * math.sqrt(2), rel=0.1)
    # weights: one particle with all the weight leaves no spread; log weights agree with linear ones
    w = np.zeros(400)
    w[7] = 1.0
    assert C.loop_displacement_spread(drifted, w, since=3) == pytest.approx(0.0, abs=1e-9)
    logw = rng.normal(size=400)
    assert C.loop_displacement_spread(drifted, logw, since=3, log_weights=True) == pytest.approx(
        C.loop_displacement_spread(drifted, np.exp(logw), since=3))
    with pytest.raises(ValueError, match="since=30 is not an update index"):
        C.loop_displacement_spread(drifted, np.ones(400), since=30)


def test_widest_loop_spread_is_the_largest_spread_over_the_path():
    """The widest open loop: the spread since the update the particles disagree about most; 0 where they agree."""
    rng = np.random.default_rng(7)
    common = np.repeat(np.cumsum(rng.normal(size=(1, 30, 3)), axis=1), 400, axis=0)
    assert C.widest_loop_spread(common, np.ones(400)) == pytest.approx(0.0, abs=1e-9)
    assert C.widest_loop_spread(common[:, :1], np.ones(400)) == 0.0  # one pose: no loop
    split = common.copy()
    split[:, 10:, :2] += rng.normal(scale=0.3, size=(400, 1, 2))  # the particles split after update 9
    split[:, 20:, :2] += rng.normal(scale=0.1, size=(400, 1, 2))  # and again after update 19
    spreads = [C.loop_displacement_spread(split, np.ones(400), since=k) for k in range(30)]
    assert C.widest_loop_spread(split, np.ones(400)) == pytest.approx(max(spreads))
    assert max(spreads) == pytest.approx(spreads[0]) and spreads[0] > spreads[15] > spreads[25] == pytest.approx(0)
    logw = rng.normal(size=400)
    linear = C.widest_loop_spread(split, np.exp(logw))
    assert C.widest_loop_spread(split, logw, log_weights=True) == pytest.approx(linear)
    with pytest.raises(ValueError, match="30 paths but 400 weights"):
        C.widest_loop_spread(split[:30], np.ones(400))


@pytest.mark.parametrize("bad, message", [
    (dict(weights=[1.0, -1.0]), "non-negative"),
    (dict(weights=[0.0, 0.0]), "sum to zero"),
    (dict(weights=[1.0, 1.0, 1.0]), "2 grids but 3 weights"),
    (dict(weights=[np.nan, 1.0]), "finite"),
    (dict(grids=np.full((2, 3, 3), 1.5)), "lie in \\[0, 1\\]"),
])
def test_bad_input_is_named(bad, message):
    kwargs = dict(grids=np.full((2, 3, 3), 0.5), weights=[1.0, 1.0]) | bad
    with pytest.raises(ValueError, match=message):
        C.emmi(kwargs["grids"], kwargs["weights"])


def test_bad_log_weights_and_tolerance():
    with pytest.raises(ValueError, match="-inf"):
        C.normalize_weights([-np.inf, -np.inf], log=True)
    with pytest.raises(ValueError, match="observed_tol"):
        C.mean_information([0.2], observed_tol=1.0)
    with pytest.raises(ValueError, match="shape"):
        C.pose_entropy(np.zeros((3, 2)), np.ones(3))


@pytest.mark.slow
@given(st.integers(1, 5), st.integers(1, 300), st.sampled_from([np.int8, np.uint8, np.int16, np.uint16]),
       st.booleans(), st.integers(0, 2**31))
def test_integer_codes_with_lut_match_probabilities(m, n, dtype, narrow, seed):
    """Whole grids and rows of cells (whose 16-bit codes are looked up over the range they span: all
    of it, or a narrow band of it) against the probabilities."""
    rng = np.random.default_rng(seed)
    info = np.iinfo(dtype)
    lo = info.min + (rng.integers(0, info.max - info.min - 10) if narrow else 0)
    hi = min(info.max, lo + 10) if narrow else info.max
    codes = rng.integers(lo, hi + 1, size=(m, n)).astype(dtype)
    lut = rng.random(info.max - info.min + 1)
    lut[rng.random(lut.size) < 0.3] = 0.5  # many unknown codes, as in a map
    p = lut[codes.astype(np.int64) - info.min]
    w = rng.random(m) + 0.1
    np.testing.assert_allclose(C.expected_map(codes, w, lut=lut), ref_em(p, ref_weights(w)), atol=1e-12)
    np.testing.assert_allclose(C.expected_map_of_cells(codes.T, w, lut=lut), ref_em(p, ref_weights(w)), atol=1e-12)
    assert C.emmi(codes, w, lut=lut) == pytest.approx(C.emmi(p, w), abs=1e-12)
    nothing_agreed = np.zeros(lut.size, dtype=np.int64)
    assert C.emmi_of_parts(codes.T, w, nothing_agreed, lut=lut) == pytest.approx(C.emmi(p, w), abs=1e-12)
    assert C.weighted_map_entropy(codes, w, lut=lut) == pytest.approx(C.weighted_map_entropy(p, w), rel=1e-12)
    assert C.mean_information(codes[0], lut=lut) == pytest.approx(C.mean_information(p[0]), abs=1e-12)


def test_bad_lut_is_named():
    codes = np.zeros((2, 4), dtype=np.int8)
    with pytest.raises(ValueError, match="needs 256 entries"):
        C.emmi(codes, [1, 1], lut=np.full(10, 0.5))
    with pytest.raises(ValueError, match="integer codes"):
        C.emmi(codes.astype(np.float32), [1, 1], lut=np.full(256, 0.5))
    with pytest.raises(ValueError, match="probabilities in \\[0, 1\\]"):
        C.emmi(codes, [1, 1], lut=np.full(256, 2.0))
    agreed = np.zeros(256, dtype=np.int64)
    with pytest.raises(ValueError, match="codes of 2 particles per cell but 3 weights"):
        C.emmi_of_parts(codes.T, [1, 1, 1], agreed, lut=np.full(256, 0.5))
    with pytest.raises(ValueError, match=r"\(N cells, M particles\)"):
        C.expected_map_of_cells(codes.ravel(), [1, 1], lut=np.full(256, 0.5))
    with pytest.raises(ValueError, match="needs 256 entries"):
        C.emmi_of_parts(codes.T, [1, 1], agreed, lut=np.full(10, 0.5))


def test_observed_cells_decide_by_the_entropy_rule_of_eq_10():
    """The mask (|p - 0.5| outside a band, by a kernel; the entropy inside it) is exactly H2(p) <
    max_entropy_bits."""
    from emmi_gym.certainty.information import cell_entropy, max_entropy_bits, observed_halfwidth

    for tol in (0.0, 0.001, 0.05):
        h = observed_halfwidth(max_entropy_bits(tol))
        p = np.concatenate([0.5 + np.linspace(-2 * h, 2 * h, 20001), np.linspace(0, 1, 1001), [np.nan]])
        with np.errstate(invalid="ignore"):
            expected = cell_entropy(p) < max_entropy_bits(tol)
        assert np.array_equal(C.observed_cells(p, tol), expected)
        # and the labels: unobserved -1, else occupied (p > 0.5) 1 or free 0, in the input's shape
        labels = C.observation_labels(p.reshape(1, -1), tol)
        assert labels.shape == (1, p.size) and labels.dtype == np.int8
        assert np.array_equal(labels[0], np.where(expected, (p > 0.5).astype(np.int8), -1))


def test_emmi_of_parts_is_the_same_on_any_number_of_threads():
    """The disputed cells are split among threads (here 90 000 of them, three chunks): the same EMMI,
    bit for bit, as on one thread, and equal to EMMI over the whole grids."""
    from emmi_gym.concurrency.threads import kernel_threads, set_kernel_threads

    rng = np.random.default_rng(7)
    grids = rng.integers(-120, 120, (4, 300, 310)).astype(np.int8)
    grids[:, :, :10] = 50  # agreed cells
    lut = 1.0 / (1.0 + np.exp(-np.arange(-128, 128) / 20.0))
    disputed = np.flatnonzero(~np.all(grids == grids[:1], axis=0))
    agreed = np.bincount(grids[0].ravel()[np.all(grids == grids[:1], axis=0).ravel()].astype(np.int64) + 128,
                         minlength=256)
    rows = grids.reshape(4, -1)[:, disputed].T
    w = np.array([0.1, 0.2, 0.3, 0.4])
    threads = kernel_threads()
    try:
        set_kernel_threads(1)
        one = C.emmi_of_parts(rows, w, agreed, lut=lut)
        set_kernel_threads(3)
        three = C.emmi_of_parts(rows, w, agreed, lut=lut)
    finally:
        set_kernel_threads(threads)
    assert disputed.size > 60000 and one == three
    assert one == pytest.approx(C.emmi(grids, w, lut=lut), rel=1e-12)
    # its numerator and denominator: the expected map's information (eq. 9 summed) and its observed cells
    information, observed = C.expected_map_information_of_parts(rows, w, agreed, lut=lut)
    em = C.expected_map(grids, w, lut=lut)
    assert observed == np.count_nonzero(C.observed_cells(em)) and one == information / observed
    assert information == pytest.approx(C.map_information(em[C.observed_cells(em)]), rel=1e-12)


def test_the_pose_entropies_wrap_of_a_heading_difference_is_the_remainders_number():
    """``_kernels._wrapped`` replaces (d + pi) % 2 pi - pi by one add or subtract where that is exact: the
    same numbers, at and round the ends of that range and beyond it."""
    from emmi_gym.certainty._kernels import _wrapped

    two_pi = 2.0 * np.pi
    edges = np.array([-two_pi, 0.0, two_pi, 2 * two_pi]) - np.pi
    d = np.concatenate([np.random.default_rng(0).uniform(-4 * two_pi, 4 * two_pi, 20000), edges,
                        np.nextafter(edges, np.inf), np.nextafter(edges, -np.inf), [-0.0, np.pi, -np.pi]])
    assert [_wrapped(x) for x in d] == [(x + np.pi) % two_pi - np.pi for x in d.tolist()]
