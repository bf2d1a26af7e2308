"""Behaviour of the landmark localization env: info, rewards, bad input, collisions,
termination, the planner view, seeding and the filterpy backend.

Each test checks one promise of ``ActiveLocalizationEnv`` (its docstring and DESIGN.md):
the info keys and their types, the reward as the sum of named terms that telescope to the
drop in uncertainty, clear errors for bad input, blocked moves at the walls, when episodes
end, a planner view without the truth, and reproducibility from seeds and across backends.
"""

from __future__ import annotations

import dataclasses
import math
from typing import Any

import gymnasium as gym
import numpy as np
import pytest

import active_loc
from active_loc.beliefs import MCLBelief
from active_loc.beliefs.grid import GridBelief
from active_loc.envs import ActiveLocalizationEnv
from active_loc.envs.landmark_core import ROW_DTYPE, STATE_SIZE, WORLD_DTYPE, WORLD_SIZE
from active_loc.maps import OccupancyGrid

ENV_IDS = [env_id for env_id, _, _ in active_loc.ENV_IDS]
LANDMARK = "ActiveLoc/LandmarkEKF-v0"
TEXTBOOK = "ActiveLoc/Textbook-v0"
#: info key -> its numpy dtype (reals float64 and counts int64 scalars, flags 0-d bool
#: arrays: see active_loc/envs/outcome.py)
INFO_TYPES = {
    "pose_error": np.float64,
    "heading_error": np.float64,
    "entropy": np.float64,
    "is_success": np.bool_,
    "localized": np.bool_,
    "collisions": np.int64,
}
TELESCOPING = ("info_gain", "logdet", "trace")


def random_actions(space: gym.Space, rng: np.random.Generator, n: int) -> list[Any]:
    """``n`` actions of ``space`` drawn from ``rng``."""
    if isinstance(space, gym.spaces.Discrete):
        return [int(a) for a in rng.integers(0, space.n, n)]
    return list(rng.uniform(-1.0, 1.0, (n, 2)).astype(np.float32))


def run_episode(env: gym.Env, seed: int, rng: np.random.Generator) -> list[tuple]:
    """Reset with ``seed`` and step random actions until the episode ends.

    Returns the reset ``(obs, info)`` followed by every step's 5-tuple.
    """
    results: list[tuple] = [env.reset(seed=seed)]
    while True:
        (action,) = random_actions(env.action_space, rng, 1)
        result = env.step(action)
        results.append(result)
        if result[2] or result[3]:
            return results


def assert_info_is_well_typed(info: dict[str, Any]) -> None:
    for key, kind in INFO_TYPES.items():
        assert key in info, key
        value = info[key]
        if kind is np.bool_:
            assert isinstance(value, np.ndarray) and value.shape == (), (key, type(value))
            assert value.dtype == np.bool_, (key, value.dtype)
        else:
            assert type(value) is kind, (key, type(value))
    terms = info["reward_terms"]
    assert isinstance(terms, dict)
    assert terms
    for name, value in terms.items():
        assert isinstance(name, str)
        assert type(value) is np.float64, (name, type(value))
        assert math.isfinite(value), name
    assert info["pose_error"] >= 0.0
    assert 0.0 <= info["heading_error"] <= math.pi
    assert info["collisions"] >= 0
    assert info["localized"] or not info["is_success"]  # success needs confidence


# -- info --------------------------------------------------------------------------------------


@pytest.mark.parametrize("action_type", ["continuous", "discrete"])
@pytest.mark.parametrize("env_id", ENV_IDS)
def test_info_has_every_key_with_its_type_at_reset_and_every_step(
    env_id: str, action_type: str
) -> None:
    env = gym.make(env_id, action_type=action_type)
    rng = np.random.default_rng(0)
    for seed in (0, 1):
        (_, info), *steps = run_episode(env, seed, rng)
        assert_info_is_well_typed(info)
        assert info["collisions"] == 0
        for _, reward, terminated, truncated, info in steps:
            assert_info_is_well_typed(info)
            assert type(reward) is float
            assert type(terminated) is bool
            assert type(truncated) is bool


def test_reset_info_has_zero_reward_terms() -> None:
    _, info = gym.make(LANDMARK, step_cost=0.5).reset(seed=0)
    assert info["reward_terms"]["info_gain"] == 0.0
    assert info["reward_terms"]["collision"] == 0.0
    assert info["reward_terms"]["outcome"] == 0.0


# -- rewards -----------------------------------------------------------------------------------


@pytest.mark.parametrize("reward", ["info_gain", "neg_entropy", "logdet", "trace"])
@pytest.mark.parametrize("env_id", ENV_IDS)
def test_reward_is_the_sum_of_its_named_terms(env_id: str, reward: str) -> None:
    env = gym.make(env_id, reward=reward, step_cost=0.01)
    rng = np.random.default_rng(1)
    for seed in (0, 1):
        _, *steps = run_episode(env, seed, rng)
        for _, r, _, _, info in steps:
            terms = info["reward_terms"]
            assert set(terms) == {reward, "step_cost", "collision", "outcome"}
            assert terms["step_cost"] == -0.01
            assert r == pytest.approx(sum(terms.values()), rel=0, abs=1e-12)


@pytest.mark.parametrize("env_id", ENV_IDS)
def test_the_outcome_term_is_paid_only_on_the_terminal_step_signed_by_success(
    env_id: str,
) -> None:
    # Textbook-v0 runs its exercise to the end unless told to stop when localized
    env = gym.make(env_id, outcome_reward=2.5, terminate_when_localized=True,
                   max_episode_steps=100)
    rng = np.random.default_rng(5)
    for seed in (0, 1):
        _, *steps = run_episode(env, seed, rng)
        for _, r, terminated, _, info in steps:
            expected = (2.5 if info["is_success"] else -2.5) if terminated else 0.0
            assert info["reward_terms"]["outcome"] == expected
            assert r == pytest.approx(sum(info["reward_terms"].values()), rel=0, abs=1e-12)


@pytest.mark.parametrize(
    "env_id", [LANDMARK, TEXTBOOK, "ActiveLoc/LandmarkMCL-v0", "ActiveLoc/GridMarkov-v0"]
)
def test_the_outcome_term_rewards_a_right_belief_and_charges_a_confidently_wrong_one(
    env_id: str,
) -> None:
    """The same episodes, once with the default success tolerances (the EKF ends right) and
    once with tolerances no belief meets (every confident end is a false convergence); the
    EKF kernel's term and the particle and grid cores'."""
    outcomes = {}
    for tol in (0.3, 1e-9):
        env = gym.make(env_id, outcome_reward=2.5, terminate_when_localized=True,
                       success_position_tol=tol, max_episode_steps=100)
        rng = np.random.default_rng(6)
        outcomes[tol] = []
        for seed in range(4):
            *_, (_, _, terminated, _, info) = run_episode(env, seed, rng)
            if terminated:
                outcomes[tol].append(info["reward_terms"]["outcome"])
    assert outcomes[0.3] and outcomes[1e-9]  # the episodes do end confident
    assert 2.5 in outcomes[0.3]
    assert set(outcomes[1e-9]) == {-2.5}


def uncertainty(env: gym.Env, reward: str, info: dict[str, Any]) -> float:
    """The quantity whose drop the telescoping reward ``reward`` pays, as the core recorded
    it (that it is the belief's log det / trace is checked per belief elsewhere)."""
    row = env.unwrapped.core.rows[0]
    if reward == "info_gain":
        assert row["entropy"] == info["entropy"]
        return info["entropy"]
    if reward == "logdet":
        assert np.isfinite(row["logdet"])
        return float(row["logdet"])
    return float(row["trace"])


def belief_summary(belief: Any) -> tuple[np.ndarray, ...]:
    """Copies of the arrays that define a belief (EKF: mean, cov; MCL: particles, weights;
    grid: the histogram)."""
    if isinstance(belief, MCLBelief):
        return belief.particles.copy(), belief.log_weights.copy()
    if isinstance(belief, GridBelief):
        return (belief.prob.copy(),)
    return belief.mean.copy(), belief.cov.copy()


@pytest.mark.parametrize("terminate", [True, False])
@pytest.mark.parametrize("reward", TELESCOPING)
@pytest.mark.parametrize("env_id", ENV_IDS)
def test_uncertainty_reward_telescopes_to_the_total_drop(
    env_id: str, reward: str, terminate: bool
) -> None:
    # 100 steps are enough to show the telescoping, and keep the particle envs quick
    env = gym.make(
        env_id, reward=reward, terminate_when_localized=terminate, max_episode_steps=100
    )
    rng = np.random.default_rng(2)
    for seed in (0, 1, 2):
        _, info = env.reset(seed=seed)
        start = uncertainty(env, reward, info)
        total = 0.0
        done = False
        while not done:
            (action,) = random_actions(env.action_space, rng, 1)
            _, _, terminated, truncated, info = env.step(action)
            total += info["reward_terms"][reward]
            done = terminated or truncated
        end = uncertainty(env, reward, info)
        assert total == pytest.approx(start - end, rel=0, abs=1e-9)


def test_entropy_in_info_is_the_gaussian_entropy_of_the_belief() -> None:
    env = gym.make(LANDMARK)
    rng = np.random.default_rng(3)
    _, info = env.reset(seed=0)
    for action in random_actions(env.action_space, rng, 30):
        cov = env.unwrapped.core.belief.cov[0]
        expected = 0.5 * (3 * math.log(2 * math.pi * math.e) + np.linalg.slogdet(cov)[1])
        assert info["entropy"] == pytest.approx(expected, rel=0, abs=1e-9)
        _, _, terminated, truncated, info = env.step(action)
        if terminated or truncated:
            break


@pytest.mark.parametrize("env_id", ENV_IDS)
def test_neg_entropy_term_is_minus_the_entropy(env_id: str) -> None:
    env = gym.make(env_id, reward="neg_entropy")
    rng = np.random.default_rng(4)
    for seed in (0, 1):
        _, *steps = run_episode(env, seed, rng)
        for _, _, _, _, info in steps:
            assert info["reward_terms"]["neg_entropy"] == -info["entropy"]


# -- bad input ---------------------------------------------------------------------------------


@pytest.mark.parametrize(
    ("action", "match"),
    [
        (np.zeros(3, dtype=np.float32), r"shape \(2,\)"),
        (np.zeros((1, 2), dtype=np.float32), r"shape \(2,\)"),
        (0.5, r"shape \(2,\)"),
        ([0.1], r"shape \(2,\)"),
        (np.array([np.nan, 0.0]), "NaN or inf"),
        (np.array([0.0, np.nan], dtype=np.float32), "NaN or inf"),
        (np.array([np.inf, 0.0]), "NaN or inf"),
        (np.array([0.0, -np.inf]), "NaN or inf"),
    ],
    ids=["3", "1x2", "scalar", "list1", "nan", "nan32", "inf", "-inf"],
)
def test_bad_continuous_action_raises_a_clear_error(action: Any, match: str) -> None:
    env = gym.make(LANDMARK)
    env.reset(seed=0)
    with pytest.raises(ValueError, match=match):
        env.step(action)


@pytest.mark.parametrize(
    ("action", "match"),
    [
        (6, r"integer in \[0, 6\)"),
        (-1, r"integer in \[0, 6\)"),
        (1.5, "integer index"),
        (float("nan"), "integer index"),
        (np.array([1]), "integer index"),
        ("1", "integer index"),
        (True, "integer index"),
        (None, "integer index"),
    ],
    ids=["6", "-1", "1.5", "nan", "array1", "str", "bool", "none"],
)
def test_bad_discrete_action_raises_a_clear_error(action: Any, match: str) -> None:
    env = gym.make(LANDMARK, action_type="discrete")
    env.reset(seed=0)
    with pytest.raises(ValueError, match=match):
        env.step(action)


@pytest.mark.parametrize("action_type", ["continuous", "discrete"])
def test_rejected_action_leaves_the_episode_unchanged(action_type: str) -> None:
    bad = np.array([np.nan, 0.0]) if action_type == "continuous" else 7
    env = gym.make(LANDMARK, action_type=action_type)
    twin = gym.make(LANDMARK, action_type=action_type)
    env.reset(seed=0)
    twin.reset(seed=0)
    actions = random_actions(env.action_space, np.random.default_rng(5), 10)
    for action in actions:
        with pytest.raises(ValueError):
            env.step(bad)
        result, result_t = env.step(action), twin.step(action)
        assert np.array_equal(result[0], result_t[0])
        assert result[1:] == result_t[1:]
        if result[2] or result[3]:
            break


@pytest.mark.parametrize(
    ("kwargs", "match"),
    [
        ({"reward": "nope"}, "reward='nope' is not one of"),
        ({"action_type": "joystick"}, "action_type='joystick' is not one of"),
        ({"range_std": -1}, r"range_std must be a finite number > 0, got -1"),
        ({"motion_noise_std": (-0.1, 0, 0)}, r"motion_noise_std must be a finite number >= 0"),
        ({"motion_noise_std": (0.1, 0.1)},
         r"motion_noise_std \(x m, y m, theta rad\) must be 3 finite numbers"),
        ({"map": np.zeros((0, 2))}, r"map must be .*non-empty .*got shape \(0, 2\)"),
        ({"map": [[np.nan, 0.0]]}, "NaN or inf"),
        ({"map": "atlantis"}, "map='atlantis' is not one of"),
        ({"fov": 0}, r"fov must be in \(0, 2\*pi\]"),
        ({"fov": 7.0}, r"fov must be in \(0, 2\*pi\]"),
        ({"dt": float("nan")}, "dt must be a finite number > 0"),
        ({"n_landmarks": (5, 3)}, "n_landmarks must satisfy"),
        ({"n_landmarks": (8, 20)}, "max_landmarks=15"),
        ({"start_pose": (1.0, 2.0)},
         r"start_pose \(x m, y m, theta rad\) must be 3 finite numbers"),
        ({"initial_belief_std": (0.0, 1.0, 1.0)}, "initial_belief_std must be a finite number > 0"),
        ({"outcome_reward": -1.0}, "outcome_reward must be a finite number >= 0"),
        ({"kidnap_grace": -1}, "kidnap_grace must be an integer >= 0, got -1"),
        ({"kidnap_grace": 2.5}, "kidnap_grace must be an integer >= 0, got 2.5"),
        ({"proposal": "dual"}, "proposal='dual' is not one of"),
        ({"mixture_share": 0.0}, "mixture_share must be in \\(0, 1\\), got 0.0"),
        ({"mixture_share": "0.2"}, "mixture_share must be a number"),
        ({"proposal": "mixture", "belief": "ekf"}, "proposal='mixture' is mixture MCL"),
        ({"outcome_reward": 1.0, "terminate_when_localized": False},
         "outcome_reward .* needs terminate_when_localized=True"),
    ],
    ids=lambda v: str(v)[:40] if isinstance(v, dict) else None,
)
def test_bad_config_raises_value_error_naming_the_field(kwargs: dict, match: str) -> None:
    with pytest.raises(ValueError, match=match):
        gym.make(LANDMARK, **kwargs)


def test_unknown_kwarg_raises_type_error_naming_it() -> None:
    with pytest.raises(TypeError, match=r"unknown env kwargs \['bogus'\]"):
        gym.make(LANDMARK, bogus=1)


@pytest.mark.filterwarnings("ignore:.*not in the possible render_modes:UserWarning")
def test_bad_render_mode_raises_value_error() -> None:
    with pytest.raises(ValueError, match=r"render_mode='ascii' is not one of"):
        gym.make(LANDMARK, render_mode="ascii")
    with pytest.raises(ValueError, match=r"render_mode='ascii' is not one of"):
        ActiveLocalizationEnv(render_mode="ascii")


@pytest.mark.parametrize("env_id", ENV_IDS)
def test_step_before_reset_raises_runtime_error(env_id: str) -> None:
    env = gym.make(env_id)
    with pytest.raises(RuntimeError, match=r"reset\(\) before step\(\)"):
        env.unwrapped.step(np.zeros(2, dtype=np.float32))
    with pytest.raises(RuntimeError, match=r"reset\(\) before planner_view\(\)"):
        env.unwrapped.planner_view()
    with pytest.raises(gym.error.ResetNeeded):  # gymnasium's OrderEnforcing wrapper
        env.step(np.zeros(2, dtype=np.float32))


def test_map_given_as_a_list_of_positions_is_used() -> None:
    positions = [[2.0, 3.0], [5.0, 1.0], [4.0, 6.0]]
    env = gym.make(LANDMARK, map=positions)
    env.reset(seed=0)
    np.testing.assert_array_equal(env.unwrapped.core.maps[0].positions, positions)


def test_map_given_as_a_numpy_array_is_used() -> None:
    positions = np.array([[2.0, 3.0], [5.0, 1.0], [4.0, 6.0]])
    env = gym.make(LANDMARK, map=positions)
    env.reset(seed=0)
    np.testing.assert_array_equal(env.unwrapped.core.maps[0].positions, positions)


# -- collisions --------------------------------------------------------------------------------


def test_driving_into_the_west_wall_is_a_blocked_collision() -> None:
    env = gym.make(
        LANDMARK, start="fixed", start_pose=(0.5, 10, 3.14159), motion_noise_std=(0, 0, 0)
    )
    _, info = env.reset(seed=0)
    core = env.unwrapped.core
    lmap = core.maps[0]
    assert info["collisions"] == 0
    collisions = []
    for _ in range(10):
        _, reward, terminated, _, info = env.step(np.array([1.0, 0.0], dtype=np.float32))
        assert lmap.contains(core.pose[0, :2])
        collisions.append(info["collisions"])
        blocked = info["reward_terms"]["collision"]
        assert blocked in (0.0, -1.0)
        if terminated:
            break
    assert collisions == sorted(collisions)
    assert collisions[-1] >= 5  # 0.2 m per step from x = 0.5: the third move hits the wall
    assert info["reward_terms"]["collision"] == -1.0
    assert reward == pytest.approx(info["reward_terms"]["info_gain"] - 1.0, abs=1e-12)
    assert core.pose[0, 0] == pytest.approx(0.1)
    assert env.reset(seed=0)[1]["collisions"] == 0


def test_collision_penalty_is_configurable_and_counted_once_per_blocked_move() -> None:
    env = gym.make(
        LANDMARK,
        start="fixed",
        start_pose=(0.5, 10, 3.14159),
        motion_noise_std=(0, 0, 0),
        collision_penalty=0.25,
        terminate_when_localized=False,
    )
    env.reset(seed=0)
    blocked = 0
    for _ in range(8):
        _, _, _, _, info = env.step(np.array([1.0, 0.0], dtype=np.float32))
        blocked += info["reward_terms"]["collision"] == -0.25
        assert info["collisions"] == blocked
    assert blocked == 6


# -- termination -------------------------------------------------------------------------------


def test_landmark_env_terminates_exactly_when_localized() -> None:
    env = gym.make(LANDMARK, localized_position_std=0.3, localized_heading_std=0.1)
    rng = np.random.default_rng(6)
    ended_localized = 0
    for seed in range(3):
        _, *steps = run_episode(env, seed, rng)
        for _, _, terminated, truncated, info in steps:
            assert terminated == info["localized"]
            assert not (terminated and truncated)
        ended_localized += steps[-1][2]
    assert ended_localized >= 1


def test_landmark_env_never_terminates_when_asked_not_to() -> None:
    env = gym.make(
        LANDMARK,
        localized_position_std=0.3,
        localized_heading_std=0.1,
        terminate_when_localized=False,
    )
    _, *steps = run_episode(env, 0, np.random.default_rng(7))
    assert len(steps) == 200
    assert not any(terminated for _, _, terminated, _, _ in steps)
    assert [truncated for _, _, _, truncated, _ in steps] == [False] * 199 + [True]
    assert any(info["localized"] for *_, info in steps)


def test_textbook_never_terminates_and_is_truncated_at_150_steps() -> None:
    env = gym.make(TEXTBOOK)
    for seed in (0, 1):
        _, *steps = run_episode(env, seed, np.random.default_rng(seed))
        assert len(steps) == 150
        assert not any(terminated for _, _, terminated, _, _ in steps)
        assert [truncated for _, _, _, truncated, _ in steps] == [False] * 149 + [True]
        assert any(info["localized"] for *_, info in steps)


# -- planner view ------------------------------------------------------------------------------


def numbers_in(obj: Any, seen: set[int] | None = None) -> list[float]:
    """Every number reachable from ``obj`` through fields, attributes and containers."""
    seen = set() if seen is None else seen
    if id(obj) in seen or obj is None or isinstance(obj, str | np.random.Generator):
        return []
    seen.add(id(obj))
    if isinstance(obj, bool | int | float | np.number):
        return [float(obj)]
    if isinstance(obj, np.ndarray):
        return [float(v) for v in obj.ravel()] if obj.dtype.kind in "biuf" else []
    if isinstance(obj, dict):
        children = list(obj.values())
    elif isinstance(obj, list | tuple | set | frozenset):
        children = list(obj)
    elif dataclasses.is_dataclass(obj):
        children = [getattr(obj, f.name) for f in dataclasses.fields(obj)]
        children += list(getattr(obj, "__dict__", {}).values())
    elif hasattr(obj, "__dict__"):
        children = list(vars(obj).values())
    else:
        return []
    return [v for child in children for v in numbers_in(child, seen)]


def test_planner_view_has_the_planning_interface() -> None:
    env = gym.make(LANDMARK)
    env.reset(seed=0)
    view = env.unwrapped.planner_view()
    for name in ("belief", "map", "motion", "sensor", "action_space", "simulate"):
        assert hasattr(view, name), name
    assert view.action_space == env.action_space
    np.testing.assert_array_equal(view.map.positions, env.unwrapped.core.maps[0].positions)
    np.testing.assert_array_equal(view.belief.mean, env.unwrapped.core.belief.mean)
    np.testing.assert_array_equal(view.belief.cov, env.unwrapped.core.belief.cov)


def test_planner_view_belief_is_a_copy() -> None:
    env = gym.make(LANDMARK)
    env.reset(seed=0)
    core = env.unwrapped.core
    mean, cov = core.belief.mean.copy(), core.belief.cov.copy()
    view = env.unwrapped.planner_view()
    view.belief.mean[:] = 99.0
    view.belief.cov[:] *= 10.0
    view.belief.predict(np.array([[1.0, 1.0]]))
    np.testing.assert_array_equal(core.belief.mean, mean)
    np.testing.assert_array_equal(core.belief.cov, cov)


@pytest.mark.parametrize("steps", [0, 30])
def test_planner_view_holds_no_true_pose(steps: int) -> None:
    env = gym.make(LANDMARK, terminate_when_localized=False)
    env.reset(seed=3)
    for action in random_actions(env.action_space, np.random.default_rng(8), steps):
        env.step(action)
    view = env.unwrapped.planner_view()
    truth = env.unwrapped.core.pose[0]
    assert not np.allclose(view.belief.mean[0], truth)
    assert not any("pose" in f.name or "true" in f.name for f in dataclasses.fields(view))
    assert not np.isin(truth, numbers_in(view)).any()


def test_planner_view_hides_a_fixed_start_pose() -> None:
    env = gym.make(LANDMARK, start="fixed", start_pose=(3.25, 4.75, 0.625))
    env.reset(seed=0)
    truth = env.unwrapped.core.pose[0]
    assert not np.isin(truth, numbers_in(env.unwrapped.planner_view())).any()


@pytest.mark.parametrize("action_type", ["continuous", "discrete"])
@pytest.mark.parametrize("env_id", ENV_IDS)
def test_planner_simulate_updates_a_copy_and_leaves_the_env_alone(
    env_id: str, action_type: str
) -> None:
    # start="random": a landmark in view from the start, so that a simulated standstill
    # still updates the belief
    kwargs = {"action_type": action_type, "start": "random"}
    env, twin = gym.make(env_id, **kwargs), gym.make(env_id, **kwargs)
    env.reset(seed=4)
    twin.reset(seed=4)
    rng = np.random.default_rng(9)
    core = env.unwrapped.core
    for action in random_actions(env.action_space, rng, 20):
        view = env.unwrapped.planner_view()
        before = belief_summary(view.belief)
        state = env.unwrapped.np_random.bit_generator.state
        core_state = core.state.copy()
        updated, z, visible = view.simulate(action, view.belief, rng)
        assert updated is not view.belief
        # predicted at least
        assert not np.array_equal(belief_summary(updated)[0], before[0])
        if isinstance(view.map, OccupancyGrid):
            assert z.shape == (view.sensor.n_beams,)
        else:
            assert z.shape == (view.map.n_landmarks, 2)
        assert visible.shape == z.shape[:1]
        for a, b in zip(belief_summary(view.belief), before, strict=True):
            np.testing.assert_array_equal(a, b)
        for a, b in zip(belief_summary(core.belief), before, strict=True):
            np.testing.assert_array_equal(a, b)
        np.testing.assert_array_equal(core.state, core_state)
        assert env.unwrapped.np_random.bit_generator.state == state
        obs, *rest = env.step(action)
        obs_t, *rest_t = twin.step(action)
        assert np.array_equal(obs, obs_t)
        assert rest == rest_t
        if rest[1] or rest[2]:
            break


# -- seeding -----------------------------------------------------------------------------------


def test_same_seed_gives_the_same_map_start_and_belief() -> None:
    a, b = gym.make(LANDMARK), gym.make(LANDMARK)
    obs_a, _ = a.reset(seed=11)
    b.reset(seed=99)
    obs_b, _ = b.reset(seed=11)
    core_a, core_b = a.unwrapped.core, b.unwrapped.core
    np.testing.assert_array_equal(core_a.maps[0].positions, core_b.maps[0].positions)
    np.testing.assert_array_equal(core_a.pose, core_b.pose)
    np.testing.assert_array_equal(core_a.belief.mean, core_b.belief.mean)
    np.testing.assert_array_equal(obs_a, obs_b)


def test_different_seeds_give_different_maps_and_starts() -> None:
    env = gym.make(LANDMARK)
    maps, starts = [], []
    for seed in range(5):
        env.reset(seed=seed)
        maps.append(env.unwrapped.core.maps[0].positions.copy())
        starts.append(env.unwrapped.core.pose[0].copy())
    for i in range(5):
        for j in range(i):
            assert maps[i].shape != maps[j].shape or not np.array_equal(maps[i], maps[j])
            assert not np.array_equal(starts[i], starts[j])


def test_unseeded_reset_continues_the_seeded_stream() -> None:
    env = gym.make(LANDMARK)
    env.reset(seed=0)
    first = env.unwrapped.core.maps[0].positions.copy()
    env.reset()
    second = env.unwrapped.core.maps[0].positions
    assert first.shape != second.shape or not np.array_equal(first, second)


def test_textbook_map_and_start_are_fixed() -> None:
    env = gym.make(TEXTBOOK)
    for seed in (0, 1):
        env.reset(seed=seed)
        core = env.unwrapped.core
        np.testing.assert_array_equal(
            core.maps[0].positions, [[0.0, 0.0], [2.0, 8.0], [8.0, 2.0], [10.0, 10.0]]
        )
        np.testing.assert_array_equal(core.pose[0], [1.0, 1.0, 0.0])


# -- filterpy backend --------------------------------------------------------------------------


@pytest.mark.parametrize("env_id", ENV_IDS)
def test_filterpy_backend_matches_numba_backend(env_id: str) -> None:
    numba_env = gym.make(env_id)
    filterpy_env = gym.make(env_id, ekf_backend="filterpy")
    obs_n, _ = numba_env.reset(seed=12)
    obs_f, _ = filterpy_env.reset(seed=12)
    np.testing.assert_allclose(obs_f, obs_n, rtol=0, atol=1e-6)
    for action in random_actions(numba_env.action_space, np.random.default_rng(10), 100):
        obs_n, reward_n, terminated_n, truncated_n, info_n = numba_env.step(action)
        obs_f, reward_f, terminated_f, truncated_f, info_f = filterpy_env.step(action)
        np.testing.assert_allclose(obs_f, obs_n, rtol=0, atol=1e-6)
        assert reward_f == pytest.approx(reward_n, abs=1e-6)
        assert (terminated_f, truncated_f) == (terminated_n, truncated_n)
        assert info_f["entropy"] == pytest.approx(info_n["entropy"], abs=1e-6)
        if terminated_n or truncated_n:
            np.testing.assert_allclose(
                filterpy_env.reset()[0], numba_env.reset()[0], rtol=0, atol=1e-6
            )


def test_step_noise_is_drawn_for_the_landmarks_in_view_only() -> None:
    """A step uses 3 normals for the motion and 2 per landmark seen (the buffer's cursor
    moves by that much); an unseeded reset goes on with the buffer, a reseeded one drops it,
    so that a seed alone fixes the episode."""
    env = gym.make(LANDMARK)
    core = env.unwrapped.core
    env.reset(seed=1)
    rng = np.random.default_rng(1)
    cursor = None
    for _ in range(100):
        _, _, terminated, _, info = env.step(rng.uniform(-1, 1, 2).astype(np.float32))
        now = int(core.rows[0]["noise_cursor"])
        if cursor is not None and now > cursor:  # not refilled on this step
            assert now - cursor == 3 + 2 * info["n_visible"]
        cursor = now
        if terminated:
            break
    assert core.noise_source[0] is env.unwrapped.np_random
    env.reset()  # the same Generator goes on: so does its buffer
    assert int(core.rows[0]["noise_cursor"]) == cursor
    env.reset(seed=7)  # a new Generator: the old buffer is dropped
    assert core.rows[0]["noise_cursor"] >= core.noise.shape[1]
    again = gym.make(LANDMARK)
    again.reset(seed=7)
    assert np.array_equal(env.step(np.array([0.5, 0.1], dtype=np.float32))[0],
                          again.step(np.array([0.5, 0.1], dtype=np.float32))[0])


@pytest.mark.parametrize(("dtype", "size"), [(ROW_DTYPE, STATE_SIZE), (WORLD_DTYPE, WORLD_SIZE)])
def test_the_named_records_cover_the_packed_rows_without_overlap(dtype: np.dtype,
                                                                 size: int) -> None:
    """Every float of a packed row has exactly one name, so the Python side can reach all of
    it without offsets."""
    owner = np.full(size, -1)
    for k, name in enumerate(dtype.names):
        field, offset = dtype.fields[name][:2]
        first, count = offset // 8, field.itemsize // 8
        assert np.all(owner[first : first + count] == -1), f"{name} overlaps another field"
        owner[first : first + count] = k
    assert np.all(owner >= 0) and dtype.itemsize == 8 * size


@pytest.mark.parametrize("env_id", [LANDMARK, "ActiveLoc/LandmarkMCL-v0", "ActiveLoc/GridMCL-v0"])
def test_the_named_rows_agree_with_the_step_outcome(env_id: str) -> None:
    """The outcome a shell reads and the named row are the same numbers: a field named at the
    wrong offset shows here."""
    env = gym.make(env_id)
    core = env.unwrapped.core
    env.reset(seed=3)
    rng = np.random.default_rng(3)
    for _ in range(40):
        _, _, terminated, truncated, info = env.step(rng.uniform(-1, 1, 2).astype(np.float32))
        row, outcome = core.rows[0], core.outcome(0)
        assert outcome.pose_error == row["pos_err"] == info["pose_error"]
        assert outcome.entropy == row["entropy"] == info["entropy"]
        assert outcome.collided == bool(row["collided"])
        assert outcome.localized == bool(row["localized"]) == info["localized"]
        assert outcome.success == bool(row["success"]) == info["is_success"]
        assert np.array_equal(core.pose[0], row["pose"])
        assert math.hypot(*(row["pose"][:2] - row["mean"][:2])) == pytest.approx(row["pos_err"])
        for flag in ("collided", "localized", "success", "terminal", "kidnapped"):
            assert row[flag] in (0.0, 1.0)
        if terminated or truncated:
            env.reset()
