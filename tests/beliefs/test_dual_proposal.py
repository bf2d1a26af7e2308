"""The dual proposal of mixture MCL on landmark maps, against brute-force densities on grids."""

from __future__ import annotations

import numpy as np
import pytest

from active_loc.beliefs.dual_proposal import (
    dual_log_density,
    dual_pairs,
    sample_dual_poses,
)
from active_loc.beliefs.mcl import landmark_log_likelihood
from active_loc.sensors.landmarks import RANGE_BEARING, RELATIVE_POSITION, measurement

#: a wide range noise, so that the range-bearing Jacobian 1 / r changes the shape visibly
R = np.diag([0.4**2, 0.05**2])
EDGES = (np.linspace(-3, 3, 25), np.linspace(-3, 3, 25), np.linspace(-np.pi, np.pi, 9))
SUB = 6  # integration points per bin and axis


def _points() -> tuple[np.ndarray, float]:
    """Midpoints of SUB^3 sub-cells of every bin of EDGES ``(M, 3)`` and a sub-cell's volume."""
    axes = [
        (e[:-1, None] + (np.arange(SUB) + 0.5) / SUB * np.diff(e)[:, None]).ravel() for e in EDGES
    ]
    mesh = np.meshgrid(*axes, indexing="ij")
    volume = float(np.prod([np.diff(e)[0] / SUB for e in EDGES]))
    return np.stack([m.ravel() for m in mesh], axis=1), volume


def _bin_mass(points: np.ndarray, density: np.ndarray) -> np.ndarray:
    mass = np.histogramdd(points, bins=EDGES, weights=density)[0]
    return mass / mass.sum()


def _histogram(poses: np.ndarray, weights: np.ndarray) -> np.ndarray:
    hist = np.histogramdd(poses, bins=EDGES, weights=weights)[0]
    return hist / hist.sum()


def _total_variation(p: np.ndarray, q: np.ndarray) -> float:
    return 0.5 * float(np.abs(p - q).sum())


CASES = [(RELATIVE_POSITION, (1.5, 0.8)), (RANGE_BEARING, (2.0, 0.3))]


@pytest.mark.parametrize(("kind", "reading"), CASES)
def test_dual_samples_reproduce_the_measurement_likelihood(kind, reading) -> None:
    """One detection: the dual poses, weighted by the Jacobian's inverse (1 for relative
    position, r for range and bearing), are distributed as p(z | x) of the filter's own
    likelihood, binned on a grid of poses; without the weight range-bearing is visibly off."""
    landmarks = np.zeros((1, 2))
    z = np.array([reading])
    pairs = dual_pairs([True], 1, known_correspondence=True)
    points, _ = _points()
    target = _bin_mass(points, np.exp(landmark_log_likelihood(points, z, [True], landmarks,
                                                              kind, R)))
    poses, valid = sample_dual_poses(400_000, z, landmarks, pairs, kind, R,
                                     np.random.default_rng(0))
    poses = poses[valid]
    r = np.hypot(poses[:, 0], poses[:, 1])
    weights = np.ones(len(poses)) if kind == RELATIVE_POSITION else r
    assert _total_variation(_histogram(poses, weights), target) < 0.05
    if kind == RANGE_BEARING:
        assert _total_variation(_histogram(poses, np.ones(len(poses))), target) > 0.07


@pytest.mark.parametrize(("kind", "reading"), CASES)
@pytest.mark.parametrize("known", [True, False])
def test_the_dual_density_integrates_to_one_and_describes_the_samples(kind, reading, known):
    """q(x) of two detections (and, unknown correspondences, two candidate landmarks each)
    integrates to 1 over the poses and matches the histogram of its own samples."""
    landmarks = np.array([[0.0, 0.0], [0.5, -0.4]])
    z = np.array([reading, (reading[0] * 0.8, reading[1] - 0.2)])
    pairs = dual_pairs([True, True], 2, known_correspondence=known)
    assert len(pairs) == (2 if known else 4)
    points, volume = _points()
    q = np.exp(dual_log_density(points, z, landmarks, pairs, kind, R))
    assert q.sum() * volume == pytest.approx(1.0, abs=0.01)
    poses, valid = sample_dual_poses(300_000, z, landmarks, pairs, kind, R,
                                     np.random.default_rng(1))
    assert _total_variation(_histogram(poses[valid], np.ones(valid.sum())),
                            _bin_mass(points, q)) < 0.06


@pytest.mark.parametrize("kind", [RELATIVE_POSITION, RANGE_BEARING])
@pytest.mark.parametrize("known", [True, False])
def test_dual_poses_weighted_by_the_prior_give_the_brute_force_posterior(kind, known) -> None:
    """Importance weights p(z | x) bel(x) / q(x) on dual poses give the posterior mean and
    spread of a Gaussian prior times the scan's likelihood, computed on a grid of poses."""
    landmarks = np.array([[0.0, 0.0], [1.0, 1.5]])
    truth = np.array([1.0, -1.2, 0.5])
    z = np.array([measurement(kind, *truth, *m) for m in landmarks])
    visible = [True, True]
    prior_mean, prior_std = np.array([1.2, -1.0, 0.3]), np.array([0.6, 0.6, 0.5])

    def log_prior(x: np.ndarray) -> np.ndarray:
        return -0.5 * (((x - prior_mean) / prior_std) ** 2).sum(axis=1)

    def log_posterior(x: np.ndarray) -> np.ndarray:
        return landmark_log_likelihood(x, z, visible, landmarks, kind, R, known) + log_prior(x)

    axes = [np.linspace(-1.5, 3.5, 101), np.linspace(-3.7, 1.3, 101), np.linspace(-np.pi, np.pi,
                                                                                   73)[:-1]]
    grid = np.stack([m.ravel() for m in np.meshgrid(*axes, indexing="ij")], axis=1)
    p = np.exp(log_posterior(grid) - log_posterior(grid).max())
    exact_mean = (grid * p[:, None]).sum(0) / p.sum()
    exact_std = np.sqrt((((grid - exact_mean) ** 2) * p[:, None]).sum(0) / p.sum())

    pairs = dual_pairs(visible, 2, known_correspondence=known)
    poses, valid = sample_dual_poses(200_000, z, landmarks, pairs, kind, R,
                                     np.random.default_rng(2))
    poses = poses[valid]
    log_w = log_posterior(poses) - dual_log_density(poses, z, landmarks, pairs, kind, R)
    w = np.exp(log_w - log_w.max())
    mean = (poses * w[:, None]).sum(0) / w.sum()
    std = np.sqrt((((poses - mean) ** 2) * w[:, None]).sum(0) / w.sum())
    np.testing.assert_allclose(mean, exact_mean, atol=0.02)
    np.testing.assert_allclose(std, exact_std, rtol=0.1)


def test_bad_inputs_are_refused_by_name() -> None:
    landmarks = np.zeros((1, 2))
    z = np.array([[1.0, 0.0]])
    rng = np.random.default_rng(0)
    with pytest.raises(ValueError, match="nothing was detected"):
        sample_dual_poses(5, z, landmarks, dual_pairs([False], 1, True), RANGE_BEARING, R, rng)
    with pytest.raises(ValueError, match="noise_cov"):
        sample_dual_poses(5, z, landmarks, dual_pairs([True], 1, True), RANGE_BEARING,
                          -np.eye(2), rng)
    with pytest.raises(ValueError, match="kind"):
        dual_log_density(np.zeros((1, 3)), z, landmarks, [[0, 0]], 7, R)
    with pytest.raises(ValueError, match="landmarks outside"):
        dual_log_density(np.zeros((1, 3)), z, landmarks, [[0, 1]], RANGE_BEARING, R)
