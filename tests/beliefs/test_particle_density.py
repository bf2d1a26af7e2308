"""The binned kernel density of a particle set against the full sum over its particles."""

from __future__ import annotations

import numpy as np
import pytest

from active_loc.beliefs.particle_density import (
    _smooth_all,
    _smooth_at_queries,
    _taps,
    kde_log_density,
    silverman_bandwidth,
)


def brute_force_log_density(particles, weights, bandwidth, queries) -> np.ndarray:
    """The sum over every particle of the Gaussian product kernel, wrapped in heading."""
    r = queries[:, None, :] - particles[None, :, :]
    r[..., :2] /= bandwidth[:2]
    wrapped = sum(np.exp(-0.5 * ((r[..., 2] + 2 * np.pi * j) / bandwidth[2]) ** 2)
                  for j in range(-3, 4))
    kernel = np.exp(-0.5 * (r[..., 0] ** 2 + r[..., 1] ** 2)) * wrapped
    kernel /= (2 * np.pi) ** 1.5 * np.prod(bandwidth)
    with np.errstate(divide="ignore"):
        return np.log(kernel @ weights)


def _mixed_set(rng: np.random.Generator, k: int) -> tuple[np.ndarray, np.ndarray]:
    """A global-looking set: a uniform spread over 20 m x 20 m, two tight modes, headings
    across the wrap."""
    spread = np.column_stack([rng.uniform(0, 20, k // 2), rng.uniform(0, 20, k // 2),
                              rng.uniform(-np.pi, np.pi, k // 2)])
    mode_a = rng.normal([5.0, 5.0, 3.1], [0.2, 0.2, 0.05], (k // 4, 3))
    mode_b = rng.normal([15.0, 12.0, -1.0], [0.3, 0.1, 0.1], (k - k // 2 - k // 4, 3))
    particles = np.vstack([spread, mode_a, mode_b])
    weights = rng.uniform(0.1, 1.0, k)
    return particles, weights / weights.sum()


@pytest.mark.parametrize("bandwidth", [(0.6, 0.6, 0.3), (1.5, 1.0, 0.8), (0.3, 0.3, 4.0)])
def test_the_binned_density_is_close_to_the_full_sum(bandwidth) -> None:
    """Where the density is more than a thousandth of its peak, the binned estimate is within
    20% of the exact sum (90th percentile: how a mode sits between the grid nodes matters),
    and not biased by more than 3%."""
    rng = np.random.default_rng(0)
    particles, weights = _mixed_set(rng, 3000)
    queries = np.vstack([
        particles[rng.integers(0, len(particles), 300)] + rng.normal(0, 0.2, (300, 3)),
        np.column_stack([rng.uniform(-2, 22, 200), rng.uniform(-2, 22, 200),
                         rng.uniform(-4, 4, 200)]),
    ])
    h = np.array(bandwidth)
    binned = kde_log_density(particles, weights, h, queries)
    exact = brute_force_log_density(particles, weights, np.minimum(h, np.pi), queries)
    reached = exact > exact.max() + np.log(1e-3)
    assert reached.sum() > 100
    assert np.all(np.isfinite(binned[reached]))
    error = binned[reached] - exact[reached]
    assert np.quantile(np.abs(error), 0.9) < 0.2
    assert abs(np.mean(np.exp(error)) - 1.0) < 0.03


@pytest.mark.parametrize("reach", [(4, 4, 4), (2, 3, 1), (5, 1, 7)])
def test_the_lazy_convolution_gives_the_full_grids_numbers(reach) -> None:
    """Nodes computed on demand (a few queries against a large grid) hold exactly the full
    convolution's values, heading wrap and grid edges included."""
    rx, ry, rh = reach
    rng = np.random.default_rng(3)
    mass = rng.random((12, 9, 16)) * (rng.random((12, 9, 16)) < 0.3)
    taps = [_taps(0.8 * r + 0.3, 1.0, r) for r in reach]
    full = _smooth_all(mass.copy(), taps[0], rx, taps[1], ry, taps[2], rh)
    nodes = np.column_stack([rng.integers(0, n, 200) for n in mass.shape])
    nodes[:4] = [[0, 0, 0], [11, 8, 15], [0, 8, 15], [11, 0, 0]]  # the corners
    lazy = _smooth_at_queries(mass, taps[0], rx, taps[1], ry, taps[2], rh, nodes)
    got = lazy[nodes[:, 0], nodes[:, 1], nodes[:, 2]]
    assert np.array_equal(got, full[nodes[:, 0], nodes[:, 1], nodes[:, 2]])
    assert np.any(got > 0.0)


def test_the_density_integrates_to_one() -> None:
    rng = np.random.default_rng(1)
    particles = rng.normal([2.0, -1.0, 3.0], [0.5, 0.3, 0.2], (400, 3))
    weights = np.full(400, 1 / 400)
    h = silverman_bandwidth(particles, weights, (0.01, 0.01, 0.01))
    axes = [np.linspace(-1, 5, 61), np.linspace(-3.5, 1.5, 51),
            np.linspace(-np.pi, np.pi, 73)[:-1]]
    grid = np.stack([m.ravel() for m in np.meshgrid(*axes, indexing="ij")], axis=1)
    volume = 0.1 * 0.1 * (2 * np.pi / 72)
    assert np.exp(kde_log_density(particles, weights, h, grid)).sum() * volume == pytest.approx(
        1.0, abs=0.01)


def test_silverman_bandwidth_follows_the_spread_and_is_floored() -> None:
    rng = np.random.default_rng(2)
    wide = rng.normal(0.0, [2.0, 1.0, 0.5], (5000, 3))
    h = silverman_bandwidth(wide, np.full(5000, 1 / 5000), (0.01, 0.01, 0.01))
    factor = (4.0 / (5.0 * 5000)) ** (1 / 7)
    np.testing.assert_allclose(h, np.array([2.0, 1.0, 0.5]) * factor, rtol=0.05)
    one_pose = np.zeros((10, 3))
    np.testing.assert_array_equal(
        silverman_bandwidth(one_pose, np.full(10, 0.1), (0.1, 0.1, 0.05)), [0.1, 0.1, 0.05])


def test_bad_inputs_are_refused() -> None:
    with pytest.raises(ValueError, match="bandwidth"):
        kde_log_density(np.zeros((2, 3)), np.full(2, 0.5), (0.1, 0.0, 0.1), np.zeros((1, 3)))
    with pytest.raises(ValueError, match="weights"):
        kde_log_density(np.zeros((2, 3)), np.full(3, 0.5), (0.1, 0.1, 0.1), np.zeros((1, 3)))
    with pytest.raises(ValueError, match="finite"):
        kde_log_density(np.full((2, 3), np.nan), np.full(2, 0.5), (0.1, 0.1, 0.1),
                        np.zeros((1, 3)))
