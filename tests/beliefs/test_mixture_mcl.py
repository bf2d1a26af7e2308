"""Mixture MCL: its dual proposals and its measurement update, against brute-force posteriors."""

from __future__ import annotations

import numpy as np
import pytest

from active_loc.beliefs.lidar_dual import LidarDualProposal, update_with_scan
from active_loc.beliefs.mcl import FreeSpace, MCLBelief, landmark_log_likelihood
from active_loc.maps import OccupancyGrid
from active_loc.motion import UnicycleModel
from active_loc.sensors.landmarks import LandmarkSensor, RangeBearingSensor
from active_loc.sensors.lidar import LidarSensor

LANDMARKS = np.array([[2.0, 1.0], [-1.0, 2.5]])
TRUTH = np.array([0.0, 0.0, 0.0])
# the prior is off the truth and about as wide as the likelihood, so the posterior is neither
PRIOR_MEAN = np.array([0.4, -0.3, 0.15])
PRIOR_STD = np.array([0.5, 0.5, 0.3])


def _landmark_posterior(
    sensor: LandmarkSensor, z: np.ndarray, known: bool
) -> tuple[np.ndarray, np.ndarray]:
    """Mean ``(3,)`` and std ``(3,)`` of prior x likelihood on a fine pose grid."""
    axes = [np.linspace(m - 5 * s, m + 5 * s, n)
            for m, s, n in zip(PRIOR_MEAN, PRIOR_STD, (81, 81, 61), strict=True)]
    grid = np.stack([a.ravel() for a in np.meshgrid(*axes, indexing="ij")], axis=1)
    log_p = -0.5 * (((grid - PRIOR_MEAN) / PRIOR_STD) ** 2).sum(axis=1)
    log_p += landmark_log_likelihood(grid, z, np.ones(2, bool), LANDMARKS, sensor.kind,
                                     sensor.noise_cov, known)
    w = np.exp(log_p - log_p.max())
    w /= w.sum()
    mean = w @ grid
    return mean, np.sqrt(w @ (grid - mean) ** 2)


def _gaussian_belief(free: FreeSpace, n: int, share: float, rng) -> MCLBelief:
    belief = MCLBelief(free, UnicycleModel(), n, proposal="mixture", mixture_share=share)
    belief.initialize_gaussian(PRIOR_MEAN, np.diag(PRIOR_STD**2), rng)
    return belief


@pytest.mark.parametrize("known", [True, False])
def test_mixture_update_on_a_landmark_map_matches_the_brute_force_posterior(known) -> None:
    """One update with nine tenths of the particles from the detections (with known
    correspondences, and with each detection possibly either landmark): the resampled set's
    mean and spread are the brute-force posterior's. Dual poses weighted without the
    predicted belief would land on the likelihood's peak alone, off by the prior's pull."""
    sensor = RangeBearingSensor(np.diag([0.4**2, 0.25**2]), 2 * np.pi, 20.0)
    rng = np.random.default_rng(3)
    z, visible = sensor.measure(TRUTH, LANDMARKS, rng)
    assert visible.all()
    mean, std = _landmark_posterior(sensor, z, known)
    belief = _gaussian_belief(FreeSpace.from_box(-6, -6, 6, 6), 40_000, 0.9, rng)
    belief.update_landmarks(z, visible, LANDMARKS, sensor, rng, known_correspondence=known)
    np.testing.assert_allclose(belief.mean(), mean, atol=0.02)
    np.testing.assert_allclose(np.sqrt(np.diag(belief.covariance())), std, rtol=0.08)


def _room() -> OccupancyGrid:
    """A 4 m x 3 m room at 0.05 m, origin (0, 0), walls round it and an L-shaped block at
    x 2.5-3.5 m, y 1.0-2.25 m."""
    values = np.zeros((60, 80), dtype=np.int8)
    values[[0, -1], :] = 100
    values[:, [0, -1]] = 100
    values[35:45, 50:70] = 100
    values[20:45, 60:70] = 100
    return OccupancyGrid(values, 0.05, (0.0, 0.0, 0.0))


def _lidar_setup(sigma_hit: float = 0.2):
    grid = _room()
    sensor = LidarSensor(n_beams=16, fov=2 * np.pi, max_range=5.0, sigma_hit=sigma_hit)
    table = sensor.log_table(grid.distance_field())
    return grid, sensor, table, LidarDualProposal.build(grid, sensor, table)


def _score(sensor, grid, z):
    def score(poses):
        return sensor.log_likelihood(z, np.ascontiguousarray(poses), grid.kernel_arrays(),
                                     grid.distance_field())
    return score


def test_lidar_dual_poses_weighted_by_their_density_reproduce_the_likelihood() -> None:
    """Dual poses of a scan, weighted by ``p(z | x)^a / q(x)``, are distributed as ``p^a`` over
    the free poses: the binned mass agrees with the likelihood at uniform free poses, and
    ``q`` is the draws' density."""
    grid, sensor, _, dual = _lidar_setup()
    rng = np.random.default_rng(0)
    truth = np.array([1.6, 1.2, 0.4])
    z = sensor.measure(truth, grid.kernel_arrays(), rng)
    exponent = 0.1
    poses, log_q = dual.draw(300_000, z, exponent, rng)
    free = FreeSpace.from_grid(grid.values, grid.resolution, grid.origin)
    ok = free.is_free(poses)
    score = _score(sensor, grid, z)
    weights = np.exp(exponent * score(poses[ok]) - log_q[ok])
    edges = (np.linspace(0.0, 4.0, 9), np.linspace(0.0, 3.0, 7), np.linspace(-np.pi, np.pi, 5))
    hist = np.histogramdd(poses[ok], bins=edges, weights=weights)[0]
    # brute force: p^a at points uniform on the free space (the same volume each)
    points = free.sample(1_000_000, np.random.default_rng(1))
    target = np.histogramdd(points, bins=edges, weights=np.exp(exponent * score(points)))[0]
    tv = 0.5 * np.abs(hist / hist.sum() - target / target.sum()).sum()
    assert tv < 0.04  # the two estimates' own noise is about 0.02
    # q is the draws' density: E_q[1 / q] is the volume of the lattice's poses
    volume = int(dual.free.sum()) * dual.cell_side**2 * 2 * np.pi
    assert np.mean(np.exp(-log_q)) == pytest.approx(volume, rel=0.02)


def test_mixture_update_on_a_grid_map_matches_the_brute_force_posterior() -> None:
    """A Gaussian prior in the open part of the room, one lidar update with most particles
    from the scan lattice: mean and spread are prior x p^a on a fine pose grid."""
    grid, sensor, _, dual = _lidar_setup()
    rng = np.random.default_rng(5)
    truth = np.array([1.5, 1.3, 0.2])
    z = sensor.measure(truth, grid.kernel_arrays(), rng)
    free = FreeSpace.from_grid(grid.values, grid.resolution, grid.origin)
    exponent = 0.2
    belief = MCLBelief(free, UnicycleModel(), 40_000, proposal="mixture", mixture_share=0.9,
                       likelihood_exponent=exponent)
    prior_mean, prior_std = np.array([1.6, 1.2, 0.1]), np.array([0.3, 0.3, 0.3])
    belief.initialize_gaussian(prior_mean, np.diag(prior_std**2), rng)
    score = _score(sensor, grid, z)
    update_with_scan(belief, z, score, dual, rng)
    axes = [np.linspace(m - 4.5 * s, m + 4.5 * s, 61)
            for m, s in zip(prior_mean, prior_std, strict=True)]
    pts = np.stack([a.ravel() for a in np.meshgrid(*axes, indexing="ij")], axis=1)
    log_p = -0.5 * (((pts - prior_mean) / prior_std) ** 2).sum(axis=1)
    log_p = np.where(free.is_free(pts), log_p + exponent * score(pts), -np.inf)
    w = np.exp(log_p - log_p.max())
    w /= w.sum()
    mean = w @ pts
    std = np.sqrt(w @ (pts - mean) ** 2)
    # the dual poses see the predicted belief through a kernel density, a little wider
    np.testing.assert_allclose(belief.mean(), mean, atol=0.03)
    np.testing.assert_allclose(np.sqrt(np.diag(belief.covariance())), std, rtol=0.1)


def test_a_kidnapped_mixture_belief_recovers_with_poses_that_explain_the_scan() -> None:
    """Augmented mixture MCL tracks the robot, which is then carried elsewhere: once w_fast
    drops below w_slow its recovery share goes to dual poses under a uniform prior (nothing
    uniform is injected), which put a good part of the particles at the new pose; plain
    augmented MCL's uniform poses, as few particles, hardly reach it."""
    grid, sensor, _, dual = _lidar_setup(sigma_hit=0.05)
    free = FreeSpace.from_grid(grid.values, grid.resolution, grid.origin)
    start, kidnapped = np.array([3.2, 0.7, 2.0]), np.array([1.3, 2.3, -0.5])
    errors: dict[str, float] = {}
    for proposal in ("mixture", "motion"):
        rng = np.random.default_rng(11)
        belief = MCLBelief(free, UnicycleModel(), 300, proposal=proposal, augmented=True,
                           alpha_slow=0.05, alpha_fast=0.5, likelihood_exponent=0.2)
        belief.initialize_gaussian(start, np.diag([0.01, 0.01, 0.01]), rng)
        recovered, near = [], []
        for t in range(25):
            truth = start if t < 10 else kidnapped
            z = sensor.measure(truth, grid.kernel_arrays(), rng)
            belief.predict(np.zeros(2), rng)
            update_with_scan(belief, z, _score(sensor, grid, z), dual, rng)
            recovered.append(belief.last_injection_rate)
            p = belief.particles
            near.append(np.mean(np.hypot(*(p[:, :2] - kidnapped[:2]).T) < 0.3))
            if proposal == "mixture":
                assert belief.last_injected == 0
        assert max(recovered[10:]) > 0.0  # the kidnapping was noticed
        errors[proposal] = max(near[10:])  # the largest share of particles at the new pose
    assert errors["mixture"] > 0.2 and errors["motion"] < 0.05


def test_mixture_mcl_is_deterministic_and_copies_continue_identically() -> None:
    grid, sensor, _, dual = _lidar_setup()
    free = FreeSpace.from_grid(grid.values, grid.resolution, grid.origin)

    def run(belief, seed):
        rng = np.random.default_rng(seed)
        for _ in range(3):
            z = sensor.measure(np.array([1.5, 1.3, 0.2]), grid.kernel_arrays(), rng)
            belief.predict(np.array([0.2, 0.1]), rng)
            update_with_scan(belief, z, _score(sensor, grid, z), dual, rng)
        return belief.particles.copy()

    make = lambda: MCLBelief(free, UnicycleModel(), 500, proposal="mixture", kld=True,  # noqa: E731
                             min_particles=50)
    a, b = make(), make()
    a.initialize_uniform(np.random.default_rng(0))
    b.initialize_uniform(np.random.default_rng(0))
    np.testing.assert_array_equal(run(a, 1), run(b, 1))
    c = a.copy()
    np.testing.assert_array_equal(run(a, 2), run(c, 2))


@pytest.mark.parametrize(
    ("kwargs", "match"),
    [({"proposal": "dual"}, "proposal"), ({"proposal": "mixture", "mixture_share": 0.0},
                                          "mixture_share"),
     ({"mixture_share": 1.0}, "mixture_share"), ({"mixture_share": "0.2"}, "mixture_share"),
     ({"mixture_share": float("nan")}, "mixture_share")],
)
def test_bad_proposals_are_refused_by_name(kwargs, match) -> None:
    with pytest.raises(ValueError, match=match):
        MCLBelief(FreeSpace.from_box(0, 0, 1, 1), UnicycleModel(), 10, **kwargs)


def test_a_grid_mixture_without_the_lattice_is_refused() -> None:
    grid, sensor, _, _ = _lidar_setup()
    free = FreeSpace.from_grid(grid.values, grid.resolution, grid.origin)
    belief = MCLBelief(free, UnicycleModel(), 10, proposal="mixture")
    belief.initialize_uniform(np.random.default_rng(0))
    z = sensor.measure(np.array([1.5, 1.3, 0.2]), grid.kernel_arrays(), np.random.default_rng(0))
    with pytest.raises(ValueError, match="LidarDualProposal"):
        update_with_scan(belief, z, _score(sensor, grid, z), None, np.random.default_rng(0))
