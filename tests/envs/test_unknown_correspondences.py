"""EKF localization with unknown correspondences through the env (``LandmarkEKFUnknown-v0``).

The statistical checks drive the robot on a circle of 2 m radius (0.5 m/s, 0.25 rad/s)
through a map of well-separated landmarks (a 5 x 5 lattice, 4 m apart), so that it keeps
seeing landmarks from moderate distances: the regime in which the EKF with known
correspondences is consistent. Under the scenario's sensor (90 degrees, 6 m, misses 0.1,
clutter 1 per scan, 99% gate) the association is then almost always right, the gate rejects
nearly all false detections, and the filter stays consistent; without the gate the clutter
pulls the filter off and it loses the robot.
"""

from __future__ import annotations

import dataclasses
import math

import gymnasium as gym
import numpy as np
import pytest
from scipy.stats import chi2

import active_loc  # noqa: F401  (registers the env ids)
from active_loc.beliefs import EKFBelief
from active_loc.envs.association_core import (
    A_CLUTTER,
    A_CLUTTER_REJECTED,
    A_DETECTIONS,
    A_LANDMARK_DETECTIONS,
    AssociationCore,
)
from active_loc.envs.config import LocalizationConfig
from active_loc.envs.observations import BELIEF_HEADER, SLOT_SIZE
from active_loc.maps import LandmarkMap
from active_loc.scenarios import scenario_kwargs

ENV_ID = "ActiveLoc/LandmarkEKFUnknown-v0"
LATTICE = np.arange(2.0, 19.0, 4.0)
SEPARATED = LandmarkMap(
    np.array([(x, y) for x in LATTICE for y in LATTICE]), (0.0, 0.0, 20.0, 20.0)
)
CIRCLE = np.array([0.0, 1.0 / 6.0], dtype=np.float32)  # V = 0.5 m/s, omega = 0.25 rad/s
STEPS = 200


def circling_env(**kwargs) -> gym.Env:
    """The registered id on the lattice map, starting 2 m below its centre, heading east."""
    return gym.make(
        ENV_ID, map=SEPARATED, max_landmarks=25, start="fixed", start_pose=(10.0, 8.0, 0.0),
        terminate_when_localized=False, **kwargs,
    )


def nees(core: AssociationCore) -> float:
    err = core.pose[0] - core.belief.mean[0]
    err[2] = math.remainder(err[2], 2 * math.pi)
    return float(err @ np.linalg.solve(core.belief.cov[0], err))


def run_circles(n_runs: int, **kwargs) -> dict[str, np.ndarray]:
    """NEES ``(runs, steps)``, info accuracies, clutter counts and final errors."""
    env = circling_env(**kwargs)
    values = np.empty((n_runs, STEPS))
    accuracy = np.empty((n_runs, STEPS))
    counts = np.zeros((n_runs, 2))  # clutter, clutter rejected
    final_error = np.empty(n_runs)
    for run in range(n_runs):
        env.reset(seed=run)
        core = env.unwrapped.core
        for k in range(STEPS):
            _, _, terminated, truncated, info = env.step(CIRCLE)
            assert not terminated and truncated == (k == STEPS - 1)
            values[run, k] = nees(core)
            accuracy[run, k] = info["association_accuracy"]
            counts[run] += core.association[0, [A_CLUTTER, A_CLUTTER_REJECTED]]
        final_error[run] = info["pose_error"]
    env.close()
    return {"nees": values, "accuracy": accuracy, "clutter": counts, "error": final_error}


@pytest.fixture(scope="module")
def gated_with_clutter() -> dict[str, np.ndarray]:
    return run_circles(100)


# -- the env and its configuration -------------------------------------------------------------


def test_landmark_ekf_with_unknown_correspondences_and_clutter_runs() -> None:
    env = gym.make(
        "ActiveLoc/LandmarkEKF-v0", known_correspondences=False, clutter_rate=2.0,
        miss_probability=0.1,
    )
    obs, info = env.reset(seed=0)
    core = env.unwrapped.core
    assert isinstance(core, AssociationCore)
    assert info["association_accuracy"] == 1.0
    for _ in range(50):
        obs, _, terminated, truncated, info = env.step(env.action_space.sample())
        assert env.observation_space.contains(obs)
        assert type(info["association_accuracy"]) is np.float64
        assert 0.0 <= info["association_accuracy"] <= 1.0
        if terminated or truncated:
            break
    view = env.unwrapped.planner_view()
    assert view.known_correspondences is False and view.association_gate == 0.99


def test_the_registered_id_is_the_scenario() -> None:
    env = gym.make(ENV_ID)
    cfg = env.unwrapped.config
    expected = LocalizationConfig(**scenario_kwargs("landmark_unknown"))
    assert cfg == expected
    assert not cfg.known_correspondences and cfg.clutter_rate == 1.0
    assert cfg.miss_probability == 0.1 and cfg.association_gate == 0.99
    assert env.spec is not None and env.spec.max_episode_steps == 200


@pytest.mark.parametrize(
    ("kwargs", "field"),
    [
        ({"miss_probability": 1.0}, "miss_probability"),
        ({"miss_probability": -0.1}, "miss_probability"),
        ({"miss_probability": "0.1"}, "miss_probability"),
        ({"clutter_rate": -1.0}, "clutter_rate"),
        ({"clutter_rate": 60.0}, "clutter_rate"),
        ({"clutter_rate": math.nan}, "clutter_rate"),
        ({"association_gate": 0.0}, "association_gate"),
        ({"association_gate": 1.5}, "association_gate"),
        ({"association_gate": "0.99"}, "association_gate"),
        ({"known_correspondences": True}, "clutter_rate"),  # clutter needs unknown ids
        ({"belief": "mcl"}, "clutter_rate"),  # MCL envs simulate neither misses nor clutter
    ],
)
def test_bad_config_raises_value_error_naming_the_field(kwargs, field) -> None:
    with pytest.raises(ValueError, match=field):
        gym.make(ENV_ID, **kwargs)


def test_the_filterpy_backend_runs_the_same_numba_association() -> None:
    runs = []
    for backend in ("numba", "filterpy"):
        env = gym.make(ENV_ID, ekf_backend=backend)
        env.reset(seed=4)
        assert isinstance(env.unwrapped.core.belief, EKFBelief)
        rng = np.random.default_rng(0)
        runs.append([env.step(rng.uniform(-1, 1, 2).astype(np.float32))[0] for _ in range(30)])
    np.testing.assert_array_equal(runs[0], runs[1])


def test_gate_none_and_gate_one_are_both_ungated() -> None:
    results = []
    for gate in (None, 1.0):
        env = gym.make(ENV_ID, association_gate=gate, clutter_rate=3.0)
        env.reset(seed=3)
        rng = np.random.default_rng(0)
        results.append([env.step(rng.uniform(-1, 1, 2).astype(np.float32))[0]
                        for _ in range(40)])
        core = env.unwrapped.core
        assert np.all(core.index[0, : core.n_detections[0]] < core.world.shape[1])
    np.testing.assert_array_equal(results[0], results[1])


@pytest.mark.parametrize("env_id", ["ActiveLoc/LandmarkEKF-v0", "ActiveLoc/Textbook-v0"])
def test_ids_with_known_correspondences_report_accuracy_one(env_id: str) -> None:
    env = gym.make(env_id)
    _, info = env.reset(seed=0)
    assert info["association_accuracy"] == 1.0
    for _ in range(10):
        assert env.step(env.action_space.sample())[4]["association_accuracy"] == 1.0


# -- what a step reports -------------------------------------------------------------------------


def test_accuracy_and_n_visible_follow_the_true_correspondences() -> None:
    env = gym.make(ENV_ID, clutter_rate=2.0, terminate_when_localized=False)
    env.reset(seed=11)
    core = env.unwrapped.core
    count = core.maps[0].n_landmarks
    rng = np.random.default_rng(1)
    for _ in range(200):
        _, _, _, _, info = env.step(rng.uniform(-1, 1, 2).astype(np.float32))
        n = core.n_detections[0]
        truth, index = core.truth[0, :n], core.index[0, :n]
        correct = np.where(truth < 0, index == count, index == truth)
        expected = correct.mean() if n else 1.0
        assert info["association_accuracy"] == pytest.approx(expected, abs=1e-15)
        assert info["n_visible"] == int(np.sum(truth >= 0)) == int(core.visible[0].sum())
        assert core.association[0, A_LANDMARK_DETECTIONS] == np.sum(truth >= 0)


def test_a_step_without_detections_has_accuracy_one() -> None:
    env = gym.make(ENV_ID, max_range=0.01, clutter_rate=0.0)  # sees nothing
    env.reset(seed=0)
    for _ in range(5):
        info = env.step(env.action_space.sample())[4]
        assert env.unwrapped.core.association[0, A_DETECTIONS] == 0
        assert info["association_accuracy"] == 1.0 and info["nis"] == 0.0


def test_the_observation_shows_the_scan_by_distance_not_by_landmark() -> None:
    env = gym.make(ENV_ID, clutter_rate=2.0, terminate_when_localized=False)
    env.reset(seed=5)
    core = env.unwrapped.core
    scale = core.config.max_range
    rng = np.random.default_rng(2)
    for _ in range(100):
        obs = env.step(rng.uniform(-1, 1, 2).astype(np.float32))[0]
        n = core.n_detections[0]
        z = core.z[0, :n]
        shown = z[np.argsort(z[:, 0])][: core.config.max_landmarks]
        slots = obs[BELIEF_HEADER:].reshape(-1, SLOT_SIZE)
        flags = slots[:, 3]
        assert np.all(flags[: len(shown)] == 1.0) and np.all(flags[len(shown) :] == 0.0)
        expected = np.column_stack([shown[:, 0] / scale, shown[:, 1] / np.pi])
        np.testing.assert_allclose(slots[: len(shown), 4:6], np.clip(expected, -1, 1),
                                   atol=1e-6)


def test_the_planner_view_simulates_with_association() -> None:
    env = gym.make(ENV_ID)
    env.reset(seed=0)
    view = env.unwrapped.planner_view()
    assert view.known_correspondences is False
    before = view.belief.copy()
    after, z, visible = view.simulate(np.array([0.5, 0.0]), view.belief, np.random.default_rng(0))
    assert isinstance(after, EKFBelief)
    assert z.shape == (view.map.n_landmarks, 2) and visible.shape == (view.map.n_landmarks,)
    np.testing.assert_array_equal(view.belief.mean, before.mean)  # the view's copy is untouched
    assert not np.array_equal(after.cov, before.cov)


def test_a_batch_core_equals_single_cores() -> None:
    config = LocalizationConfig(**{**scenario_kwargs("landmark_unknown"), "clutter_rate": 2.0})
    batch = AssociationCore(config, batch_size=2)
    singles = [AssociationCore(config) for _ in range(2)]
    rngs_batch = [np.random.default_rng(s) for s in (1, 2)]
    rngs_single = [np.random.default_rng(s) for s in (1, 2)]
    for b in range(2):
        batch.reset_member(b, rngs_batch[b])
        singles[b].reset_member(0, rngs_single[b])
    actions = np.random.default_rng(0).uniform(-1, 1, (150, 2, 2))
    for step_actions in actions:
        batch.actions[:] = step_actions
        assert batch.step(rngs_batch) == -1
        for b in range(2):
            singles[b].actions[0] = step_actions[b]
            assert singles[b].step(rngs_single[b : b + 1]) == -1
            np.testing.assert_array_equal(batch.state[b], singles[b].state[0])
            np.testing.assert_array_equal(batch.obs[b], singles[b].obs[0])


def test_nan_actions_raise_and_change_nothing() -> None:
    env = gym.make(ENV_ID)
    env.reset(seed=0)
    core = env.unwrapped.core
    state = core.state.copy()
    with pytest.raises(ValueError, match="NaN"):
        env.step(np.array([np.nan, 0.0], dtype=np.float32))
    np.testing.assert_array_equal(core.state, state)


# -- association and consistency -----------------------------------------------------------------


@pytest.mark.parametrize("gate", [0.99, None])
def test_with_well_separated_landmarks_association_is_near_perfect(gate) -> None:
    result = run_circles(20, clutter_rate=0.0, miss_probability=0.0, association_gate=gate)
    accuracy = result["accuracy"].mean()
    print(f"\nwell-separated landmarks, no clutter, gate {gate}: association accuracy "
          f"{accuracy:.5f} over 20 x {STEPS} steps")
    # ungated every detection is matched, and to its own landmark; the 99% gate also leaves
    # out about 1% of the true detections by design (they count as wrong)
    assert accuracy >= (0.999 if gate is None else 0.98)
    assert np.all(result["error"] < 0.3)


def test_with_clutter_the_gate_rejects_false_detections(gated_with_clutter) -> None:
    clutter, rejected = gated_with_clutter["clutter"].sum(axis=0)
    fraction = rejected / clutter
    accuracy = gated_with_clutter["accuracy"].mean()
    print(f"\nclutter 1/scan, misses 0.1, 99% gate, 100 x {STEPS} steps: {int(clutter)} false "
          f"detections, {fraction:.4f} rejected; association accuracy {accuracy:.4f}")
    assert clutter > 0.8 * 100 * STEPS  # Poisson(1) per scan
    assert fraction > 0.95
    assert accuracy > 0.97


def test_with_clutter_the_gated_filter_stays_consistent(gated_with_clutter) -> None:
    """NEES of 100 runs against the chi-square band, as in test_textbook.py.

    The grand mean over runs and steps must lie in the two-sided 95% band of
    chi^2(3 N) / N (conservative for run-averaged NEES, see test_textbook.py). Per step, the
    run average must be inside that band on at least 3/4 of the steps: fewer than the 90% the
    known-correspondence filter meets, because the false detections that do pass the gate
    (about 3% of them) are taken for landmarks. The truth must also lie in the filter's 95%
    ellipsoid on at least 90% of the steps.
    """
    values = gated_with_clutter["nees"]
    n_runs = values.shape[0]
    low, high = chi2.ppf([0.025, 0.975], 3 * n_runs) / n_runs
    per_step = values.mean(axis=0)
    inside = np.mean((per_step >= low) & (per_step <= high))
    coverage = np.mean(values <= chi2.ppf(0.95, 3))
    print(f"\nclutter 1/scan, 99% gate, {n_runs} runs x {STEPS} steps: mean NEES "
          f"{values.mean():.3f} (band {low:.3f}..{high:.3f}), steps inside {inside:.2f}, "
          f"95% ellipsoid coverage {coverage:.3f}, median final error "
          f"{np.median(gated_with_clutter['error']):.3f} m")
    assert np.all(np.isfinite(values))
    assert low <= values.mean() <= high
    assert inside >= 0.75
    assert coverage >= 0.90


def test_without_the_gate_clutter_makes_the_filter_diverge(gated_with_clutter) -> None:
    """Ungated, every false detection is matched to some landmark and pulls the update. At the
    scenario's clutter (1 per scan) the filter becomes grossly overconfident; in heavy clutter
    (5 per scan) it loses the robot, where the gated filter keeps tracking it."""
    ungated = run_circles(20, association_gate=None)
    gated = gated_with_clutter["nees"][:20].mean()
    heavy_ungated = run_circles(20, association_gate=None, clutter_rate=5.0)
    heavy_gated = run_circles(20, clutter_rate=5.0)
    errors = {name: result["error"] for name, result in
              (("ungated", heavy_ungated), ("gated", heavy_gated))}
    print(f"\nclutter 1/scan, 20 runs: mean NEES {gated:.2f} gated, "
          f"{ungated['nees'].mean():.0f} ungated (association accuracy "
          f"{ungated['accuracy'].mean():.3f}); clutter 5/scan: final pose error median "
          f"{np.median(errors['gated']):.3f} m gated, {np.median(errors['ungated']):.3f} m "
          f"ungated, ungated runs off by more than 1 m: {np.mean(errors['ungated'] > 1.0):.2f}")
    assert ungated["nees"].mean() > 30 * gated
    assert np.median(errors["ungated"]) > 1.0 and np.mean(errors["ungated"] > 1.0) >= 0.6
    assert np.median(errors["gated"]) < 0.2 and np.all(errors["gated"] < 0.5)
    assert heavy_gated["nees"].mean() < 10.0


def test_the_scenario_changes_nothing_else_than_the_landmark_ekf() -> None:
    base = dataclasses.asdict(LocalizationConfig(**scenario_kwargs("landmark_tracking")))
    unknown = dataclasses.asdict(LocalizationConfig(**scenario_kwargs("landmark_unknown")))
    changed = {key for key in base if base[key] != unknown[key]}
    assert changed == {
        "known_correspondences", "miss_probability", "clutter_rate", "initial_error_std",
        "initial_belief_std",
    }
