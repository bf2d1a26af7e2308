"""Tests of the EKF beliefs (``active_loc.beliefs.ekf``, ``ekf_filterpy``) and Gaussian entropy.

The references are independent of the package wherever it matters:

* the chapter's exercise (section 13.8, problem 1) is simulated here, with the dynamics and
  measurement models and their Jacobians written out from the chapter, and a plain
  ``filterpy.kalman.ExtendedKalmanFilter`` is driven with them; the numba ``EKFBelief`` and the
  ``FilterpyEKFBelief`` backend must agree with it step for step;
* with the heading known exactly the model is linear in (x, y), and the EKF must equal a plain
  ``filterpy.kalman.KalmanFilter``;
* the entropy is checked against the closed form and ``scipy.stats``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import pytest
from filterpy.kalman import ExtendedKalmanFilter, KalmanFilter
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy.linalg import block_diag
from scipy.stats import multivariate_normal

from active_loc.beliefs import EKFBelief, FilterpyEKFBelief, gaussian_entropy
from active_loc.beliefs.ekf import ekf_update
from active_loc.beliefs.entropy import gaussian_entropy3
from active_loc.motion import UnicycleModel
from active_loc.sensors import RANGE_BEARING, RangeBearingSensor, RelativePositionSensor

TEXTBOOK_LANDMARKS = np.array([[0.0, 0.0], [2.0, 8.0], [8.0, 2.0], [10.0, 10.0]])
DT = 0.1
Q_TEXTBOOK = 0.1 * DT**2 * np.eye(3)
R_TEXTBOOK = 0.25 * np.eye(2)
START = np.array([1.0, 1.0, 0.0])
STEPS = 150
TOL = 1e-9


# --- the chapter's models, written out independently ----------------------------------------------


def wrap(a):
    return (np.asarray(a, dtype=np.float64) + np.pi) % (2 * np.pi) - np.pi


def angle_diff(a, b):
    d = np.asarray(a, dtype=np.float64) - np.asarray(b, dtype=np.float64)
    return np.arctan2(np.sin(d), np.cos(d))


def f_chapter(x, u):
    return np.array(
        [x[0] + u[0] * math.cos(x[2]) * DT, x[1] + u[0] * math.sin(x[2]) * DT, x[2] + u[1] * DT]
    )


def jac_f_chapter(x, u):
    return np.array(
        [
            [1.0, 0.0, -u[0] * math.sin(x[2]) * DT],
            [0.0, 1.0, u[0] * math.cos(x[2]) * DT],
            [0.0, 0.0, 1.0],
        ]
    )


def h_relative(x, m):
    """Section 13.8, problem 1: z = R(theta)^T (m - p)."""
    c, s = math.cos(x[2]), math.sin(x[2])
    return np.array([[c, s], [-s, c]]) @ (m - x[:2])


def jac_h_relative(x, m):
    c, s = math.cos(x[2]), math.sin(x[2])
    dx, dy = m[0] - x[0], m[1] - x[1]
    return np.array([[-c, -s, -s * dx + c * dy], [s, -c, -c * dx - s * dy]])


def h_range_bearing(x, m):
    """Eq. 13.8."""
    dx, dy = m[0] - x[0], m[1] - x[1]
    return np.array([math.sqrt(dx * dx + dy * dy), math.atan2(dy, dx) - x[2]])


def jac_h_range_bearing(x, m):
    """Eq. 13.9."""
    dx, dy = m[0] - x[0], m[1] - x[1]
    q = dx * dx + dy * dy
    r = math.sqrt(q)
    return np.array([[-dx / r, -dy / r, 0.0], [dy / q, -dx / q, -1.0]])


@dataclass
class Scenario:
    """One simulated run of the exercise: controls, truth, measurements and visibility."""

    mean0: np.ndarray
    controls: np.ndarray  # (T, 2)
    truth: np.ndarray  # (T, 3)
    z: np.ndarray  # (T, N, 2), zero where not visible
    visible: np.ndarray  # (T, N)


def simulate_textbook(
    seed, kind="relative_position", r=R_TEXTBOOK, fov=2 * np.pi, max_range=np.inf
):
    """The exercise: start (1, 1, 0), mean0 = start + N(0, 0.1 I), V = 1, omega = sin(k dt)."""
    rng = np.random.default_rng(seed)
    mean0 = START + rng.normal(0.0, math.sqrt(0.1), 3)
    q_root = np.linalg.cholesky(Q_TEXTBOOK)
    r_root = np.linalg.cholesky(r)
    n = TEXTBOOK_LANDMARKS.shape[0]
    x = START.copy()
    controls = np.empty((STEPS, 2))
    truth = np.empty((STEPS, 3))
    z = np.zeros((STEPS, n, 2))
    visible = np.zeros((STEPS, n), dtype=bool)
    for k in range(1, STEPS + 1):
        u = np.array([1.0, math.sin(k * DT)])
        x = f_chapter(x, u) + q_root @ rng.standard_normal(3)
        x[2] = wrap(x[2])
        controls[k - 1] = u
        truth[k - 1] = x
        for j, m in enumerate(TEXTBOOK_LANDMARKS):
            noise = r_root @ rng.standard_normal(2)
            if kind == "relative_position":
                seen = np.hypot(*(m - x[:2])) <= max_range
                zj = h_relative(x, m) + noise
            else:
                exact = h_range_bearing(x, m)
                seen = exact[0] <= max_range and abs(wrap(exact[1])) <= fov / 2
                zj = exact + noise
                zj[1] = wrap(zj[1])
            if seen:
                visible[k - 1, j] = True
                z[k - 1, j] = zj
    return Scenario(mean0, controls, truth, z, visible)


def make_sensor(kind, r, fov=2 * np.pi, max_range=np.inf):
    if kind == "relative_position":
        return RelativePositionSensor(r, fov, max_range)
    return RangeBearingSensor(r, fov, max_range)


def plain_filterpy_ekf(mean0, cov0, q):
    """A stock filterpy EKF whose prediction is the chapter's f (filterpy's own is linear)."""
    ekf = ExtendedKalmanFilter(dim_x=3, dim_z=2)
    ekf.x = mean0.reshape(3, 1).copy()
    ekf.P = cov0.copy()
    ekf.Q = q.copy()

    def predict_x(u):
        ekf.x = f_chapter(ekf.x.ravel(), u).reshape(3, 1)

    ekf.predict_x = predict_x  # the documented extension point of filterpy's EKF
    return ekf


def plain_predict(ekf, u):
    ekf.F = jac_f_chapter(ekf.x.ravel(), u)
    ekf.predict(u)
    ekf.x[2, 0] = wrap(ekf.x[2, 0])


def plain_update(ekf, z, visible, kind, r):
    seen = TEXTBOOK_LANDMARKS[visible]
    if seen.shape[0] == 0:
        return
    h, jac = (
        (h_relative, jac_h_relative)
        if kind == "relative_position"
        else (h_range_bearing, jac_h_range_bearing)
    )

    def hx(x):
        return np.concatenate([h(x.ravel(), m) for m in seen]).reshape(-1, 1)

    def h_jacobian(x):
        return np.vstack([jac(x.ravel(), m) for m in seen])

    def residual(a, b):
        d = (a - b).reshape(-1, 2)
        if kind != "relative_position":
            d[:, 1] = wrap(d[:, 1])
        return d.reshape(-1, 1)

    r_blk = block_diag(*[r] * seen.shape[0])
    ekf.update(z[visible].reshape(-1, 1), h_jacobian, hx, R=r_blk, residual=residual)
    ekf.x[2, 0] = wrap(ekf.x[2, 0])


def assert_same_belief(mean, cov, ref_mean, ref_cov, what):
    mean = np.asarray(mean).ravel()
    ref_mean = np.asarray(ref_mean).ravel()
    np.testing.assert_allclose(mean[:2], ref_mean[:2], rtol=0, atol=TOL, err_msg=what)
    assert abs(angle_diff(mean[2], ref_mean[2])) <= TOL, what
    np.testing.assert_allclose(cov, ref_cov, rtol=0, atol=TOL, err_msg=what)


# --- EKF == filterpy, step for step ---------------------------------------------------------------

SCENARIOS = {
    # the exercise exactly
    "textbook": ("relative_position", R_TEXTBOOK, 2 * np.pi, np.inf),
    # range and bearing all round: landmark (0, 0) crosses the bearing seam behind the robot
    "range_bearing": ("range_bearing", np.diag([0.1**2, 0.05**2]), 2 * np.pi, np.inf),
    # a narrow, short sensor: some steps see nothing
    "range_bearing_fov": ("range_bearing", np.diag([0.1**2, 0.05**2]), np.pi / 3, 6.0),
}


@pytest.mark.parametrize("seed", [0, 1, 2])
@pytest.mark.parametrize("name", list(SCENARIOS))
def test_ekf_equals_filterpy_step_for_step(name, seed):
    kind, r, fov, max_range = SCENARIOS[name]
    run = simulate_textbook(seed, kind, r, fov, max_range)
    motion = UnicycleModel(DT, Q_TEXTBOOK)
    sensor = make_sensor(kind, r, fov, max_range)
    numba_ekf = EKFBelief(run.mean0[None], np.eye(3)[None], motion, sensor)
    backend = FilterpyEKFBelief(run.mean0[None], np.eye(3)[None], motion, sensor)
    plain = plain_filterpy_ekf(run.mean0, np.eye(3), Q_TEXTBOOK)
    n_seen = run.visible.sum(axis=1)
    if name == "textbook":
        assert (n_seen == 4).all()
    if name == "range_bearing_fov":
        assert (n_seen == 0).any() and (n_seen > 0).any()
    for k in range(STEPS):
        u = run.controls[k]
        numba_ekf.predict(u[None])
        backend.predict(u[None])
        plain_predict(plain, u)
        for label, belief in (("numba", numba_ekf), ("backend", backend)):
            assert_same_belief(
                belief.mean[0], belief.cov[0], plain.x, plain.P, f"{label} after predict {k + 1}"
            )
        numba_ekf.update(run.z[k][None], run.visible[k][None], TEXTBOOK_LANDMARKS)
        backend.update(run.z[k][None], run.visible[k][None], TEXTBOOK_LANDMARKS)
        plain_update(plain, run.z[k], run.visible[k], kind, r)
        for label, belief in (("numba", numba_ekf), ("backend", backend)):
            assert_same_belief(
                belief.mean[0], belief.cov[0], plain.x, plain.P, f"{label} after update {k + 1}"
            )
        np.testing.assert_allclose(numba_ekf.last_nis, backend.last_nis, rtol=1e-7, atol=1e-9)
    # and the filter did its job: the final estimate is near the truth
    assert np.hypot(*(numba_ekf.mean[0, :2] - run.truth[-1, :2])) < 1.0


def test_textbook_run_visits_the_bearing_seam():
    """The range-bearing scenario above really exercises wrapped bearing residuals."""
    run = simulate_textbook(0, "range_bearing", SCENARIOS["range_bearing"][1])
    near_seam = np.abs(run.z[..., 1]) > np.pi - 0.2
    assert near_seam.any()
    assert (run.z[..., 1] > 0)[near_seam].any() and (run.z[..., 1] < 0)[near_seam].any()


def test_batched_ekf_equals_members_run_alone():
    runs = [simulate_textbook(seed) for seed in range(4)]
    motion = UnicycleModel(DT, Q_TEXTBOOK)
    sensor = RelativePositionSensor(R_TEXTBOOK)
    batch = EKFBelief(
        np.stack([r.mean0 for r in runs]), np.broadcast_to(np.eye(3), (4, 3, 3)), motion, sensor
    )
    alone = [EKFBelief(r.mean0[None], np.eye(3)[None], motion, sensor) for r in runs]
    rng = np.random.default_rng(0)
    for k in range(40):
        controls = np.stack([r.controls[k] for r in runs])
        z = np.stack([r.z[k] for r in runs])
        visible = rng.random((4, 4)) < 0.6
        batch.predict(controls)
        batch.update(z, visible, TEXTBOOK_LANDMARKS)
        for b, belief in enumerate(alone):
            belief.predict(controls[b][None])
            belief.update(z[b][None], visible[b][None], TEXTBOOK_LANDMARKS)
            np.testing.assert_array_equal(batch.mean[b], belief.mean[0])
            np.testing.assert_array_equal(batch.cov[b], belief.cov[0])


# --- EKF == Kalman filter on a linear model -------------------------------------------------------


def test_ekf_with_known_heading_equals_linear_kalman_filter():
    """With the heading known exactly the EKF *is* a Kalman filter.

    Construction: the heading variance and every heading cross-covariance are exactly zero,
    and Q has no heading component. Then the heading evolves deterministically,
    theta_k = theta_{k-1} + omega dt, and given theta the model is linear in p = (x, y):

        p_k = p_{k-1} + B_k V,   B_k = dt (cos theta_{k-1}, sin theta_{k-1})     (F = I)
        z_j = R(theta_k)^T m_j - R(theta_k)^T p_k + delta  ->  H_j = -R(theta_k)^T,
                                                               z'_j = z_j - R(theta_k)^T m_j

    The EKF's linearization is then exact: its (x, y) block follows the Kalman filter on p,
    and the heading rows of F Sigma F^T and of the gain are exactly zero. The motion (V and
    omega non-zero) and the measurements (random visibility, some steps blind) are arbitrary.
    """
    rng = np.random.default_rng(2024)
    q_xy = np.array([[0.02, 0.005], [0.005, 0.01]])
    r = np.array([[0.3, 0.1], [0.1, 0.2]])
    motion = UnicycleModel(DT, block_diag(q_xy, 0.0))
    sensor = RelativePositionSensor(r)
    landmarks = rng.uniform(-10, 10, size=(5, 2))
    mean0 = np.array([0.5, -1.0, 0.7])
    p0 = np.array([[2.0, 0.3], [0.3, 1.0]])
    cov0 = block_diag(p0, 0.0)

    beliefs = {
        "numba": EKFBelief(mean0[None], np.eye(3)[None], motion, sensor),
        "backend": FilterpyEKFBelief(mean0[None], np.eye(3)[None], motion, sensor),
    }
    beliefs["numba"].cov[0] = cov0  # the constructors insist on a PD covariance
    beliefs["backend"].filter.P = cov0.copy()

    kf = KalmanFilter(dim_x=2, dim_z=2, dim_u=1)
    kf.x = mean0[:2].reshape(2, 1).copy()
    kf.P = p0.copy()
    theta = mean0[2]
    truth = mean0.copy()
    for _ in range(120):
        u = np.array([rng.uniform(0.0, 2.0), rng.uniform(-1.0, 1.0)])
        b_mat = DT * np.array([[math.cos(theta)], [math.sin(theta)]])
        kf.predict(u=np.array([[u[0]]]), B=b_mat, F=np.eye(2), Q=q_xy)
        theta = theta + u[1] * DT
        truth = f_chapter(truth, u)
        truth[:2] += rng.multivariate_normal(np.zeros(2), q_xy)
        visible = rng.random(5) < 0.5
        z = np.zeros((5, 2))
        for j in np.flatnonzero(visible):
            z[j] = h_relative(truth, landmarks[j]) + rng.multivariate_normal(np.zeros(2), r)
        if visible.any():
            c, s = math.cos(theta), math.sin(theta)
            rot_t = np.array([[c, s], [-s, c]])
            h_mat = np.vstack([-rot_t] * visible.sum())
            z_lin = np.concatenate([z[j] - rot_t @ landmarks[j] for j in np.flatnonzero(visible)])
            kf.update(z_lin.reshape(-1, 1), R=block_diag(*[r] * visible.sum()), H=h_mat)
        for label, belief in beliefs.items():
            belief.predict(u[None])
            belief.update(z[None], visible[None], landmarks)
            mean, cov = belief.mean[0], belief.cov[0]
            np.testing.assert_allclose(mean[:2], kf.x.ravel(), rtol=0, atol=TOL, err_msg=label)
            np.testing.assert_allclose(cov[:2, :2], kf.P, rtol=0, atol=TOL, err_msg=label)
            assert abs(angle_diff(mean[2], theta)) <= TOL, label
            np.testing.assert_allclose(cov[2], 0.0, atol=1e-15, err_msg=label)
            np.testing.assert_allclose(cov[:, 2], 0.0, atol=1e-15, err_msg=label)


@pytest.mark.parametrize("kind", ["relative_position", "range_bearing"])
def test_one_ekf_update_equals_kalman_update_on_the_linearization(kind):
    """One correction is one Kalman update of the model linearized at the prior mean.

    For a single update the EKF uses h(mu) + H (x - mu) with H = dh/dx(mu); that model is
    linear (affine), so a Kalman filter with this H and the measurement shifted by
    h(mu) - H mu gives exactly the EKF's posterior (bearing residuals wrapped).
    """
    rng = np.random.default_rng(7)
    r = np.diag([0.2, 0.1]) if kind == "relative_position" else np.diag([0.05, 0.01])
    h, jac = (
        (h_relative, jac_h_relative)
        if kind == "relative_position"
        else (h_range_bearing, jac_h_range_bearing)
    )
    for _ in range(20):
        mu = np.array([*rng.uniform(-3, 3, 2), rng.uniform(-np.pi, np.pi)])
        a = rng.normal(size=(3, 3))
        cov = a @ a.T + 0.1 * np.eye(3)
        landmarks = rng.uniform(-10, 10, size=(3, 2))
        z = np.stack([h(mu, m) for m in landmarks]) + rng.normal(0, 0.3, (3, 2))
        if kind == "range_bearing":
            z[:, 1] = wrap(z[:, 1])
        h_mat = np.vstack([jac(mu, m) for m in landmarks])
        hx = np.concatenate([h(mu, m) for m in landmarks])
        innovation = z.ravel() - hx
        if kind == "range_bearing":
            innovation[1::2] = wrap(innovation[1::2])
        kf = KalmanFilter(dim_x=3, dim_z=6)
        kf.x = mu.reshape(3, 1).copy()
        kf.P = cov.copy()
        kf.update((innovation + h_mat @ mu).reshape(-1, 1), R=block_diag(r, r, r), H=h_mat)
        belief = EKFBelief(mu[None], cov[None], UnicycleModel(DT), make_sensor(kind, r))
        belief.update(z[None], np.ones((1, 3), dtype=bool), landmarks)
        assert_same_belief(belief.mean[0], belief.cov[0], kf.x, kf.P, kind)


# --- covariance stays a covariance ----------------------------------------------------------------


def assert_valid_belief(belief, what):
    cov = belief.cov[0]
    assert np.all(np.isfinite(belief.mean)), what
    assert np.all(np.isfinite(cov)), what
    np.testing.assert_array_equal(cov, cov.T, err_msg=what)
    assert np.linalg.eigvalsh(cov).min() > 0, (what, np.linalg.eigvalsh(cov))
    np.linalg.cholesky(cov)
    assert -np.pi <= belief.mean[0, 2] < np.pi, what


@settings(deadline=None, max_examples=40)
@given(
    seed=st.integers(0, 2**32 - 1),
    kind=st.sampled_from(["relative_position", "range_bearing"]),
    r_scale=st.sampled_from([1e-8, 1e-4, 1.0, 1e6]),
    q_scale=st.sampled_from([1e-10, 1e-4, 1e-2, 1.0]),
    n_landmarks=st.integers(1, 6),
    dt=st.floats(0.01, 0.5),
    speed=st.floats(-2.0, 2.0),
)
def test_covariance_stays_symmetric_positive_definite(
    seed, kind, r_scale, q_scale, n_landmarks, dt, speed
):
    rng = np.random.default_rng(seed)
    motion = UnicycleModel(dt, q_scale * np.diag(rng.uniform(0.1, 1.0, 3)))
    r = r_scale * np.diag(rng.uniform(0.5, 2.0, 2))
    sensor = make_sensor(kind, r)
    landmarks = rng.uniform(-30, 30, size=(n_landmarks, 2))
    truth = np.array([*rng.uniform(-20, 20, 2), rng.uniform(-np.pi, np.pi)])
    mean = truth + rng.normal(0, 0.5, 3)
    mean[2] = wrap(mean[2])
    belief = EKFBelief(mean[None], np.diag(rng.uniform(0.01, 4.0, 3))[None], motion, sensor)
    # measuring, then a long blind stretch, then measuring again
    pattern = [True] * 30 + [False] * 100 + [True] * 20
    for k, measuring in enumerate(pattern):
        u = np.array([speed * rng.uniform(0.5, 1.0), rng.uniform(-2.0, 2.0)])
        truth = motion.sample(truth, u, rng)
        belief.predict(u[None])
        assert_valid_belief(belief, f"predict {k}")
        visible = (rng.random(n_landmarks) < 0.7) & measuring
        z, _ = sensor.measure(truth, landmarks, rng)
        belief.update(z[None], visible[None], landmarks)
        assert_valid_belief(belief, f"update {k}")
        assert np.isfinite(belief.last_nis[0])


# --- bearings across the seam ---------------------------------------------------------------------


@pytest.mark.parametrize("backend", [EKFBelief, FilterpyEKFBelief])
@pytest.mark.parametrize("true_heading", [0.0, np.pi - 0.005, -np.pi + 0.005, 2.0])
@pytest.mark.parametrize("offset", [0.02, -0.02])
def test_bearing_residual_across_the_seam_stays_small(backend, true_heading, offset):
    # a landmark exactly behind the robot: its bearing is +-pi, and the belief's heading is
    # off by 0.02 rad so that expected and measured bearings lie on opposite sides of the seam
    truth = np.array([2.0, -1.0, true_heading])
    landmark = truth[:2] - 5.0 * np.array([math.cos(true_heading), math.sin(true_heading)])
    sensor = RangeBearingSensor.from_std(0.05, 0.01)
    mean = truth.copy()
    mean[2] = wrap(true_heading + offset)
    cov = np.diag([0.01, 0.01, 0.05**2])
    belief = backend(mean[None], cov[None], UnicycleModel(DT), sensor)
    zhat = sensor.expected(mean, landmark[None])[0, 1]
    # the measured bearing is +-pi plus 0.001 rad of noise, on the other side of the seam
    # from the expected one
    z = np.array([[5.0, -np.pi + 0.001 if zhat > 0 else np.pi - 0.001]])
    assert abs(zhat - z[0, 1]) > np.pi  # the raw difference is ~2 pi
    belief.update(z[None], np.ones((1, 1), dtype=bool), landmark[None])
    new = belief.mean[0]
    change = angle_diff(new[2], mean[2])
    assert -np.pi <= new[2] < np.pi
    assert abs(change) <= abs(offset) + 0.002  # a correction of at most the error, not ~2 pi
    assert change * offset < 0  # towards the truth
    assert abs(angle_diff(new[2], true_heading)) < 0.5 * abs(offset)
    assert np.hypot(*(new[:2] - mean[:2])) < 0.1
    assert belief.last_nis[0] < 10.0


def test_bearing_seam_kernel_and_backend_agree():
    truth = np.array([0.0, 0.0, np.pi - 0.003])
    landmark = np.array([[-4.0 * math.cos(truth[2]), -4.0 * math.sin(truth[2])]])
    sensor = RangeBearingSensor.from_std(0.05, 0.02)
    mean = np.array([0.05, -0.03, wrap(truth[2] + 0.01)])
    cov = np.diag([0.02, 0.03, 0.01])
    z = np.array([[4.0, wrap(np.pi) + 0.001]])
    a = EKFBelief(mean[None], cov[None], UnicycleModel(DT), sensor)
    b = FilterpyEKFBelief(mean[None], cov[None], UnicycleModel(DT), sensor)
    for belief in (a, b):
        belief.update(z[None], np.ones((1, 1), dtype=bool), landmark)
    assert_same_belief(a.mean[0], a.cov[0], b.mean[0], b.cov[0], "seam")


# --- invisible landmarks change nothing -----------------------------------------------------------


def random_belief(backend, rng, sensor):
    a = rng.normal(size=(3, 3))
    mean = np.array([*rng.uniform(-2, 2, 2), rng.uniform(-np.pi, np.pi)])
    return backend(mean[None], (a @ a.T + 0.1 * np.eye(3))[None], UnicycleModel(DT), sensor)


@pytest.mark.parametrize("backend", [EKFBelief, FilterpyEKFBelief])
@pytest.mark.parametrize("kind", ["relative_position", "range_bearing"])
def test_update_with_nothing_visible_changes_nothing(backend, kind):
    rng = np.random.default_rng(3)
    sensor = make_sensor(kind, np.diag([0.1, 0.02]))
    landmarks = rng.uniform(-5, 5, size=(6, 2))
    # many headings: wrapping an already wrapped angle can change its last bits
    for heading in [0.3, *np.linspace(-np.pi, np.pi, 25, endpoint=False)]:
        a = rng.normal(size=(3, 3))
        mean = np.array([0.5, -0.5, heading])
        belief = backend(mean[None], (a @ a.T + 0.1 * np.eye(3))[None], UnicycleModel(DT), sensor)
        before_mean, before_cov = belief.mean.copy(), belief.cov.copy()
        z = rng.normal(size=(1, 6, 2))
        z[0, 2] = np.nan  # never read
        belief.update(z, np.zeros((1, 6), dtype=bool), landmarks)
        np.testing.assert_array_equal(belief.mean, before_mean)
        np.testing.assert_array_equal(belief.cov, before_cov)
        assert belief.last_nis[0] == 0.0


@pytest.mark.parametrize("backend", [EKFBelief, FilterpyEKFBelief])
@pytest.mark.parametrize("kind", ["relative_position", "range_bearing"])
def test_masked_update_equals_update_with_visible_landmarks_only(backend, kind):
    rng = np.random.default_rng(4)
    sensor = make_sensor(kind, np.diag([0.1, 0.02]))
    landmarks = rng.uniform(-8, 8, size=(7, 2))
    for _ in range(10):
        masked = random_belief(backend, rng, sensor)
        subset = masked.copy()
        visible = rng.random(7) < 0.5
        visible[rng.integers(7)] = True
        z = sensor.expected(masked.mean[0], landmarks) + rng.normal(0, 0.2, (7, 2))
        z[~visible] = np.nan  # rows of unseen landmarks must never be read
        masked.update(z[None], visible[None], landmarks)
        subset.update(z[visible][None], np.ones((1, visible.sum()), dtype=bool), landmarks[visible])
        np.testing.assert_array_equal(masked.mean, subset.mean)
        np.testing.assert_array_equal(masked.cov, subset.cov)
        np.testing.assert_array_equal(masked.last_nis, subset.last_nis)


def test_kernel_update_returns_zero_nis_when_blind():
    mu, cov = np.array([1.0, 2.0, 0.3]), np.eye(3)
    nis = ekf_update(
        mu,
        cov,
        np.zeros((3, 2)),
        np.zeros(3, dtype=np.bool_),
        np.ones((3, 2)),
        RANGE_BEARING,
        np.eye(2),
    )
    assert nis == 0.0
    np.testing.assert_array_equal(mu, [1.0, 2.0, 0.3])
    np.testing.assert_array_equal(cov, np.eye(3))


def test_copy_is_deep():
    belief = EKFBelief(
        np.zeros((1, 3)), np.eye(3)[None], UnicycleModel(DT), RelativePositionSensor()
    )
    other = belief.copy()
    other.predict(np.array([[1.0, 1.0]]))
    np.testing.assert_array_equal(belief.mean, np.zeros((1, 3)))
    np.testing.assert_array_equal(belief.cov, np.eye(3)[None])


@pytest.mark.parametrize(
    ("mean", "cov", "match"),
    [
        (np.zeros((2, 3)), np.eye(3)[None], "batch"),
        (np.array([[0.0, np.nan, 0.0]]), np.eye(3)[None], "finite"),
        (np.zeros((1, 3)), np.diag([1.0, 0.0, 1.0])[None], "positive definite"),
    ],
    ids=["batch_mismatch", "nan", "singular"],
)
def test_ekf_belief_rejects_bad_initial_state(mean, cov, match):
    with pytest.raises(ValueError, match=match):
        EKFBelief(mean, cov, UnicycleModel(DT), RelativePositionSensor())


# --- entropy --------------------------------------------------------------------------------------


def random_covariances(rng, shape):
    a = rng.normal(size=(*shape, 3, 3)) * rng.uniform(0.01, 3.0, size=(*shape, 1, 1))
    return a @ np.swapaxes(a, -1, -2) + 1e-3 * np.eye(3)


def test_gaussian_entropy_closed_form_and_scipy():
    rng = np.random.default_rng(5)
    covs = random_covariances(rng, (20,))
    ent = gaussian_entropy(covs)
    assert ent.shape == (20,)
    for cov, value in zip(covs, ent, strict=True):
        closed = 0.5 * math.log((2 * math.pi * math.e) ** 3 * np.linalg.det(cov))
        assert value == pytest.approx(closed, rel=1e-12, abs=1e-12)
        assert value == pytest.approx(multivariate_normal(np.zeros(3), cov).entropy(), abs=1e-10)
        assert gaussian_entropy3(cov) == pytest.approx(value, abs=1e-10)


def test_gaussian_entropy_of_identity_and_scaling():
    h0 = float(gaussian_entropy(np.eye(3)))
    assert h0 == pytest.approx(1.5 * math.log(2 * math.pi * math.e), abs=1e-14)
    # scaling every std by s adds 3 log s
    assert float(gaussian_entropy(4.0 * np.eye(3))) == pytest.approx(h0 + 3 * math.log(2.0))


def test_gaussian_entropy_batch_shape_and_belief_entropy():
    rng = np.random.default_rng(6)
    covs = random_covariances(rng, (2, 4))
    ent = gaussian_entropy(covs)
    assert ent.shape == (2, 4)
    assert ent[1, 2] == gaussian_entropy(covs[1, 2])
    belief = EKFBelief(np.zeros((4, 3)), covs[0], UnicycleModel(DT), RelativePositionSensor())
    np.testing.assert_array_equal(belief.entropy(), ent[0])


@pytest.mark.parametrize(
    "cov",
    [np.zeros((3, 3)), np.diag([1.0, -1.0, 1.0]), np.diag([1.0, 1.0, 0.0])],
    ids=["zero", "indefinite", "singular"],
)
def test_gaussian_entropy_rejects_non_positive_definite(cov):
    with pytest.raises(ValueError, match="not positive definite"):
        gaussian_entropy(cov)


def test_gaussian_entropy_rejects_indefinite_with_positive_determinant():
    with pytest.raises(ValueError, match="not positive definite"):
        gaussian_entropy(np.diag([-1.0, -1.0, 1.0]))
