"""Tests of ``active_loc.motion``: the chapter's unicycle model, its Jacobian, noise and walls.

The reference equations (section 13.8, problem 1) are written out here independently:

    x' = x + V cos(theta) dt,  y' = y + V sin(theta) dt,  theta' = theta + omega dt  (+ eps)
"""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from active_loc.motion import (
    UnicycleModel,
    move_within_bounds,
    unicycle_jacobian,
    unicycle_mean,
)

HYP = settings(deadline=None, max_examples=60)

finite = {"allow_nan": False, "allow_infinity": False}
poses = st.tuples(
    st.floats(-50, 50, **finite), st.floats(-50, 50, **finite), st.floats(-np.pi, np.pi, **finite)
).map(np.array)
controls = st.tuples(st.floats(-3, 3, **finite), st.floats(-3, 3, **finite)).map(np.array)
dts = st.floats(1e-3, 1.0, **finite)


def angle_diff(a, b):
    d = np.asarray(a, dtype=np.float64) - np.asarray(b, dtype=np.float64)
    return np.arctan2(np.sin(d), np.cos(d))


def chapter_mean(pose, u, dt):
    """The chapter's noise-free dynamics, without heading wrap."""
    x, y, theta = pose
    v, omega = u
    return np.array([x + v * np.cos(theta) * dt, y + v * np.sin(theta) * dt, theta + omega * dt])


# --- mean -----------------------------------------------------------------------------------------


@HYP
@given(poses, controls, dts)
def test_mean_equals_chapter_equations(pose, u, dt):
    model = UnicycleModel(dt=dt, noise_cov=0.01 * np.eye(3))
    out = model.mean(pose, u)
    ref = chapter_mean(pose, u, dt)
    # x and y bit for bit; the heading is the same angle, wrapped into [-pi, pi)
    assert out[0] == ref[0]
    assert out[1] == ref[1]
    assert -np.pi <= out[2] < np.pi
    assert abs(angle_diff(out[2], ref[2])) < 1e-12


def test_mean_of_textbook_first_step():
    # the exercise: start (1, 1, 0), V = 1, omega = sin(dt), dt = 0.1
    model = UnicycleModel(dt=0.1, noise_cov=0.1 * 0.1**2 * np.eye(3))
    out = model.mean(np.array([1.0, 1.0, 0.0]), np.array([1.0, np.sin(0.1)]))
    np.testing.assert_array_equal(out[:2], [1.1, 1.0])
    # wrapping (theta + pi) % 2pi - pi rounds at the scale of pi, so the heading is exact up
    # to an ulp of pi
    assert out[2] == pytest.approx(0.1 * np.sin(0.1), abs=4.5e-16)


def test_mean_is_batched():
    rng = np.random.default_rng(0)
    batch = rng.uniform(-3, 3, size=(4, 5, 3))
    u = rng.uniform(-1, 1, size=(4, 5, 2))
    model = UnicycleModel(dt=0.2)
    out = model.mean(batch, u)
    assert out.shape == (4, 5, 3)
    for i in range(4):
        for j in range(5):
            np.testing.assert_array_equal(out[i, j], model.mean(batch[i, j], u[i, j]))


@HYP
@given(poses, controls, dts)
def test_kernel_mean_matches_model(pose, u, dt):
    out = np.empty(3)
    unicycle_mean(pose, u[0], u[1], dt, out)
    np.testing.assert_allclose(out[:2], UnicycleModel(dt=dt).mean(pose, u)[:2], atol=1e-12)
    assert abs(angle_diff(out[2], UnicycleModel(dt=dt).mean(pose, u)[2])) < 1e-12
    assert -np.pi <= out[2] < np.pi


# --- Jacobian -------------------------------------------------------------------------------------


def finite_difference_jacobian(model, pose, u, h=1e-6):
    jac = np.empty((3, 3))
    for k in range(3):
        step = np.zeros(3)
        step[k] = h
        plus = model.mean(pose + step, u)
        minus = model.mean(pose - step, u)
        diff = plus - minus
        diff[2] = angle_diff(plus[2], minus[2])  # the heading may wrap between the two
        jac[:, k] = diff / (2 * h)
    return jac


@HYP
@given(poses, controls, dts)
def test_jacobian_equals_central_finite_difference(pose, u, dt):
    model = UnicycleModel(dt=dt)
    np.testing.assert_allclose(
        model.jacobian(pose, u), finite_difference_jacobian(model, pose, u), rtol=0, atol=1e-7
    )


def test_jacobian_at_the_heading_seam():
    model = UnicycleModel(dt=0.1)
    pose = np.array([0.0, 0.0, np.pi - 1e-7])
    u = np.array([1.0, 0.0])
    np.testing.assert_allclose(
        model.jacobian(pose, u), finite_difference_jacobian(model, pose, u), atol=1e-7
    )


@HYP
@given(poses, controls, dts)
def test_kernel_jacobian_matches_model(pose, u, dt):
    out = np.full((3, 3), np.nan)
    unicycle_jacobian(pose[2], u[0], dt, out)
    np.testing.assert_allclose(out, UnicycleModel(dt=dt).jacobian(pose, u), atol=1e-12)


def test_jacobian_is_batched():
    rng = np.random.default_rng(1)
    batch = rng.uniform(-3, 3, size=(6, 3))
    u = rng.uniform(-1, 1, size=(6, 2))
    model = UnicycleModel(dt=0.3)
    jac = model.jacobian(batch, u)
    assert jac.shape == (6, 3, 3)
    for b in range(6):
        np.testing.assert_array_equal(jac[b], model.jacobian(batch[b], u[b]))


# --- sampling -------------------------------------------------------------------------------------


def test_sample_mean_and_covariance_match_q():
    q = np.array([[0.04, 0.01, 0.0], [0.01, 0.02, 0.005], [0.0, 0.005, 0.01]])
    model = UnicycleModel(dt=0.1, noise_cov=q)
    n = 200_000
    pose = np.array([1.0, -2.0, 0.3])
    u = np.array([1.5, 0.4])
    rng = np.random.default_rng(12345)
    samples = model.sample(np.broadcast_to(pose, (n, 3)), np.broadcast_to(u, (n, 2)), rng)
    eps = samples - model.mean(pose, u)
    eps[:, 2] = angle_diff(samples[:, 2], model.mean(pose, u)[2])
    # mean: each component's standard error is sqrt(Q_ii / n); allow 5 of them
    np.testing.assert_array_less(np.abs(eps.mean(axis=0)), 5 * np.sqrt(np.diag(q) / n))
    # covariance: Var(S_ij) ~ (Q_ii Q_jj + Q_ij^2) / n for Gaussian data; allow 5 std errors
    emp = np.cov(eps, rowvar=False)
    se = np.sqrt((np.outer(np.diag(q), np.diag(q)) + q**2) / n)
    np.testing.assert_array_less(np.abs(emp - q), 5 * se)


def test_sample_is_reproducible_with_seeded_generator():
    model = UnicycleModel(dt=0.1, noise_cov=0.01 * np.eye(3))
    pose, u = np.zeros((10, 3)), np.ones((10, 2))
    a = model.sample(pose, u, np.random.default_rng(7))
    b = model.sample(pose, u, np.random.default_rng(7))
    np.testing.assert_array_equal(a, b)
    assert not np.array_equal(a, model.sample(pose, u, np.random.default_rng(8)))


def test_sample_with_singular_q_has_no_noise_where_q_is_zero():
    model = UnicycleModel(dt=0.1, noise_cov=np.diag([0.01, 0.02, 0.0]))
    np.testing.assert_allclose(model.noise_root @ model.noise_root.T, model.noise_cov, atol=1e-15)
    pose, u = np.array([0.0, 0.0, 0.5]), np.array([1.0, 0.2])
    samples = model.sample(
        np.broadcast_to(pose, (1000, 3)), np.broadcast_to(u, (1000, 2)), np.random.default_rng(3)
    )
    np.testing.assert_allclose(samples[:, 2], model.mean(pose, u)[2], atol=1e-15)
    assert samples[:, 0].std() > 0.05


def test_sampled_heading_is_wrapped():
    model = UnicycleModel(dt=0.1, noise_cov=np.diag([1e-4, 1e-4, 0.5]))
    pose = np.array([0.0, 0.0, np.pi - 0.01])
    samples = model.sample(
        np.broadcast_to(pose, (5000, 3)), np.zeros((5000, 2)), np.random.default_rng(4)
    )
    assert np.all(samples[:, 2] >= -np.pi)
    assert np.all(samples[:, 2] < np.pi)


# --- walls ----------------------------------------------------------------------------------------

BOUNDS = np.array([0.0, 0.0, 10.0, 10.0])


def test_move_within_bounds_moves_inside():
    pose = np.array([5.0, 5.0, 0.0])
    noise = np.array([0.01, -0.02, 0.03])
    collided = move_within_bounds(pose, 1.0, 0.5, 0.1, noise, BOUNDS, True)
    assert collided is False
    np.testing.assert_allclose(pose, [5.0 + 0.1 + 0.01, 5.0 - 0.02, 0.05 + 0.03], atol=1e-15)


@pytest.mark.parametrize(
    ("start", "heading"),
    [((9.95, 5.0), 0.0), ((0.05, 5.0), np.pi), ((5.0, 9.95), np.pi / 2), ((5.0, 0.05), -np.pi / 2)],
)
def test_move_within_bounds_blocks_at_the_border(start, heading):
    pose = np.array([start[0], start[1], heading])
    collided = move_within_bounds(pose, 1.0, 0.5, 0.1, np.zeros(3), BOUNDS, True)
    assert collided is True
    # the translation is blocked, the heading still turns
    np.testing.assert_array_equal(pose[:2], start)
    assert abs(angle_diff(pose[2], heading + 0.05)) < 1e-12
    assert -np.pi <= pose[2] < np.pi


def test_move_within_bounds_noise_can_cause_the_collision():
    pose = np.array([9.99, 5.0, np.pi / 2])
    assert move_within_bounds(pose, 0.0, 0.0, 0.1, np.array([0.05, 0.0, 0.0]), BOUNDS, True)
    np.testing.assert_array_equal(pose[:2], [9.99, 5.0])


def test_move_within_bounds_without_walls_leaves_the_box():
    pose = np.array([9.95, 5.0, 0.0])
    collided = move_within_bounds(pose, 1.0, 0.0, 0.1, np.zeros(3), BOUNDS, False)
    assert collided is False
    assert pose[0] == pytest.approx(10.05)


def test_move_within_bounds_equals_mean_plus_noise():
    rng = np.random.default_rng(5)
    model = UnicycleModel(dt=0.2)
    for _ in range(50):
        pose = np.array([*rng.uniform(3, 7, 2), rng.uniform(-np.pi, np.pi)])
        u = rng.uniform(-1, 1, 2)
        noise = rng.normal(0, 0.05, 3)
        expected = model.mean(pose, u) + noise
        moved = pose.copy()
        assert not move_within_bounds(moved, u[0], u[1], 0.2, noise, BOUNDS, True)
        np.testing.assert_allclose(moved[:2], expected[:2], atol=1e-12)
        assert abs(angle_diff(moved[2], expected[2])) < 1e-12


# --- validation -----------------------------------------------------------------------------------


@pytest.mark.parametrize("dt", [0.0, -0.1, np.nan, np.inf])
def test_invalid_dt_raises_naming_the_field(dt):
    with pytest.raises(ValueError, match=r"UnicycleModel\.dt"):
        UnicycleModel(dt=dt)


@pytest.mark.parametrize(
    "q",
    [
        np.eye(2),
        np.eye(4),
        np.zeros(3),
        np.diag([0.1, np.nan, 0.1]),
        np.diag([0.1, np.inf, 0.1]),
        np.array([[0.1, 0.05, 0.0], [0.0, 0.1, 0.0], [0.0, 0.0, 0.1]]),
        np.diag([0.1, -0.1, 0.1]),
    ],
    ids=["2x2", "4x4", "vector", "nan", "inf", "asymmetric", "negative"],
)
def test_invalid_q_raises_naming_the_field(q):
    with pytest.raises(ValueError, match=r"UnicycleModel\.noise_cov"):
        UnicycleModel(dt=0.1, noise_cov=q)


def test_q_is_copied_and_read_only():
    q = 0.01 * np.eye(3)
    model = UnicycleModel(dt=0.1, noise_cov=q)
    q[0, 0] = 5.0
    assert model.noise_cov[0, 0] == 0.01
    with pytest.raises(ValueError):
        model.noise_cov[0, 0] = 1.0
