"""The Monte Carlo localization envs: the chapter's problem 2, global localization, symmetric
maps, the kidnapped robot, ROS maps as ``map=``, and the particle belief's reported figures."""

from __future__ import annotations

from pathlib import Path

import gymnasium as gym
import numpy as np
import pytest

import active_loc  # noqa: F401  (registers the ids)
from active_loc.agents import TextbookAgent
from active_loc.beliefs.particle_stats import ENTROPY_BINS
from active_loc.geometry import wrap_angle
from active_loc.maps import rooms_map
from tests.envs.wander import wander

SHARED_MAPS = Path(__file__).resolve().parents[3] / "shared" / "maps"


def particle_mass_near(belief: object, center: np.ndarray) -> float:
    """Weight of the particles within 1 m and 0.5 rad of ``center`` (3,)."""
    particles, weights = belief.particles, belief.weights  # type: ignore[attr-defined]
    close = np.hypot(*(particles[:, :2] - center[:2]).T) < 1.0
    aligned = np.abs(wrap_angle(particles[:, 2] - center[2])) < 0.5
    return float(weights[close & aligned].sum())


def test_textbook_with_mcl_is_problem_2() -> None:
    env = gym.make("ActiveLoc/Textbook-v0", belief="mcl")
    core = env.unwrapped.core
    assert core.config.n_particles == 1000
    agent = TextbookAgent()
    errors = []
    for seed in range(5):
        obs, _ = env.reset(seed=seed)
        done = False
        while not done:
            action = agent.act(obs, env.unwrapped.planner_view())
            obs, _, terminated, truncated, _ = env.step(action)
            done = terminated or truncated
            error = core.pose[0] - core.belief_mean[0]
            error[2] = wrap_angle(error[2])
            errors.append(error)
    rmse = np.sqrt(np.mean(np.square(errors), axis=0))
    print(f"Textbook-v0 belief='mcl', 5 runs: RMSE x {rmse[0]:.3f} m, y {rmse[1]:.3f} m, "
          f"theta {rmse[2]:.3f} rad")
    assert rmse[0] < 0.2 and rmse[1] < 0.2 and rmse[2] < 0.06


def test_passive_wanderer_localizes_globally_on_grid_maps() -> None:
    """The wall-avoiding wanderer (passive: it reads the scan, never the belief) on 100 seeded
    generated office maps, belief uniform over the free space at the start: the episode ends
    on confidence, and the confident belief is right in at least 95 of them."""
    env = gym.make("ActiveLoc/GridMCL-v0", action_type="discrete")
    successes, lengths = 0, []
    for seed in range(100):
        obs, info = env.reset(seed=seed)
        terminated = truncated = False
        while not (terminated or truncated):
            obs, _, terminated, truncated, info = env.step(wander(obs))
        successes += info["is_success"]
        lengths.append(env.unwrapped.core.episode(0).t)
    print(f"GridMCL-v0 passive wanderer: {successes}/100 localized, mean episode "
          f"{np.mean(lengths):.1f} steps")
    assert successes >= 95


def test_symmetric_arena_leaves_passive_localization_ambiguous() -> None:
    """In the pillar arena, equal to its own 180-degree rotation, the wanderer's belief settles
    as often on the mirrored pose as on the true one: no passive strategy can tell them apart."""
    env = gym.make(
        "ActiveLoc/GridMCL-v0", map="pillars", map_size=(12.0, 8.0), action_type="discrete",
        terminate_when_localized=False,
    )
    near_truth = near_mirror = 0
    for seed in range(10):
        obs, _ = env.reset(seed=seed)
        for _ in range(60):
            obs, *_ = env.step(wander(obs))
        core = env.unwrapped.core
        x_min, y_min, x_max, y_max = core.maps[0].bounds
        pose = core.pose[0]
        mirror = np.array([x_min + x_max - pose[0], y_min + y_max - pose[1], pose[2] + np.pi])
        near_truth += particle_mass_near(core.belief, pose) > 0.25
        near_mirror += particle_mass_near(core.belief, mirror) > 0.25
    print(f"pillar arena: mass on the true pose in {near_truth}/10, on its mirror in "
          f"{near_mirror}/10")
    assert near_truth >= 2 and near_mirror >= 2


@pytest.mark.parametrize(("grace", "proposal"), [(10, "mixture"), (0, "motion")])
def test_kidnapping_happens_once_inside_its_window_and_success_waits_for_it(
    grace, proposal
) -> None:
    """Until ``kidnap_grace`` steps after the kidnapping, no success and no termination,
    however confident the belief. A belief can be confident on the kidnapping step itself (it
    cannot know yet), which is why the grace exists: plain MCL's is in some of these episodes
    (the mixture's, whose dual poses keep it wider, is not in the first eight seeds)."""
    env = gym.make("ActiveLoc/GridMCLKidnapped-v0", action_type="discrete", kidnap_grace=grace,
                   terminate_when_localized=False, proposal=proposal)
    config = env.unwrapped.config
    lo, hi = (round(f * config.horizon) for f in config.kidnap_window)
    confident_when_kidnapped = 0
    for seed in range(3):
        obs, info = env.reset(seed=seed)
        assert not info["kidnapped"]
        kidnap_steps = []
        for step in range(1, hi + grace + 2):
            before = env.unwrapped.core.pose[0].copy()
            obs, _, terminated, _, info = env.step(wander(obs))
            assert not terminated
            if info["kidnapped"]:
                kidnap_steps.append(step)
                confident_when_kidnapped += info["localized"]
                assert np.hypot(*(env.unwrapped.core.pose[0, :2] - before[:2])) > 0.0
            if not kidnap_steps or step < kidnap_steps[0] + grace:
                assert not info["is_success"]
                assert not env.unwrapped.core.outcome(0).terminal
        assert len(kidnap_steps) == 1 and lo <= kidnap_steps[0] <= hi
    if grace == 0:
        assert confident_when_kidnapped >= 1  # the case the grace is for


def test_grid_env_runs_on_a_ros_map_file() -> None:
    path = SHARED_MAPS / "tb3_sandbox.yaml"
    if not path.is_file():
        pytest.skip(f"{path} not found: CI has ../shared beside the checkout")
    env = gym.make("ActiveLoc/GridMCL-v0", map=str(path), n_particles=2000, kld=False)
    obs, _ = env.reset(seed=0)
    grid = env.unwrapped.core.maps[0]
    assert grid.shape == (384, 384)
    assert grid.is_free(env.unwrapped.core.pose[:, :2])[0]
    for _ in range(5):
        obs, *_ = env.step(env.action_space.sample())
    assert env.observation_space.contains(obs)


def test_a_missing_ros_map_file_is_a_clear_error(tmp_path: Path) -> None:
    with pytest.raises(ValueError, match="no such map file"):
        gym.make("ActiveLoc/GridMCL-v0", map=str(tmp_path / "nowhere.yaml"))


def test_particle_log_det_is_finite_and_matches_the_binned_covariance() -> None:
    env = gym.make("ActiveLoc/LandmarkMCL-v0", reward="logdet")
    env.reset(seed=0)
    bin_variance = np.square(ENTROPY_BINS) / 12.0
    for _ in range(20):
        _, reward, *_ = env.step(env.action_space.sample())
        assert np.isfinite(reward)
        row = env.unwrapped.core.rows[0]
        cov = row["cov"]
        logdet = np.linalg.slogdet(cov + np.diag(bin_variance))[1]
        assert row["logdet"] == pytest.approx(logdet, abs=1e-9)
        assert row["trace"] == pytest.approx(np.trace(cov), abs=1e-12)


def kidnapped_recoveries(augmented: bool, seeds: range) -> list[bool]:
    """Success at the end of each GridMCLKidnapped-v0 episode (the wanderer drives), with
    plain MCL: augmented MCL's uniform injection is the mechanism under test."""
    env = gym.make(
        "ActiveLoc/GridMCLKidnapped-v0", action_type="discrete", augmented=augmented,
        terminate_when_localized=False, proposal="motion", n_particles=50000,
    )
    outcomes = []
    for seed in seeds:
        obs, info = env.reset(seed=seed)
        done = False
        while not done:
            obs, _, _, truncated, info = env.step(wander(obs))
            done = truncated
        outcomes.append(bool(info["is_success"]))
    return outcomes


def test_injection_brings_the_kidnapped_robot_back() -> None:
    """With random-particle injection the filter re-localizes after the kidnapping in 9 of 10
    episodes."""
    with_injection = kidnapped_recoveries(True, range(10))
    print(f"GridMCLKidnapped-v0: re-localized {sum(with_injection)}/10 with injection")
    assert sum(with_injection) >= 9


def test_without_injection_the_kidnapped_robot_stays_lost() -> None:
    """Without it, in at most 3 of the same 10: nothing else brings particles to the new
    pose (the mechanism is what matters)."""
    without = kidnapped_recoveries(False, range(10))
    print(f"GridMCLKidnapped-v0: re-localized {sum(without)}/10 without injection")
    assert sum(without) <= 3


def test_the_beam_model_from_a_range_table_localizes_like_ray_casting() -> None:
    """Pose tracking on one ROS-sized generated map with the beam model, ray-cast every step
    or looked up in the precomputed table: both stay on the robot."""
    grid = rooms_map(np.random.default_rng(5), size_m=(10.0, 10.0), resolution=0.1)
    errors = {}
    for bins in (0, 360):
        env = gym.make(
            "ActiveLoc/GridMCLKidnapped-v0", map=grid, kidnap=False, lidar_model="beam",
            lidar_range_bins=bins, n_particles=500, kld=False, augmented=False,
            action_type="discrete", terminate_when_localized=False,
        )
        final = []
        for seed in range(3):
            obs, info = env.reset(seed=seed)
            for _ in range(40):
                obs, *_, info = env.step(wander(obs))
            final.append(info["pose_error"])
        errors[bins] = final
        if bins:
            assert env.unwrapped.core.range_table.n_angles == bins
    print(f"beam model, final position errors (m): ray casting {errors[0]}, table "
          f"{errors[360]}")
    assert max(errors[0]) < 0.3 and max(errors[360]) < 0.3


def test_passive_wanderer_localizes_globally_on_landmark_maps() -> None:
    """A constant-curvature wanderer (passive: it never looks at the belief) on 50 seeded
    random landmark maps, belief uniform at the start, episodes ending on confidence: they
    end localized and right, rarely confidently wrong (a filter short of particles settles on
    the one particle nearest the truth after the first scan)."""
    env = gym.make("ActiveLoc/LandmarkMCL-v0")
    successes = false = 0
    for seed in range(50):
        env.reset(seed=seed)
        terminated = truncated = False
        while not (terminated or truncated):
            _, _, terminated, truncated, info = env.step(np.array([0.2, 0.5], dtype=np.float32))
        successes += info["is_success"]
        false += info["localized"] and not info["is_success"]
    print(f"LandmarkMCL-v0 passive wanderer: {successes}/50 localized, {false}/50 "
          f"confidently wrong")
    # over seeds 0-199 this measured 180 right and 13 confidently wrong (90% and 6.5%)
    assert successes >= 42 and false <= 7


@pytest.mark.parametrize(("model", "bins"), [("likelihood_field", 0), ("beam", 0), ("beam", 90)])
def test_the_planner_view_scores_scans_as_the_filter_does(model: str, bins: int) -> None:
    """``planner_view().scan_log_likelihood`` is the env filter's own scan likelihood: the
    likelihood field, the ray-cast beam model, or the beam model from the env's range table
    (which the view carries)."""
    grid = rooms_map(np.random.default_rng(2), size_m=(8.0, 8.0), resolution=0.1)
    env = gym.make("ActiveLoc/GridMCL-v0", map=grid, lidar_model=model, lidar_range_bins=bins,
                   n_particles=300, kld=False, action_type="discrete")
    env.reset(seed=1)
    env.step(1)
    core, view = env.unwrapped.core, env.unwrapped.planner_view()
    assert (view.range_table is None) == (bins == 0)
    poses = view.belief.particles[:50]
    np.testing.assert_array_equal(view.scan_log_likelihood(core.ranges[0], poses),
                                  core._scan_log_likelihood(0, core.ranges[0], poses))
