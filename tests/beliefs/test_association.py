"""Maximum-likelihood data association with a validation gate (Algorithm 3, eqs. 13.6-13.7).

The numba kernel is checked against a brute-force numpy evaluation of the chapter's formulas;
the correction that follows it against the known-correspondence EKF; and a constructed case
shows what the gate is for: a persistent spurious detection next to a landmark drags an
ungated filter off the truth and makes it confidently wrong, while the gated filter rejects it.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy.stats import chi2

from active_loc.beliefs.association import (
    DEFAULT_GATE,
    associate_measurements,
    gate_threshold,
    update_with_association,
)
from active_loc.beliefs.ekf import EKFBelief
from active_loc.geometry import wrap_angle
from active_loc.motion import UnicycleModel
from active_loc.sensors.landmarks import LandmarkSensor, RangeBearingSensor, RelativePositionSensor

SENSORS = {
    "range_bearing": RangeBearingSensor.from_std(0.1, 0.035),
    "relative_position": RelativePositionSensor(0.25 * np.eye(2)),
}


def brute_force_association(
    mean: np.ndarray, cov: np.ndarray, z: np.ndarray, landmarks: np.ndarray,
    sensor: LandmarkSensor, gate: float | None,
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Eqs. 13.6-13.7 with numpy matrices: for each z_i the landmark maximizing
    N(z_i; h(mu, m_k), H_k Sigma H_k^T + R), unmatched (index L) beyond the chi^2 gate; also
    the (ungated) landmark of smallest Mahalanobis distance alone."""
    threshold = math.inf if gate is None or gate == 1.0 else chi2.ppf(gate, 2)
    z_hat = sensor.expected(mean, landmarks)  # (L, 2)
    jac = sensor.jacobian(mean, landmarks)  # (L, 2, 3)
    index = np.empty(len(z), dtype=np.int64)
    nearest = np.empty(len(z), dtype=np.int64)
    d2 = np.empty(len(z))
    for i, z_i in enumerate(z):
        scores, dists = [], []
        for k in range(len(landmarks)):
            s_k = jac[k] @ cov @ jac[k].T + sensor.noise_cov
            nu = sensor.residual(z_i, z_hat[k])
            dist = float(nu @ np.linalg.solve(s_k, nu))
            dists.append(dist)
            scores.append(dist + np.linalg.slogdet(s_k)[1])  # -2 log N up to a constant
        best = int(np.argmin(scores))
        d2[i] = dists[best]
        index[i] = best if dists[best] <= threshold else len(landmarks)
        nearest[i] = int(np.argmin(dists))
    return index, d2, nearest


def random_case(rng: np.random.Generator, sensor: LandmarkSensor) -> tuple:
    """A belief, a map and a scan mixing noisy landmark measurements and random points."""
    n_landmarks = int(rng.integers(1, 12))
    landmarks = rng.uniform(-8.0, 8.0, (n_landmarks, 2))
    truth = np.array([rng.uniform(-2, 2), rng.uniform(-2, 2), rng.uniform(-np.pi, np.pi)])
    root = rng.normal(0.0, 1.0, (3, 3)) * rng.uniform(0.01, 0.5)
    cov = root @ root.T + 1e-4 * np.eye(3)
    mean = truth + np.linalg.cholesky(cov) @ rng.standard_normal(3)
    mean[2] = wrap_angle(mean[2])
    seen = landmarks[rng.random(n_landmarks) < 0.7]
    noise = rng.standard_normal((len(seen), 2)) @ np.linalg.cholesky(sensor.noise_cov).T
    z_true = sensor.expected(truth, seen) + noise
    if sensor.kind == RangeBearingSensor.kind:
        clutter = np.column_stack([rng.uniform(0, 10, 3), rng.uniform(-np.pi, np.pi, 3)])
    else:
        clutter = rng.uniform(-10, 10, (3, 2))
    z = np.concatenate([z_true, clutter])[rng.permutation(len(seen) + 3)]
    return mean, cov, z, landmarks


@pytest.mark.parametrize("gate", [DEFAULT_GATE, 0.9, None])
@pytest.mark.parametrize("kind", list(SENSORS))
def test_association_equals_brute_force(kind: str, gate: float | None) -> None:
    sensor = SENSORS[kind]
    rng = np.random.default_rng(42)
    n_unmatched = n_matched = n_not_nearest = 0
    for _ in range(150):
        mean, cov, z, landmarks = random_case(rng, sensor)
        index, d2 = associate_measurements(mean, cov, z, landmarks, sensor, gate)
        ref_index, ref_d2, nearest = brute_force_association(
            mean, cov, z, landmarks, sensor, gate
        )
        np.testing.assert_array_equal(index, ref_index)
        np.testing.assert_allclose(d2, ref_d2, rtol=1e-9, atol=1e-9)
        matched = index < len(landmarks)
        n_unmatched += int(np.sum(~matched))
        n_matched += int(np.sum(matched))
        n_not_nearest += int(np.sum(index[matched] != nearest[matched]))
    assert n_matched > 0
    # the cases exercise the gate: some measurements fall outside it unless there is none
    assert (n_unmatched > 0) == (gate is not None)
    # and the likelihood (d^2 + log det S), not d^2 alone: some ML choices are not the nearest
    if gate is None:
        assert n_not_nearest > 0


def test_gate_threshold_is_the_chi_square_quantile() -> None:
    assert gate_threshold(0.99) == pytest.approx(chi2.ppf(0.99, 2), rel=1e-12)
    assert gate_threshold(0.5) == pytest.approx(chi2.ppf(0.5, 2), rel=1e-12)
    assert gate_threshold(None) == math.inf
    assert gate_threshold(1.0) == math.inf
    for bad in (0.0, -0.1, 1.5, float("nan"), "0.9", True):
        with pytest.raises(ValueError, match="association_gate"):
            gate_threshold(bad)  # type: ignore[arg-type]


def make_belief(mean: np.ndarray, cov: np.ndarray, sensor: LandmarkSensor) -> EKFBelief:
    return EKFBelief(mean[None], cov[None], UnicycleModel(0.1, 1e-4 * np.eye(3)), sensor)


@pytest.mark.parametrize("kind", list(SENSORS))
def test_correct_association_gives_the_known_correspondence_update(kind: str) -> None:
    """With every measurement matched to its own landmark, Algorithm 3's correction is
    Algorithm 2's stacked update, whatever the order of the scan."""
    sensor = SENSORS[kind]
    rng = np.random.default_rng(7)
    landmarks = np.array([[4.0, 0.0], [0.0, 5.0], [-4.0, -3.0], [3.0, 4.0]])
    truth = np.array([0.1, -0.2, 0.3])
    mean = truth + np.array([0.05, -0.04, 0.02])
    cov = np.diag([0.01, 0.01, 0.001])
    z = sensor.expected(truth, landmarks) + 0.5 * rng.standard_normal((4, 2)) @ np.linalg.cholesky(
        sensor.noise_cov
    ).T
    known = make_belief(mean, cov, sensor)
    known.update(z[None], np.ones((1, 4), dtype=bool), landmarks)
    order = np.array([2, 0, 3, 1])
    unknown = make_belief(mean, cov, sensor)
    index = update_with_association(unknown, z[order], landmarks)
    np.testing.assert_array_equal(index, order)
    np.testing.assert_allclose(unknown.mean, known.mean, atol=1e-12)
    np.testing.assert_allclose(unknown.cov, known.cov, atol=1e-12)
    assert unknown.last_nis[0] == pytest.approx(known.last_nis[0], rel=1e-9)


def test_unmatched_measurements_leave_the_belief_unchanged() -> None:
    sensor = SENSORS["range_bearing"]
    landmarks = np.array([[4.0, 0.0], [0.0, 5.0]])
    mean, cov = np.zeros(3), np.diag([0.01, 0.01, 0.001])
    belief = make_belief(mean, cov, sensor)
    far_away = np.array([[9.0, 2.5], [1.0, -2.0]])  # nowhere near any prediction
    index = update_with_association(belief, far_away, landmarks)
    np.testing.assert_array_equal(index, [2, 2])
    np.testing.assert_array_equal(belief.mean[0], mean)
    np.testing.assert_array_equal(belief.cov[0], cov)
    assert belief.last_nis[0] == 0.0
    # an empty scan too
    assert update_with_association(belief, np.empty((0, 2)), landmarks).shape == (0,)
    np.testing.assert_array_equal(belief.mean[0], mean)


def nees(truth: np.ndarray, belief: EKFBelief) -> float:
    err = truth - belief.mean[0]
    err[2] = wrap_angle(err[2])
    return float(err @ np.linalg.solve(belief.cov[0], err))


def test_a_phantom_detection_drags_an_ungated_filter_but_not_a_gated_one() -> None:
    """A robot standing at the origin sees two landmarks and, every scan, a spurious detection
    1.5 m beside one of them (a persistent reflection). Ungated, the ML association gives it
    to that landmark, every update pulls the heading toward it, and the filter ends up far off
    and overconfident; the gate rejects it once the belief is sharper than the phantom's
    offset and the filter stays consistent."""
    sensor = SENSORS["range_bearing"]
    motion = UnicycleModel(0.1, np.diag([1e-4, 1e-4, 1e-5]))
    landmarks = np.array([[5.0, 0.0], [0.0, 5.0]])
    phantom = np.array([[5.0, 1.5]])
    results = {}
    for gate in (DEFAULT_GATE, None):
        values, errors, rejected = [], [], 0
        for seed in range(20):
            rng = np.random.default_rng(seed)
            mean = rng.normal(0.0, [0.2, 0.2, 0.05])
            belief = EKFBelief(mean[None], np.diag([0.04, 0.04, 0.0025])[None], motion, sensor)
            truth = np.zeros(3)
            for _ in range(100):
                # the robot stands still up to the motion noise the filter expects
                truth = truth + motion.noise_root @ rng.standard_normal(3)
                belief.predict(np.zeros((1, 2)))
                noise = rng.standard_normal((2, 2)) @ np.linalg.cholesky(sensor.noise_cov).T
                z = np.concatenate([sensor.expected(truth, landmarks) + noise,
                                    sensor.expected(truth, phantom)])  # phantom: no noise
                index = update_with_association(belief, z[rng.permutation(3)], landmarks, gate)
                rejected += int(np.sum(index == 2))
            values.append(nees(truth, belief))
            errors.append(abs(wrap_angle(belief.mean[0, 2] - truth[2])))
        results[gate] = (np.mean(values), np.median(errors), rejected)
    gated, ungated = results[DEFAULT_GATE], results[None]
    print(f"\nphantom detection, 20 runs x 100 scans: gated mean final NEES {gated[0]:.2f}, "
          f"heading error {gated[1]:.4f} rad, {gated[2]} rejections; ungated NEES "
          f"{ungated[0]:.1f}, heading error {ungated[1]:.4f} rad")
    assert ungated[2] == 0
    assert ungated[0] > 50.0 and ungated[1] > 0.05
    low, high = chi2.ppf([0.005, 0.995], 3 * 20) / 20
    assert low <= gated[0] <= high and gated[1] < 0.02
    assert gated[2] >= 20 * 90  # the phantom, nearly every scan
