"""Tests of ``active_loc.sensors.landmarks``: the two landmark measurement models of the chapter.

The references are written out here from the chapter, independently of the package:

* relative position (section 13.8, problem 1): ``z = R(theta)^T (m - p)``;
* range and bearing (eq. 13.8): ``z = (|m - p|, atan2(m_y - y, m_x - x) - theta)``;

and their Jacobians are checked against central finite differences.
"""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from active_loc.sensors.landmarks import (
    RANGE_BEARING,
    RELATIVE_POSITION,
    RangeBearingSensor,
    RelativePositionSensor,
    expected_measurement,
    in_view,
)

HYP = settings(deadline=None, max_examples=60)

finite = {"allow_nan": False, "allow_infinity": False}
poses = st.tuples(
    st.floats(-20, 20, **finite), st.floats(-20, 20, **finite), st.floats(-np.pi, np.pi, **finite)
).map(np.array)
landmark_sets = st.lists(
    st.tuples(st.floats(-20, 20, **finite), st.floats(-20, 20, **finite)), min_size=1, max_size=6
).map(np.array)


def angle_diff(a, b):
    d = np.asarray(a, dtype=np.float64) - np.asarray(b, dtype=np.float64)
    return np.arctan2(np.sin(d), np.cos(d))


def rot(theta):
    c, s = np.cos(theta), np.sin(theta)
    return np.array([[c, -s], [s, c]])


def chapter_relative_position(pose, m):
    return rot(pose[2]).T @ (m - pose[:2])


def chapter_range_bearing(pose, m):
    dx, dy = m[0] - pose[0], m[1] - pose[1]
    return np.array([np.sqrt(dx**2 + dy**2), np.arctan2(dy, dx) - pose[2]])


def chapter_range_bearing_jacobian(pose, m):
    """Eq. 13.9."""
    dx, dy = m[0] - pose[0], m[1] - pose[1]
    q = dx**2 + dy**2
    r = np.sqrt(q)
    return np.array([[-dx / r, -dy / r, 0.0], [dy / q, -dx / q, -1.0]])


def far_enough(pose, landmarks, distance=0.5):
    return bool(np.all(np.hypot(*(landmarks - pose[:2]).T) > distance))


def finite_difference(sensor, pose, landmarks, h=1e-6):
    jac = np.empty((landmarks.shape[0], 2, 3))
    for k in range(3):
        step = np.zeros(3)
        step[k] = h
        plus = sensor.expected(pose + step, landmarks)
        minus = sensor.expected(pose - step, landmarks)
        # residual() wraps the angular components: a bearing may cross the seam
        jac[:, :, k] = sensor.residual(plus, minus) / (2 * h)
    return jac


# --- expected measurements ------------------------------------------------------------------------


@HYP
@given(poses, landmark_sets)
def test_relative_position_expected_is_rotated_offset(pose, landmarks):
    out = RelativePositionSensor().expected(pose, landmarks)
    assert out.shape == (landmarks.shape[0], 2)
    for j, m in enumerate(landmarks):
        np.testing.assert_allclose(out[j], chapter_relative_position(pose, m), atol=1e-10)


@HYP
@given(poses, landmark_sets)
def test_range_bearing_expected_is_eq_13_8(pose, landmarks):
    out = RangeBearingSensor().expected(pose, landmarks)
    assert out.shape == (landmarks.shape[0], 2)
    for j, m in enumerate(landmarks):
        ref = chapter_range_bearing(pose, m)
        assert out[j, 0] == pytest.approx(ref[0], abs=1e-10)
        assert abs(angle_diff(out[j, 1], ref[1])) < 1e-10
        assert -np.pi <= out[j, 1] < np.pi


def test_expected_of_textbook_start():
    landmarks = np.array([[0.0, 0.0], [2.0, 8.0], [8.0, 2.0], [10.0, 10.0]])
    pose = np.array([1.0, 1.0, np.pi / 2])
    # heading +y: the robot's x axis is the map's +y, its y axis the map's -x
    np.testing.assert_allclose(
        RelativePositionSensor().expected(pose, landmarks),
        [[-1.0, 1.0], [7.0, -1.0], [1.0, -7.0], [9.0, -9.0]],
        atol=1e-12,
    )
    rb = RangeBearingSensor().expected(pose, landmarks)
    np.testing.assert_allclose(rb[:, 0], np.hypot([-1, 1, 7, 9], [-1, 7, 1, 9]), atol=1e-12)
    np.testing.assert_allclose(rb[2, 1], np.arctan2(1.0, 7.0) - np.pi / 2, atol=1e-12)


def test_expected_is_batched_over_poses():
    rng = np.random.default_rng(0)
    batch = rng.uniform(-5, 5, size=(3, 4, 3))
    landmarks = rng.uniform(-5, 5, size=(6, 2))
    for sensor in (RelativePositionSensor(), RangeBearingSensor()):
        out = sensor.expected(batch, landmarks)
        assert out.shape == (3, 4, 6, 2)
        np.testing.assert_array_equal(out[1, 2], sensor.expected(batch[1, 2], landmarks))


@pytest.mark.parametrize("kind", [RELATIVE_POSITION, RANGE_BEARING])
def test_kernel_expected_matches_class(kind):
    sensor = RelativePositionSensor() if kind == RELATIVE_POSITION else RangeBearingSensor()
    rng = np.random.default_rng(1)
    for _ in range(50):
        pose = np.array([*rng.uniform(-5, 5, 2), rng.uniform(-np.pi, np.pi)])
        m = rng.uniform(-10, 10, 2)
        z, jac = np.empty(2), np.empty((2, 3))
        expected_measurement(kind, pose, m, z, jac)
        ref = sensor.expected(pose, m[None])[0]
        assert z[0] == pytest.approx(ref[0], abs=1e-12)
        assert abs(angle_diff(z[1], ref[1])) < 1e-12


# --- Jacobians ------------------------------------------------------------------------------------


@HYP
@given(poses, landmark_sets)
def test_relative_position_jacobian_equals_finite_difference(pose, landmarks):
    sensor = RelativePositionSensor()
    np.testing.assert_allclose(
        sensor.jacobian(pose, landmarks),
        finite_difference(sensor, pose, landmarks),
        rtol=1e-6,
        atol=1e-6,
    )


@HYP
@given(poses, landmark_sets)
def test_range_bearing_jacobian_equals_finite_difference(pose, landmarks):
    if not far_enough(pose, landmarks):
        return  # the bearing's curvature ~ 1/r^2 makes the difference quotient inaccurate
    sensor = RangeBearingSensor()
    jac = sensor.jacobian(pose, landmarks)
    np.testing.assert_allclose(jac, finite_difference(sensor, pose, landmarks), atol=1e-6)
    for j, m in enumerate(landmarks):
        np.testing.assert_allclose(jac[j], chapter_range_bearing_jacobian(pose, m), atol=1e-12)


@pytest.mark.parametrize("heading", [0.0, np.pi - 1e-9, -np.pi, 1.0, -2.5])
@pytest.mark.parametrize("lateral", [0.0, 1e-9, -1e-9, 0.3, -0.3])
def test_range_bearing_jacobian_behind_the_robot(heading, lateral):
    # landmark 4 m behind the robot (bearing ~ +-pi), slightly to either side: the finite
    # differences straddle the bearing seam and must be wrapped
    pose = np.array([1.0, -2.0, heading])
    back = -np.array([np.cos(heading), np.sin(heading)])
    side = np.array([-np.sin(heading), np.cos(heading)])
    landmarks = (pose[:2] + 4.0 * back + lateral * side)[None]
    sensor = RangeBearingSensor()
    z = sensor.expected(pose, landmarks)[0]
    assert abs(abs(z[1]) - np.pi) < 0.1
    jac = sensor.jacobian(pose, landmarks)
    np.testing.assert_allclose(jac, finite_difference(sensor, pose, landmarks), atol=1e-6)
    np.testing.assert_allclose(
        jac[0], chapter_range_bearing_jacobian(pose, landmarks[0]), atol=1e-12
    )


def test_jacobian_is_batched():
    rng = np.random.default_rng(2)
    batch = rng.uniform(-5, 5, size=(2, 3, 3))
    landmarks = rng.uniform(6, 9, size=(4, 2))
    for sensor in (RelativePositionSensor(), RangeBearingSensor()):
        jac = sensor.jacobian(batch, landmarks)
        assert jac.shape == (2, 3, 4, 2, 3)
        np.testing.assert_array_equal(jac[1, 0], sensor.jacobian(batch[1, 0], landmarks))


def test_range_bearing_at_the_landmark_stays_finite():
    sensor = RangeBearingSensor()
    pose = np.array([1.0, 1.0, 0.0])
    jac = sensor.jacobian(pose, np.array([[1.0, 1.0]]))
    assert np.all(np.isfinite(jac))


# --- visibility -----------------------------------------------------------------------------------


def visibility_ref(pose, landmarks, fov, max_range):
    d = landmarks - pose[:2]
    dist = np.hypot(d[:, 0], d[:, 1])
    bearing = angle_diff(np.arctan2(d[:, 1], d[:, 0]), pose[2])
    return (dist <= max_range) & ((fov >= 2 * np.pi) | (np.abs(bearing) <= fov / 2))


def test_visibility_respects_fov():
    sensor = RangeBearingSensor(fov=np.pi / 2, max_range=10.0)
    pose = np.array([0.0, 0.0, 0.0])
    angles = np.deg2rad([0.0, 44.0, -44.0, 46.0, -46.0, 90.0, 180.0])
    landmarks = 3.0 * np.stack([np.cos(angles), np.sin(angles)], axis=1)
    np.testing.assert_array_equal(
        sensor.visible(pose, landmarks), [True, True, True, False, False, False, False]
    )


def test_visibility_respects_max_range():
    sensor = RelativePositionSensor(max_range=5.0)
    pose = np.array([1.0, 1.0, 2.0])
    landmarks = pose[:2] + np.array([[4.9, 0.0], [0.0, -5.1], [3.0, 4.0 - 1e-9], [-6.0, 0.0]])
    np.testing.assert_array_equal(sensor.visible(pose, landmarks), [True, False, True, False])


def test_visibility_fov_across_the_heading_seam():
    # heading just below +pi; a landmark at world angle just above -pi is 0.2 rad to the left
    sensor = RangeBearingSensor(fov=np.pi / 2)
    pose = np.array([0.0, 0.0, np.pi - 0.1])
    world = np.array([-np.pi + 0.1, np.pi - 0.1 - 0.9, 0.0])
    landmarks = 2.0 * np.stack([np.cos(world), np.sin(world)], axis=1)
    np.testing.assert_array_equal(sensor.visible(pose, landmarks), [True, False, False])


def test_full_fov_sees_everything_in_range():
    sensor = RangeBearingSensor()
    rng = np.random.default_rng(3)
    landmarks = rng.uniform(-50, 50, size=(30, 2))
    assert sensor.visible(np.array([0.0, 0.0, 1.0]), landmarks).all()


@HYP
@given(
    poses,
    landmark_sets,
    st.floats(0.1, 2 * np.pi),
    st.floats(0.5, 40.0),
)
def test_visibility_matches_reference_and_kernel(pose, landmarks, fov, max_range):
    sensor = RangeBearingSensor(fov=fov, max_range=max_range)
    ref = visibility_ref(pose, landmarks, fov, max_range)
    seen = sensor.visible(pose, landmarks)
    kernel = np.array([in_view(*pose, *m, fov, max_range) for m in landmarks])
    # the package may disagree with the reference only within rounding of a boundary
    d = landmarks - pose[:2]
    margin = np.minimum(
        np.abs(np.hypot(d[:, 0], d[:, 1]) - max_range),
        np.abs(np.abs(angle_diff(np.arctan2(d[:, 1], d[:, 0]), pose[2])) - fov / 2),
    )
    clear = margin > 1e-9
    np.testing.assert_array_equal(seen[clear], ref[clear])
    np.testing.assert_array_equal(kernel, seen)
    z, visible = sensor.measure(pose, landmarks, np.random.default_rng(0))
    np.testing.assert_array_equal(visible, seen)
    assert np.all(z[~visible] == 0.0)


# --- noise ----------------------------------------------------------------------------------------


@pytest.mark.parametrize(
    "sensor",
    [
        RelativePositionSensor(np.array([[0.25, 0.1], [0.1, 0.16]])),
        RangeBearingSensor(np.array([[0.01, 0.0005], [0.0005, 0.0025]])),
    ],
    ids=["relative_position", "range_bearing"],
)
def test_measurement_noise_statistics_match_r(sensor):
    n = 40_000
    landmarks = np.array([[3.0, 4.0], [-2.0, 1.0], [-5.0, -0.01]])  # the last one behind, seam
    pose = np.array([0.0, 0.0, 0.0])
    z, visible = sensor.measure(np.broadcast_to(pose, (n, 3)), landmarks, np.random.default_rng(42))
    assert z.shape == (n, 3, 2)
    assert visible.all()
    resid = sensor.residual(z, sensor.expected(pose, landmarks)).reshape(-1, 2)
    r = sensor.noise_cov
    m = resid.shape[0]
    np.testing.assert_array_less(np.abs(resid.mean(axis=0)), 5 * np.sqrt(np.diag(r) / m))
    emp = np.cov(resid, rowvar=False)
    se = np.sqrt((np.outer(np.diag(r), np.diag(r)) + r**2) / m)
    np.testing.assert_array_less(np.abs(emp - r), 5 * se)


def test_measured_bearings_are_wrapped():
    sensor = RangeBearingSensor.from_std(0.1, 0.3)
    z, _ = sensor.measure(np.zeros((2000, 3)), np.array([[-5.0, 0.0]]), np.random.default_rng(1))
    assert np.all(z[..., 1] >= -np.pi)
    assert np.all(z[..., 1] < np.pi)
    # both sides of the seam occur
    assert (z[..., 1] > 3.0).any()
    assert (z[..., 1] < -3.0).any()


def test_measure_is_reproducible():
    sensor = RangeBearingSensor(fov=np.pi, max_range=8.0)
    landmarks = np.random.default_rng(5).uniform(-10, 10, size=(8, 2))
    pose = np.zeros((4, 3))
    a = sensor.measure(pose, landmarks, np.random.default_rng(9))
    b = sensor.measure(pose, landmarks, np.random.default_rng(9))
    np.testing.assert_array_equal(a[0], b[0])
    np.testing.assert_array_equal(a[1], b[1])


def test_noise_root_is_cholesky_of_r():
    r = np.array([[0.3, 0.1], [0.1, 0.2]])
    sensor = RelativePositionSensor(r)
    np.testing.assert_allclose(sensor.noise_root @ sensor.noise_root.T, r, atol=1e-15)
    rb = RangeBearingSensor.from_std(0.2, 0.05)
    np.testing.assert_allclose(rb.noise_cov, np.diag([0.04, 0.0025]), atol=1e-15)


# --- validation -----------------------------------------------------------------------------------


@pytest.mark.parametrize("cls", [RelativePositionSensor, RangeBearingSensor])
@pytest.mark.parametrize(
    "r",
    [
        np.eye(3),
        np.ones(2),
        np.array([[0.1, np.nan], [np.nan, 0.1]]),
        np.array([[0.1, 0.05], [0.0, 0.1]]),
        np.zeros((2, 2)),
        np.diag([0.1, -0.1]),
        np.array([[1.0, 1.0], [1.0, 1.0]]),
    ],
    ids=["3x3", "vector", "nan", "asymmetric", "zero", "negative", "singular"],
)
def test_bad_r_raises(cls, r):
    with pytest.raises(ValueError, match=rf"{cls.__name__}\.noise_cov"):
        cls(r)


@pytest.mark.parametrize("cls", [RelativePositionSensor, RangeBearingSensor])
@pytest.mark.parametrize("fov", [0.0, -1.0, 2 * np.pi + 0.1, np.nan, np.inf])
def test_bad_fov_raises(cls, fov):
    with pytest.raises(ValueError, match=rf"{cls.__name__}\.fov"):
        cls(fov=fov)


@pytest.mark.parametrize("cls", [RelativePositionSensor, RangeBearingSensor])
@pytest.mark.parametrize("max_range", [0.0, -3.0, np.nan])
def test_bad_max_range_raises(cls, max_range):
    with pytest.raises(ValueError, match=rf"{cls.__name__}\.max_range"):
        cls(max_range=max_range)


@pytest.mark.parametrize("stds", [(0.0, 0.1), (0.1, 0.0), (-0.1, 0.1), (np.nan, 0.1)])
def test_bad_from_std_raises(stds):
    with pytest.raises(ValueError, match="range_std and bearing_std"):
        RangeBearingSensor.from_std(*stds)
