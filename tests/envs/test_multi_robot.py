"""The multi-robot PettingZoo env: API and seeding, covariance-intersection fusion (NEES,
conservativeness), MCL reciprocal sampling, observations free of the truth, rendering, bad
input and reproducibility."""

from __future__ import annotations

import itertools
import math
import warnings

import matplotlib
import numpy as np
import pytest
from pettingzoo.test import api_test, parallel_api_test, parallel_seed_test
from scipy.stats import chi2

from active_loc.envs.multi_robot import MultiRobotLocalizationEnv, env, parallel_env
from active_loc.envs.multi_robot_fusion import (
    ci_detection_update,
    ci_omega,
    detection_model,
    kde_log_density,
    naive_detection_update,
    reciprocal_log_likelihood,
    symmetric_landmark_map,
)
from active_loc.geometry import wrap_angle

SMALL_MCL = {"n_particles": 300, "fusion_samples": 300}
R_DET = np.diag([0.1**2, 0.035**2])


def kwargs_for(belief: str, action_type: str) -> dict:
    return {"belief": belief, "action_type": action_type, **(SMALL_MCL if belief == "mcl" else {})}


def drive(env_: MultiRobotLocalizationEnv, steps: int, action=(0.0, 0.3)) -> list:
    """Step with one fixed continuous action for every live robot; returns the step tuples."""
    out = []
    for _ in range(steps):
        if not env_.agents:
            break
        actions = {a: np.array(action, dtype=np.float32) for a in env_.agents}
        out.append(env_.step(actions))
    return out


# --- PettingZoo API ------------------------------------------------------------------------


@pytest.mark.parametrize(("belief", "action_type"),
                         list(itertools.product(("ekf", "mcl"), ("continuous", "discrete"))))
def test_parallel_api_and_seed_tests_pass(belief: str, action_type: str) -> None:
    kwargs = kwargs_for(belief, action_type)
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # the API test warns about what it does not assert
        parallel_api_test(parallel_env(3, **kwargs), num_cycles=40)
        parallel_seed_test(lambda: parallel_env(3, **kwargs), num_cycles=40)


def test_aec_interface_passes_the_api_test() -> None:
    api_test(env(2, max_cycles=20), num_cycles=20)


def test_agents_spaces_and_first_observation() -> None:
    e = parallel_env(3, belief="mcl", **SMALL_MCL)
    obs, infos = e.reset(seed=0)
    assert e.possible_agents == ["robot_0", "robot_1", "robot_2"] == e.agents
    for a in e.agents:
        space = e.observation_space(a)
        assert space is e.observation_space(a) and obs[a] in space
        assert obs[a].dtype == np.float32
        assert space.shape == (11 + 64 + 6 * 15 + 4 * 2,)
        assert e.action_space(a).shape == (2,)
        assert set(infos[a]) >= {"pose_error", "heading_error", "entropy", "localized",
                                 "is_success", "collisions", "fused"}


# --- covariance intersection ---------------------------------------------------------------


def _ci_trial(rng: np.random.Generator, correlation: float) -> tuple[float, float]:
    """NEES of the CI and of the naive fusion of one detection, with robot j's error sharing a
    fraction ``correlation`` of its variance with robot i's (as after an earlier exchange)."""
    truth_i = np.array([*rng.uniform(0.0, 10.0, 2), rng.uniform(-np.pi, np.pi)])
    r, bearing = rng.uniform(1.0, 5.0), rng.uniform(-0.7, 0.7)
    p_j = truth_i[:2] + r * np.array([np.cos(truth_i[2] + bearing),
                                      np.sin(truth_i[2] + bearing)])
    truth_j = np.array([*p_j, rng.uniform(-np.pi, np.pi)])
    cov_i, cov_j = np.diag([0.3, 0.3, 0.1]) ** 2, np.diag([0.2, 0.2, 0.05]) ** 2
    common, own_i, own_j = rng.standard_normal((3, 3))
    a, b = math.sqrt(correlation), math.sqrt(1.0 - correlation)
    mean_i = truth_i + np.sqrt(np.diag(cov_i)) * (a * common + b * own_i)
    mean_j = truth_j + np.sqrt(np.diag(cov_j)) * (a * common + b * own_j)
    d = p_j - truth_i[:2]
    z = np.array([np.hypot(*d), np.arctan2(d[1], d[0]) - truth_i[2]])
    z += rng.standard_normal(2) * np.sqrt(np.diag(R_DET))
    z[1] = wrap_angle(z[1])
    out = []
    res = ci_detection_update(mean_i, cov_i, mean_j, cov_j, z, R_DET, gate=None)
    naive = naive_detection_update(mean_i, cov_i, mean_j, cov_j, z, R_DET)
    for mean, cov in ((res.mean, res.cov), naive):
        err = mean - truth_i
        err[2] = wrap_angle(err[2])
        out.append(float(err @ np.linalg.solve(cov, err)))
    # CI never claims more than the naive fusion: Sigma_CI - Sigma_naive is PSD
    assert np.linalg.eigvalsh(res.cov - naive[1]).min() > -1e-12
    return out[0], out[1]


def test_ci_fusion_is_consistent_where_naive_fusion_is_overconfident() -> None:
    runs = 1000
    lo, hi = chi2.ppf([0.025, 0.975], 3 * runs) / runs  # 95% band of the mean NEES (3 dof)
    rng = np.random.default_rng(7)
    independent = np.array([_ci_trial(rng, 0.0) for _ in range(runs)]).mean(axis=0)
    shared = np.array([_ci_trial(rng, 0.9) for _ in range(runs)]).mean(axis=0)
    # independent errors: the naive update is the right one (the setup is sound) ...
    assert lo <= independent[1] <= hi
    # ... and CI, which cannot know that, stays consistent (conservative: below the band)
    assert independent[0] <= hi
    # after an exchange (correlated errors) the naive update is overconfident, CI is not
    assert shared[1] > hi
    assert shared[0] <= hi


def test_ci_omega_minimizes_the_determinant_and_fusion_gains_information() -> None:
    mean_i, cov_i = np.array([1.0, 2.0, 0.3]), np.diag([0.4, 0.3, 0.2]) ** 2
    mean_j, cov_j = np.array([4.0, 3.0, -1.0]), np.diag([0.1, 0.1, 0.05]) ** 2
    _, jac, r_eff = detection_model(mean_i, mean_j, cov_j, R_DET)
    info_i, info_z = np.linalg.inv(cov_i), jac.T @ np.linalg.solve(r_eff, jac)
    omega = ci_omega(info_i, info_z, "det")
    grid = np.linspace(1e-3, 1.0, 2000)
    dets = [np.linalg.det(np.linalg.inv(w * info_i + (1 - w) * info_z)) for w in grid]
    best = np.linalg.det(np.linalg.inv(omega * info_i + (1 - omega) * info_z))
    assert best <= min(dets) * (1 + 1e-6) and 0 < omega < 1
    z = np.array([np.hypot(3.0, 1.0), wrap_angle(np.arctan2(1.0, 3.0) - 0.3)])
    res = ci_detection_update(mean_i, cov_i, mean_j, cov_j, z, R_DET)
    assert res.fused and np.linalg.det(res.cov) < np.linalg.det(cov_i)
    trace = ci_detection_update(mean_i, cov_i, mean_j, cov_j, z, R_DET, criterion="trace")
    assert np.trace(trace.cov) <= np.trace(res.cov) + 1e-12
    # a detection far from what the beliefs predict fails the gate and changes nothing
    wild = ci_detection_update(mean_i, cov_i, mean_j, cov_j, z + np.array([3.0, 0.0]), R_DET)
    assert not wild.fused and np.array_equal(wild.cov, cov_i)


def test_ekf_env_fusion_helps_a_robot_with_a_wide_belief() -> None:
    common = {"belief": "ekf", "initial_belief": ("gaussian", "wide"), "detection_fov": 2 * np.pi,
              "detection_max_range": 30.0, "fov": 2 * np.pi, "max_range": 0.5}
    gains = {}
    for fuse in (True, False):
        e = parallel_env(2, fuse_detections=fuse, **common)
        _, infos = e.reset(seed=3)
        h0 = infos["robot_1"]["entropy"]
        results = drive(e, 3)
        assert all(info["fused"] == fuse for info in results[0][4].values())
        gains[fuse] = h0 - results[-1][4]["robot_1"]["entropy"]
    assert gains[True] > gains[False] + 1.0  # nats: the landmarks are out of range


# --- MCL reciprocal sampling ---------------------------------------------------------------


def _mass_near(particles: np.ndarray, weights: np.ndarray, pose: np.ndarray) -> float:
    near = (np.hypot(*(particles[:, :2] - pose[:2]).T) < 1.0) & (
        np.abs(wrap_angle(particles[:, 2] - pose[2])) < 0.5)
    return float(weights[near].sum())


def test_reciprocal_density_moves_mass_toward_the_truth() -> None:
    rng = np.random.default_rng(0)
    truth_i, truth_j = np.array([3.0, 4.0, 0.5]), np.array([6.0, 6.0, 2.0])
    particles_j = truth_j + rng.standard_normal((1000, 3)) * [0.05, 0.05, 0.02]
    particles_i = np.column_stack([rng.uniform(0, 10, (4000, 2)), rng.uniform(-np.pi, np.pi, 4000)])
    d = truth_j[:2] - truth_i[:2]
    z = np.array([np.hypot(*d), wrap_angle(np.arctan2(d[1], d[0]) - truth_i[2])])
    log_lik = reciprocal_log_likelihood(particles_i, particles_j, np.full(1000, 1e-3), z,
                                        [0.1, 0.035], [0.25, 0.25, 0.15], 100.0, 2000, rng)
    weights = np.exp(log_lik - log_lik.max())
    weights /= weights.sum()
    before = _mass_near(particles_i, np.full(4000, 1 / 4000), truth_i)
    assert _mass_near(particles_i, weights, truth_i) > 10 * before


def test_kernel_density_matches_brute_force_across_the_heading_seam() -> None:
    rng = np.random.default_rng(0)
    m = 500
    headings = -np.pi + 2 * np.pi * (np.arange(m) + rng.random(m)) / m  # stratified
    samples = np.column_stack([rng.normal(0, 0.3, (m, 2)), headings])
    points = np.column_stack([rng.normal(0, 0.3, (50, 2)),
                              rng.choice([-3.1, 3.1, 0.0, -np.pi], 50)])
    bandwidth = np.array([0.25, 0.25, 0.15])
    out = np.empty(50)
    kde_log_density(points, samples, bandwidth, out)
    d = points[:, None, :] - samples[None]
    d[..., 2] = wrap_angle(d[..., 2])
    d /= bandwidth
    dens = np.exp(-0.5 * (d**2).sum(-1)).mean(axis=1) / ((2 * np.pi) ** 1.5 * bandwidth.prod())
    np.testing.assert_allclose(out, np.log(dens), atol=1e-5)


def test_mcl_fusion_waits_between_fusions_of_a_pair() -> None:
    common = {"belief": "mcl", "n_particles": 500, "fusion_samples": 500,
              "initial_belief": ("uniform", "gaussian"), "initial_error_std": (0.0, 0.0, 0.0),
              "initial_belief_std": (0.03, 0.03, 0.01), "detection_fov": 2 * np.pi,
              "detection_max_range": 30.0, "fusion_interval": 3}
    for fuse in (True, False):
        e = parallel_env(2, fuse_detections=fuse, **common)
        e.reset(seed=1)
        results = drive(e, 12)
        fused_steps = [t + 1 for t, step in enumerate(results) if step[4]["robot_0"]["fused"]]
        # robot_1 is localized from the start, stops after step 1, and is always in view:
        # robot_0 fuses its detection every third step until it is localized itself
        every_third = [t for t in (1, 4, 7, 10) if t <= len(results)]
        assert len(every_third) >= 2
        assert fused_steps == (every_third if fuse else [])
        assert not results[0][4]["robot_1"]["fused"] and results[0][2]["robot_1"]
        assert all(set(step[4]) == {"robot_0"} for step in results[1:])


def test_mcl_fusion_disambiguates_the_symmetric_arena() -> None:
    """Robot 0 starts uniform in the symmetric arena, robot 1 localized: with fusion robot 0's
    mass gathers near its true pose, alone it stays split with (or lost to) the mirror pose."""
    common = {"belief": "mcl", "map": "symmetric", "map_size": (10.0, 6.0),
              "n_landmarks": (7, 7), "max_landmarks": 7, "n_particles": 5000,
              "fusion_samples": 1000, "likelihood_exponent": 0.3, "range_std": 0.3,
              "bearing_std": 0.1, "fov": np.pi, "max_range": 5.0,
              "initial_belief": ("uniform", "gaussian"), "initial_error_std": (0.0, 0.0, 0.0),
              "initial_belief_std": (0.03, 0.03, 0.01), "detection_fov": 2 * np.pi,
              "detection_max_range": 30.0}
    mass = {True: [], False: []}
    for seed in range(8):
        for fuse in (True, False):
            e = parallel_env(2, fuse_detections=fuse, **common)
            e.reset(seed=seed)
            for _ in range(8):
                if "robot_0" in e.agents:
                    drive(e, 1)
            belief = e.particle_beliefs[0]
            mass[fuse].append(_mass_near(belief.particles, belief.weights, e.poses[0]))
    together, alone = np.array(mass[True]), np.array(mass[False])
    assert together.mean() > alone.mean() + 0.25
    assert np.sum(together >= alone - 0.05) >= 7


def test_symmetric_arena_repeats_under_rotation_but_for_the_cue() -> None:
    for seed in range(20):
        lmap = symmetric_landmark_map(np.random.default_rng(seed), (10.0, 6.0), (7, 9))
        pos = lmap.positions
        twins = np.array([10.0, 6.0]) - pos
        has_twin = (np.linalg.norm(pos[:, None] - twins[None], axis=-1) < 1e-9).any(axis=1)
        assert has_twin[:-1].all() and not has_twin[-1] and pos.shape[0] % 2 == 1
    e = parallel_env(2, belief="mcl", map="symmetric", map_size=(10.0, 6.0),
                     n_landmarks=(7, 7), initial_belief="uniform", **SMALL_MCL)
    assert e.config.known_correspondences is False
    e.reset(seed=0)
    assert e.map.n_landmarks == 7


# --- what the agents see ---------------------------------------------------------------------


@pytest.mark.parametrize("belief", ["ekf", "mcl"])
def test_observations_never_read_the_true_pose(belief: str) -> None:
    e = parallel_env(2, belief=belief, detection_fov=2 * np.pi, detection_max_range=50.0,
                     **SMALL_MCL)
    e.reset(seed=5)
    obs = drive(e, 4)[-1][0]
    for a in obs:
        i = int(a[-1])
        assert np.array_equal(obs[a], e._observe(i))
        e.poses[i] += [1.0, -2.0, 0.7]  # move the truth: the observation must not follow
        assert np.array_equal(obs[a], e._observe(i))
        # the detections slot is filled (the robots see each other all around)
        assert obs[a][-4] == 1.0


def test_identical_landmarks_fill_slots_by_range_not_identity() -> None:
    e = parallel_env(1, belief="mcl", known_correspondences=False, fov=2 * np.pi,
                     max_range=math.inf, **SMALL_MCL)
    e.reset(seed=0)
    drive(e, 1)
    n = e.map.n_landmarks
    ranges = e._z[0, :n, 0]
    assert e._visible[0, :n].all() and np.all(np.diff(ranges) >= 0)


# --- rewards, termination ------------------------------------------------------------------


def test_team_reward_and_a_localized_robot_stops() -> None:
    e = parallel_env(3, team_reward=True, step_cost=0.01)
    e.reset(seed=2)
    _, rewards, _, _, infos = drive(e, 1)[0]
    total = sum(info["reward_terms"]["info_gain"] - 0.01 + info["reward_terms"]["collision"]
                for info in infos.values())
    assert all(r == pytest.approx(total) for r in rewards.values())
    e = parallel_env(2, initial_error_std=(0.0, 0.0, 0.0),
                     initial_belief_std=(0.05, 0.05, 0.01))
    e.reset(seed=0)
    _, _, terminated, _, _ = drive(e, 1)[0]
    assert all(terminated.values()) and e.agents == []
    e = parallel_env(2, initial_belief=("gaussian", "wide"), initial_error_std=(0.0,) * 3,
                     initial_belief_std=(0.05, 0.05, 0.01))
    e.reset(seed=0)
    _, _, terminated, _, _ = drive(e, 1)[0]
    assert terminated == {"robot_0": True, "robot_1": False} and e.agents == ["robot_1"]
    parked = e.poses[0].copy()
    drive(e, 3, action=(1.0, 0.0))
    assert np.array_equal(e.poses[0], parked)


def test_localized_robots_can_stay_in_the_episode_until_max_cycles() -> None:
    """terminate_when_localized=False: the agent set stays whole until every robot is
    truncated together, as SuperSuit's vector wrappers need; a confident robot keeps moving."""
    kwargs = {"initial_belief": ("gaussian", "wide"), "initial_error_std": (0.0,) * 3,
              "initial_belief_std": (0.05, 0.05, 0.01), "max_cycles": 6}
    e = parallel_env(2, terminate_when_localized=False, **kwargs)
    e.reset(seed=0)
    start = e.poses[0].copy()
    steps = drive(e, 10, action=(1.0, 0.0))
    assert len(steps) == 6
    for _, _, terminated, truncated, infos in steps[:-1]:
        assert not any(terminated.values()) and not any(truncated.values())
        assert sorted(infos) == ["robot_0", "robot_1"]
    assert bool(steps[0][4]["robot_0"]["localized"])  # confident from the first step on
    assert all(steps[-1][3].values()) and e.agents == []
    assert not np.array_equal(e.poses[0], start)
    # the default ends a confident robot's episode at once
    e = parallel_env(2, **kwargs)
    e.reset(seed=0)
    assert drive(e, 1)[0][2] == {"robot_0": True, "robot_1": False}
    with pytest.raises(ValueError, match="terminate_when_localized must be True or False"):
        parallel_env(2, terminate_when_localized="False")


def test_truncation_at_max_cycles() -> None:
    e = parallel_env(2, max_cycles=3, initial_belief="wide", fov=0.1, max_range=0.1)
    e.reset(seed=0)
    steps = drive(e, 10)
    assert len(steps) == 3 and all(steps[-1][3].values()) and e.agents == []


# --- rendering -----------------------------------------------------------------------------


@pytest.mark.parametrize("belief", ["ekf", "mcl"])
def test_rgb_frames(belief: str) -> None:
    e = parallel_env(2, belief=belief, render_mode="rgb_array", detection_fov=2 * np.pi,
                     **SMALL_MCL)
    e.reset(seed=0)
    first = e.render()
    drive(e, 3, action=(1.0, 0.0))
    second = e.render()
    assert first.shape == second.shape == (600, 600, 3) and first.dtype == np.uint8
    assert not np.array_equal(first, second)
    e.close()


def test_human_mode_runs_headless() -> None:
    matplotlib.use("Agg")
    e = parallel_env(2, render_mode="human")
    e.reset(seed=0)
    drive(e, 2)
    assert e.render() is None
    e.close()


# --- bad input -----------------------------------------------------------------------------


@pytest.mark.parametrize(("kwargs", "field"), [
    ({"n_robots": 0}, "n_robots"),
    ({"belief": "grid"}, "belief"),
    ({"range_std": -0.1}, "range_std"),
    ({"detection_bearing_std": 0.0}, "detection_bearing_std"),
    ({"motion_noise_std": (0.1, 0.1)}, "motion_noise_std"),
    ({"initial_belief_std": (0.1, 0.0, 0.1)}, "initial_belief_std"),
    ({"initial_belief": ("gaussian",)}, "initial_belief"),
    ({"belief": "ekf", "initial_belief": "uniform"}, "belief='ekf'"),
    ({"map": "maze"}, "map"),
    ({"detection_fov": 7.0}, "detection_fov"),
])
def test_bad_config_names_the_field(kwargs: dict, field: str) -> None:
    with pytest.raises(ValueError, match=field):
        parallel_env(**kwargs)


def test_unknown_kwarg_is_a_type_error() -> None:
    with pytest.raises(TypeError, match="unknown env kwargs"):
        parallel_env(2, n_robot=3)


@pytest.mark.parametrize(("action", "match"), [
    (np.zeros(3, dtype=np.float32), r"actions\['robot_1'\] must have shape \(2,\)"),
    (np.array([np.nan, 0.0], dtype=np.float32), r"actions\['robot_1'\] contains NaN"),
    (np.array([np.inf, 0.0]), r"actions\['robot_1'\] contains NaN or inf"),
    (np.array(["a", "b"]), r"actions\['robot_1'\] must be real numbers"),
])
def test_bad_actions_raise_and_change_nothing(action, match: str) -> None:
    e = parallel_env(2)
    e.reset(seed=0)
    poses = e.poses.copy()
    with pytest.raises(ValueError, match=match):
        e.step({"robot_0": np.zeros(2, dtype=np.float32), "robot_1": action})
    with pytest.raises(ValueError, match="no action for the live agents"):
        e.step({"robot_0": np.zeros(2, dtype=np.float32)})
    with pytest.raises(ValueError, match="unknown agents"):
        e.step({"robot_0": np.zeros(2), "robot_1": np.zeros(2), "robot_9": np.zeros(2)})
    assert np.array_equal(e.poses, poses) and e.steps == 0


def test_bad_discrete_actions() -> None:
    e = parallel_env(2, action_type="discrete")
    e.reset(seed=0)
    with pytest.raises(ValueError, match=r"actions\['robot_0'\] must be an integer in \[0, 6\)"):
        e.step({"robot_0": 6, "robot_1": 0})
    with pytest.raises(ValueError, match=r"actions\['robot_1'\] must be an integer index"):
        e.step({"robot_0": 1, "robot_1": 1.5})


# --- reproducibility -----------------------------------------------------------------------


@pytest.mark.parametrize("belief", ["ekf", "mcl"])
def test_same_seed_same_trajectories(belief: str) -> None:
    def run(seed: int) -> tuple[list, list]:
        e = parallel_env(2, belief=belief, detection_fov=2 * np.pi, fusion_sender_localized=False,
                         **SMALL_MCL)
        e.reset(seed=seed)
        rng = np.random.default_rng(0)
        poses, observations = [], []
        for _ in range(15):
            if not e.agents:
                break
            actions = {a: rng.uniform(-1, 1, 2).astype(np.float32) for a in e.agents}
            obs, rewards, *_ = e.step(actions)
            poses.append(e.poses.copy())
            observations.append((obs, rewards))
        return poses, observations

    first, again, other = run(11), run(11), run(12)
    assert len(first[0]) == len(again[0])
    for a, b in zip(first[0], again[0], strict=True):
        assert np.array_equal(a, b)
    for (obs_a, rew_a), (obs_b, rew_b) in zip(first[1], again[1], strict=True):
        assert rew_a == rew_b and all(np.array_equal(obs_a[k], obs_b[k]) for k in obs_a)
    assert not np.array_equal(first[0][0], other[0][0])


def test_fusion_does_not_change_the_world_noise() -> None:
    """Fusion on or off, a seed gives the same true paths under the same actions (until a
    robot stops): the world's noise has its own stream."""
    paths = []
    for fuse in (True, False):
        e = parallel_env(2, fuse_detections=fuse, detection_fov=2 * np.pi,
                         initial_belief="wide", localized_position_std=1e-6)
        e.reset(seed=4)
        drive(e, 10, action=(0.5, 0.2))
        paths.append(e.poses.copy())
    assert np.array_equal(*paths)
