"""Tests of ``active_loc.geometry``: angle wrapping, pose algebra, frames, circular means.

Angles are compared modulo 2 pi (through the wrapped difference) wherever the package is free
to return either representative; the range ``[-pi, pi)`` itself is checked separately.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from active_loc.geometry import (
    circular_mean,
    compose,
    inverse,
    relative,
    rotation_matrix,
    to_robot_frame,
    wrap_angle,
    wrap_angle_scalar,
)

HYP = settings(deadline=None, max_examples=60)

coords = st.floats(-100.0, 100.0, allow_nan=False, allow_infinity=False)
headings = st.floats(-20.0, 20.0, allow_nan=False, allow_infinity=False)
poses = st.tuples(coords, coords, headings).map(lambda p: np.array(p, dtype=np.float64))


def angle_diff(a, b):
    """Smallest signed difference a - b of angles (rad), computed independently of the package."""
    d = np.asarray(a, dtype=np.float64) - np.asarray(b, dtype=np.float64)
    return np.arctan2(np.sin(d), np.cos(d))


def assert_pose_close(a, b, atol=1e-9):
    a = np.asarray(a)
    b = np.asarray(b)
    np.testing.assert_allclose(a[..., :2], b[..., :2], rtol=0, atol=atol)
    np.testing.assert_allclose(angle_diff(a[..., 2], b[..., 2]), 0.0, rtol=0, atol=atol)


def assert_in_range(angles):
    angles = np.asarray(angles)
    assert np.all(angles >= -np.pi), angles
    assert np.all(angles < np.pi), angles


# --- wrap_angle ---------------------------------------------------------------------------------

EDGE_CASES = [
    (0.0, 0.0),
    (np.pi, -np.pi),
    (-np.pi, -np.pi),
    (3 * np.pi, -np.pi),
    (-3 * np.pi, -np.pi),
    (2 * np.pi, 0.0),
    (-2 * np.pi, 0.0),
    (np.pi / 2, np.pi / 2),
    (-np.pi / 2, -np.pi / 2),
    (np.pi - 1e-9, np.pi - 1e-9),
    (-np.pi + 1e-9, -np.pi + 1e-9),
]


@pytest.mark.parametrize(("angle", "expected"), EDGE_CASES)
def test_wrap_angle_edge_cases(angle, expected):
    out = float(wrap_angle(angle))
    assert_in_range(out)
    assert out == pytest.approx(expected, abs=1e-12)
    assert wrap_angle_scalar(angle) == out


@pytest.mark.parametrize("angle", [1e6, -1e6, 1e12, -1e12, 1e20, -1e20, 1e300, -1e300])
def test_wrap_angle_huge_values_stay_in_range_and_match_kernel(angle):
    out = float(wrap_angle(angle))
    assert_in_range(out)
    assert wrap_angle_scalar(angle) == out


@HYP
@given(st.floats(-1e9, 1e9, allow_nan=False, allow_infinity=False))
def test_wrap_angle_range_and_equivalence(angle):
    out = float(wrap_angle(angle))
    assert_in_range(out)
    # the same direction: equal modulo 2 pi (absolute error grows with |angle|)
    tol = 1e-12 + 4 * np.spacing(abs(angle) + np.pi)
    assert abs(angle_diff(out, angle)) <= tol


@HYP
@given(st.floats(-1e9, 1e9, allow_nan=False, allow_infinity=False))
def test_wrap_angle_equals_scalar_kernel(angle):
    assert wrap_angle_scalar(angle) == float(wrap_angle(angle))


def test_wrap_angle_keeps_shape_and_is_idempotent():
    rng = np.random.default_rng(0)
    angles = rng.uniform(-50, 50, size=(4, 5, 3))
    once = wrap_angle(angles)
    assert once.shape == angles.shape
    assert once.dtype == np.float64
    assert_in_range(once)
    np.testing.assert_array_equal(wrap_angle(once), once)


def test_wrap_angle_just_below_minus_pi_stays_in_range():
    angle = np.nextafter(-np.pi, -np.inf)
    out = float(wrap_angle(angle))
    assert_in_range(out)
    assert out == wrap_angle_scalar(angle)


# --- pose composition -----------------------------------------------------------------------------


def test_compose_matches_hand_computation():
    a = np.array([1.0, 2.0, np.pi / 2])
    b = np.array([3.0, 0.5, np.pi / 4])
    # b's x axis points along a's heading (+y in the map); b's y axis along -x
    assert_pose_close(compose(a, b), [1.0 - 0.5, 2.0 + 3.0, 3 * np.pi / 4], atol=1e-12)


@HYP
@given(poses)
def test_compose_with_inverse_is_identity(a):
    assert_pose_close(compose(a, inverse(a)), np.zeros(3))
    assert_pose_close(compose(inverse(a), a), np.zeros(3))


@HYP
@given(poses)
def test_inverse_is_an_involution(a):
    assert_pose_close(inverse(inverse(a)), a)


@HYP
@given(poses, poses, poses)
def test_compose_is_associative(a, b, c):
    assert_pose_close(compose(compose(a, b), c), compose(a, compose(b, c)), atol=1e-8)


@HYP
@given(poses, poses)
def test_relative_undoes_compose(a, b):
    assert_pose_close(relative(a, compose(a, b)), b, atol=1e-8)
    assert_pose_close(compose(a, relative(a, b)), b, atol=1e-8)


@HYP
@given(poses, poses)
def test_compose_heading_is_wrapped(a, b):
    assert_in_range(compose(a, b)[2])
    assert_in_range(inverse(a)[2])


def test_compose_broadcasts_over_batches():
    rng = np.random.default_rng(1)
    a = rng.uniform(-5, 5, size=(4, 1, 3))
    b = rng.uniform(-5, 5, size=(1, 6, 3))
    out = compose(a, b)
    assert out.shape == (4, 6, 3)
    for i in range(4):
        for j in range(6):
            np.testing.assert_array_equal(out[i, j], compose(a[i, 0], b[0, j]))


# --- frames -------------------------------------------------------------------------------------


@HYP
@given(headings)
def test_rotation_matrix_is_a_rotation(theta):
    rot = rotation_matrix(theta)
    assert rot.shape == (2, 2)
    np.testing.assert_allclose(rot @ rot.T, np.eye(2), atol=1e-12)
    assert np.linalg.det(rot) == pytest.approx(1.0, abs=1e-12)
    # robot x axis seen in the map frame is (cos theta, sin theta)
    np.testing.assert_allclose(rot @ [1.0, 0.0], [math.cos(theta), math.sin(theta)], atol=1e-12)


@HYP
@given(poses, st.tuples(coords, coords).map(np.array))
def test_to_robot_frame_equals_rotation_transpose(pose, point):
    expected = rotation_matrix(pose[2]).T @ (point - pose[:2])
    np.testing.assert_allclose(to_robot_frame(point, pose), expected, rtol=0, atol=1e-9)


@HYP
@given(poses, st.tuples(coords, coords).map(np.array))
def test_to_robot_frame_agrees_with_relative_pose(pose, point):
    # a point is a pose with any heading: its position seen from ``pose``
    rel = relative(pose, np.array([point[0], point[1], 0.0]))
    np.testing.assert_allclose(to_robot_frame(point, pose), rel[:2], rtol=0, atol=1e-9)


def test_to_robot_frame_broadcasts_points_against_poses():
    rng = np.random.default_rng(2)
    points = rng.uniform(-10, 10, size=(7, 2))
    batch = rng.uniform(-3, 3, size=(5, 3))
    out = to_robot_frame(points[None, :, :], batch[:, None, :])
    assert out.shape == (5, 7, 2)
    rots = rotation_matrix(batch[:, 2])  # (5, 2, 2)
    expected = np.einsum("bji,bkj->bki", rots, points[None] - batch[:, None, :2])
    np.testing.assert_allclose(out, expected, atol=1e-12)


# --- circular mean --------------------------------------------------------------------------------


def test_circular_mean_across_the_seam():
    angles = np.array([np.pi - 0.1, -np.pi + 0.1, np.pi - 0.05, -np.pi + 0.05])
    out = float(circular_mean(angles))
    assert_in_range(out)
    assert abs(angle_diff(out, np.pi)) < 1e-12
    # the arithmetic mean would be ~0, the opposite direction
    assert abs(float(np.mean(angles))) < 1e-12


def test_circular_mean_weighted_across_the_seam():
    angles = np.array([np.pi - 0.1, -np.pi + 0.1])  # pi - 0.1 and pi + 0.1
    out = float(circular_mean(angles, weights=np.array([3.0, 1.0])))
    expected = np.pi - math.atan(0.5 * math.tan(0.1))
    assert_in_range(out)
    assert abs(angle_diff(out, expected)) < 1e-12


def test_circular_mean_weights_need_not_be_normalized():
    rng = np.random.default_rng(3)
    angles = rng.uniform(-np.pi, np.pi, size=20)
    weights = rng.uniform(0.1, 2.0, size=20)
    a = circular_mean(angles, weights)
    b = circular_mean(angles, 17.0 * weights)
    assert abs(angle_diff(a, b)) < 1e-12


def test_circular_mean_zero_weight_ignores_an_angle():
    out = circular_mean(np.array([0.3, 2.0, 0.5]), np.array([1.0, 0.0, 1.0]))
    assert float(out) == pytest.approx(0.4, abs=1e-12)


@HYP
@given(
    st.lists(st.floats(-0.5, 0.5), min_size=1, max_size=20),
    st.floats(-np.pi, np.pi, exclude_max=True),
)
def test_circular_mean_is_rotation_equivariant(offsets, centre):
    # angles clustered around ``centre`` (possibly across the seam): the mean is centre + mean
    # of the offsets' circular mean, and it is wrapped
    offsets = np.array(offsets)
    out = circular_mean(wrap_angle(centre + offsets))
    assert_in_range(out)
    assert abs(angle_diff(out, centre + circular_mean(offsets))) < 1e-9


def test_circular_mean_along_an_axis():
    rng = np.random.default_rng(4)
    angles = rng.uniform(-np.pi, np.pi, size=(3, 8))
    weights = rng.uniform(0.0, 1.0, size=(3, 8))
    out = circular_mean(angles, weights, axis=1)
    assert out.shape == (3,)
    for i in range(3):
        assert out[i] == pytest.approx(float(circular_mean(angles[i], weights[i])), abs=1e-12)
    out0 = circular_mean(angles.T, weights.T, axis=0)
    np.testing.assert_allclose(out0, out, atol=1e-12)
