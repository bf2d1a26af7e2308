"""Tests of Monte Carlo localization (``active_loc.beliefs.mcl``, ``particle_stats``).

References are independent of the package wherever it matters: scipy's ``logsumexp`` and
chi-square quantiles, numpy covariances, a plain numpy landmark likelihood, the chapter's
exercise (section 13.8, problem 1) simulated here from its equations, and the grid convention
(row 0 at the bottom, origin = world pose of the bottom-left corner of cell (0, 0)) written out
by hand. Statistical checks use fixed seeds and thresholds with a wide margin.
"""

from __future__ import annotations

import copy
import math
import pickle
import time

import numpy as np
import pytest
from scipy.special import logsumexp as scipy_logsumexp
from scipy.stats import chi2, multivariate_normal, norm

from active_loc.beliefs.entropy import gaussian_entropy
from active_loc.beliefs.mcl import (
    OCCUPIED,
    UNKNOWN,
    FreeSpace,
    MCLBelief,
    add_log_likelihood,
    landmark_log_likelihood,
    mask_free_space,
    sample_motion,
    stratified_resample,
    systematic_resample,
)
from active_loc.beliefs.particle_stats import (
    ENTROPY_BINS,
    histogram_entropy,
    kld_limit,
    logsumexp,
    normalize_log_weights,
    summarize_particles,
)
from active_loc.motion import UnicycleModel
from active_loc.sensors import (
    RANGE_BEARING,
    RELATIVE_POSITION,
    RangeBearingSensor,
    RelativePositionSensor,
)

TEXTBOOK_LANDMARKS = np.array([[0.0, 0.0], [2.0, 8.0], [8.0, 2.0], [10.0, 10.0]])
# four landmarks without symmetry, for global localization and kidnapping in a 10 m box
DISTINCT_LANDMARKS = np.array([[1.0, 1.0], [8.5, 2.0], [3.0, 9.0], [7.0, 6.5]])
BOX10 = FreeSpace.from_box(0.0, 0.0, 10.0, 10.0)


def wrap(a):
    return (np.asarray(a, dtype=np.float64) + np.pi) % (2 * np.pi) - np.pi


def angle_diff(a, b):
    d = np.asarray(a, dtype=np.float64) - np.asarray(b, dtype=np.float64)
    return np.arctan2(np.sin(d), np.cos(d))


def numpy_weights(log_w):
    w = np.exp(log_w - np.max(log_w))
    return w / w.sum()


def big_box() -> FreeSpace:
    return FreeSpace.from_box(-100.0, -100.0, 100.0, 100.0)


# --- weights -------------------------------------------------------------------------------------


def test_logsumexp_and_normalization_match_scipy():
    rng = np.random.default_rng(0)
    for scale in (1.0, 50.0, 1e4, 1e300):
        a = rng.normal(size=200) * scale
        a[::7] = -np.inf
        assert logsumexp(a) == pytest.approx(scipy_logsumexp(a), rel=1e-12, abs=1e-12)
        lw = a.copy()
        lse = normalize_log_weights(lw)
        assert lse == pytest.approx(scipy_logsumexp(a), rel=1e-12, abs=1e-12)
        assert scipy_logsumexp(lw) == pytest.approx(0.0, abs=1e-12)
        assert not np.any(np.isnan(lw))
    assert logsumexp(np.full(5, -np.inf)) == -np.inf
    assert logsumexp(np.empty(0)) == -np.inf
    lw = np.full(4, -np.inf)
    assert normalize_log_weights(lw) == -np.inf
    assert np.all(lw == -np.inf)  # left alone: the caller recovers


def summarize(parts, log_w, parallel=False):
    """``(weights, mean, cov, entropy, ess)`` of summarize_particles."""
    parts = np.ascontiguousarray(parts, dtype=np.float64)
    k = parts.shape[0]
    w, mean, cov = np.empty(k), np.empty(3), np.empty((3, 3))
    entropy, ess = summarize_particles(parts, np.asarray(log_w, dtype=np.float64),
                                       np.array(ENTROPY_BINS), parallel, w, mean, cov)
    return w, mean, cov, entropy, ess


def effective_sample_size(log_w):
    return summarize(np.zeros((len(log_w), 3)), log_w)[4]


def test_effective_sample_size_formula():
    rng = np.random.default_rng(1)
    for _ in range(5):
        lw = rng.normal(size=100) * 3.0
        w = numpy_weights(lw)
        assert effective_sample_size(lw) == pytest.approx(1.0 / np.sum(w**2), rel=1e-12)
    assert effective_sample_size(np.zeros(64)) == pytest.approx(64.0)
    one = np.full(10, -np.inf)
    one[3] = -5.0
    assert effective_sample_size(one) == pytest.approx(1.0)
    # every weight zero: read as uniform (the filter re-initializes before it gets here)
    assert effective_sample_size(np.full(10, -np.inf)) == pytest.approx(10.0)


def test_the_summary_is_the_same_on_one_thread_and_on_blocks_in_parallel():
    rng = np.random.default_rng(2)
    k = 10_000  # several blocks
    parts = np.column_stack([rng.uniform(0, 9, k), rng.uniform(0, 9, k),
                             rng.uniform(-np.pi, np.pi, k)])
    lw = rng.normal(size=k)
    for a, b in zip(summarize(parts, lw, False), summarize(parts, lw, True), strict=True):
        np.testing.assert_array_equal(a, b)


def test_add_log_likelihood_returns_the_evidence():
    rng = np.random.default_rng(2)
    lw = rng.normal(size=30)
    lw -= scipy_logsumexp(lw)
    ll = rng.normal(size=30) * 10.0 - 500.0  # exp(ll) underflows nowhere in log space
    expected_ev = scipy_logsumexp(lw + ll)
    expected_post = lw + ll - expected_ev
    work = lw.copy()
    ev = add_log_likelihood(work, ll)
    assert ev == pytest.approx(expected_ev, rel=1e-12)
    np.testing.assert_allclose(work, expected_post, rtol=1e-12, atol=1e-9)
    work = lw.copy()
    assert add_log_likelihood(work, np.full(30, -np.inf)) == -np.inf


# --- resampling ----------------------------------------------------------------------------------


def copies(idx, k):
    return np.bincount(idx, minlength=k)


def test_systematic_copies_within_floor_and_ceil():
    rng = np.random.default_rng(3)
    for trial in range(200):
        k = int(rng.integers(2, 60))
        w = rng.dirichlet(np.full(k, 0.3))
        w[rng.random(k) < 0.2] = 0.0  # some particles in walls
        if w.sum() == 0:
            w[0] = 1.0
        w /= w.sum()
        with np.errstate(divide="ignore"):
            lw = np.log(w)
        idx = np.empty(k, dtype=np.int64)
        systematic_resample(lw, rng.random(), idx)
        c = copies(idx, k)
        assert np.all(c >= np.floor(k * w - 1e-9)), trial
        assert np.all(c <= np.ceil(k * w + 1e-9)), trial
        assert np.all(c[w == 0] == 0)
        assert np.all(np.diff(idx) >= 0)


def test_stratified_copies_bounded():
    rng = np.random.default_rng(4)
    for trial in range(200):
        k = int(rng.integers(2, 60))
        w = rng.dirichlet(np.full(k, 0.3))
        w[rng.random(k) < 0.2] = 0.0
        if w.sum() == 0:
            w[-1] = 1.0
        w /= w.sum()
        with np.errstate(divide="ignore"):
            lw = np.log(w)
        idx = np.empty(k, dtype=np.int64)
        stratified_resample(lw, rng.random(k), idx)
        c = copies(idx, k)
        # each stratum gives one copy: at most one more or fewer than systematic's bounds
        assert np.all(c >= np.floor(k * w - 1e-9) - 1), trial
        assert np.all(c <= np.ceil(k * w + 1e-9) + 1), trial
        assert np.all(c[w == 0] == 0)


@pytest.mark.parametrize("scheme", ["systematic", "stratified"])
def test_resampling_is_unbiased(scheme):
    rng = np.random.default_rng(5)
    w = np.array([0.31, 0.005, 0.0, 0.2, 0.12, 0.015, 0.25, 0.1])
    with np.errstate(divide="ignore"):
        lw = np.log(w)
    k, n_draws = w.size, 4000
    total = np.zeros(k)
    idx = np.empty(k, dtype=np.int64)
    for _ in range(n_draws):
        if scheme == "systematic":
            systematic_resample(lw, rng.random(), idx)
        else:
            stratified_resample(lw, rng.random(k), idx)
        total += copies(idx, k)
    # the per-draw count has standard deviation <= 1, so the mean is within ~0.016 * 4
    np.testing.assert_allclose(total / n_draws, k * w, atol=0.07)


def test_resampling_reproducible_with_same_seed():
    lw = np.log(np.random.default_rng(6).dirichlet(np.ones(100)))
    a = np.empty(100, dtype=np.int64)
    b = np.empty(100, dtype=np.int64)
    systematic_resample(lw, np.random.default_rng(7).random(), a)
    systematic_resample(lw, np.random.default_rng(7).random(), b)
    np.testing.assert_array_equal(a, b)
    stratified_resample(lw, np.random.default_rng(8).random(100), a)
    stratified_resample(lw, np.random.default_rng(8).random(100), b)
    np.testing.assert_array_equal(a, b)


@pytest.mark.parametrize("kld", [False, True])
def test_belief_runs_reproducible(kld):
    model = UnicycleModel(0.1, 0.002 * np.eye(3))
    sensor = RangeBearingSensor.from_std(0.3, np.deg2rad(5.0))
    runs = []
    for _ in range(2):
        rng = np.random.default_rng(42)
        b = MCLBelief(BOX10, model, 1500, augmented=True, kld=kld, min_particles=200,
                      resampling="stratified")
        b.initialize_uniform(rng)
        truth = np.array([4.0, 5.0, 0.3])
        for _ in range(15):
            truth = model.sample(truth, [0.5, 0.2], rng)
            z, vis = sensor.measure(truth, DISTINCT_LANDMARKS, rng)
            b.predict([0.5, 0.2], rng)
            b.update_landmarks(z, vis, DISTINCT_LANDMARKS, sensor, rng)
        runs.append((b.particles.copy(), b.log_weights.copy(), b.entropy()))
    np.testing.assert_array_equal(runs[0][0], runs[1][0])
    np.testing.assert_array_equal(runs[0][1], runs[1][1])
    assert runs[0][2] == runs[1][2]


@pytest.mark.parametrize("bit_generator", [np.random.PCG64, np.random.MT19937])
@pytest.mark.parametrize("augmented", [False, True])
@pytest.mark.parametrize("kld", [False, True])
def test_draws_scale_with_the_active_particles(bit_generator, augmented, kld):
    """predict draws 3 K normals for the K ACTIVE particles (not the maximum), update one key,
    whether or not it resamples, with KLD and injection or without."""
    model = UnicycleModel(0.1, 0.01 * np.eye(3))
    b = MCLBelief(BOX10, model, 3000, augmented=augmented, kld=kld, min_particles=100)
    rng0 = np.random.default_rng(0)
    b.initialize_gaussian([5.0, 5.0, 0.0], 0.001 * np.eye(3), rng0)
    if kld:
        b.resample(rng0)  # a tight Gaussian: KLD keeps far fewer than 3000
    k = b.n_active
    assert (k < 3000) == kld
    rng = np.random.Generator(bit_generator(9))
    ref = np.random.Generator(bit_generator(9))
    b.predict([1.0, 0.0], rng)
    ref.standard_normal((k, 3))
    assert rng.random() == ref.random()
    b.update(np.zeros(k), rng)  # no resampling needed
    assert not b.resampled
    ref.bit_generator.random_raw()
    assert rng.random() == ref.random()
    b.update(np.where(np.arange(k) < 30, 0.0, -50.0), rng)  # ESS 30 of K: resamples
    assert b.resampled
    ref.bit_generator.random_raw()
    assert rng.random() == ref.random()


def test_a_copy_draws_what_the_original_draws():
    """Common random numbers: a copy and its original, stepped with equal Generators, end
    with equal particles, resampling included."""
    model = UnicycleModel(0.1, 0.01 * np.eye(3))
    b = MCLBelief(BOX10, model, 2000, augmented=True, kld=True, min_particles=100)
    b.initialize_uniform(np.random.default_rng(1))
    c = b.copy()
    sensor = RangeBearingSensor.from_std(0.3, np.deg2rad(5.0))
    z, vis = sensor.measure(np.array([3.0, 4.0, 0.5]), DISTINCT_LANDMARKS,
                            np.random.default_rng(2))
    for belief in (b, c):
        rng = np.random.default_rng(3)
        belief.predict([0.5, 0.1], rng)
        belief.update_landmarks(z, vis, DISTINCT_LANDMARKS, sensor, rng)
        assert belief.resampled
    np.testing.assert_array_equal(b.particles, c.particles)


# --- motion and the map --------------------------------------------------------------------------


def test_motion_sampling_matches_unicycle_plus_q():
    q = np.array([[0.010, 0.004, 0.001], [0.004, 0.020, -0.002], [0.001, -0.002, 0.005]])
    model = UnicycleModel(0.1, q)
    k = 40000
    b = MCLBelief(big_box(), model, k)
    start = np.array([1.0, 2.0, 3.0])  # heading near the seam: the mean wraps to -3.08
    b.set_particles(np.tile(start, (k, 1)))
    u = np.array([1.5, 2.0])
    b.predict(u, np.random.default_rng(10))
    p = b.particles
    mean_ref = np.array([
        start[0] + u[0] * np.cos(start[2]) * 0.1,
        start[1] + u[0] * np.sin(start[2]) * 0.1,
        wrap(start[2] + u[1] * 0.1),
    ])
    assert np.all((p[:, 2] >= -np.pi) & (p[:, 2] < np.pi))
    res = np.column_stack([p[:, 0] - mean_ref[0], p[:, 1] - mean_ref[1],
                           angle_diff(p[:, 2], mean_ref[2])])
    se = np.sqrt(np.diag(q) / k)
    assert np.all(np.abs(res.mean(axis=0)) < 5 * se)
    cov = res.T @ res / k
    # entries of a sample covariance have sd <= sqrt(2 / k) * sigma_i sigma_j
    scale = np.sqrt(np.outer(np.diag(q), np.diag(q)))
    assert np.all(np.abs(cov - q) < 6 * np.sqrt(2.0 / k) * scale)


def grid_to_world(gx, gy, res, origin):
    ox, oy, yaw = origin
    c, s = np.cos(yaw), np.sin(yaw)
    return ox + res * (c * gx - s * gy), oy + res * (s * gx + c * gy)


def hand_grid():
    """A 6 x 4 grid (0.5 m) rotated by 0.4 rad: a wall column at ix = 3, one unknown cell."""
    values = np.zeros((4, 6), dtype=np.int8)
    values[:, 3] = OCCUPIED
    values[0, 5] = UNKNOWN
    return values, 0.5, (1.0, -0.5, 0.4)


def test_particles_entering_walls_get_minus_inf_on_a_grid():
    values, res, origin = hand_grid()
    fs = FreeSpace.from_grid(values, res, origin)
    yaw = origin[2]
    # (start cell centre, heading in grid frame, expected to stay valid)
    cases = [
        ((1, 0), 0.0, True),  # into (2, 0): free
        ((1, 3), 0.0, True),
        ((2, 0), 0.0, False),  # into the wall column
        ((2, 2), 0.0, False),
        ((4, 0), 0.0, False),  # into (5, 0): unknown
        ((4, 1), 0.0, True),  # into (5, 1): free
        ((5, 1), 0.0, False),  # off the map at ix = 6
        ((0, 2), np.pi, False),  # off the map at ix = -1
        ((1, 3), np.pi / 2, False),  # off the top (row 4)
        ((1, 0), -np.pi / 2, False),  # off the bottom (row -1)
        ((4, 2), np.pi, False),  # back into the wall
        ((0, 1), np.pi / 2, True),  # up into (0, 2)
    ]
    k = len(cases)
    parts = np.empty((1, k, 3))
    for i, ((ix, iy), head, _) in enumerate(cases):
        parts[0, i, 0], parts[0, i, 1] = grid_to_world(ix + 0.5, iy + 0.5, res, origin)
        parts[0, i, 2] = wrap(yaw + head)
    lw = np.zeros((1, k))
    counts = np.array([k], dtype=np.int64)
    # one cell per step: V dt = res, no noise
    sample_motion(parts, counts, np.array([[res / 0.1, 0.0]]), 0.1, np.zeros((1, k, 3)),
                  np.zeros((3, 3)))
    mask_free_space(parts, lw, counts, fs.values, fs.geom, fs.is_grid)
    expected = np.array([ok for *_, ok in cases])
    np.testing.assert_array_equal(np.isfinite(lw[0]), expected)
    assert np.all(lw[0][expected] == 0.0)
    # and the point test agrees with the hand-written convention
    np.testing.assert_array_equal(fs.is_free(parts[0]), expected)


def test_grid_point_test_follows_the_convention():
    values, res, origin = hand_grid()
    fs = FreeSpace.from_grid(values, res, origin)
    rng = np.random.default_rng(11)
    gx = rng.uniform(-1.5, 7.5, 2000)
    gy = rng.uniform(-1.5, 5.5, 2000)
    wx, wy = grid_to_world(gx, gy, res, origin)
    ix, iy = np.floor(gx).astype(int), np.floor(gy).astype(int)
    inside = (ix >= 0) & (ix < 6) & (iy >= 0) & (iy < 4)
    expected = np.zeros(2000, dtype=bool)
    expected[inside] = values[iy[inside], ix[inside]] == 0
    np.testing.assert_array_equal(fs.is_free(np.column_stack([wx, wy])), expected)
    assert fs.area == pytest.approx(19 * 0.25)  # 24 cells, 4 walls, 1 unknown
    # uniform free poses are free, with headings in [-pi, pi)
    poses = fs.sample(3000, rng)
    assert fs.is_free(poses).all()
    assert np.all((poses[:, 2] >= -np.pi) & (poses[:, 2] < np.pi))


def test_particles_leaving_the_box_get_minus_inf():
    fs = FreeSpace.from_box(0.0, 0.0, 2.0, 1.0)
    parts = np.array([[[1.95, 0.5, 0.0], [1.0, 0.5, 0.0], [0.5, 0.95, np.pi / 2],
                       [0.05, 0.5, -np.pi + 1e-9], [0.5, 0.5, -np.pi / 2]]])
    lw = np.zeros((1, 5))
    counts = np.array([5], dtype=np.int64)
    sample_motion(parts, counts, np.array([[1.0, 0.0]]), 0.1, np.zeros((1, 5, 3)),
                  np.zeros((3, 3)))
    mask_free_space(parts, lw, counts, fs.values, fs.geom, fs.is_grid)
    np.testing.assert_array_equal(np.isfinite(lw[0]), [False, True, False, False, True])
    # the border itself is inside (inclusive, as motion.move_within_bounds)
    assert fs.is_free(np.array([[2.0, 1.0], [0.0, 0.0], [2.0 + 1e-12, 0.5]])).tolist() == [
        True, True, False,
    ]


# --- moments and entropy -------------------------------------------------------------------------


def test_circular_mean_across_the_seam():
    parts = np.array([[0.0, 0.0, np.pi - 0.1], [2.0, 0.0, -np.pi + 0.1]])
    out = summarize(parts, np.zeros(2))[1]
    assert out[0] == pytest.approx(1.0)
    assert abs(angle_diff(out[2], np.pi)) < 1e-12
    assert -np.pi <= out[2] < np.pi
    lw = np.log(np.array([0.75, 0.25]))
    out = summarize(parts, lw)[1]
    expected = np.arctan2(0.75 * np.sin(np.pi - 0.1) + 0.25 * np.sin(-np.pi + 0.1),
                          0.75 * np.cos(np.pi - 0.1) + 0.25 * np.cos(-np.pi + 0.1))
    assert out[2] == pytest.approx(expected)
    assert out[0] == pytest.approx(0.5)


def test_covariance_matches_numpy_with_wrapped_residuals():
    rng = np.random.default_rng(12)
    k = 500
    parts = np.column_stack([rng.normal(3, 0.5, k), rng.normal(-1, 0.2, k),
                             wrap(np.pi + rng.normal(0, 0.3, k))])
    lw = rng.normal(size=k)
    w = numpy_weights(lw)
    mean = summarize(parts, lw)[1]
    c_mean = np.arctan2(np.sum(w * np.sin(parts[:, 2])), np.sum(w * np.cos(parts[:, 2])))
    assert abs(angle_diff(mean[2], c_mean)) < 1e-12
    np.testing.assert_allclose(mean[:2], w @ parts[:, :2], rtol=1e-12)
    res = np.column_stack([parts[:, 0] - mean[0], parts[:, 1] - mean[1],
                           angle_diff(parts[:, 2], mean[2])])
    # the second moment about the circular mean (np.cov would centre the wrapped heading
    # residuals on their own average, which differs from the circular mean by ~1e-4 rad)
    expected = (res * w[:, None]).T @ res
    np.testing.assert_allclose(expected[:2, :2], np.cov(res[:, :2].T, aweights=w, bias=True),
                               rtol=1e-10)
    out = summarize(parts, lw)[2]
    np.testing.assert_allclose(out, expected, rtol=1e-10, atol=1e-14)
    assert out[2, 2] < 0.15  # ~0.09: not the huge variance of unwrapped residuals
    # the belief methods are the same kernels
    b = MCLBelief(big_box(), UnicycleModel(), k)
    b.set_particles(parts, lw)
    np.testing.assert_allclose(b.covariance(), expected, rtol=1e-10, atol=1e-14)


def test_entropy_of_a_uniform_cloud_is_log_of_the_volume():
    k = 300_000
    b = MCLBelief(FreeSpace.from_box(0.0, 0.0, 4.0, 4.0), UnicycleModel(), k)
    b.initialize_uniform(np.random.default_rng(13))
    h = b.entropy()
    # 9216 cells, 32 particles each: the histogram's finite-sample bias is ~ -cells / (2 K)
    assert h == pytest.approx(np.log(16.0 * 2 * np.pi), abs=0.05)
    tight = MCLBelief(big_box(), UnicycleModel(), 5000)
    tight.initialize_gaussian([1.1, 1.1, 0.1], np.diag([0.02, 0.02, 0.01]) ** 2,
                              np.random.default_rng(14))
    assert tight.entropy() < h - 4.0


def test_entropy_all_in_one_bin_is_log_cell_volume():
    bins = (0.25, 0.25, 2 * np.pi / 36)
    parts = np.tile([1.1, -0.3, 0.05], (50, 1))
    lw = np.random.default_rng(15).normal(size=50)
    assert histogram_entropy(parts, lw, *bins) == pytest.approx(np.log(np.prod(bins)))
    b = MCLBelief(big_box(), UnicycleModel(), 50, entropy_bins=(0.5, 0.1, 0.2))
    b.set_particles(parts, lw)
    assert b.entropy() == pytest.approx(np.log(0.5 * 0.1 * 0.2))


def test_entropy_of_a_gaussian_cloud_is_close_to_the_gaussian_entropy():
    """The histogram entropy plus log(cell volume) is comparable with the EKF's figure."""
    cov = np.diag([0.6, 0.5, 0.35]) ** 2
    b = MCLBelief(big_box(), UnicycleModel(), 200_000)
    b.initialize_gaussian([0.3, -0.2, 0.5], cov, np.random.default_rng(16))
    assert b.entropy() == pytest.approx(float(gaussian_entropy(cov)), abs=0.06)


# --- landmark likelihood -------------------------------------------------------------------------


def h_reference(pose, landmark, kind):
    dx, dy = landmark[0] - pose[0], landmark[1] - pose[1]
    if kind == RELATIVE_POSITION:
        c, s = np.cos(pose[2]), np.sin(pose[2])
        return np.array([c * dx + s * dy, -s * dx + c * dy])
    return np.array([np.hypot(dx, dy), angle_diff(np.arctan2(dy, dx), pose[2])])


def loglik_reference(particles, z, visible, landmarks, kind, r, known):
    out = np.zeros(len(particles))
    for k, pose in enumerate(particles):
        for i in range(len(z)):
            if not visible[i]:
                continue
            vals = []
            for j in [i] if known else range(len(landmarks)):
                resid = z[i] - h_reference(pose, landmarks[j], kind)
                if kind == RANGE_BEARING:
                    resid[1] = angle_diff(resid[1], 0.0)
                vals.append(multivariate_normal.logpdf(resid, np.zeros(2), r))
            out[k] += max(vals)
    return out


@pytest.mark.parametrize("kind", [RELATIVE_POSITION, RANGE_BEARING])
@pytest.mark.parametrize("known", [True, False])
def test_landmark_likelihood_matches_numpy(kind, known):
    rng = np.random.default_rng(17 + kind)
    particles = np.column_stack([rng.uniform(0, 10, 60), rng.uniform(0, 10, 60),
                                 rng.uniform(-np.pi, np.pi, 60)])
    truth = np.array([4.0, 6.0, 3.0])
    r = np.array([[0.09, 0.01], [0.01, 0.04]]) if kind == RELATIVE_POSITION else np.diag(
        [0.04, 0.01]
    )
    z = np.array([h_reference(truth, m, kind) for m in TEXTBOOK_LANDMARKS])
    z += rng.normal(size=z.shape) * 0.1
    if kind == RANGE_BEARING:
        z[:, 1] = wrap(z[:, 1])
    visible = np.array([True, False, True, True])
    got = landmark_log_likelihood(particles, z, visible, TEXTBOOK_LANDMARKS, kind, r, known)
    expected = loglik_reference(particles, z, visible, TEXTBOOK_LANDMARKS, kind, r, known)
    np.testing.assert_allclose(got, expected, rtol=1e-10, atol=1e-8)
    if not known:
        # ML matching can only do better than the true correspondence
        assert np.all(got >= landmark_log_likelihood(
            particles, z, visible, TEXTBOOK_LANDMARKS, kind, r, True) - 1e-9)


def test_identical_landmarks_match_the_nearest_one_per_particle():
    """Relative position with R = sigma^2 I: the ML landmark is the one nearest to the point
    where the particle would put the measurement, ``p + R(theta) z``."""
    rng = np.random.default_rng(19)
    lms = np.array([[0.0, 0.0], [3.0, 0.0], [0.0, 3.0], [3.0, 3.0], [1.5, 1.5]])
    particles = np.column_stack([rng.uniform(-1, 4, 300), rng.uniform(-1, 4, 300),
                                 rng.uniform(-np.pi, np.pi, 300)])
    z = np.array([[1.0, 0.5]])
    r = 0.05 * np.eye(2)
    got = landmark_log_likelihood(particles, z, [True], lms, RELATIVE_POSITION, r, False)
    c, s = np.cos(particles[:, 2]), np.sin(particles[:, 2])
    world = particles[:, :2] + np.column_stack([c * z[0, 0] - s * z[0, 1],
                                                s * z[0, 0] + c * z[0, 1]])
    nearest = np.argmin(np.linalg.norm(world[:, None, :] - lms[None], axis=-1), axis=1)
    assert len(np.unique(nearest)) == len(lms)  # every landmark wins somewhere
    d2 = np.sum((world - lms[nearest]) ** 2, axis=1)
    expected = -np.log(2 * np.pi * 0.05) - 0.5 * d2 / 0.05
    np.testing.assert_allclose(got, expected, rtol=1e-10, atol=1e-10)


def test_landmark_likelihood_rejects_bad_input():
    p = np.zeros((3, 3))
    with pytest.raises(ValueError, match="one row per landmark"):
        landmark_log_likelihood(p, np.zeros((3, 2)), np.ones(3, bool), TEXTBOOK_LANDMARKS, 0,
                                np.eye(2))
    with pytest.raises(ValueError, match="positive definite"):
        landmark_log_likelihood(p, np.zeros((4, 2)), np.ones(4, bool), TEXTBOOK_LANDMARKS, 0,
                                -np.eye(2))
    with pytest.raises(ValueError, match="kind"):
        landmark_log_likelihood(p, np.zeros((4, 2)), np.ones(4, bool), TEXTBOOK_LANDMARKS, 7,
                                np.eye(2))


# --- filtering -----------------------------------------------------------------------------------


def test_textbook_exercise_tracking():
    """Section 13.8, problem 1, with MCL: 1000 particles track the truth."""
    dt, steps = 0.1, 150
    q = 0.1 * dt**2 * np.eye(3)
    r = 0.25 * np.eye(2)
    start = np.array([1.0, 1.0, 0.0])
    sim = np.random.default_rng(2024)
    # the chapter's models, written out
    truth = start.copy()
    truths, zs, controls = [], [], []
    for k in range(1, steps + 1):
        u = np.array([1.0, np.sin(k * dt)])
        truth = truth + np.array([u[0] * np.cos(truth[2]) * dt, u[0] * np.sin(truth[2]) * dt,
                                  u[1] * dt]) + sim.multivariate_normal(np.zeros(3), q)
        c, s = np.cos(truth[2]), np.sin(truth[2])
        rot_t = np.array([[c, s], [-s, c]])
        z = (TEXTBOOK_LANDMARKS - truth[:2]) @ rot_t.T + sim.multivariate_normal(
            np.zeros(2), r, size=4)
        truths.append(truth.copy())
        zs.append(z)
        controls.append(u)
    b = MCLBelief(FreeSpace.from_box(-10.0, -10.0, 20.0, 20.0), UnicycleModel(dt, q), 1000)
    rng = np.random.default_rng(7)
    b.initialize_gaussian(start, 0.1 * np.eye(3), rng)
    sensor = RelativePositionSensor(r)
    errors = []
    for u, z, truth in zip(controls, zs, truths, strict=True):
        b.predict(u, rng)
        b.update_landmarks(z, np.ones(4, bool), TEXTBOOK_LANDMARKS, sensor, rng)
        m = b.mean()
        errors.append([m[0] - truth[0], m[1] - truth[1], angle_diff(m[2], truth[2])])
        assert np.all(np.isfinite(b.log_weights[np.isfinite(b.log_weights)]))
    rmse = np.sqrt(np.mean(np.square(errors), axis=0))
    print(f"\nMCL textbook RMSE: x {rmse[0]:.3f} m, y {rmse[1]:.3f} m, theta {rmse[2]:.3f} rad")
    assert rmse[0] < 0.3 and rmse[1] < 0.3
    assert rmse[2] < 0.15


def run_circle(b, truth, steps, model, sensor, sim, rng, u=(0.5, 0.3)):
    for _ in range(steps):
        truth = model.sample(truth, u, sim)
        z, vis = sensor.measure(truth, DISTINCT_LANDMARKS, sim)
        b.predict(u, rng)
        b.update_landmarks(z, vis, DISTINCT_LANDMARKS, sensor, rng)
    return truth


def pose_ok(b, truth, tol_xy=0.5, tol_th=0.2):
    m = b.mean()
    return bool(np.hypot(*(m[:2] - truth[:2])) < tol_xy and abs(angle_diff(m[2], truth[2]))
                < tol_th)


def test_global_localization_converges():
    true_model = UnicycleModel(0.1, np.diag([0.02, 0.02, 0.01]) ** 2)
    filt_model = UnicycleModel(0.1, 0.001 * np.eye(3))
    sensor = RangeBearingSensor.from_std(0.3, np.deg2rad(5.0))
    ok = 0
    for seed in range(20):
        sim = np.random.default_rng(seed)
        rng = np.random.default_rng(1000 + seed)
        truth = np.array([sim.uniform(2, 8), sim.uniform(2, 8), sim.uniform(-np.pi, np.pi)])
        b = MCLBelief(BOX10, filt_model, 1000)
        b.initialize_uniform(rng)
        h0 = b.entropy()
        truth = run_circle(b, truth, 30, true_model, sensor, sim, rng)
        ok += pose_ok(b, truth)
        assert b.entropy() < h0
    print(f"\nglobal localization: {ok}/20 seeds within 0.5 m and 0.2 rad after 30 steps")
    assert ok >= 16


def test_augmented_mcl_recovers_from_kidnapping():
    true_model = UnicycleModel(0.1, np.diag([0.02, 0.02, 0.01]) ** 2)
    filt_model = UnicycleModel(0.1, 0.001 * np.eye(3))
    sensor = RangeBearingSensor.from_std(0.3, np.deg2rad(5.0))
    n_seeds, n_after = 20, 50
    recovered = {True: 0, False: 0}
    injected = 0
    for augmented in (True, False):
        for seed in range(n_seeds):
            sim = np.random.default_rng(seed)
            rng = np.random.default_rng(1000 + seed)
            truth = np.array([3.0, 3.0, 0.0])
            b = MCLBelief(BOX10, filt_model, 1000, augmented=augmented)
            b.initialize_gaussian(truth, np.diag([0.01, 0.01, 0.001]), rng)
            truth = run_circle(b, truth, 20, true_model, sensor, sim, rng)
            assert pose_ok(b, truth)  # tracking before the kidnapping
            truth = truth + np.array([4.0, 3.5, 2.0])  # kidnapped
            truth[2] = wrap(truth[2])
            max_rate = 0.0
            for _ in range(n_after):
                truth = run_circle(b, truth, 1, true_model, sensor, sim, rng)
                max_rate = max(max_rate, b.last_injection_rate)
            recovered[augmented] += pose_ok(b, truth)
            if augmented:
                injected += max_rate > 0.0
            else:
                assert max_rate == 0.0
    print(f"\nkidnapped: recovered within {n_after} steps in {recovered[True]}/{n_seeds} seeds "
          f"with augmented MCL, {recovered[False]}/{n_seeds} without")
    assert injected == n_seeds
    assert recovered[True] >= 13
    assert recovered[False] <= 4


def test_kld_limit_matches_the_chi_square_quantile():
    z = 0.99
    for k in (5, 10, 50, 200, 1000):
        exact = chi2.ppf(norm.cdf(z), k - 1) / (2 * 0.01)
        assert kld_limit(k, 1, 10**9, 0.01, z) == pytest.approx(exact, rel=0.03)
    assert kld_limit(1, 500, 5000, 0.01, z) == 500
    assert kld_limit(0, 500, 5000, 0.01, z) == 500
    assert kld_limit(3, 500, 5000, 0.01, z) == 500
    assert kld_limit(10**5, 500, 5000, 0.01, z) == 5000
    limits = [kld_limit(k, 1, 10**9, 0.01, z) for k in range(2, 300)]
    assert np.all(np.diff(limits) >= 0)


def test_kld_particle_count_adapts():
    true_model = UnicycleModel(0.1, np.diag([0.02, 0.02, 0.01]) ** 2)
    filt_model = UnicycleModel(0.1, 0.001 * np.eye(3))
    sensor = RangeBearingSensor.from_std(0.3, np.deg2rad(5.0))
    sim = np.random.default_rng(20)
    rng = np.random.default_rng(21)
    b = MCLBelief(BOX10, filt_model, 5000, kld=True)  # ROS AMCL's defaults: 100 .. 5000
    b.initialize_uniform(rng)
    assert b.n_active == 5000
    b.resample(rng)  # a uniform belief needs the maximum
    assert b.n_active >= 0.9 * 5000
    truth = np.array([5.0, 4.0, 1.0])
    counts = []
    for _ in range(40):
        truth = run_circle(b, truth, 1, true_model, sensor, sim, rng)
        counts.append(b.n_active)
        assert b.particles.shape == (b.n_active, 3)
        assert b.log_weights.shape == (b.n_active,)
        assert np.isfinite(b.entropy())
    print(f"\nKLD particle counts: first {counts[:5]}, last {counts[-5:]}")
    assert all(100 <= c <= 5000 for c in counts)
    assert counts[-1] <= 1200
    assert pose_ok(b, truth)
    # an (almost) point belief: the minimum
    # (centred inside one KLD bin: 5.0 m and 0 rad are bin edges, a cloud there spans 8 bins)
    b.initialize_gaussian([5.25, 5.25, np.deg2rad(5.0)], np.diag([0.01, 0.01, 0.01]) ** 2, rng)
    b.resample(rng)
    assert b.n_active == 100
    # the full-size arrays keep their shape
    assert b._particles.shape == (1, 5000, 3)


# --- robustness ----------------------------------------------------------------------------------


def tracked_belief(k=400, **kwargs):
    b = MCLBelief(BOX10, UnicycleModel(0.1, 0.001 * np.eye(3)), k, **kwargs)
    b.initialize_gaussian([5.0, 5.0, 0.5], 0.05 * np.eye(3), np.random.default_rng(22))
    return b


def test_all_minus_inf_likelihoods_reinitialize():
    b = tracked_belief()
    b.update(np.full(400, -np.inf), np.random.default_rng(23))
    assert b.reinitialized and b.n_reinitializations == 1
    assert np.all(np.isfinite(b.log_weights))
    np.testing.assert_allclose(b.weights, 1 / 400)
    assert BOX10.is_free(b.particles).all()
    assert np.all(np.isfinite(b.mean())) and np.all(np.isfinite(b.covariance()))
    # spread over the box now
    assert b.covariance()[0, 0] > 4.0
    b.predict([0.1, 0.0], np.random.default_rng(24))
    assert not b.reinitialized  # the flag is per step


def test_a_move_that_puts_every_particle_in_a_wall_is_read_as_blocked():
    values = np.zeros((4, 8), dtype=np.int8)
    values[:, 4:] = OCCUPIED
    fs = FreeSpace.from_grid(values, 0.5, (0.0, 0.0, 0.0))
    b = MCLBelief(fs, UnicycleModel(0.1, 1e-6 * np.eye(3)), 200)
    b.initialize_gaussian([1.8, 1.0, 0.0], np.diag([0.01, 0.1, 0.0]) ** 2,
                          np.random.default_rng(25))
    before, before_w = b.particles.copy(), b.log_weights.copy()
    b.predict([10.0, 0.0], np.random.default_rng(26))  # 1 m east: every particle in the wall
    assert b.blocked and not b.reinitialized
    np.testing.assert_array_equal(b.particles, before)
    np.testing.assert_array_equal(b.log_weights, before_w)
    assert np.all(np.isfinite(b.log_weights))
    assert not np.any(np.isnan(b.mean()))
    b.predict([-1.0, 0.0], np.random.default_rng(27))  # 0.1 m west: free again
    assert not b.blocked
    assert np.all(b.particles[:, 0] < before[:, 0])


def test_an_initial_gaussian_inside_a_wall_reinitializes():
    values = np.zeros((4, 8), dtype=np.int8)
    values[:, 4:] = OCCUPIED
    fs = FreeSpace.from_grid(values, 0.5, (0.0, 0.0, 0.0))
    b = MCLBelief(fs, UnicycleModel(0.1, 1e-6 * np.eye(3)), 200)
    b.initialize_gaussian([3.0, 1.0, 0.0], np.diag([0.01, 0.01, 0.01]) ** 2,
                          np.random.default_rng(25))
    assert b.reinitialized
    assert fs.is_free(b.particles).all()
    assert np.all(np.isfinite(b.log_weights))


def test_some_particles_in_walls_lose_their_weight():
    values = np.zeros((4, 8), dtype=np.int8)
    values[:, 4:] = OCCUPIED
    fs = FreeSpace.from_grid(values, 0.5, (0.0, 0.0, 0.0))
    b = MCLBelief(fs, UnicycleModel(0.1, 1e-6 * np.eye(3)), 200)
    parts = np.column_stack([np.linspace(0.2, 1.9, 200), np.full(200, 1.0), np.zeros(200)])
    b.set_particles(parts)
    b.predict([2.0, 0.0], np.random.default_rng(27))  # 0.2 m east
    dead = parts[:, 0] + 0.2 >= 2.0
    assert not b.reinitialized
    assert np.all(b.log_weights[dead] == -np.inf)
    np.testing.assert_allclose(b.weights[~dead], 1 / np.sum(~dead))


def test_single_surviving_particle_is_copied():
    b = tracked_belief()
    survivor = b.particles[7].copy()
    ll = np.full(400, -np.inf)
    ll[7] = -3.0
    b.update(ll, np.random.default_rng(28))
    assert b.resampled and not b.reinitialized
    np.testing.assert_array_equal(b.particles, np.tile(survivor, (400, 1)))
    np.testing.assert_allclose(b.weights, 1 / 400)
    assert np.all(np.isfinite(b.covariance()))


@pytest.mark.parametrize("scheme", ["systematic", "stratified"])
def test_hugely_negative_log_likelihoods(scheme):
    b = tracked_belief(resampling=scheme)
    before = b.particles.copy()
    b.update(np.full(400, -1e300), np.random.default_rng(29))  # finite: no collapse
    assert not b.reinitialized and not b.resampled
    np.testing.assert_allclose(b.weights, 1 / 400)
    np.testing.assert_array_equal(b.particles, before)
    ll = np.zeros(400)
    ll[100:] = -1e300
    b.update(ll, np.random.default_rng(30))
    assert b.resampled and not b.reinitialized
    # only the first 100 particles can have survived
    assert np.all(np.isin(b.particles[:, 0], before[:100, 0]))
    for x in (b.log_weights, b.mean(), b.covariance(), [b.entropy()]):
        assert not np.any(np.isnan(x))
    # -inf mixed with finite values, and repeated tiny likelihoods, stay finite
    for _ in range(5):
        ll = np.full(400, -1e300)
        ll[::3] = -np.inf
        b.update(ll, np.random.default_rng(31))
        assert not np.any(np.isnan(b.log_weights))
        assert b.n_reinitializations == 0


def test_augmented_weights_stay_finite_through_a_collapse():
    b = tracked_belief(augmented=True)
    rng = np.random.default_rng(32)
    for _ in range(3):
        b.update(np.random.default_rng(0).normal(size=400) - 1e4, rng)
    b.update(np.full(400, -np.inf), rng)
    assert b.reinitialized
    assert b.injection_rate == 0.0  # the averages restart with the new set
    b.update(np.zeros(400), rng)
    assert 0.0 <= b.injection_rate <= 1.0


def test_bad_input_raises():
    b = MCLBelief(BOX10, UnicycleModel(), 100)
    with pytest.raises(RuntimeError, match="initialize"):
        b.predict([1.0, 0.0], np.random.default_rng(0))
    b.initialize_uniform(np.random.default_rng(0))
    with pytest.raises(ValueError, match="one entry per active particle"):
        b.update(np.zeros(99), np.random.default_rng(0))
    with pytest.raises(ValueError, match="NaN"):
        b.update(np.full(100, np.nan), np.random.default_rng(0))
    with pytest.raises(ValueError, match="NaN or"):
        b.update(np.full(100, np.inf), np.random.default_rng(0))
    with pytest.raises(ValueError, match="control"):
        b.predict([np.nan, 0.0], np.random.default_rng(0))
    with pytest.raises(ValueError, match="positive weight"):
        b.set_particles(np.full((100, 3), 20.0))
    for kwargs, field in [
        ({"n_particles": 0}, "n_particles"),
        ({"resampling": "multinomial"}, "resampling"),
        ({"resample_threshold": 1.5}, "resample_threshold"),
        ({"alpha_slow": 0.2, "alpha_fast": 0.1}, "alpha_slow"),
        ({"kld": True, "min_particles": 1000}, "min_particles"),
        ({"kld": True, "min_particles": 50, "kld_err": 0.0}, "kld_err"),
        ({"entropy_bins": (0.1, 0.0, 0.1)}, "entropy_bins"),
    ]:
        args = {"n_particles": 100, **kwargs}
        with pytest.raises(ValueError, match=field):
            MCLBelief(BOX10, UnicycleModel(), **args)
    with pytest.raises(ValueError, match="no FREE"):
        FreeSpace.from_grid(np.full((3, 3), OCCUPIED), 1.0)
    with pytest.raises(ValueError, match="box"):
        FreeSpace.from_box(0.0, 0.0, -1.0, 1.0)
    with pytest.raises(ValueError, match="resolution"):
        FreeSpace.from_grid(np.zeros((3, 3)), 0.0)


def test_copy_is_deep_and_views_are_read_only():
    b = tracked_belief(augmented=True)
    c = b.copy()
    c.predict([1.0, 0.5], np.random.default_rng(33))
    c.update(np.random.default_rng(34).normal(size=400) * 5, np.random.default_rng(35))
    assert not np.array_equal(b.particles, c.particles)
    assert b.batch_size == 1
    with pytest.raises(ValueError):
        b.particles[0, 0] = 1.0
    with pytest.raises(ValueError):
        b.log_weights[0] = 1.0


def test_pickle_and_deepcopy_continue_identically():
    sensor = RangeBearingSensor.from_std(0.3, np.deg2rad(5.0))
    b = MCLBelief(BOX10, UnicycleModel(0.1, 0.002 * np.eye(3)), 800, augmented=True, kld=True,
                  min_particles=100)
    rng = np.random.default_rng(37)
    b.initialize_uniform(rng)
    truth = np.array([5.0, 5.0, 0.0])
    model = UnicycleModel(0.1, 1e-4 * np.eye(3))
    truth = run_circle(b, truth, 5, model, sensor, rng, rng)
    clones = [pickle.loads(pickle.dumps(b)), copy.deepcopy(b), b.copy()]
    results = []
    for belief in [b, *clones]:
        r = np.random.default_rng(38)
        run_circle(belief, truth.copy(), 5, model, sensor, r, r)
        results.append((belief.particles.copy(), belief.log_weights.copy(), belief.n_active))
    for other in results[1:]:
        np.testing.assert_array_equal(results[0][0], other[0])
        np.testing.assert_array_equal(results[0][1], other[1])
        assert results[0][2] == other[2]


def test_timing_of_one_cycle():
    """Not an assertion: one predict + landmark likelihood + update + resample, K = 1000."""
    sensor = RelativePositionSensor(0.25 * np.eye(2))
    b = MCLBelief(FreeSpace.from_box(-10, -10, 20, 20), UnicycleModel(0.1, 0.001 * np.eye(3)),
                  1000, resample_threshold=1.0)  # resample every time
    rng = np.random.default_rng(36)
    b.initialize_gaussian([1.0, 1.0, 0.0], 0.1 * np.eye(3), rng)
    z, vis = sensor.measure(np.array([1.0, 1.0, 0.0]), TEXTBOOK_LANDMARKS, rng)

    def cycle():
        b.predict([1.0, 0.1], rng)
        b.update_landmarks(z, vis, TEXTBOOK_LANDMARKS, sensor, rng)

    def stats():
        b.mean()
        b.covariance()
        b.entropy()

    for fn in (cycle, stats):
        fn()
    n = 300
    t0 = time.perf_counter()
    for _ in range(n):
        cycle()
    t_cycle = (time.perf_counter() - t0) / n
    t0 = time.perf_counter()
    for _ in range(n):
        stats()
    t_stats = (time.perf_counter() - t0) / n
    assert b.resampled
    print(f"\nMCL K=1000, 4 landmarks: predict+update+resample {t_cycle * 1e6:.0f} us; "
          f"mean+cov+entropy {t_stats * 1e6:.0f} us")
    assert math.isfinite(t_cycle)


def test_dense_entropy_grid_gives_the_hash_tables_entropy():
    """The dense grid of entropy bins and the hash table bin alike: the same entropy, for
    sets large and small, and a particle off the grid sends the belief to the hash table."""
    from active_loc.beliefs.particle_stats import binned_entropy, dense_binned_entropy

    rng = np.random.default_rng(4)
    box = FreeSpace.from_box(-3.0, 2.0, 9.0, 11.0)
    b = MCLBelief(box, UnicycleModel(0.1, 0.01 * np.eye(3)), 20000, kld=True, min_particles=1)
    dx, dy, dth = b.entropy_bins
    origin, acc, touched = b._entropy_grid()
    for k in (1, 7, 600, 20000):
        parts = np.column_stack([rng.uniform(-3, 9, k), rng.uniform(2, 11, k),
                                 rng.uniform(-np.pi, np.pi, k)])
        w = rng.random(k)
        w[rng.random(k) < 0.2] = 0.0
        w = w / w.sum() if w.sum() > 0 else np.full(k, 1.0 / k)
        dense = dense_binned_entropy(parts, w, dx, dy, dth, origin, acc, touched)
        assert dense == pytest.approx(binned_entropy(parts, w, dx, dy, dth), abs=1e-12)
        assert not acc.any()  # left as zeros for the next call
        b.set_particles(parts)
        assert b.entropy() == pytest.approx(histogram_entropy(parts, np.log(np.full(k, 1 / k)),
                                                              dx, dy, dth), abs=1e-12)
    parts = np.array([[0.0, 3.0, 0.0], [50.0, 3.0, 0.0]])
    w = np.array([0.5, 0.5])
    assert np.isnan(dense_binned_entropy(parts, w, dx, dy, dth, origin, acc, touched))
    assert not acc.any()


@pytest.mark.parametrize("rho", [1.0, 0.5, 0.2])
def test_the_recovery_threshold_delays_injection_in_closed_form(rho):
    """Uniform log-likelihoods c0, then c1 < c0: w_slow and w_fast follow their averaging
    rates, and the rate is max(0, 1 - w_fast / (rho w_slow))."""
    slow, fast = 0.05, 0.5
    b = tracked_belief(augmented=True, alpha_slow=slow, alpha_fast=fast,
                       recovery_threshold=rho, resample_threshold=0.0)
    rng = np.random.default_rng(40)
    c0, c1 = -2.0, -4.0
    b.update(np.full(400, c0), rng)
    assert b.injection_rate == 0.0  # both averages start at the first evidence
    b.update(np.full(400, c1), rng)
    w_slow = (1 - slow) * math.exp(c0) + slow * math.exp(c1)
    w_fast = (1 - fast) * math.exp(c0) + fast * math.exp(c1)
    assert b.injection_rate == pytest.approx(max(0.0, 1.0 - w_fast / (rho * w_slow)))
    assert (b.injection_rate > 0.0) == (w_fast / w_slow < rho)


@pytest.mark.parametrize("rho", [0.0, 1.5, True, "0.5"])
def test_a_bad_recovery_threshold_is_refused(rho):
    with pytest.raises(ValueError, match="recovery_threshold"):
        tracked_belief(augmented=True, recovery_threshold=rho)
