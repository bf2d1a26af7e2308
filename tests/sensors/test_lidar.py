"""Tests of ``active_loc.sensors.lidar``: ray casting and the range-finder models of
Probabilistic Robotics (Thrun, Burgard, Fox), chapter 6.

The references are written out here independently of the kernels:

* the ray cast against an exact slab intersection of the ray with every reflecting cell, and
  against marching along the ray in tiny steps; axis-aligned and diagonal cases analytically;
* the beam model (section 6.3) and the likelihood field (section 6.4) as plain numpy/scipy.

Grids are built by hand: ``values[iy, ix]`` int8, FREE 0, OCCUPIED 100, UNKNOWN -1, row 0 at the
bottom, origin ``(ox, oy, yaw)`` at the bottom-left corner of cell (0, 0).
"""

from __future__ import annotations

import math
import time

import numpy as np
import pytest
from scipy import integrate
from scipy.special import ndtr
from scipy.stats import norm

from active_loc.sensors.lidar import (
    MAX_READING_TOL,
    PROB_FLOOR,
    LidarSensor,
    beam_model_log_likelihood,
    beam_probability,
    cast_ray,
    cast_rays,
    likelihood_field_log_likelihood,
)

FREE, OCC, UNK = 0, 100, -1


def grid_to_world(gx, gy, res, ox, oy, yaw):
    """Inverse of the grid convention: continuous grid coordinates -> world (m)."""
    c, s = math.cos(yaw), math.sin(yaw)
    return ox + res * (c * gx - s * gy), oy + res * (s * gx + c * gy)


def grid_arrays(values, res=1.0, ox=0.0, oy=0.0, yaw=0.0):
    return (np.asarray(values, dtype=np.int8), res, ox, oy, math.cos(yaw), math.sin(yaw))


def reflecting(values, unknown_reflects):
    return (values >= 50) | (unknown_reflects & (values < 0))


def exact_range(values, res, ox, oy, c, s, x, y, angle, max_range, unknown_reflects):
    """Slab intersection of the ray with every reflecting cell (as a closed box); the first
    cell the ray overlaps for a positive length is the one hit."""
    gx = (c * (x - ox) + s * (y - oy)) / res
    gy = (-s * (x - ox) + c * (y - oy)) / res
    dx = c * math.cos(angle) + s * math.sin(angle)
    dy = -s * math.cos(angle) + c * math.sin(angle)
    assert abs(dx) > 1e-9 and abs(dy) > 1e-9, "reference is for generic directions"
    iy, ix = np.nonzero(reflecting(values, unknown_reflects))
    if ix.size == 0:
        return max_range
    tx = np.stack([(ix - gx) / dx, (ix + 1 - gx) / dx])
    ty = np.stack([(iy - gy) / dy, (iy + 1 - gy) / dy])
    t_lo = np.maximum(tx.min(0), ty.min(0))
    t_hi = np.minimum(tx.max(0), ty.max(0))
    t_in = np.maximum(t_lo, 0.0)
    hit = t_hi > t_in
    if not hit.any():
        return max_range
    return min(t_in[hit].min() * res, max_range)


def marched_range(values, res, ox, oy, c, s, x, y, angle, max_range, unknown_reflects, step):
    """First sample, every ``step`` m along the ray, that falls in a reflecting cell."""
    ny, nx = values.shape
    t = np.arange(math.ceil(max_range / step) + 1) * step
    px = x + t * math.cos(angle) - ox
    py = y + t * math.sin(angle) - oy
    gx = np.floor((c * px + s * py) / res)
    gy = np.floor((-s * px + c * py) / res)
    inside = (gx >= 0) & (gx < nx) & (gy >= 0) & (gy < ny)
    refl = np.zeros(t.shape, dtype=bool)
    refl[inside] = reflecting(values, unknown_reflects)[
        gy[inside].astype(int), gx[inside].astype(int)
    ]
    if not refl.any():
        return max_range
    return min(t[np.argmax(refl)], max_range)


def random_case(rng, yawed=True):
    ny, nx = rng.integers(4, 13, size=2)
    values = rng.choice(
        np.array([FREE, OCC, UNK], dtype=np.int8), size=(ny, nx), p=[0.75, 0.15, 0.1]
    )
    res = rng.uniform(0.1, 0.5)
    ox, oy = rng.uniform(-2, 2, size=2)
    yaw = rng.uniform(-np.pi, np.pi) if yawed else 0.0
    return values, res, ox, oy, yaw


# --------------------------------------------------------------------------- cast_ray


@pytest.mark.parametrize("unknown_reflects", [True, False])
def test_cast_ray_matches_exact_slab_reference(unknown_reflects):
    rng = np.random.default_rng(1)
    for case in range(40):
        values, res, ox, oy, yaw = random_case(rng, yawed=case % 4 != 0)
        c, s = math.cos(yaw), math.sin(yaw)
        ny, nx = values.shape
        for _ in range(30):
            # starts inside and outside the map (up to 3 cells beyond each border)
            x, y = grid_to_world(rng.uniform(-3, nx + 3), rng.uniform(-3, ny + 3), res, ox, oy, yaw)
            angle = rng.uniform(-np.pi, np.pi)
            max_range = rng.uniform(0.2, 1.5) * res * max(nx, ny)
            got = cast_ray(values, res, ox, oy, c, s, x, y, angle, max_range, unknown_reflects)
            want = exact_range(values, res, ox, oy, c, s, x, y, angle, max_range, unknown_reflects)
            assert got == pytest.approx(want, abs=1e-9), (case, x, y, angle)


def test_cast_ray_matches_marching_reference():
    rng = np.random.default_rng(2)
    step = 1e-4
    for case in range(25):
        values, res, ox, oy, yaw = random_case(rng, yawed=case % 3 != 0)
        c, s = math.cos(yaw), math.sin(yaw)
        ny, nx = values.shape
        for _ in range(6):
            x, y = grid_to_world(rng.uniform(-1, nx + 1), rng.uniform(-1, ny + 1), res, ox, oy, yaw)
            angle = rng.uniform(-np.pi, np.pi)
            unknown_reflects = bool(rng.integers(2))
            grid = (values, res, ox, oy, c, s)
            got = cast_ray(*grid, x, y, angle, 3.0, unknown_reflects)
            want = marched_range(*grid, x, y, angle, 3.0, unknown_reflects, step)
            # marching overshoots the cell border by less than one step, never undershoots
            assert want - step - 1e-9 <= got <= want + 1e-9, (case, x, y, angle)


def walled_box(nx=10, ny=8):
    values = np.zeros((ny, nx), dtype=np.int8)
    values[0, :] = values[-1, :] = values[:, 0] = values[:, -1] = OCC
    return values


@pytest.mark.parametrize("yaw", [0.0, 0.7, -2.4])
def test_cast_ray_axis_aligned_walls(yaw):
    values = walled_box(10, 8)
    res, ox, oy = 0.25, 1.0, -3.0
    g = grid_arrays(values, res, ox, oy, yaw)
    x, y = grid_to_world(3.3, 2.6, res, ox, oy, yaw)
    # the walls' inner faces are at gx = 1 and 9, gy = 1 and 7
    for rel, cells in [(0.0, 9 - 3.3), (np.pi / 2, 7 - 2.6), (np.pi, 3.3 - 1), (-np.pi / 2, 1.6)]:
        got = cast_ray(*g, x, y, yaw + rel, 100.0, True)
        assert got == pytest.approx(cells * res, abs=1e-12)
    # within max range only
    assert cast_ray(*g, x, y, yaw, 1.0, True) == 1.0


def test_cast_ray_along_grid_lines_stays_on_its_half_open_row_and_column():
    values = np.zeros((10, 10), dtype=np.int8)
    g = grid_arrays(values, 0.5, -1.0, 2.0)
    # start exactly on the vertical line gx = 3 (column 3 by the half-open convention)
    x, y = grid_to_world(3.0, 1.5, 0.5, -1.0, 2.0, 0.0)
    values[6, 2] = OCC  # left of the line: not touched by the beam
    for angle in (np.pi / 2, 5 * np.pi / 2, -3 * np.pi / 2):
        assert cast_ray(*g, x, y, angle, 100.0, True) == 100.0
    values[8, 3] = OCC  # on the beam's column
    for angle in (np.pi / 2, 5 * np.pi / 2, -3 * np.pi / 2):
        assert cast_ray(*g, x, y, angle, 100.0, True) == pytest.approx((8 - 1.5) * 0.5)
    # downwards along the same line, and horizontally along gy = 4
    values[0, 3] = OCC
    for angle in (-np.pi / 2, 3 * np.pi / 2):
        assert cast_ray(*g, x, y, angle, 100.0, True) == pytest.approx(0.5 * 0.5)
    x, y = grid_to_world(0.5, 4.0, 0.5, -1.0, 2.0, 0.0)
    values[3, 7] = OCC  # below the line gy = 4: not touched
    assert cast_ray(*g, x, y, 0.0, 100.0, True) == 100.0
    values[4, 7] = OCC
    assert cast_ray(*g, x, y, 0.0, 100.0, True) == pytest.approx(6.5 * 0.5)
    assert cast_ray(*g, x, y, -2 * np.pi, 100.0, True) == pytest.approx(6.5 * 0.5)


@pytest.mark.parametrize("yaw", [0.0, 0.3, np.pi / 2, -1.9])
def test_cast_ray_along_diagonals(yaw):
    res, ox, oy = 0.2, 0.5, -0.5
    values = np.zeros((8, 8), dtype=np.int8)
    g = grid_arrays(values, res, ox, oy, yaw)
    x, y = grid_to_world(0.5, 0.5, res, ox, oy, yaw)
    angle = yaw + np.pi / 4
    assert cast_ray(*g, x, y, angle, 100.0, True) == 100.0  # leaves through the far corner
    values[5, 5] = OCC  # on the diagonal
    assert cast_ray(*g, x, y, angle, 100.0, True) == pytest.approx(4.5 * math.sqrt(2) * res)
    # a rasterized anti-diagonal wall does not leak, nor does either of its cells alone: the
    # beam through the corner (3, 3) touches both
    for cells in ([(3, 2), (2, 3)], [(3, 2)], [(2, 3)]):
        values[:] = FREE
        for ix, iy in cells:
            values[iy, ix] = OCC
        got = cast_ray(*g, x, y, angle, 100.0, True)
        assert got == pytest.approx(2.5 * math.sqrt(2) * res), cells
    # down-left diagonal from the opposite cell centre
    values[:] = FREE
    values[1, 1] = OCC
    x, y = grid_to_world(6.5, 6.5, res, ox, oy, yaw)
    got = cast_ray(*g, x, y, angle + np.pi, 100.0, True)
    assert got == pytest.approx(4.5 * math.sqrt(2) * res)


def test_cast_ray_off_map():
    values = np.zeros((10, 10), dtype=np.int8)
    g = grid_arrays(values)
    # a beam that leaves the map reads max range (no return) ...
    assert cast_ray(*g, 5.5, 5.5, 0.3, 50.0, True) == 50.0
    # ... also from outside, pointing away or missing the map
    assert cast_ray(*g, -3.0, 5.5, np.pi, 50.0, True) == 50.0
    assert cast_ray(*g, -3.0, 5.5, np.pi / 2, 50.0, True) == 50.0
    assert cast_ray(*g, -3.0, 5.5, 0.0, 50.0, True) == 50.0
    # a start outside travels until it enters the map
    values[:, 9] = OCC
    assert cast_ray(*g, -3.0, 5.5, 0.0, 50.0, True) == pytest.approx(12.0)
    assert cast_ray(*g, -3.0, 5.5, 0.0, 11.0, True) == 11.0  # but only within range
    angle = math.atan2(0.5, 12.0)
    assert cast_ray(*g, -3.0, 5.0, angle, 50.0, True) == pytest.approx(12.0 / math.cos(angle))
    # along the border lines: y = 0 is row 0 (inside), y = 10 is outside (half-open)
    values[:] = FREE
    values[0, 4] = OCC
    values[9, 4] = OCC
    assert cast_ray(*g, -3.0, 0.0, 0.0, 50.0, True) == pytest.approx(7.0)
    assert cast_ray(*g, -3.0, 10.0, 0.0, 50.0, True) == 50.0
    # unknown off-map never reflects, whatever unknown_reflects says
    values[:] = FREE
    assert cast_ray(*g, 5.5, 5.5, 1.0, 50.0, True) == 50.0


def test_cast_ray_start_inside_reflecting_cell_and_unknown_cells():
    values = np.zeros((6, 12), dtype=np.int8)
    values[:, 11] = OCC
    values[2, 3] = OCC
    values[:, 6] = UNK
    g = grid_arrays(values, 0.5)
    x, y = grid_to_world(3.4, 2.7, 0.5, 0, 0, 0)
    for angle in np.linspace(-np.pi, np.pi, 9):
        assert cast_ray(*g, x, y, angle, 10.0, True) == 0.0
        assert cast_ray(*g, x, y, angle, 10.0, False) == 0.0
    x, y = grid_to_world(4.5, 1.5, 0.5, 0, 0, 0)
    assert cast_ray(*g, x, y, 0.0, 10.0, True) == pytest.approx(1.5 * 0.5)
    assert cast_ray(*g, x, y, 0.0, 10.0, False) == pytest.approx(6.5 * 0.5)
    x, y = grid_to_world(6.5, 1.5, 0.5, 0, 0, 0)  # inside an unknown cell
    assert cast_ray(*g, x, y, 0.0, 10.0, True) == 0.0
    assert cast_ray(*g, x, y, 0.0, 10.0, False) == pytest.approx(4.5 * 0.5)


def test_cast_ray_non_finite_input_gives_nan():
    g = grid_arrays(np.zeros((4, 4)))
    assert np.isnan(cast_ray(*g, np.nan, 1.0, 0.0, 5.0, True))
    assert np.isnan(cast_ray(*g, 1.0, 1.0, np.inf, 5.0, True))


def test_cast_rays_equals_looping_cast_ray():
    rng = np.random.default_rng(3)
    values, res, ox, oy, yaw = random_case(rng)
    g = grid_arrays(values, res, ox, oy, yaw)
    poses = np.column_stack(
        [rng.uniform(-2, 4, 17), rng.uniform(-2, 4, 17), rng.uniform(-np.pi, np.pi, 17)]
    )
    angles = np.linspace(-2.0, 2.0, 11)
    for unknown_reflects in (True, False):
        out = np.empty((17, 11))
        cast_rays(*g, poses, angles, 2.5, unknown_reflects, out)
        want = [
            [cast_ray(*g, p[0], p[1], p[2] + a, 2.5, unknown_reflects) for a in angles]
            for p in poses
        ]
        np.testing.assert_array_equal(out, want)


# --------------------------------------------------------------------------- beam model

BEAM = {
    "max_range": 8.0,
    "z_hit": 0.7,
    "z_short": 0.1,
    "z_max": 0.1,
    "z_rand": 0.1,
    "sigma_hit": 0.3,
    "lambda_short": 0.6,
}
ORDER = ("max_range", "z_hit", "z_short", "z_max", "z_rand", "sigma_hit", "lambda_short")


def beam_args(params=BEAM):
    return tuple(params[k] for k in ORDER)


def numpy_beam_model(z, expected, max_range, z_hit, z_short, z_max, z_rand, sigma, lam):
    """Table 6.1 with p_hit normalized on [0, max_range] and p_max a probability."""
    z = np.clip(z, 0.0, max_range)[None, :]
    e = np.clip(expected, 0.0, max_range)
    mass = ndtr((max_range - e) / sigma) - ndtr(-e / sigma)
    p_hit = norm.pdf(z, e, sigma) / mass
    norm_short = -np.expm1(-lam * e)
    safe = np.where(norm_short > 0, norm_short, 1.0)
    p_short = np.where((z <= e) & (norm_short > 0), lam * np.exp(-lam * z) / safe, 0.0)
    p_max = (z >= max_range * (1 - MAX_READING_TOL)).astype(float)
    p = z_hit * p_hit + z_short * p_short + z_max * p_max + z_rand / max_range
    return np.log(np.maximum(p, PROB_FLOOR)).sum(axis=1)


@pytest.mark.parametrize("expected", [0.0, 0.05, 2.5, 7.9, 8.0])
@pytest.mark.parametrize("sigma", [0.05, 0.3, 3.0])
def test_beam_density_integrates_to_one(expected, sigma):
    params = dict(BEAM, sigma_hit=sigma)
    args = beam_args(params)
    max_range, z_max = params["max_range"], params["z_max"]
    threshold = max_range * (1 - MAX_READING_TOL)

    def density(z):  # the continuous part: the point mass at max range is a probability
        return beam_probability(z, expected, *args) - (z_max if z >= threshold else 0.0)

    total, _ = integrate.quad(
        density, 0.0, max_range, points=[expected, threshold], limit=500, epsabs=1e-10
    )
    # with z* = 0 the short interval [0, z*] is empty and that term vanishes
    short = params["z_short"] if expected > 0 else 0.0
    assert total == pytest.approx(params["z_hit"] + short + params["z_rand"], abs=1e-6)
    # and the point mass is there
    assert beam_probability(max_range, expected, *args) >= z_max


def test_beam_log_likelihood_peaks_near_expected_range():
    zs = np.linspace(0.0, 8.0, 1601)
    expected = np.array([[3.7]])
    ll = np.empty(1)
    values = []
    for z in zs[:-1]:  # max range has the point mass; it is not a "near" reading
        beam_model_log_likelihood(np.array([z]), expected, *beam_args(), ll)
        values.append(ll[0])
    assert abs(zs[int(np.argmax(values))] - 3.7) <= BEAM["sigma_hit"]
    # over particles: the one whose expected scan matches the measured one wins
    rng = np.random.default_rng(4)
    truth = rng.uniform(0.5, 7.5, 30)
    shifted = truth[None, :] + np.linspace(-1.0, 1.0, 21)[:, None]
    out = np.empty(21)
    beam_model_log_likelihood(truth, shifted, *beam_args(), out)
    assert int(np.argmax(out)) == 10


@pytest.mark.parametrize("z_rand", [0.1, 0.0])
def test_beam_log_likelihood_is_finite_for_any_reading(z_rand):
    params = dict(BEAM, z_hit=0.8 - z_rand + 0.1, z_rand=z_rand, sigma_hit=0.01)
    z = np.array([0.0, 1e-12, 3.0, 8.0 - 1e-12, 8.0, 8.0 * (1 - 1e-7), 9.0, np.inf])
    expected = np.array([[0.0] * 8, [8.0] * 8, [4.0] * 8, [1e-9] * 8])
    out = np.empty(4)
    beam_model_log_likelihood(z, expected, *beam_args(params), out)
    assert np.all(np.isfinite(out))


def test_beam_log_likelihood_equals_numpy():
    rng = np.random.default_rng(5)
    m, k = 40, 25
    z = rng.uniform(0.0, 8.0, m)
    z[[0, 5, 9]] = 8.0  # max readings
    z[[1, 2]] = 0.0
    z[3] = 12.0  # beyond range: a max reading
    expected = rng.uniform(0.0, 8.0, (k, m))
    expected[0] = 0.0
    expected[1] = 8.0
    expected[2, :] = z
    out = np.empty(k)
    for params in (BEAM, dict(BEAM, sigma_hit=0.02, lambda_short=3.0)):
        beam_model_log_likelihood(z, expected, *beam_args(params), out)
        np.testing.assert_allclose(out, numpy_beam_model(z, expected, *beam_args(params)),
                                   rtol=1e-10)


# --------------------------------------------------------------------------- likelihood field


def numpy_likelihood_field(z, angles, poses, field, res, ox, oy, c, s, max_range, z_hit, z_rand,
                           sigma):
    keep = z < max_range * (1 - MAX_READING_TOL)
    r = np.maximum(z[keep], 0.0)
    a = poses[:, 2:3] + angles[keep]
    wx = poses[:, 0:1] + r * np.cos(a) - ox
    wy = poses[:, 1:2] + r * np.sin(a) - oy
    gx = (c * wx + s * wy) / res
    gy = (-s * wx + c * wy) / res
    ny, nx = field.shape
    inside = (gx >= 0) & (gx < nx) & (gy >= 0) & (gy < ny)
    ix = np.where(inside, np.floor(gx), 0).astype(int)
    iy = np.where(inside, np.floor(gy), 0).astype(int)
    d = np.where(inside, field[iy, ix], np.inf)
    p = z_hit * norm.pdf(d, 0.0, sigma) + z_rand / max_range
    return np.log(np.maximum(p, PROB_FLOOR)).sum(axis=1)


def lf_case(rng):
    ny, nx = 30, 40
    res, ox, oy, yaw = 0.1, -1.0, 0.5, 0.4
    field = rng.uniform(0.0, 1.0, (ny, nx))
    poses = np.column_stack(
        [rng.uniform(-1.5, 3.0, 50), rng.uniform(0.0, 4.0, 50), rng.uniform(-np.pi, np.pi, 50)]
    )
    angles = np.linspace(-np.pi, np.pi, 24, endpoint=False)
    z = rng.uniform(0.0, 4.0, 24)
    z[[2, 7]] = 4.0
    z[11] = np.inf
    z[12] = 0.0
    return z, angles, poses, field, (res, ox, oy, math.cos(yaw), math.sin(yaw))


def test_likelihood_field_equals_numpy():
    rng = np.random.default_rng(6)
    z, angles, poses, field, g = lf_case(rng)
    out = np.empty(50)
    for z_hit, z_rand, sigma in [(0.9, 0.1, 0.2), (0.5, 0.5, 0.05), (1.0, 0.0, 0.1)]:
        likelihood_field_log_likelihood(z, angles, poses, field, *g, 4.0, z_hit, z_rand, sigma,
                                        out)
        want = numpy_likelihood_field(z, angles, poses, field, *g, 4.0, z_hit, z_rand, sigma)
        np.testing.assert_allclose(out, want, rtol=1e-10)
        assert np.all(np.isfinite(out))


def test_likelihood_field_skips_max_readings():
    rng = np.random.default_rng(7)
    z, angles, poses, field, g = lf_case(rng)
    full, part = np.empty(50), np.empty(50)
    likelihood_field_log_likelihood(z, angles, poses, field, *g, 4.0, 0.9, 0.1, 0.2, full)
    keep = z < 4.0
    likelihood_field_log_likelihood(z[keep], angles[keep], poses, field, *g, 4.0, 0.9, 0.1, 0.2,
                                    part)
    np.testing.assert_array_equal(full, part)
    likelihood_field_log_likelihood(np.full(24, 4.0), angles, poses, field, *g, 4.0, 0.9, 0.1,
                                    0.2, full)
    np.testing.assert_array_equal(full, 0.0)
    # end points off the map keep only the random term
    far = np.array([[100.0, 100.0, 0.0]])
    one = np.empty(1)
    likelihood_field_log_likelihood(z, angles, far, field, *g, 4.0, 0.9, 0.1, 0.2, one)
    assert one[0] == pytest.approx(int(keep.sum()) * math.log(0.1 / 4.0))


# --------------------------------------------------------------------------- LidarSensor


def room(n=100, res=0.05):
    values = walled_box(n, n)
    values.setflags(write=False)  # as OccupancyGrid.kernel_arrays() hands them out
    return grid_arrays(values, res, -2.0, 1.0, 0.2)


def test_beam_angles():
    np.testing.assert_allclose(
        LidarSensor(n_beams=4).beam_angles, [-np.pi, -np.pi / 2, 0.0, np.pi / 2]
    )
    np.testing.assert_allclose(
        LidarSensor(n_beams=3, fov=np.pi / 2).beam_angles, [-np.pi / 4, 0.0, np.pi / 4]
    )
    np.testing.assert_array_equal(LidarSensor(n_beams=1, fov=1.0).beam_angles, [0.0])
    full = LidarSensor(n_beams=7, fov=np.deg2rad(360.0)).beam_angles
    assert full.shape == (7,) and full[-1] - full[0] < 2 * np.pi - 0.1
    with pytest.raises(ValueError):
        LidarSensor().beam_angles[0] = 1.0


@pytest.mark.parametrize(
    ("kwargs", "field"),
    [
        ({"n_beams": 0}, "n_beams"),
        ({"n_beams": 2.5}, "n_beams"),
        ({"n_beams": True}, "n_beams"),
        ({"fov": 0.0}, "fov"),
        ({"fov": 7.0}, "fov"),
        ({"fov": np.nan}, "fov"),
        ({"max_range": 0.0}, "max_range"),
        ({"max_range": np.inf}, "max_range"),
        ({"sigma_hit": 0.0}, "sigma_hit"),
        ({"lambda_short": -1.0}, "lambda_short"),
        ({"z_hit": -0.1, "z_short": 0.25}, "z_hit"),
        ({"z_rand": 0.5}, "sum to 1"),
        ({"model": "ray"}, "model"),
        ({"unknown_reflects": "yes"}, "unknown_reflects"),
    ],
)
def test_sensor_validation(kwargs, field):
    with pytest.raises(ValueError, match=field):
        LidarSensor(**kwargs)


def test_sensor_call_validation():
    sensor = LidarSensor(n_beams=8)
    g = room()
    rng = np.random.default_rng(0)
    with pytest.raises(ValueError, match="int8"):
        sensor.measure(np.zeros(3), (np.zeros((5, 5)), 1.0, 0.0, 0.0, 1.0, 0.0), rng)
    with pytest.raises(ValueError, match="resolution"):
        sensor.measure(np.zeros(3), (g[0], 0.0, *g[2:]), rng)
    with pytest.raises(ValueError, match="grid_arrays"):
        sensor.measure(np.zeros(3), g[:4], rng)
    with pytest.raises(ValueError, match="pose"):
        sensor.measure(np.zeros(2), g, rng)
    with pytest.raises(ValueError, match="z must"):
        sensor.log_likelihood(np.zeros(7), np.zeros((2, 3)), g, np.zeros((100, 100)))
    with pytest.raises(ValueError, match="z must"):
        sensor.log_likelihood(np.full(8, np.nan), np.zeros((2, 3)), g, np.zeros((100, 100)))
    with pytest.raises(ValueError, match="poses"):
        sensor.log_likelihood(np.ones(8), np.zeros((2, 2)), g, np.zeros((100, 100)))
    with pytest.raises(ValueError, match="distance_field"):
        sensor.log_likelihood(np.ones(8), np.zeros((2, 3)), g)
    with pytest.raises(ValueError, match="distance_field"):
        sensor.log_likelihood(np.ones(8), np.zeros((2, 3)), g, np.zeros((9, 9)))


def test_measure_is_reproducible_and_in_range():
    sensor = LidarSensor(n_beams=90, max_range=3.0)
    g = room()
    pose = np.array([0.5, 3.5, 0.3])
    a = sensor.measure(pose, g, np.random.default_rng(11))
    b = sensor.measure(pose, g, np.random.default_rng(11))
    np.testing.assert_array_equal(a, b)
    assert a.shape == (90,)
    assert np.all((a >= 0) & (a <= 3.0))


def test_measure_consumes_a_fixed_number_of_draws():
    sensor = LidarSensor(n_beams=30)
    rng_a, rng_b = np.random.default_rng(12), np.random.default_rng(12)
    sensor.measure(np.array([0.5, 3.5, 0.3]), room(), rng_a)
    sensor.measure(np.array([100.0, 100.0, 0.0]), grid_arrays(np.zeros((3, 3))), rng_b)
    assert rng_a.random() == rng_b.random()


def test_measure_noise_free_equals_ray_cast():
    sensor = LidarSensor(
        n_beams=45, max_range=4.0, sigma_hit=1e-9, z_hit=1.0, z_short=0.0, z_max=0.0, z_rand=0.0
    )
    g = room()
    pose = np.array([1.0, 2.0, -0.4])
    expected = sensor.expected_ranges(pose[None], g)[0]
    assert np.any(expected == 4.0) and np.any(expected < 4.0)  # some beams see no wall
    np.testing.assert_allclose(sensor.measure(pose, g, np.random.default_rng(0)), expected,
                               atol=1e-7)


def test_measure_mixture_statistics():
    z_hit, z_short, z_max, z_rand, sigma, lam = 0.6, 0.15, 0.1, 0.15, 0.05, 0.5
    sensor = LidarSensor(
        n_beams=36, max_range=10.0, sigma_hit=sigma, z_hit=z_hit, z_short=z_short, z_max=z_max,
        z_rand=z_rand, lambda_short=lam,
    )
    g = room()
    pose = np.array([0.3, 3.6, 1.0])
    e = sensor.expected_ranges(pose[None], g)[0]
    assert np.all(e < 10.0 - 5 * sigma) and np.all(e > 5 * sigma)  # a closed room
    rng = np.random.default_rng(13)
    scans = np.array([sensor.measure(pose, g, rng) for _ in range(2000)])
    lo, hi = e - 4 * sigma, e + 4 * sigma

    def short_mass(a, b):  # probability that a short reading falls in [a, b]
        return (np.exp(-lam * a) - np.exp(-lam * b)) / -np.expm1(-lam * e)

    want_near = z_hit * (2 * ndtr(4) - 1) + z_short * short_mass(lo, e) + z_rand * 8 * sigma / 10
    want_below = z_short * short_mass(0.0, lo) + z_rand * lo / 10
    want_above = z_rand * (10 - hi) / 10
    assert np.mean(scans == 10.0) == pytest.approx(z_max, abs=0.01)
    assert np.mean((scans >= lo) & (scans <= hi)) == pytest.approx(want_near.mean(), abs=0.01)
    assert np.mean(scans < lo) == pytest.approx(want_below.mean(), abs=0.01)
    assert np.mean((scans > hi) & (scans < 10.0)) == pytest.approx(want_above.mean(), abs=0.01)


@pytest.mark.parametrize("model", ["beam", "likelihood_field"])
def test_log_likelihood_dispatch(model):
    sensor = LidarSensor(n_beams=20, max_range=5.0, model=model)
    g = room()
    rng = np.random.default_rng(14)
    truth = np.array([1.0, 3.0, 0.5])
    z = sensor.measure(truth, g, rng)
    poses = truth + np.column_stack([rng.normal(0, 0.3, (30, 2)), rng.normal(0, 0.2, 30)])
    poses[0] = truth
    field = rng.uniform(0.0, 2.0, g[0].shape)
    got = sensor.log_likelihood(z, poses, g, field)
    want = np.empty(30)
    if model == "beam":
        expected = np.empty((30, 20))
        cast_rays(*g, poses, sensor.beam_angles, 5.0, True, expected)
        beam_model_log_likelihood(z, expected, 5.0, sensor.z_hit, sensor.z_short, sensor.z_max,
                                  sensor.z_rand, sensor.sigma_hit, sensor.lambda_short, want)
        # the beam model ray-casts itself: the distance field is not needed
        np.testing.assert_array_equal(sensor.log_likelihood(z, poses, g), want)
    else:
        likelihood_field_log_likelihood(z, sensor.beam_angles, poses, field, *g[1:], 5.0,
                                        sensor.z_hit, sensor.z_rand, sensor.sigma_hit, want)
    np.testing.assert_array_equal(got, want)
    out = np.empty(30)
    assert sensor.log_likelihood(z, poses, g, field, out=out) is out
    np.testing.assert_array_equal(out, want)


def test_beam_model_prefers_the_true_pose():
    sensor = LidarSensor(n_beams=60, max_range=8.0, model="beam")
    g = room()
    truth = np.array([1.0, 3.0, 0.5])
    z = sensor.measure(truth, g, np.random.default_rng(15))
    offsets = np.array([[0, 0, 0], [0.3, 0, 0], [0, -0.3, 0], [0, 0, 0.2], [-0.2, 0.2, -0.1]])
    ll = sensor.log_likelihood(z, truth + offsets, g)
    assert int(np.argmax(ll)) == 0


# --------------------------------------------------------------------------- timing (no assert)


def test_timing_report(capsys):
    rng = np.random.default_rng(16)
    n, res = 200, 0.05
    values = walled_box(n, n)
    values[rng.random((n, n)) < 0.01] = OCC
    values[50:150, 100] = OCC
    g = grid_arrays(values, res)
    k, m = 1000, 60
    poses = np.column_stack(
        [rng.uniform(0.1, 9.9, k), rng.uniform(0.1, 9.9, k), rng.uniform(-np.pi, np.pi, k)]
    )
    angles = np.linspace(-np.pi, np.pi, m, endpoint=False)
    expected = np.empty((k, m))
    out = np.empty(k)
    field = rng.uniform(0.0, 2.0, (n, n))
    z = rng.uniform(0.0, 10.0, m)

    def best(fn, repeats=7):
        fn()  # compile / warm up
        times = []
        for _ in range(repeats):
            t0 = time.perf_counter()
            fn()
            times.append(time.perf_counter() - t0)
        return 1e3 * min(times)

    t_cast = best(lambda: cast_rays(*g, poses, angles, 10.0, True, expected))
    beam = beam_args(dict(BEAM, max_range=10.0))
    t_beam = best(lambda: beam_model_log_likelihood(z, expected, *beam, out))
    t_lf = best(lambda: likelihood_field_log_likelihood(z, angles, poses, field, *g[1:], 10.0,
                                                        0.9, 0.1, 0.2, out))
    with capsys.disabled():
        print(
            f"\n[lidar timing] 1000 poses x 60 beams, 200x200 grid: cast_rays {t_cast:.2f} ms, "
            f"beam model {t_beam:.2f} ms, likelihood field {t_lf:.2f} ms"
        )


def test_the_precomputed_field_table_gives_the_same_log_likelihoods() -> None:
    from active_loc.maps.generators import rooms_map

    rng = np.random.default_rng(5)
    grid = rooms_map(rng, size_m=(10.0, 8.0))
    sensor = LidarSensor(n_beams=30, fov=1.5 * np.pi, max_range=6.0)
    arrays = grid.kernel_arrays()
    field = grid.distance_field()
    poses = np.column_stack([grid.sample_free(rng, 200), rng.uniform(-np.pi, np.pi, 200)])
    # a few poses off the map too, so end points fall outside it
    poses[:5, :2] += 50.0
    z = sensor.measure(poses[10], arrays, rng)
    direct = sensor.log_likelihood(z, poses, arrays, field)
    table = sensor.field_log_likelihood(z, poses, arrays, sensor.log_table(field))
    np.testing.assert_allclose(table, direct, rtol=1e-12, atol=1e-9)
