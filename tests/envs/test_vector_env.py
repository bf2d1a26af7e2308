"""The native vector env (``vectorization_mode="vector_entry_point"``) of every id.

The reference is gymnasium's own ``SyncVectorEnv`` over single envs seeded seed + i: for every
id and action type, and in each autoreset mode, the native vector env must give the same
observations, rewards, flags and infos (values and dtypes), exactly. Its batched info holds
arrays only: ``SyncVectorEnv``'s nested ``reward_terms`` is there as the flat ``reward_<term>``
arrays, which ``SyncVectorEnv`` stacks too.
"""

from __future__ import annotations

import multiprocessing
from typing import Any

import gymnasium as gym
import numpy as np
import pytest
from gymnasium.vector import AutoresetMode

from active_loc.envs import ActiveLocalizationVectorEnv
from active_loc.envs.landmark_core import PRANGE_MIN_MEMBERS
from active_loc.envs.vector_engines import BatchedEngine, BatchedMazeEngine, MemberEngine
from tests.envs.test_envs import CASES, ENV_IDS, vector_actions

N_ENVS = 3
#: a short limit, so that every sub-env ends (and is reset) several times in a test
LIMIT = 8
#: ids stepped by one batched kernel call (and their discrete-action twins); the other ids
#: but the maze and the identical-looking landmarks run on one core of n members too
BATCHED_BASE_IDS = ("ActiveLoc/Textbook-v0", "ActiveLoc/LandmarkEKF-v0")


def make_pair(
    env_id: str, mode: AutoresetMode, n: int = N_ENVS, **kwargs: Any
) -> tuple[gym.vector.VectorEnv, gym.vector.VectorEnv]:
    """(native, gymnasium's SyncVectorEnv) of n sub-envs with the same kwargs and autoreset
    mode."""
    native = gym.make_vec(
        env_id, n, vectorization_mode="vector_entry_point", autoreset_mode=mode,
        max_episode_steps=LIMIT, **kwargs,
    )
    sync = gym.make_vec(
        env_id, n, vectorization_mode="sync", vector_kwargs={"autoreset_mode": mode},
        max_episode_steps=LIMIT, **kwargs,
    )
    return native, sync


def without_nested_terms(sync: dict[str, Any]) -> dict[str, Any]:
    """SyncVectorEnv's info without its nested ``reward_terms`` (and the same in
    ``final_info``), after checking that the flat ``reward_<term>`` arrays hold its values."""
    out = dict(sync)
    if "reward_terms" in out:
        terms = out.pop("reward_terms")
        out.pop("_reward_terms")
        for term, values in terms.items():
            if not term.startswith("_"):
                assert np.array_equal(values, sync[f"reward_{term}"]), term
                assert np.array_equal(terms[f"_{term}"], sync[f"_reward_{term}"]), term
    if "final_info" in out:
        out["final_info"] = without_nested_terms(out["final_info"])
    return out


def assert_infos_equal(native: dict[str, Any], sync: dict[str, Any]) -> None:
    """Same keys and masks; where a mask is set, the same values and dtypes (rows a mask
    leaves out are not compared: SyncVectorEnv leaves zeros there)."""
    sync = without_nested_terms(sync)
    assert native.keys() == sync.keys()
    for key, value in native.items():
        if key.startswith("_"):
            continue
        mask = native[f"_{key}"]
        assert np.array_equal(mask, sync[f"_{key}"]), key
        if isinstance(value, dict):
            assert_infos_equal(value, sync[key])
        elif value.dtype == object:  # final_obs
            for b in np.flatnonzero(mask):
                assert np.array_equal(value[b], sync[key][b]), key
        else:
            assert value.dtype == sync[key].dtype, (key, value.dtype, sync[key].dtype)
            assert np.array_equal(value[mask], sync[key][mask], equal_nan=True), key


def assert_same(native_result: tuple, sync_result: tuple) -> None:
    *arrays_n, info_n = native_result
    *arrays_s, info_s = sync_result
    for part_n, part_s in zip(arrays_n, arrays_s, strict=True):
        assert part_n.dtype == part_s.dtype
        assert np.array_equal(part_n, part_s)
    assert_infos_equal(info_n, info_s)


def run_pair(native: Any, sync: Any, steps: int, seed: int = 5) -> int:
    """Step both with the same random actions; returns how many episodes ended."""
    assert_same(native.reset(seed=seed), sync.reset(seed=seed))
    rng = np.random.default_rng(seed)
    ended = 0
    for _ in range(steps):
        actions = vector_actions(native.action_space, rng)
        result = native.step(actions)
        assert_same(result, sync.step(actions))
        ended += int(np.sum(result[2] | result[3]))
    return ended


@pytest.mark.parametrize(("env_id", "action_type"), CASES)
def test_native_equals_single_envs(env_id: str, action_type: str) -> None:
    native, sync = make_pair(env_id, AutoresetMode.NEXT_STEP, action_type=action_type)
    assert isinstance(native, ActiveLocalizationVectorEnv)
    assert native.metadata["autoreset_mode"] == AutoresetMode.NEXT_STEP
    engine = (BatchedMazeEngine if env_id == "ActiveLoc/Maze-v0"
              else MemberEngine if "Unknown" in env_id else BatchedEngine)
    assert isinstance(native.engine, engine)
    assert native.single_observation_space == sync.single_observation_space
    assert native.action_space == sync.action_space
    ended = run_pair(native, sync, 3 * LIMIT)
    assert ended >= N_ENVS  # autoreset was exercised
    native.close()
    sync.close()


@pytest.mark.parametrize("action_type", ["continuous", "discrete"])
@pytest.mark.parametrize("env_id", BATCHED_BASE_IDS)
def test_the_prange_kernel_on_one_thread_is_the_single_envs(env_id: str, action_type: str) -> None:
    """From PRANGE_MIN_MEMBERS sub-envs on, the batch steps in the prange kernel even with one
    worker; the single envs step in the plain loop: the same results."""
    n = PRANGE_MIN_MEMBERS + 1
    native, sync = make_pair(env_id, AutoresetMode.NEXT_STEP, n=n, action_type=action_type)
    assert native.engine.workers == 1  # too few sub-envs for a second thread
    assert run_pair(native, sync, 3 * LIMIT) >= n


def _batched_trace(seed: int) -> list[np.ndarray]:
    """Observations and rewards of 8 LandmarkEKF sub-envs (the prange kernel) for 5 steps."""
    envs = gym.make_vec("ActiveLoc/LandmarkEKF-v0", 8, vectorization_mode="vector_entry_point")
    trace = [envs.reset(seed=seed)[0]]
    rng = np.random.default_rng(seed)
    for _ in range(5):
        obs, rewards, *_ = envs.step(vector_actions(envs.action_space, rng))
        trace += [obs, rewards]
    return trace


def _child_trace(connection: Any) -> None:
    connection.send(_batched_trace(4))


@pytest.mark.skipif("fork" not in multiprocessing.get_all_start_methods(), reason="no fork")
def test_a_child_forked_after_the_prange_kernel_ran_still_steps() -> None:
    """GNU OpenMP kills a forked child that launches a parallel kernel once its parent has:
    the child steps in the plain loop instead, with the same results."""
    parent = _batched_trace(4)  # launches the prange kernel here
    context = multiprocessing.get_context("fork")
    receiver, sender = context.Pipe(duplex=False)
    child = context.Process(target=_child_trace, args=(sender,))
    child.start()
    sender.close()  # the child's end only: if the child dies, recv() raises EOFError
    assert receiver.poll(120)
    child_trace = receiver.recv()
    child.join(60)
    assert child.exitcode == 0
    for a, b in zip(parent, child_trace, strict=True):
        assert np.array_equal(a, b)


def test_the_outcome_reward_of_the_batched_kernel_is_the_single_envs() -> None:
    """Episodes long enough to end confident: the terminal rewards carry the outcome term."""
    kwargs = {"outcome_reward": 3.0, "max_episode_steps": 60}
    native = gym.make_vec("ActiveLoc/LandmarkEKF-v0", N_ENVS,
                          vectorization_mode="vector_entry_point", **kwargs)
    sync = gym.make_vec("ActiveLoc/LandmarkEKF-v0", N_ENVS, vectorization_mode="sync", **kwargs)
    assert_same(native.reset(seed=7), sync.reset(seed=7))
    rng = np.random.default_rng(7)
    outcomes = []
    for _ in range(120):
        actions = vector_actions(native.action_space, rng)
        result = native.step(actions)
        assert_same(result, sync.step(actions))
        terms = result[4]["reward_outcome"]
        outcomes += terms[result[2]].tolist()
    assert outcomes and set(outcomes) <= {3.0, -3.0}


@pytest.mark.parametrize("env_id", ["ActiveLoc/LandmarkEKF-v0", "ActiveLoc/GridMarkov-v0"])
def test_same_step_autoreset_reports_final_obs_and_info(env_id: str) -> None:
    native, sync = make_pair(env_id, AutoresetMode.SAME_STEP)
    assert native.metadata["autoreset_mode"] == AutoresetMode.SAME_STEP
    native.reset(seed=1)
    sync.reset(seed=1)
    rng = np.random.default_rng(1)
    saw_final = False
    for _ in range(2 * LIMIT):
        actions = vector_actions(native.action_space, rng)
        result = native.step(actions)
        assert_same(result, sync.step(actions))
        info = result[4]
        if (result[2] | result[3]).any():
            saw_final = True
            assert np.array_equal(info["_final_obs"], result[2] | result[3])
            assert set(info["final_info"]) >= {"pose_error", "entropy", "is_success"}
    assert saw_final


@pytest.mark.parametrize("env_id", ["ActiveLoc/LandmarkEKF-v0", "ActiveLoc/Maze-v0"])
def test_disabled_autoreset_resets_only_the_masked_envs(env_id: str) -> None:
    native, sync = make_pair(env_id, AutoresetMode.DISABLED)
    native.reset(seed=2)
    sync.reset(seed=2)
    rng = np.random.default_rng(2)
    for _ in range(3 * LIMIT):
        actions = vector_actions(native.action_space, rng)
        result = native.step(actions)
        assert_same(result, sync.step(actions))
        ended = result[2] | result[3]
        if ended.any():
            with pytest.raises(RuntimeError, match="reset_mask"):
                native.step(actions)
            mask = ended.copy()
            assert_same(native.reset(options={"reset_mask": mask}),
                        sync.reset(options={"reset_mask": mask.copy()}))


def test_every_id_has_the_native_vector_env() -> None:
    for env_id in ENV_IDS:
        assert gym.spec(env_id).vector_entry_point is not None, env_id


def test_seeds_list_and_none() -> None:
    native = gym.make_vec("ActiveLoc/LandmarkEKF-v0", 2, vectorization_mode="vector_entry_point")
    single = gym.make("ActiveLoc/LandmarkEKF-v0")
    obs, _ = native.reset(seed=[11, 3])
    assert np.array_equal(obs[1], single.reset(seed=3)[0])
    assert np.array_equal(obs[0], single.reset(seed=11)[0])
    unseeded_a, _ = native.reset()
    unseeded_b, _ = native.reset()
    assert not np.array_equal(unseeded_a, unseeded_b)
    with pytest.raises(ValueError, match="one per sub-env"):
        native.reset(seed=[1, 2, 3])


def test_info_keys_and_dtypes_are_stable() -> None:
    native = gym.make_vec("ActiveLoc/GridMarkov-v0", 2, vectorization_mode="vector_entry_point",
                          max_episode_steps=5, action_type="discrete")
    _, info = native.reset(seed=0)
    layout = {key: value.dtype for key, value in info.items() if not isinstance(value, dict)}
    rng = np.random.default_rng(0)
    for _ in range(12):
        info = native.step(vector_actions(native.action_space, rng))[4]
        assert {k: v.dtype for k, v in info.items() if not isinstance(v, dict)} == layout
        assert all(info[f"_{key}"].all() for key in layout if not key.startswith("_"))


@pytest.mark.parametrize(("env_id", "tiles"), [("ActiveLoc/LandmarkEKF-v0", 1),
                                               ("ActiveLoc/LandmarkEKF-v0", 4),
                                               ("ActiveLoc/Maze-v0", 3)])
def test_render_first_env_or_tiled(env_id: str, tiles: int) -> None:
    native = gym.make_vec(env_id, 4, vectorization_mode="vector_entry_point",
                          render_mode="rgb_array", render_envs=tiles)
    single = gym.make(env_id, render_mode="rgb_array")
    native.reset(seed=0)
    single.reset(seed=0)
    frame = native.render()
    reference = single.render()
    assert frame.dtype == np.uint8
    if tiles == 1:
        assert frame.shape == reference.shape
    else:
        h, w, _ = reference.shape
        assert frame.shape == (2 * h, 2 * w, 3)  # 3 or 4 frames: a 2 x 2 grid
        assert frame[h:, w:].max() == (255 if tiles == 4 else 0)  # the 4th tile: empty or not


def test_bad_input_is_named() -> None:
    native = gym.make_vec("ActiveLoc/LandmarkEKF-v0", 2, vectorization_mode="vector_entry_point")
    with pytest.raises(RuntimeError, match="reset"):
        native.step(np.zeros((2, 2), dtype=np.float32))
    native.reset(seed=0)
    with pytest.raises(ValueError, match=r"shape \(2, 2\)"):
        native.step(np.zeros((3, 2), dtype=np.float32))
    with pytest.raises(ValueError, match="sub-env 1 contains NaN"):
        native.step(np.array([[0.0, 0.0], [np.nan, 0.0]]))
    wide = gym.make_vec("ActiveLoc/LandmarkEKF-v0", 130, vectorization_mode="vector_entry_point",
                        workers=2)
    wide.reset(seed=0)
    before = wide.engine.core.state.copy()
    actions = np.zeros((130, 2))
    actions[100, 1] = np.inf  # in the second worker's share: nobody moves
    with pytest.raises(ValueError, match="sub-env 100 contains NaN or inf"):
        wide.step(actions)
    assert np.array_equal(wide.engine.core.state, before)
    with pytest.raises(ValueError, match="reset_mask"):
        native.reset(options={"reset_mask": np.array([1, 0])})
    with pytest.raises(ValueError, match="num_envs"):
        ActiveLocalizationVectorEnv(0)
    with pytest.raises(ValueError, match="autoreset_mode"):
        ActiveLocalizationVectorEnv(2, autoreset_mode="sometimes")
    discrete = gym.make_vec("ActiveLoc/LandmarkEKF-v0", 2, vectorization_mode="vector_entry_point",
                            action_type="discrete")
    discrete.reset(seed=0)
    with pytest.raises(ValueError, match=r"sub-env 0 must be in \[0, 6\)"):
        discrete.step(np.array([7, 0]))


def test_bad_actions_of_threaded_sub_envs_are_named_before_any_moves() -> None:
    """The MCL, grid and maze ids check every action before a worker thread steps anyone."""
    for kwargs, bad_action, message in [
        ({}, [np.nan, 0.0], "sub-env 2 contains NaN or inf"),
        ({"action_type": "discrete"}, 9, r"sub-env 2 must be in \[0, 6\)"),
    ]:
        envs = gym.make_vec("ActiveLoc/GridMCL-v0", 4, vectorization_mode="vector_entry_point",
                            workers=2, n_particles=600, **kwargs)
        obs, _ = envs.reset(seed=0)
        actions = np.array([envs.single_action_space.sample() for _ in range(4)])
        actions[2] = bad_action
        with pytest.raises(ValueError, match=message):
            envs.step(actions)
        assert np.array_equal(envs.engine.obs, obs)  # nobody moved
        with pytest.raises(ValueError, match="shape"):
            envs.step(actions[:3])
        envs.close()
    maze = gym.make_vec("ActiveLoc/Maze-v0", 2, vectorization_mode="vector_entry_point", size=7)
    maze.reset(seed=0)
    with pytest.raises(ValueError, match=r"sub-env 1 must be in \[0, 3\)"):
        maze.step(np.array([0, 3]))


@pytest.mark.parametrize(("env_id", "n", "kwargs"), [
    ("ActiveLoc/GridMCL-v0", 4, {"n_particles": 2000}),
    ("ActiveLoc/LandmarkEKF-v0", 130, {}),  # two shares of 65 rows
])
@pytest.mark.parametrize("mode", [AutoresetMode.NEXT_STEP, AutoresetMode.SAME_STEP])
def test_threads_do_not_change_the_results(
    env_id: str, n: int, kwargs: dict, mode: AutoresetMode
) -> None:
    """Worker threads step and autoreset disjoint members, in whatever order they take them:
    the same results as one thread."""
    runs = []
    for workers in (1, 2):
        envs = gym.make_vec(env_id, n, vectorization_mode="vector_entry_point", workers=workers,
                            max_episode_steps=6, autoreset_mode=mode, **kwargs)
        assert envs.engine.workers == workers
        obs, _ = envs.reset(seed=3)
        rng = np.random.default_rng(3)
        trace = [obs]
        for _ in range(80 if n > 100 else 10):  # past the 64-step noise blocks
            result = envs.step(vector_actions(envs.action_space, rng))
            trace += [result[0], result[1], result[2], result[4]["entropy"]]
        envs.close()
        runs.append(trace)
    for a, b in zip(*runs, strict=True):
        assert np.array_equal(a, b)


@pytest.mark.parametrize("env_id", ["ActiveLoc/LandmarkEKF-v0", "ActiveLoc/GridMCL-v0"])
def test_info_dicts_are_the_single_envs_infos(env_id: str) -> None:
    """``step_with_info_dicts`` (the SB3 path) gives each sub-env the info dict, final
    observation and reset info of a single env seeded seed + i, episode ends included."""
    kwargs = {"n_particles": 500} if "MCL" in env_id else {}
    native = gym.make_vec(env_id, N_ENVS, vectorization_mode="vector_entry_point",
                          autoreset_mode=AutoresetMode.SAME_STEP, max_episode_steps=LIMIT,
                          **kwargs)
    singles = [gym.make(env_id, max_episode_steps=LIMIT, **kwargs) for _ in range(N_ENVS)]
    native.reset(seed=5)
    for i, env in enumerate(singles):
        env.reset(seed=5 + i)
    rng = np.random.default_rng(5)
    ends = 0
    for _ in range(2 * LIMIT + 1):
        actions = vector_actions(native.action_space, rng)
        obs, rewards, terminated, truncated, infos, reset_infos = (
            native.unwrapped.step_with_info_dicts(actions)
        )
        for i, env in enumerate(singles):
            obs_i, reward_i, term_i, trunc_i, info_i = env.step(actions[i])
            assert (rewards[i], terminated[i], truncated[i]) == (reward_i, term_i, trunc_i)
            if term_i or trunc_i:
                ends += 1
                assert np.array_equal(infos[i].pop("terminal_observation"), obs_i)
                obs_i, info_reset = env.reset()
                assert reset_infos[i] == info_reset
            assert infos[i] == info_i
            assert np.array_equal(obs[i], obs_i)
        assert set(reset_infos) == set(np.flatnonzero(terminated | truncated).tolist())
    assert ends >= N_ENVS * 2

    next_step = gym.make_vec(env_id, 1, vectorization_mode="vector_entry_point", **kwargs)
    next_step.reset(seed=0)
    with pytest.raises(RuntimeError, match="needs autoreset_mode=SAME_STEP"):
        next_step.unwrapped.step_with_info_dicts(vector_actions(next_step.action_space, rng))


# -- call, get_attr, set_attr ----------------------------------------------------------------

#: one id per engine: the batched EKF kernel, the member threads, the batched maze
ENGINE_IDS = ["ActiveLoc/LandmarkEKF-v0", "ActiveLoc/GridMarkov-v0", "ActiveLoc/Maze-v0"]
#: the member attributes compared with SyncVectorEnv's sub-envs by value
PLAIN_ATTRIBUTES = ("spec", "config", "metadata", "render_mode", "observation_space",
                    "action_space")


def rendering_pair(env_id: str) -> tuple[gym.vector.VectorEnv, gym.vector.VectorEnv]:
    """(native, SyncVectorEnv) with every sub-env rendering."""
    native = gym.make_vec(env_id, N_ENVS, vectorization_mode="vector_entry_point",
                          render_mode="rgb_array", render_envs=N_ENVS, max_episode_steps=LIMIT)
    sync = gym.make_vec(env_id, N_ENVS, vectorization_mode="sync", render_mode="rgb_array",
                        max_episode_steps=LIMIT)
    return native, sync


def assert_same_generators(native: Any, sync: Any) -> None:
    states = [g.bit_generator.state for g in native.get_attr("np_random")]
    assert states == [g.bit_generator.state for g in sync.get_attr("np_random")]


@pytest.mark.parametrize("env_id", ENGINE_IDS)
def test_get_attr_and_call_are_sync_vector_envs(env_id: str) -> None:
    """Every member attribute, the Generators and seeds, and the frames of call("render")
    equal SyncVectorEnv's sub-envs', before and after stepping."""
    native, sync = rendering_pair(env_id)
    for name in PLAIN_ATTRIBUTES:
        values = native.get_attr(name)
        assert isinstance(values, tuple) and len(values) == N_ENVS, name
        assert values == sync.get_attr(name), name
        assert native.call(name) == values, name
    assert native.get_attr("spec")[0].max_episode_steps == LIMIT
    assert_same(native.reset(seed=4), sync.reset(seed=4))
    assert native.get_attr("np_random_seed") == sync.get_attr("np_random_seed") == (4, 5, 6)
    rng = np.random.default_rng(4)
    for _ in range(LIMIT + 1):  # through an autoreset
        actions = vector_actions(native.action_space, rng)
        assert_same(native.step(actions), sync.step(actions))
    assert_same_generators(native, sync)
    frames, reference = native.call("render"), sync.call("render")
    assert isinstance(frames, tuple) and len(frames) == N_ENVS
    for frame, expected in zip(frames, reference, strict=True):
        assert frame.dtype == np.uint8
        np.testing.assert_array_equal(frame, expected)
    np.testing.assert_array_equal(native.get_attr("render")[1], frames[1])  # as SyncVectorEnv


@pytest.mark.parametrize("env_id", ENGINE_IDS)
def test_a_sub_env_spec_makes_its_single_env(env_id: str) -> None:
    native = gym.make_vec(env_id, 2, vectorization_mode="vector_entry_point", workers=1,
                          autoreset_mode=AutoresetMode.SAME_STEP)
    obs, _ = native.reset(seed=8)
    for b, spec in enumerate(native.get_attr("spec")):
        assert not set(spec.kwargs) & {"num_envs", "workers", "autoreset_mode"}
        single = gym.make(spec)
        assert single.spec == spec
        np.testing.assert_array_equal(single.reset(seed=8 + b)[0], obs[b])
    assert ActiveLocalizationVectorEnv(2).get_attr("spec") == (None, None)  # not made by id


def test_call_render_past_render_envs_and_without_a_render_mode() -> None:
    native = gym.make_vec("ActiveLoc/LandmarkEKF-v0", N_ENVS,
                          vectorization_mode="vector_entry_point", render_mode="rgb_array")
    assert native.get_attr("render_mode") == ("rgb_array", None, None)
    with pytest.raises(RuntimeError, match="reset"):
        native.call("render")
    native.reset(seed=0)
    frame, *rest = native.call("render")
    np.testing.assert_array_equal(frame, native.render())  # render_envs=1: the first frame
    assert rest == [None, None]
    with pytest.raises(TypeError, match="no arguments"):
        native.call("render", "human")
    plain = gym.make_vec("ActiveLoc/LandmarkEKF-v0", 2, vectorization_mode="vector_entry_point")
    plain.reset(seed=0)
    with pytest.warns(UserWarning, match="render_mode"):
        assert plain.call("render") == (None, None)


@pytest.mark.parametrize("env_id", ENGINE_IDS)
def test_set_attr_np_random_is_sync_vector_envs(env_id: str) -> None:
    """Generators set per sub-env drive its steps and autoresets, as in SyncVectorEnv."""
    native, sync = make_pair(env_id, AutoresetMode.NEXT_STEP)
    assert_same(native.reset(seed=1), sync.reset(seed=1))
    for env in (native, sync):
        env.set_attr("np_random", [np.random.default_rng(100 + b) for b in range(N_ENVS)])
        assert env.get_attr("np_random_seed") == (-1,) * N_ENVS
    rng = np.random.default_rng(1)
    for _ in range(2 * LIMIT):
        actions = vector_actions(native.action_space, rng)
        assert_same(native.step(actions), sync.step(actions))
    assert_same_generators(native, sync)
    reseeded = native.reset(seed=2)  # a seed replaces the set Generators
    assert native.get_attr("np_random_seed") == (2, 3, 4)
    assert_same(reseeded, sync.reset(seed=2))


def test_set_attr_refuses_what_cannot_be_set_per_sub_env() -> None:
    native = gym.make_vec("ActiveLoc/LandmarkEKF-v0", 2, vectorization_mode="vector_entry_point")
    native.reset(seed=0)
    before = [g.bit_generator.state for g in native.get_attr("np_random")]
    for name in PLAIN_ATTRIBUTES:
        with pytest.raises(AttributeError, match=rf"set_attr\('{name}'\).*fixed when"):
            native.set_attr(name, [None, None])
    with pytest.raises(AttributeError, match=r"np_random_seed.*read-only"):
        native.set_attr("np_random_seed", 3)
    with pytest.raises(AttributeError, match=r"'render'.*method"):
        native.set_attr("render", None)
    with pytest.raises(AttributeError, match="no attribute 'speed'"):
        native.set_attr("speed", 1.0)
    with pytest.raises(ValueError, match="`3` values for 2 environments"):
        native.set_attr("np_random", [np.random.default_rng(i) for i in range(3)])
    with pytest.raises(ValueError, match="Generator of its own"):
        native.set_attr("np_random", np.random.default_rng(0))  # one for all: shared
    with pytest.raises(TypeError, match=r"sub-env 1 needs a numpy\.random\.Generator, got int"):
        native.set_attr("np_random", [np.random.default_rng(0), 7])
    assert [g.bit_generator.state for g in native.get_attr("np_random")] == before


def test_unknown_names_and_vector_methods_are_named() -> None:
    native = gym.make_vec("ActiveLoc/GridMarkov-v0", 2, vectorization_mode="vector_entry_point")
    for call in (native.get_attr, native.call):
        with pytest.raises(AttributeError, match="no attribute 'planner_view'"):
            call("planner_view")
    for name in ("reset", "step", "close"):
        with pytest.raises(AttributeError, match=rf"no {name}\(\) of their own"):
            native.call(name)
    with pytest.raises(AttributeError, match="no attribute 'walls'"):
        native.get_attr("walls")  # a maze env's attribute is no other id's


@pytest.mark.parametrize("env_id", ENGINE_IDS)
def test_the_batched_info_is_flat_arrays_in_the_single_envs_dtypes(env_id: str) -> None:
    """No nested dict: every entry is an array (n,) of float64, int64 or bool, the dtype of
    the single env's value, and the flat reward terms hold the single env's reward_terms."""
    native, sync = make_pair(env_id, AutoresetMode.SAME_STEP)
    single = gym.make(env_id)
    _, single_info = single.reset(seed=0)
    native.reset(seed=0)
    sync.reset(seed=0)
    rng = np.random.default_rng(0)
    for _ in range(LIMIT):
        actions = vector_actions(native.action_space, rng)
        *_, info = native.step(actions)
        sync_info = sync.step(actions)[4]
        for key, value in info.items():
            if key in ("final_obs", "final_info") or key.startswith("_"):
                continue
            assert isinstance(value, np.ndarray) and value.shape == (N_ENVS,), key
            assert value.dtype in (np.float64, np.int64, np.bool_), key
            assert value.dtype == np.asarray(single_info[key]).dtype, key
        for term, values in sync_info["reward_terms"].items():
            if not term.startswith("_"):
                np.testing.assert_array_equal(info[f"reward_{term}"], values)
