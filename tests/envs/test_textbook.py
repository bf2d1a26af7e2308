"""``ActiveLoc/Textbook-v0``: the chapter's exercise (section 13.8, problem 1) as an env.

The exercise's passive controls (``TextbookAgent``: V = 1, omega = sin(k dt)) drive 100
seeded episodes of 150 steps; the EKF belief is checked against the truth for consistency
(NEES inside the chi-square band), and one episode is replayed through an independent EKF
(a stock ``filterpy`` filter with the chapter's equations) fed with the env's own scan.
"""

from __future__ import annotations

import math

import gymnasium as gym
import numpy as np
import pytest
from filterpy.kalman import ExtendedKalmanFilter
from scipy.linalg import block_diag
from scipy.stats import chi2

import active_loc  # noqa: F401  (registers the env ids)
from active_loc.agents import TextbookAgent

ENV_ID = "ActiveLoc/Textbook-v0"
N_RUNS = 100
STEPS = 150
DT = 0.1
LANDMARKS = np.array([[0.0, 0.0], [2.0, 8.0], [8.0, 2.0], [10.0, 10.0]])


def angle_diff(a, b):
    d = np.asarray(a, dtype=np.float64) - np.asarray(b, dtype=np.float64)
    return np.arctan2(np.sin(d), np.cos(d))


def run_episodes(n_runs, env_id=ENV_ID, **kwargs):
    """Truth and belief after every step of ``n_runs`` episodes (seeds 0..n_runs-1)."""
    env = gym.make(env_id, **kwargs)
    agent = TextbookAgent()
    truth = np.empty((n_runs, STEPS, 3))
    mean = np.empty((n_runs, STEPS, 3))
    cov = np.empty((n_runs, STEPS, 3, 3))
    entropy = np.empty((n_runs, STEPS))
    core = env.unwrapped.core
    for run in range(n_runs):
        obs, _ = env.reset(seed=run)
        for k in range(STEPS):
            action = agent.act(obs, env.unwrapped.planner_view())
            obs, _, terminated, truncated, info = env.step(action)
            truth[run, k] = core.pose[0]
            mean[run, k] = core.belief.mean[0]
            cov[run, k] = core.belief.cov[0]
            entropy[run, k] = info["entropy"]
            assert not terminated
            assert truncated == (k == STEPS - 1)
    env.close()
    return truth, mean, cov, entropy


@pytest.fixture(scope="module")
def episodes():
    return run_episodes(N_RUNS)


def nees(truth, mean, cov):
    err = truth - mean
    err[..., 2] = angle_diff(truth[..., 2], mean[..., 2])
    return np.einsum("...i,...i->...", err, np.linalg.solve(cov, err[..., None])[..., 0])


def test_first_action_is_the_exercise_control():
    env = gym.make(ENV_ID)
    obs, _ = env.reset(seed=0)
    view = env.unwrapped.planner_view()
    action = TextbookAgent().act(obs, view)
    assert env.action_space.contains(action.astype(np.float32))
    v, omega = view.decode(action)
    assert v == 1.0
    assert omega == math.sin(0.1)
    # and the k-th action is omega = sin(k dt)
    for k in range(1, 6):
        obs, *_ = env.step(action)
        view = env.unwrapped.planner_view()
        action = TextbookAgent().act(obs, view)
        np.testing.assert_array_equal(view.decode(action), [1.0, math.sin((k + 1) * DT)])
    env.close()


def test_reset_is_the_exercise_start():
    env = gym.make(ENV_ID)
    errors = []
    for seed in range(200):
        env.reset(seed=seed)
        core = env.unwrapped.core
        np.testing.assert_array_equal(core.pose[0], [1.0, 1.0, 0.0])
        np.testing.assert_array_equal(core.belief.cov[0], np.eye(3))
        errors.append(core.belief.mean[0] - core.pose[0])
    env.close()
    # mean0 = start + N(0, 0.1 I): the empirical variance of 200 draws is within ~5 std errors
    var = np.var(np.array(errors), axis=0)
    np.testing.assert_array_less(np.abs(var - 0.1), 5 * 0.1 * math.sqrt(2 / 200))


def test_env_belief_equals_an_independent_ekf_on_the_env_scan():
    """Replay an episode through a stock filterpy EKF with the chapter's models.

    The filter gets the env's initial belief and each step's scan (``core.z``) and the
    exercise's controls; it must track the env's belief to 1e-9, which pins dt, Q, R, the
    controls and the stacked update of the env.
    """
    env = gym.make(ENV_ID)
    obs, _ = env.reset(seed=123)
    core = env.unwrapped.core
    ekf = ExtendedKalmanFilter(dim_x=3, dim_z=8)
    ekf.x = core.belief.mean[0].reshape(3, 1).copy()
    ekf.P = core.belief.cov[0].copy()
    ekf.Q = 0.1 * DT**2 * np.eye(3)

    def predict_x(u):
        x = ekf.x.ravel()
        ekf.x = np.array(
            [x[0] + u[0] * math.cos(x[2]) * DT, x[1] + u[0] * math.sin(x[2]) * DT, x[2] + u[1] * DT]
        ).reshape(3, 1)

    ekf.predict_x = predict_x

    def hx(x):
        x = x.ravel()
        c, s = math.cos(x[2]), math.sin(x[2])
        return np.concatenate([np.array([[c, s], [-s, c]]) @ (m - x[:2]) for m in LANDMARKS])[
            :, None
        ]

    def h_jacobian(x):
        x = x.ravel()
        c, s = math.cos(x[2]), math.sin(x[2])
        rows = []
        for m in LANDMARKS:
            dx, dy = m[0] - x[0], m[1] - x[1]
            rows.append([[-c, -s, -s * dx + c * dy], [s, -c, -c * dx - s * dy]])
        return np.vstack(rows)

    agent = TextbookAgent()
    for k in range(1, STEPS + 1):
        obs, *_ = env.step(agent.act(obs, env.unwrapped.planner_view()))
        u = np.array([1.0, math.sin(k * DT)])
        x = ekf.x.ravel()
        ekf.F = np.array(
            [[1.0, 0.0, -math.sin(x[2]) * DT], [0.0, 1.0, math.cos(x[2]) * DT], [0, 0, 1.0]]
        )
        ekf.predict(u)
        assert core.visible[0].all()
        ekf.update(core.z[0].reshape(-1, 1), h_jacobian, hx, R=block_diag(*[0.25 * np.eye(2)] * 4))
        np.testing.assert_allclose(core.belief.mean[0][:2], ekf.x.ravel()[:2], atol=1e-9)
        assert abs(angle_diff(core.belief.mean[0][2], ekf.x[2, 0])) < 1e-9
        np.testing.assert_allclose(core.belief.cov[0], ekf.P, atol=1e-9)
    env.close()


def test_filterpy_backend_env_matches_numba_env():
    a = gym.make(ENV_ID)
    b = gym.make(ENV_ID, ekf_backend="filterpy")
    agent = TextbookAgent()
    obs_a, _ = a.reset(seed=5)
    obs_b, _ = b.reset(seed=5)
    for _ in range(STEPS):
        obs_a, r_a, *_ = a.step(agent.act(obs_a, a.unwrapped.planner_view()))
        obs_b, r_b, *_ = b.step(agent.act(obs_b, b.unwrapped.planner_view()))
        np.testing.assert_array_equal(a.unwrapped.core.pose, b.unwrapped.core.pose)
        np.testing.assert_allclose(
            a.unwrapped.core.belief.mean, b.unwrapped.core.belief.mean, atol=1e-9
        )
        np.testing.assert_allclose(
            a.unwrapped.core.belief.cov, b.unwrapped.core.belief.cov, atol=1e-9
        )
        assert r_a == pytest.approx(r_b, abs=1e-8)
    a.close()
    b.close()


def test_textbook_ekf_is_consistent_over_100_seeds(episodes):
    truth, mean, cov, entropy = episodes
    err = truth - mean
    err[..., 2] = angle_diff(truth[..., 2], mean[..., 2])
    rmse = np.sqrt(np.mean(err**2, axis=(0, 1)))
    values = nees(truth, mean, cov)  # (N_RUNS, STEPS)
    print(
        f"\nTextbook-v0, {N_RUNS} runs x {STEPS} steps: RMSE x {rmse[0]:.4f} m, "
        f"y {rmse[1]:.4f} m, theta {rmse[2]:.4f} rad; mean NEES {values.mean():.3f} (3 ideal); "
        f"mean final entropy {entropy[:, -1].mean():.3f} nats"
    )
    assert np.all(np.isfinite(values))

    # Consistency criterion (Bar-Shalom, Li & Kirubarajan, ch. 5.4). For a consistent filter
    # the NEES at one time step is chi^2(3), and the runs are independent, so the average of
    # the N = 100 runs' NEES at a fixed step is chi^2(3 N) / N: the two-sided 95% band below.
    # 1) Per step: each step's run-average falls outside the band with probability 5%; the
    #    steps are correlated (the same runs), so rather than a binomial test on the count we
    #    require that at least 90% of the steps are inside.
    low, high = chi2.ppf([0.025, 0.975], 3 * N_RUNS) / N_RUNS
    per_step = values.mean(axis=0)
    inside = np.mean((per_step >= low) & (per_step <= high))
    assert inside >= 0.90, (inside, low, high, per_step)
    # 2) Grand mean: the N * T values are not independent within a run, so chi^2(3 N T)/(N T)
    #    would be far too narrow. Each run's time-averaged NEES has mean 3 and variance at
    #    most 6 (the variance of one chi^2(3), by Cauchy-Schwarz), and the runs are
    #    independent; so the average of the N run means has variance at most 6 / N, the
    #    variance of chi^2(3 N) / N. The same band is therefore a (conservative) 95% band for
    #    the grand mean.
    assert low <= values.mean() <= high, (values.mean(), low, high)

    # the filter localizes: the position error settles well below the measurement noise
    assert rmse[0] < 0.3 and rmse[1] < 0.3 and rmse[2] < 0.1
    assert entropy[:, -1].mean() < entropy[:, 0].mean()
