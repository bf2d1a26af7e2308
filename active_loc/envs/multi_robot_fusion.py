"""Cooperative localization: robot-robot detections and how a robot fuses them.

Robot ``i`` detects robot ``j`` when ``j`` lies inside ``i``'s field of view and range; it
measures ``z = (r, phi)``, the range (m) and bearing (rad, in ``i``'s frame) of ``j``'s
position, with noise ``N(0, diag(range_std^2, bearing_std^2))``, and knows who it saw (robots
carry distinct markers, as in Fox et al. 2000). The model is the chapter's range-bearing
landmark model (eq. 13.8) with robot ``j`` as the landmark:

    h(x_i, p_j) = (|p_j - p_i|, atan2(p_j,y - y_i, p_j,x - x_i) - theta_i).

Robot ``j``'s position is not known, only believed, and ``j``'s belief may already hold
information that came from ``i`` (an earlier exchange): the two estimates are correlated by an
unknown amount. Fusing as if they were independent counts that information twice and makes the
beliefs overconfident. Two fusions avoid it:

**EKF: covariance intersection** (:func:`ci_detection_update`). Linearized at the two means,
the detection is a measurement of robot ``i``'s pose,

    z - h(mu_i, mu_j) + H mu_i = H x_i + [H_j (p_j - mu_j) + v],

whose error ``H_j e_j + v`` has covariance ``R_eff = R + H_j Sigma_j,pp H_j^T``
(``H = dh/dx_i`` (2 x 3), ``H_j = dh/dp_j``). It carries information ``H^T R_eff^-1 H`` (rank 2:
range and bearing fix the position and the heading jointly, a 1-D family of poses stays free)
about ``x_i``, and its error is correlated with ``i``'s own error ``e_i`` in an unknown way,
through ``e_j``. Covariance intersection combines the two in information form,

    Sigma^-1 = omega Sigma_i^-1 + (1 - omega) H^T R_eff^-1 H,     omega in (0, 1],

which is consistent (``Sigma`` bounds the true error covariance) for *every* cross-correlation
of the two errors (Julier and Uhlmann 1997; the partial-observation form, Julier and Uhlmann
2001, "General decentralized data fusion with covariance intersection"). It is computed as the
equivalent Kalman update with the prior covariance inflated to ``Sigma_i / omega`` and the
noise to ``R_eff / (1 - omega)`` (Joseph form, symmetrized), and ``omega`` minimizes
``det Sigma`` (or ``trace Sigma``) by golden-section search on [0, 1]: ``log det Sigma^-1`` is
concave in ``omega`` and ``trace Sigma`` convex, so the search finds the global optimum. Since
``omega <= 1`` and ``1 - omega <= 1``, the fused information never exceeds the naive sum
``Sigma_i^-1 + H^T R_eff^-1 H``: CI is never more confident than the independence-assuming
update. The measurement noise ``v`` is in fact independent of both beliefs, and Split CI would
exploit that for a tighter bound; plain CI treats it conservatively. A detection whose
normalized innovation squared under the naive update exceeds the 99.9 % chi-square quantile
(2 dof) is rejected as inconsistent (a linearization far off, or a belief gone wrong).

**MCL: reciprocal sampling** (:func:`reciprocal_log_likelihood`), after Fox, Burgard, Kruppa and
Thrun (2000), "A probabilistic approach to collaborative multi-robot localization", Autonomous
Robots 8. Robot ``i``'s belief is multiplied by the density of its pose implied by ``j``'s
belief and the detection,

    Bel(x_i) <- Bel(x_i) * integral p(x_i | x_j, z) Bel(x_j) dx_j,

estimated by sampling: draw ``M`` particles of ``j`` by weight, draw the measurement noise, and
turn each into a sample of ``i``'s pose, ``theta_i`` stratified over the circle (the detection
leaves it free) and ``p_i = p_j - r (cos(theta_i + phi), sin(theta_i + phi))``; then a Gaussian
kernel density of the samples (the paper uses a density tree; a kernel estimate plays the same
role) is evaluated at ``i``'s particles and used as their likelihood, mixed with a small uniform
part (:data:`FUSION_OUTLIER_PROB`) so that one bad detection cannot wipe a belief out. Particle
beliefs offer no cross-covariance to intersect, so double counting is avoided by rules on when
to fuse (the env applies them):

* a waiting time, the paper's remedy: once a pair of robots has fused, neither fuses a
  detection of the other again until ``fusion_interval`` steps have passed and the beliefs
  have moved on with their own measurements;
* by default (``fusion_sender_localized``) a robot only lends its belief once it is localized
  (confident). An ambiguous belief's split between look-alike hypotheses is mostly resampling
  noise, not evidence; two such robots that keep multiplying each other's splits drive each
  other onto the same hypothesis, right or wrong (in 6 seeded episodes in the demo's arena, 2
  of 12 robots fusing that way ended confident on a wrong pose, none with this rule). A
  localized robot stops (its episode has ended) and its belief is frozen, so information then
  flows one way only, and the interval keeps a robot from reusing the same frozen belief at
  every step.

Randomness: every draw comes from the Generator passed in.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numba
import numpy as np
from numpy.typing import ArrayLike, NDArray

from active_loc.beliefs.mcl import MCLBelief
from active_loc.geometry import wrap_angle, wrap_angle_scalar
from active_loc.maps.landmarks import LandmarkMap
from active_loc.sensors.landmarks import RANGE_BEARING, in_view, measurement_and_jacobian

#: 99.9 % quantile of chi-square with 2 dof: the validation gate of an EKF detection
CHI2_999_2DOF = 13.815510557964274
#: weight of the uniform part of the reciprocal density (robustness to a wrong detection)
FUSION_OUTLIER_PROB = 0.01
_GOLDEN = (math.sqrt(5.0) - 1.0) / 2.0
_OMEGA_MIN = 1e-9


# --- detections ----------------------------------------------------------------------------------


@numba.njit(cache=True, nogil=True)
def detect_robots(
    poses: NDArray,
    sensing: NDArray,
    fov: float,
    max_range: float,
    noise_std: NDArray,
    normals: NDArray,
    z: NDArray,
    seen: NDArray,
) -> None:
    """Simulate every robot's detections of the others from the true poses.

    Args:
        poses: ``(n, 3)`` true poses (m, m, rad).
        sensing: ``(n,)`` bool: which robots sense this step (the others detect nothing but can
            still be detected).
        fov: field of view (rad), centred on the heading; max_range: range (m).
        noise_std: ``(2,)`` range (m) and bearing (rad) noise std.
        normals: ``(n, n, 2)`` standard normals; pair ``(i, j)`` uses ``normals[i, j]``.
        z: ``(n, n, 2)`` out: ``z[i, j]`` = (range m, bearing rad) of robot j seen by robot i,
            zero where not seen.
        seen: ``(n, n)`` out: whether robot i detects robot j (never itself).
    """
    n = poses.shape[0]
    for i in range(n):
        for j in range(n):
            ok = i != j and sensing[i] and in_view(
                poses[i, 0], poses[i, 1], poses[i, 2], poses[j, 0], poses[j, 1], fov, max_range
            )
            seen[i, j] = ok
            if not ok:
                z[i, j, 0] = 0.0
                z[i, j, 1] = 0.0
                continue
            r, b, _, _, _, _, _, _ = measurement_and_jacobian(
                RANGE_BEARING, poses[i, 0], poses[i, 1], poses[i, 2], poses[j, 0], poses[j, 1]
            )
            z[i, j, 0] = max(r + noise_std[0] * normals[i, j, 0], 0.0)
            z[i, j, 1] = wrap_angle_scalar(b + noise_std[1] * normals[i, j, 1])


# --- EKF: covariance intersection ----------------------------------------------------------------


@dataclass(frozen=True)
class CIResult:
    """Outcome of :func:`ci_detection_update`.

    Attributes:
        mean: ``(3,)`` fused pose mean (heading wrapped); the prior mean if not fused.
        cov: ``(3, 3)`` fused covariance; the prior covariance if not fused.
        omega: the CI weight of robot i's own belief, in (0, 1] (1: the detection adds nothing).
        nis: normalized innovation squared of the detection under the naive update.
        fused: False when the detection failed the chi-square gate.
    """

    mean: NDArray[np.float64]
    cov: NDArray[np.float64]
    omega: float
    nis: float
    fused: bool


def detection_model(
    mean_i: ArrayLike, mean_j: ArrayLike, cov_j: ArrayLike, noise_cov: ArrayLike
) -> tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.float64]]:
    """Linearized detection of robot j by robot i at the means.

    Args:
        mean_i: ``(3,)`` robot i's mean; mean_j ``(3,)`` and cov_j ``(3, 3)`` robot j's belief.
        noise_cov: ``(2, 2)`` detection noise R (m^2, rad^2).

    Returns:
        ``z_hat`` ``(2,)`` = h(mu_i, mu_j), ``H`` ``(2, 3)`` = dh/dx_i, and ``R_eff`` ``(2, 2)``
        = R + H_j Sigma_j,pp H_j^T with ``H_j = dh/dp_j = -H[:, :2]``.
    """
    mi = np.asarray(mean_i, dtype=np.float64)
    mj = np.asarray(mean_j, dtype=np.float64)
    out = measurement_and_jacobian(RANGE_BEARING, mi[0], mi[1], mi[2], mj[0], mj[1])
    z_hat = np.array(out[:2])
    jac = np.array(out[2:]).reshape(2, 3)
    jac_j = -jac[:, :2]
    cov_pp = np.asarray(cov_j, dtype=np.float64)[:2, :2]
    r_eff = np.asarray(noise_cov, dtype=np.float64) + jac_j @ cov_pp @ jac_j.T
    return z_hat, jac, 0.5 * (r_eff + r_eff.T)


def _kalman(
    mean: NDArray, cov: NDArray, nu: NDArray, jac: NDArray, noise: NDArray
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """One Kalman update (Cholesky solve, Joseph form, symmetrized, heading wrapped)."""
    s = jac @ cov @ jac.T + noise
    root = np.linalg.cholesky(0.5 * (s + s.T))
    gain_t = np.linalg.solve(root.T, np.linalg.solve(root, jac @ cov))  # K^T = S^-1 H Sigma
    gain = gain_t.T
    new_mean = mean + gain @ nu
    new_mean[2] = wrap_angle(new_mean[2])
    a = np.eye(3) - gain @ jac
    new_cov = a @ cov @ a.T + gain @ noise @ gain.T
    return new_mean, 0.5 * (new_cov + new_cov.T)


def _ci_objective(
    omega: float, info_i: NDArray, info_z: NDArray, criterion: str
) -> float:
    """det or trace of the CI covariance ``(omega Y_i + (1 - omega) Y_z)^-1`` (to minimize)."""
    info = omega * info_i + (1.0 - omega) * info_z
    if criterion == "det":
        sign, logdet = np.linalg.slogdet(info)
        return -logdet if sign > 0 else math.inf
    try:
        return float(np.trace(np.linalg.inv(info)))
    except np.linalg.LinAlgError:
        return math.inf


def ci_omega(
    info_i: ArrayLike, info_z: ArrayLike, criterion: str = "det", tol: float = 1e-6
) -> float:
    """The CI weight minimizing ``det`` or ``trace`` of ``(omega Y_i + (1 - omega) Y_z)^-1``
    over [0, 1], by golden-section search (the objective is unimodal: log det of the fused
    information is concave in omega, the trace of its inverse convex).

    Args:
        info_i: ``(3, 3)`` information matrix of robot i's belief (positive definite).
        info_z: ``(3, 3)`` information of the detection (positive semi-definite, rank 2).
        criterion: ``"det"`` or ``"trace"``.
    """
    if criterion not in ("det", "trace"):
        raise ValueError(f"criterion must be 'det' or 'trace', got {criterion!r}")
    yi = np.asarray(info_i, dtype=np.float64)
    yz = np.asarray(info_z, dtype=np.float64)
    lo, hi = _OMEGA_MIN, 1.0
    a = hi - _GOLDEN * (hi - lo)
    b = lo + _GOLDEN * (hi - lo)
    fa = _ci_objective(a, yi, yz, criterion)
    fb = _ci_objective(b, yi, yz, criterion)
    while hi - lo > tol:
        if fa <= fb:
            hi, b, fb = b, a, fa
            a = hi - _GOLDEN * (hi - lo)
            fa = _ci_objective(a, yi, yz, criterion)
        else:
            lo, a, fa = a, b, fb
            b = lo + _GOLDEN * (hi - lo)
            fb = _ci_objective(b, yi, yz, criterion)
    omega = 0.5 * (lo + hi)
    # the end point 1 (ignore the detection) is a candidate of its own
    if _ci_objective(1.0, yi, yz, criterion) <= _ci_objective(omega, yi, yz, criterion):
        return 1.0
    return omega


def ci_detection_update(
    mean_i: ArrayLike,
    cov_i: ArrayLike,
    mean_j: ArrayLike,
    cov_j: ArrayLike,
    z: ArrayLike,
    noise_cov: ArrayLike,
    criterion: str = "det",
    gate: float | None = CHI2_999_2DOF,
) -> CIResult:
    """Fuse robot i's detection ``z`` = (range m, bearing rad) of robot j into i's Gaussian
    belief by covariance intersection (see the module docstring).

    Args:
        mean_i, cov_i: robot i's belief ``(3,)``, ``(3, 3)``.
        mean_j, cov_j: robot j's belief ``(3,)``, ``(3, 3)`` (only the position block is used).
        z: ``(2,)`` the detection; noise_cov: ``(2, 2)`` its noise R.
        criterion: ``"det"`` or ``"trace"``: what omega minimizes.
        gate: reject the detection when its NIS under the naive update exceeds this (None:
            never).
    """
    mi = np.asarray(mean_i, dtype=np.float64).reshape(3)
    pi = np.asarray(cov_i, dtype=np.float64).reshape(3, 3)
    z_hat, jac, r_eff = detection_model(mi, mean_j, cov_j, noise_cov)
    nu = np.asarray(z, dtype=np.float64).reshape(2) - z_hat
    nu[1] = wrap_angle(nu[1])
    s = jac @ pi @ jac.T + r_eff
    nis = float(nu @ np.linalg.solve(s, nu))
    if gate is not None and nis > gate:
        return CIResult(mi.copy(), pi.copy(), 1.0, nis, False)
    info_i = np.linalg.inv(pi)
    info_z = jac.T @ np.linalg.solve(r_eff, jac)
    omega = ci_omega(0.5 * (info_i + info_i.T), 0.5 * (info_z + info_z.T), criterion)
    if omega >= 1.0:
        return CIResult(mi.copy(), pi.copy(), 1.0, nis, True)
    mean, cov = _kalman(mi, pi / omega, nu, jac, r_eff / (1.0 - omega))
    return CIResult(mean, cov, omega, nis, True)


def naive_detection_update(
    mean_i: ArrayLike,
    cov_i: ArrayLike,
    mean_j: ArrayLike,
    cov_j: ArrayLike,
    z: ArrayLike,
    noise_cov: ArrayLike,
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """The EKF update that assumes robot j's error independent of robot i's (``R_eff`` as
    measurement noise): the reference CI is compared against. Returns mean ``(3,)``, cov
    ``(3, 3)``."""
    mi = np.asarray(mean_i, dtype=np.float64).reshape(3)
    pi = np.asarray(cov_i, dtype=np.float64).reshape(3, 3)
    z_hat, jac, r_eff = detection_model(mi, mean_j, cov_j, noise_cov)
    nu = np.asarray(z, dtype=np.float64).reshape(2) - z_hat
    nu[1] = wrap_angle(nu[1])
    return _kalman(mi, pi, nu, jac, r_eff)


# --- MCL: reciprocal sampling --------------------------------------------------------------------


@numba.njit(cache=True, nogil=True)
def kde_log_density(points: NDArray, samples: NDArray, bandwidth: NDArray, out: NDArray) -> None:
    """Log of a Gaussian product-kernel density of pose ``samples`` at ``points``.

    ``f(x) = 1/M sum_m N(x - s_m; 0, diag(h^2))`` with the heading residual wrapped, a density
    over (x, y, theta) (1/(m^2 rad)). The samples must have stratified headings: sample m's
    heading in ``[-pi + 2 pi m / M, -pi + 2 pi (m + 1) / M)``, so that only the index window
    within 5 heading bandwidths of a point is visited; kernels beyond 5 sigma are dropped.

    Args:
        points: ``(K, 3)``; samples: ``(M, 3)`` as above; bandwidth: ``(3,)`` (m, m, rad).
        out: ``(K,)`` out: log density, ``-inf`` where no sample is near.
    """
    m_total = samples.shape[0]
    hx, hy, ht = bandwidth[0], bandwidth[1], bandwidth[2]
    log_norm = -np.log(m_total) - 1.5 * np.log(2.0 * np.pi) - np.log(hx * hy * ht)
    span = 5.0 * ht
    per_bin = 2.0 * np.pi / m_total
    width = int(np.ceil(span / per_bin)) + 1
    for k in range(points.shape[0]):
        x, y, th = points[k, 0], points[k, 1], points[k, 2]
        centre = int(np.floor((th + np.pi) / per_bin))
        lo, hi = centre - width, centre + width
        if hi - lo + 1 >= m_total:
            lo, hi = 0, m_total - 1
        acc = 0.0
        for idx in range(lo, hi + 1):
            m = idx % m_total
            d2 = (wrap_angle_scalar(th - samples[m, 2]) / ht) ** 2
            if d2 > 25.0:
                continue
            d2 += ((x - samples[m, 0]) / hx) ** 2 + ((y - samples[m, 1]) / hy) ** 2
            if d2 < 50.0:
                acc += np.exp(-0.5 * d2)
        out[k] = np.log(acc) + log_norm if acc > 0.0 else -np.inf


def reciprocal_samples(
    particles_j: ArrayLike,
    weights_j: ArrayLike,
    z: ArrayLike,
    noise_std: ArrayLike,
    n_samples: int,
    rng: np.random.Generator,
) -> NDArray[np.float64]:
    """Samples ``(M, 3)`` of robot i's pose implied by robot j's particles and i's detection
    ``z`` = (range m, bearing rad) of j, headings stratified over the circle (ascending).

    Draws ``M`` uniforms (j's particles, by weight), ``2 M`` normals (detection noise) and
    ``M`` uniforms (headings) from ``rng``.
    """
    parts = np.asarray(particles_j, dtype=np.float64).reshape(-1, 3)
    w = np.asarray(weights_j, dtype=np.float64).reshape(-1)
    cdf = np.cumsum(w)
    idx = np.searchsorted(cdf, rng.random(n_samples) * cdf[-1], side="right")
    idx = np.minimum(idx, parts.shape[0] - 1)
    std = np.asarray(noise_std, dtype=np.float64)
    noise = rng.standard_normal((n_samples, 2)) * std
    r = np.maximum(float(z[0]) + noise[:, 0], 0.0)  # type: ignore[index]
    phi = float(z[1]) + noise[:, 1]  # type: ignore[index]
    theta = -np.pi + 2.0 * np.pi * (np.arange(n_samples) + rng.random(n_samples)) / n_samples
    out = np.empty((n_samples, 3))
    out[:, 0] = parts[idx, 0] - r * np.cos(theta + phi)
    out[:, 1] = parts[idx, 1] - r * np.sin(theta + phi)
    out[:, 2] = theta
    return out


def reciprocal_log_likelihood(
    particles_i: ArrayLike,
    particles_j: ArrayLike,
    weights_j: ArrayLike,
    z: ArrayLike,
    noise_std: ArrayLike,
    bandwidth: ArrayLike,
    area: float,
    n_samples: int,
    rng: np.random.Generator,
) -> NDArray[np.float64]:
    """Log-likelihood ``(K,)`` of robot i's particles ``(K, 3)`` under the detection ``z`` of
    robot j, whose belief is the particle set ``particles_j`` ``(Kj, 3)`` with weights
    ``(Kj,)``: ``log((1 - a) f(x_k) + a / (area 2 pi))`` with ``f`` the kernel density of
    :func:`reciprocal_samples` (bandwidth ``(3,)`` m, m, rad) and ``a`` =
    :data:`FUSION_OUTLIER_PROB`; ``area`` (m^2) is the free area of the map.
    """
    samples = reciprocal_samples(particles_j, weights_j, z, noise_std, n_samples, rng)
    points = np.ascontiguousarray(particles_i, dtype=np.float64).reshape(-1, 3)
    log_f = np.empty(points.shape[0])
    kde_log_density(points, samples, np.asarray(bandwidth, dtype=np.float64), log_f)
    a = FUSION_OUTLIER_PROB
    log_uniform = math.log(a) - math.log(area * 2.0 * math.pi)
    with np.errstate(divide="ignore"):
        return np.logaddexp(math.log1p(-a) + log_f, log_uniform)


def fuse_ekf(
    mean: NDArray, cov: NDArray, z: NDArray, pairs: list[tuple[int, int]], noise_cov: NDArray,
    criterion: str,
) -> list[tuple[int, int]]:
    """Fuse detections into a batch of Gaussian beliefs in place by :func:`ci_detection_update`.

    Args:
        mean: ``(n, 3)``, cov: ``(n, 3, 3)``: the robots' beliefs, updated in place.
        z: ``(n, n, 2)``: ``z[i, j]`` robot i's detection of robot j.
        pairs: the ``(i, j)`` to fuse (robot i fuses its detection of robot j), in order; each
            uses robot j's belief as it was before any of them (a simultaneous exchange).
        noise_cov: ``(2, 2)`` detection noise R; criterion: ``"det"`` or ``"trace"``.

    Returns:
        The pairs that changed robot i's belief (gate passed and omega < 1).
    """
    before_mean, before_cov = mean.copy(), cov.copy()
    fused = []
    for i, j in pairs:
        res = ci_detection_update(mean[i], cov[i], before_mean[j], before_cov[j], z[i, j],
                                  noise_cov, criterion)
        if res.fused and res.omega < 1.0:
            mean[i], cov[i] = res.mean, res.cov
            fused.append((i, j))
    return fused


def fuse_mcl(
    beliefs: list[MCLBelief], pairs: list[tuple[int, int]], z: NDArray, noise_std: NDArray,
    bandwidth: tuple[float, float, float], area: float, n_samples: int,
    rng: np.random.Generator,
) -> None:
    """Fuse detections into particle beliefs by :func:`reciprocal_log_likelihood`, each pair
    ``(i, j)`` with robot j's particles as they were before any of them; the weights go
    through :meth:`MCLBelief.update` (normalization, resampling), untempered: the filter's
    ``likelihood_exponent`` is for scans, a detection is not one. Draws from ``rng`` only."""
    before = {j: (beliefs[j].particles.copy(), beliefs[j].weights) for _, j in pairs}
    for i, j in pairs:
        particles_j, weights_j = before[j]
        belief = beliefs[i]
        log_lik = reciprocal_log_likelihood(belief.particles, particles_j, weights_j, z[i, j],
                                            noise_std, bandwidth, area, n_samples, rng)
        belief.update(log_lik / belief.likelihood_exponent, rng)


# --- the symmetric arena -------------------------------------------------------------------------


def symmetric_landmark_map(
    rng: np.random.Generator,
    size: tuple[float, float],
    n_landmarks: int | tuple[int, int],
    min_separation: float = 1.5,
    margin: float = 1.0,
) -> LandmarkMap:
    """A walled arena whose landmarks repeat under a 180-degree rotation about its centre, but
    for one: ``(count - 1) // 2`` landmarks with their rotated twins, and one *cue* landmark
    whose rotation is no landmark (``count`` from ``n_landmarks``, at least 3). With
    identical-looking landmarks every view without the cue fits two poses (the true one and its
    rotation), so a robot alone stays ambiguous until it sees the cue, which makes the map as a
    whole unambiguous. Landmarks lie in ``[margin, size - margin]`` (m), every two (and every
    landmark and the cue's rotation) at least ``min_separation`` (m) apart, placed by rejection
    from a fixed block of uniforms. The map spans ``(0, 0)`` to ``size``.

    Raises:
        ValueError: fewer than 3 landmarks, or no room for them.
    """
    width, height = (float(s) for s in size)
    if isinstance(n_landmarks, tuple):
        count = int(rng.integers(n_landmarks[0], n_landmarks[1] + 1))
    else:
        count = int(n_landmarks)
    if count < 3:
        raise ValueError(f"n_landmarks: the symmetric arena needs at least 3, got {count}")
    pairs = (count - 1) // 2
    low = np.array([margin, margin])
    span = np.array([width - 2 * margin, height - 2 * margin])
    for _ in range(4):  # nearly always the first block; a rare shortfall draws another
        candidates = low + rng.random((256 * count, 2)) * span
        positions = _place_symmetric(candidates, np.array([width, height]) - candidates, pairs,
                                     min_separation**2)
        if positions is not None:
            return LandmarkMap.trusted(positions, (0.0, 0.0, width, height), True)
    raise ValueError(f"symmetric_landmark_map: could not place {count} landmarks "
                     f"{min_separation} m apart in {size}")


def _place_symmetric(
    candidates: NDArray, twins: NDArray, pairs: int, limit: float
) -> NDArray[np.float64] | None:
    """Accept candidates ``(M, 2)`` in order, each with its twin ``(M, 2)`` (its rotation),
    when both keep ``sqrt(limit)`` from each other and from everything accepted: ``pairs``
    of them with their twins, then the cue (its twin's place kept clear, not a landmark).
    Returns ``(2 pairs + 1, 2)`` positions (the pairs, their twins, the cue) or None."""
    chosen: list[NDArray] = []
    for p, twin in zip(candidates, twins, strict=True):
        if np.sum((p - twin) ** 2) < limit or any(
            np.sum((p - q) ** 2) < limit or np.sum((twin - q) ** 2) < limit for q in chosen
        ):
            continue
        if len(chosen) == 2 * pairs:
            return np.ascontiguousarray([*chosen[0::2], *chosen[1::2], p])
        chosen += [p, twin]
    return None


# --- drawing (the env's render; here to keep the env module short) ------------------------------


class MultiRobotRenderer:
    """Matplotlib (Agg) drawing of a multi-robot frame: the map and landmarks (seen ones
    filled), per robot in its colour the true pose (triangle), the belief (mean arrow and 95 %
    position ellipse, plus the particles of MCL), the true path, and the detections as lines
    between the true poses (solid: fused, dashed: not fused). Redraws the axes each frame (tens
    of ms). Pose markers, ellipses and colours are :mod:`active_loc.envs.rendering`'s.

    A frame is a dict: ``bounds`` (4,), ``landmarks`` (N, 2), ``seen`` (N,) bool or None,
    ``poses``, ``means`` (n, 3), ``covs`` (n, 3, 3), ``particles`` / ``weights`` (lists of
    (K, 3) / (K,), or None), ``detections`` [(i, j, fused)], ``paths`` [(T, 2)], ``live`` (n,),
    ``entropy`` (n,) and ``step``.
    """

    def __init__(self, size_px: tuple[int, int] = (600, 600)) -> None:
        from matplotlib.backends.backend_agg import FigureCanvasAgg
        from matplotlib.figure import Figure

        from active_loc.envs.rendering import DPI

        self.size_px = size_px
        self._fig = Figure(figsize=(size_px[0] / DPI, size_px[1] / DPI), dpi=DPI)
        self._canvas = FigureCanvasAgg(self._fig)
        self._window: Any = None

    def render_rgb(self, frame: dict[str, Any]) -> NDArray[np.uint8]:
        """``(H, W, 3)`` uint8 image of ``frame``."""
        self._draw(self._fig, frame)
        self._canvas.draw()
        rgba = np.asarray(self._canvas.buffer_rgba())
        out = np.full((self.size_px[1], self.size_px[0], 3), 255, dtype=np.uint8)
        h, w = min(out.shape[0], rgba.shape[0]), min(out.shape[1], rgba.shape[1])
        out[:h, :w] = rgba[:h, :w, :3]
        return out

    def show(self, frame: dict[str, Any]) -> None:
        """Draw ``frame`` into a pyplot window without blocking."""
        import matplotlib.pyplot as plt

        from active_loc.envs.rendering import DPI

        if self._window is None or not plt.fignum_exists(self._window.number):
            plt.ion()
            self._window = plt.figure(figsize=(self.size_px[0] / DPI, self.size_px[1] / DPI))
        self._draw(self._window, frame)
        self._window.canvas.draw_idle()
        self._window.canvas.flush_events()

    def close(self) -> None:
        if self._window is not None:
            import matplotlib.pyplot as plt

            plt.close(self._window)
            self._window = None

    @staticmethod
    def _draw(fig: Any, frame: dict[str, Any]) -> None:
        import matplotlib
        from matplotlib.patches import Ellipse, Polygon, Rectangle

        from active_loc.envs.rendering import _ARROW, _TRIANGLE, _ellipse_params, _pose_polygon

        fig.clear()
        ax = fig.add_axes((0.09, 0.07, 0.88, 0.86))
        x0, y0, x1, y1 = frame["bounds"]
        span = max(x1 - x0, y1 - y0)
        pad = 0.04 * span
        ax.set_xlim(x0 - pad, x1 + pad)
        ax.set_ylim(y0 - pad, y1 + pad)
        ax.set_aspect("equal")
        ax.tick_params(labelsize=7)
        ax.add_patch(Rectangle((x0, y0), x1 - x0, y1 - y0, fill=False, ec="black", lw=1.2))
        lms, seen = frame["landmarks"], frame["seen"]
        ax.plot(lms[:, 0], lms[:, 1], ls="none", marker="*", ms=10, mfc="white", mec="black")
        if seen is not None and seen[: len(lms)].any():
            lit = lms[seen[: len(lms)]]
            ax.plot(lit[:, 0], lit[:, 1], ls="none", marker="*", ms=10, mfc="tab:orange",
                    mec="black")
        colors = matplotlib.colormaps["tab10"].colors
        size = 0.045 * span
        poses, means, covs = frame["poses"], frame["means"], frame["covs"]
        for i, j, fused in frame["detections"]:
            ax.plot(*zip(poses[i, :2], poses[j, :2], strict=True), color=colors[i % 10],
                    lw=1.4, ls="-" if fused else "--", zorder=2)
        for i in range(poses.shape[0]):
            color = colors[i % 10]
            if frame["particles"] is not None:
                parts = frame["particles"][i]
                ax.scatter(parts[:, 0], parts[:, 1], s=2.0, color=color, alpha=0.25, lw=0,
                           zorder=1)
            path = frame["paths"][i]
            ax.plot(path[:, 0], path[:, 1], color=color, lw=0.8, alpha=0.6, zorder=1.5)
            ellipse = _ellipse_params(covs[i][:2, :2], cap=20.0 * span)
            if ellipse is not None:
                ax.add_patch(Ellipse(tuple(means[i, :2]), ellipse[0], ellipse[1],
                                     angle=ellipse[2], fc=color, ec=color, alpha=0.2, zorder=3))
            ax.add_patch(Polygon(_pose_polygon(_TRIANGLE, poses[i], 1.15 * size), fc=color,
                                 ec="black", lw=0.8, zorder=4))
            ax.add_patch(Polygon(_pose_polygon(_ARROW, means[i], size), fc="white", ec=color,
                                 lw=1.2, zorder=5))
        text = "   ".join(f"r{i}: H={h:.2f}{'' if live else ' (done)'}" for i, (h, live)
                           in enumerate(zip(frame["entropy"], frame["live"], strict=True)))
        fig.text(0.5, 0.985, f"step {frame['step']}   {text}", ha="center", va="top",
                 fontsize=8)
