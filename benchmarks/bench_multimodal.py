"""The multimodal ids against the code before the batch-first simulator, in one run.

For every MCL, grid and maze id this times two versions of the package in turns, each in a
subprocess with its source first on ``sys.path``:

* ``base``: the commit before the simulator work (:data:`BASE_COMMIT`), checked out as a git
  worktree in the temporary directory (made once, reused);
* ``head``: this checkout.

Each figure is the best of ``--repeats`` timings of the same work (the same seeds and the same
random actions, drawn up front), and the two versions alternate, so that the machine's drift
over minutes (about 25% on a shared 2-core host) lands on both. Reported:

* ``single``: one ``gymnasium.make(id)`` env, ``--steps`` random actions, the episodes reset
  inside the timed loop (the first with seed 0);
* ``native n``: ``gymnasium.make_vec(id, n, vectorization_mode="vector_entry_point")``,
  NEXT_STEP autoreset, env-steps per second (n per call), and (head only) gymnasium's
  ``SyncVectorEnv`` on the same seeds and actions: n single envs stepped in turn, the single
  env's rate on the vector env's workload (the first steps of n episodes at once, which
  differs from one env's run of consecutive episodes);
* ``single, the steps of native n``: one env doing exactly the native env's steps, one
  episode after another (:func:`single_same_work_rate`), and the native env's ratio to it:
  its speed-up over a single env on the same work;
* ``reset``: milliseconds per ``reset()`` of a single env, with a new map every episode and
  (head only, ``map_pool``) with a pool of maps;
* ``split``: where a head step's time goes (:func:`step_split`);
* ``glue``: the Python time per sub-env step of the head's native vector env at n = 16
  (:func:`vector_glue`);
* ``tracking``: LandmarkMCL-v0 tracking a converged belief of about 500 particles, with the
  default maximum of 100000 and with a maximum of 1000 (:func:`tracking_rate`);
* ``ppo``: PPO through ``train.py`` on the marked_rooms arena of docs/results.md (8 native
  envs, ``--ppo-minutes`` each): the env's share of the wall time and its steps per second,
  and (head only) the same with ``map_pool=16``.

It measures and asserts nothing; the targets are printed beside the figures.

    python benchmarks/bench_multimodal.py [--repeats 3] [--ids LandmarkMCL-v0,...]
        [--parts single,native,reset,split,glue,tracking,ppo] [--base REF] [--head REF]
        [--json out.json]
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path
from typing import Any

ROOT = Path(__file__).resolve().parents[1]
#: the last commit before the batch-first simulator (draws, cores, map pool)
BASE_COMMIT = "dd08010"
#: the marked_rooms arena of docs/results.md (GridMCL-v0 with the beam model's range table)
ARENA = {"map": "marked_rooms", "action_type": "discrete", "lidar_model": "beam",
         "lidar_range_bins": 360, "min_particles": 5000}
IDS = (
    "ActiveLoc/LandmarkMCL-v0",
    "ActiveLoc/GridMCL-v0",
    "ActiveLoc/GridMCLKidnapped-v0",
    "ActiveLoc/GridMCLDynamic-v0",
    "ActiveLoc/GridMarkov-v0",
    "ActiveLoc/Maze-v0",
)
TARGETS = {
    "ActiveLoc/LandmarkMCL-v0": "single >= 5x base",
    "ActiveLoc/GridMCL-v0": "single >= 2x base",
    "ActiveLoc/GridMarkov-v0": "single >= 2x base",
    "ActiveLoc/Maze-v0": "native n=64 >= 3x SyncVectorEnv",
    "ActiveLoc/LandmarkMCL-v0 tracking": "max 100000 costs <= 1.4x max 1000 (~500 active)",
    "native": "every multimodal id's native n=16 >= 1.8x its single env",
    "glue": "Python time per sub-env step <= 20 us",
}


# --- worker: runs inside one version's interpreter --------------------------------------------


def _actions(space: Any, count: int, seed: int) -> list:
    import gymnasium as gym
    import numpy as np

    rng = np.random.default_rng(seed)
    if isinstance(space, gym.spaces.Discrete):
        return rng.integers(space.n, size=count).tolist()
    return list(rng.uniform(space.low, space.high, (count, *space.shape)).astype(space.dtype))


def _batched_actions(space: Any, calls: int, n: int) -> Any:
    """``(calls, n, *shape)`` random actions of a single env's ``space``: call t's action of
    sub-env i at ``[t, i]`` (the same for the vector env and one env doing its steps)."""
    import numpy as np

    return np.array(_actions(space, calls * n, 1)).reshape(calls, n, *space.shape)


def _run_episodes(env: Any, seed: int, actions: list) -> float:
    """Seconds to step ``env`` (reset with ``seed``) through ``actions``, resetting ended
    episodes inside the timed loop."""
    env.reset(seed=seed)
    start = time.perf_counter()
    for action in actions:
        _, _, terminated, truncated, _ = env.step(action)
        if terminated or truncated:
            env.reset()
    return time.perf_counter() - start


def single_rate(env_id: str, steps: int, repeats: int, kwargs: dict) -> dict:
    """Best-of-``repeats`` steps per second of one env over ``steps`` random actions."""
    import gymnasium as gym

    env = gym.make(env_id, **kwargs)
    actions = _actions(env.action_space, steps, 0)

    _run_episodes(env, 100, actions[: min(20, steps)])  # warm-up: kernels compiled or loaded
    best = min(_run_episodes(env, 0, actions) for _ in range(repeats))
    env.close()
    return {"steps_per_s": steps / best}


def vector_rate(env_id: str, n: int, calls: int, repeats: int, kwargs: dict,
                sync: bool = False) -> dict:
    """Best-of-``repeats`` env-steps per second of the native vector env (or, with ``sync``,
    gymnasium's SyncVectorEnv) over ``calls`` batched random steps."""
    import gymnasium as gym

    mode = "sync" if sync else "vector_entry_point"
    envs = gym.make_vec(env_id, n, vectorization_mode=mode, **kwargs)
    actions = _batched_actions(envs.single_action_space, calls, n)

    def run(seed: int, count: int) -> float:
        envs.reset(seed=seed)
        start = time.perf_counter()
        for t in range(count):
            envs.step(actions[t])
        return time.perf_counter() - start

    run(100, min(2, calls))
    best = min(run(0, calls) for _ in range(repeats))
    envs.close()
    return {"steps_per_s": calls * n / best}


def single_same_work_rate(env_id: str, n: int, calls: int, repeats: int, kwargs: dict
                          ) -> dict:
    """Best-of-``repeats`` steps per second of one env doing what :func:`vector_rate` has its
    ``n`` sub-envs do: episode ``i`` reset with seed ``i``, then sub-env ``i``'s ``calls``
    actions, an ended episode reset in place of the next action (gymnasium's next-step
    autoreset). The native env's speed-up over a single env is the ratio of the two: the
    same steps, where :func:`single_rate`'s long run spends more of them on converged
    beliefs than the first ``calls`` steps of n episodes do."""
    import gymnasium as gym

    env = gym.make(env_id, **kwargs)
    actions = _batched_actions(env.action_space, calls, n)

    def run(count: int) -> float:
        start = time.perf_counter()
        for i in range(n):
            env.reset(seed=i)
            ended = False
            for t in range(count):
                if ended:
                    env.reset()
                    ended = False
                    continue
                action = actions[t, i]
                _, _, terminated, truncated, _ = env.step(
                    int(action) if action.ndim == 0 else action)
                ended = terminated or truncated
        return time.perf_counter() - start

    run(min(2, calls))
    best = min(run(calls) for _ in range(repeats))
    env.close()
    return {"steps_per_s": calls * n / best}


#: LandmarkMCL-v0 tracking: a Gaussian start the filter converges from in a few steps, KLD
#: sampling then holding it at about min_particles = 500 particles
TRACKING = {"initial_belief": "gaussian", "terminate_when_localized": False}


def tracking_rate(n_particles: int, steps: int, warm_up: int, repeats: int) -> dict:
    """Best-of-``repeats`` steps per second of LandmarkMCL-v0 tracking a converged belief
    with a maximum of ``n_particles``: ``steps`` random steps timed after ``warm_up`` untimed
    ones from the reset; ``particles``: the active count at the end."""
    import gymnasium as gym

    env = gym.make("ActiveLoc/LandmarkMCL-v0", n_particles=n_particles, **TRACKING)
    actions = _actions(env.action_space, warm_up + steps, 2)
    best = float("inf")
    for _ in range(repeats + 1):  # the first run compiles or loads the kernels
        env.reset(seed=0)
        for action in actions[:warm_up]:
            env.step(action)
        start = time.perf_counter()
        for action in actions[warm_up:]:
            env.step(action)
        best = min(best, time.perf_counter() - start)
    particles = env.unwrapped.core.belief.n_active
    env.close()
    return {"steps_per_s": steps / best, "particles": particles}


def reset_cost(env_id: str, resets: int, repeats: int, kwargs: dict) -> dict:
    """Best-of-``repeats`` milliseconds per ``reset()`` (each a new episode)."""
    import gymnasium as gym

    env = gym.make(env_id, **kwargs)
    env.reset(seed=100)
    best = float("inf")
    for _ in range(repeats):
        env.reset(seed=0)
        start = time.perf_counter()
        for _ in range(resets):
            env.reset()
        best = min(best, (time.perf_counter() - start) / resets)
    env.close()
    return {"ms": best * 1e3}


#: which functions' own time counts as which part of a step (by function name)
SPLIT_PARTS = {
    "motion": ("move_particles", "sample_motion", "move_on_grid", "move_within_bounds",
               "cast_ray", "translate_kernel", "turn_kernel", "predict_arrays",
               "translation_kernel_arrays", "fractional_kernels"),
    "likelihood": ("landmark_log_likelihood_kernel", "likelihood_field_table_log_likelihood",
                   "likelihood_field_skip_log_likelihood", "lattice_field_kernel",
                   "beam_model_log_likelihood", "log_likelihood", "measure",
                   "measure_landmarks", "cast_rays", "expected_ranges", "add_log_likelihood",
                   "update_kernel", "update_log_kernel", "normalize_log_weights"),
    "resampling": ("kld_resample", "resample_particles", "systematic_resample",
                   "stratified_resample", "stream_free_poses"),
    "metrics and observation": (
        "_summary_blocks", "_covariance_blocks", "binned_entropy", "histogram_entropy",
        "weighted_mean", "weighted_covariance", "effective_sample_size", "mass_histogram",
        "moments_kernel", "entropy_kernel", "write_belief_header", "write_landmark_slots",
        "slogdet", "eigvalsh", "belief_metrics", "bincount", "marginal_xy",
        "depth_kernel", "observation_kernel"),
}


class TimedGenerator:
    """A stand-in for the env's Generator that adds the time of every draw to ``seconds``
    (cProfile does not see the Generator's own methods)."""

    def __init__(self, rng: Any, clock: list[float] | None = None) -> None:
        self._rng = rng
        self._clock = clock if clock is not None else [0.0]

    @property
    def seconds(self) -> float:
        return self._clock[0]

    @property
    def bit_generator(self) -> Any:
        return TimedGenerator(self._rng.bit_generator, self._clock)

    def __getattr__(self, name: str) -> Any:
        value = getattr(self._rng, name)
        if not callable(value):
            return value
        clock = self._clock

        def timed(*args: Any, **kwargs: Any) -> Any:
            start = time.perf_counter()
            try:
                return value(*args, **kwargs)
            finally:
                clock[0] += time.perf_counter() - start

        return timed


def _own_seconds_by_part(profiler: Any) -> dict[str, float]:
    """The own time (s) of the profiled functions of each part of :data:`SPLIT_PARTS`."""
    import pstats

    own: dict[str, float] = dict.fromkeys(SPLIT_PARTS, 0.0)
    for (_, _, name), (_, _, tottime, _, _) in pstats.Stats(profiler).stats.items():  # type: ignore[attr-defined]
        # "<method 'random' of 'numpy.random._generator.Generator' objects>", or a plain name
        short = name.split("'")[1] if name.startswith("<") and "'" in name else name
        for part, names in SPLIT_PARTS.items():
            if short in names:
                own[part] += tottime
    return own


def step_split(env_id: str, steps: int, kwargs: dict) -> dict:
    """Microseconds per step in the draws (:class:`TimedGenerator`), in each part of
    :data:`SPLIT_PARTS` (the functions' own time under cProfile; the kernels are single calls,
    so the profiler hardly inflates them), and the rest of the profiled run ("Python glue",
    which the profiler does inflate: an upper bound); ``step`` is the wall time per step of
    the same ``steps`` random steps (resets included) without the profiler."""
    import cProfile

    import gymnasium as gym

    env = gym.make(env_id, **kwargs)
    actions = _actions(env.action_space, steps, 0)

    _run_episodes(env, 0, actions)  # warm-up
    wall = min(_run_episodes(env, 0, actions) for _ in range(2))
    profiler = cProfile.Profile()
    env.reset(seed=0)
    timed = TimedGenerator(env.unwrapped.np_random)
    env.unwrapped._np_random = timed  # the same Generator: the same episode as the timed runs
    start = time.perf_counter()
    profiler.enable()
    for action in actions:
        _, _, terminated, truncated, _ = env.step(action)
        if terminated or truncated:
            env.reset()
    profiler.disable()
    profiled = time.perf_counter() - start
    own = _own_seconds_by_part(profiler)
    env.close()
    split = {"draws": 1e6 * timed.seconds / steps}
    split.update({part: 1e6 * t / steps for part, t in own.items()})
    # what the parts leave of the profiled run: Python, inflated by the profiler
    split["Python glue (profiled)"] = max(0.0, 1e6 * profiled / steps - sum(split.values()))
    split["step"] = 1e6 * wall / steps
    split["step (profiled)"] = 1e6 * profiled / steps
    return {"us_per_step": split}


def vector_glue(env_id: str, n: int, calls: int, kwargs: dict) -> dict:
    """Microseconds of Python per sub-env step in the native vector env of ``n`` sub-envs
    on one worker (so that the profiler sees every call): the profiled run of ``calls``
    batched random steps less the draws (:class:`TimedGenerator`) and the parts of
    :data:`SPLIT_PARTS`, divided by ``calls * n`` (an upper bound, as in :func:`step_split`);
    ``sub-env step`` is the unprofiled wall time of the same run per sub-env step."""
    import cProfile

    import gymnasium as gym
    import numpy as np

    envs = gym.make_vec(env_id, n, vectorization_mode="vector_entry_point", workers=1, **kwargs)
    single = envs.single_action_space
    actions = np.array(_actions(single, calls * n, 1)).reshape(calls, n, *single.shape)

    def run(profiler: Any = None) -> float:
        envs.reset(seed=0)
        start = time.perf_counter()
        if profiler is not None:
            profiler.enable()
        for t in range(calls):
            envs.step(actions[t])
        if profiler is not None:
            profiler.disable()
        return time.perf_counter() - start

    run()  # warm-up
    wall = run()
    envs.reset(seed=0)
    clock = [0.0]
    engine = envs.unwrapped.engine
    if hasattr(engine, "rngs"):  # one core: the engine holds the Generators
        engine.rngs = [TimedGenerator(rng, clock) for rng in engine.rngs]
    else:  # single envs stepped in turn
        for env in engine.envs:
            env._np_random = TimedGenerator(env.np_random, clock)
    profiler = cProfile.Profile()
    start = time.perf_counter()
    profiler.enable()
    for t in range(calls):
        envs.step(actions[t])
    profiler.disable()
    profiled = time.perf_counter() - start
    inside = sum(_own_seconds_by_part(profiler).values())
    envs.close()
    steps = calls * n
    glue = max(0.0, profiled - inside - clock[0])
    return {"us_per_sub_env_step": {"Python (profiled)": 1e6 * glue / steps,
                                    "sub-env step": 1e6 * wall / steps}}


def ppo_split(env_kwargs: dict, minutes: float, n_envs: int, vec_env: str) -> dict:
    """PPO through ``train.py`` on GridMCL-v0 with ``env_kwargs`` for ``minutes``: the env's
    share of the wall time and its steps per second (``config.json``'s ``result``)."""
    import tempfile

    from active_loc.train import TrainArgs, train

    with tempfile.TemporaryDirectory() as tmp:
        out = Path(tmp) / "run"
        train(TrainArgs(
            env="ActiveLoc/GridMCL-v0", env_kwargs=json.dumps(env_kwargs), algo="ppo",
            total_steps=10**9, n_envs=n_envs, vec_env=vec_env, n_steps=256, eval_freq=0,
            checkpoint_freq=0, time_limit_minutes=minutes, progress_bar=False, out=out,
        ))
        result = json.loads((out / "config.json").read_text())["result"]
    split = result["env_time"]
    return {"timesteps": result["timesteps"], "env_share": split["env_share"],
            "env_steps_per_s": split["env_steps_per_s"],
            "steps_per_s": result["timesteps"] / result["wall_time_s"]}


def worker(request: dict) -> dict:
    import active_loc  # noqa: F401  (registers the ids)

    kind = request.pop("kind")
    return {"single": single_rate, "single_same_work": single_same_work_rate,
            "vector": vector_rate, "reset": reset_cost,
            "split": step_split, "glue": vector_glue, "ppo": ppo_split,
            "tracking": tracking_rate}[kind](**request)


# --- driver ---------------------------------------------------------------------------------


def checkout(ref: str) -> Path:
    """A worktree of commit ``ref`` in the temporary directory (made on first use)."""
    sha = subprocess.run(["git", "-C", str(ROOT), "rev-parse", "--short", ref], check=True,
                         capture_output=True, text=True).stdout.strip()
    path = Path(tempfile.gettempdir()) / f"active_loc-{sha}"
    if not (path / "active_loc").is_dir():
        subprocess.run(["git", "-C", str(ROOT), "worktree", "prune"], check=True)
        subprocess.run(["git", "-C", str(ROOT), "worktree", "add", "--detach", "--force",
                        str(path), sha], check=True, capture_output=True)
    return path


def measure(source: Path, request: dict) -> dict:
    """Run one worker request with ``source`` first on the path; its result."""
    env = {**os.environ, "PYTHONPATH": str(source), "OMP_NUM_THREADS": "1"}
    code = ("import json, sys; sys.path.insert(0, sys.argv[1]); "
            "sys.path.insert(0, sys.argv[2]); import bench_multimodal as b; "
            "print(json.dumps(b.worker(json.loads(sys.argv[3]))))")
    out = subprocess.run(
        [sys.executable, "-c", code, str(source), str(Path(__file__).parent),
         json.dumps(request)], env=env, capture_output=True, text=True, cwd=str(source),
    )
    if out.returncode != 0:
        return {"error": out.stderr.strip().splitlines()[-1] if out.stderr else "failed"}
    return json.loads(out.stdout.strip().splitlines()[-1])


def _steps_for(env_id: str, args: argparse.Namespace) -> int:
    return args.maze_steps if env_id.endswith("Maze-v0") else args.steps


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--repeats", type=int, default=3)
    parser.add_argument("--steps", type=int, default=300, help="single-env steps, MCL and grid")
    parser.add_argument("--maze-steps", type=int, default=20000)
    parser.add_argument("--calls", type=int, default=12, help="vector steps, MCL and grid")
    parser.add_argument("--maze-calls", type=int, default=300)
    parser.add_argument("--resets", type=int, default=5)
    parser.add_argument("--ids", default=",".join(i.split("/")[1] for i in IDS))
    parser.add_argument("--parts", default="single,native,reset,split,glue,tracking,ppo")
    parser.add_argument("--ppo-minutes", type=float, default=3.0)
    parser.add_argument("--base", default=BASE_COMMIT,
                        help="the commit to compare with (default: the one before the issue)")
    parser.add_argument("--head", default=None,
                        help="time this commit (a worktree) instead of the checkout's files")
    parser.add_argument("--json", default=None)
    args = parser.parse_args()
    ids = [name if "/" in name else f"ActiveLoc/{name}" for name in args.ids.split(",")]
    parts = args.parts.split(",")
    head = ROOT if args.head is None else checkout(args.head)
    versions = {"base": checkout(args.base), "head": head}
    results: list[dict] = []

    def report(row: dict) -> None:
        results.append(row)
        print(json.dumps(row), flush=True)
        if args.json:  # written as the rows come: an interrupted run keeps what it measured
            Path(args.json).parent.mkdir(parents=True, exist_ok=True)
            Path(args.json).write_text(json.dumps(results, indent=1))

    def compare(env_id: str, label: str, request: dict, head_only: dict | None = None
                ) -> dict:
        row: dict[str, Any] = {"id": env_id, "case": label}
        for name, source in versions.items():
            row[name] = measure(source, dict(request))
        if head_only is not None:
            row["head_variant"] = measure(head, dict(head_only))
        old, new = row["base"], row["head"]
        key = "steps_per_s" if "steps_per_s" in new else "ms"
        if key in old and key in new:
            row["ratio"] = new[key] / old[key] if key == "steps_per_s" else old[key] / new[key]
        report(row)
        return row

    for env_id in ids:
        maze = env_id.endswith("Maze-v0")
        if "single" in parts:
            compare(env_id, "single", {"kind": "single", "env_id": env_id,
                                       "steps": _steps_for(env_id, args),
                                       "repeats": args.repeats, "kwargs": {}})
        if "native" in parts:
            for n in (16, 64):
                calls = max(2, (args.maze_calls if maze else args.calls) * 16 // n)
                request = {"kind": "vector", "env_id": env_id, "n": n, "calls": calls,
                           "repeats": args.repeats, "kwargs": {}}
                native = compare(env_id, f"native n={n}", request, {**request, "sync": True})
                same = compare(env_id, f"single, the steps of native n={n}",
                               {**request, "kind": "single_same_work"})
                if "steps_per_s" in native["head"] and "steps_per_s" in same["head"]:
                    report({"id": env_id, "case": f"native n={n} / single, the same steps",
                            "head": native["head"]["steps_per_s"]
                            / same["head"]["steps_per_s"]})
        if "reset" in parts and not maze:
            request = {"kind": "reset", "env_id": env_id, "resets": args.resets,
                       "repeats": args.repeats, "kwargs": {}}
            compare(env_id, "reset", request,
                    {**request, "kwargs": {"map_pool": 8}})
        if "split" in parts:
            row = {"id": env_id, "case": "split",
                   "head": measure(head, {"kind": "split", "env_id": env_id,
                                          "steps": _steps_for(env_id, args) // 2,
                                          "kwargs": {}})}
            report(row)
        if "glue" in parts:
            calls = max(2, (args.maze_calls if maze else args.calls))
            report({"id": env_id, "case": "Python per sub-env step, native n=16",
                    "head": measure(head, {"kind": "glue", "env_id": env_id, "n": 16,
                                           "calls": calls, "kwargs": {}})})
    if "tracking" in parts:
        for n_particles in (100000, 1000):
            compare("ActiveLoc/LandmarkMCL-v0 tracking", f"max {n_particles} particles",
                    {"kind": "tracking", "n_particles": n_particles, "steps": 250,
                     "warm_up": 40, "repeats": args.repeats})
    if "ppo" in parts:
        request = {"kind": "ppo", "env_kwargs": ARENA, "minutes": args.ppo_minutes,
                   "n_envs": 8, "vec_env": "native"}
        compare("ActiveLoc/GridMCL-v0 arena", "ppo", request,
                {**request, "env_kwargs": {**ARENA, "map_pool": 16}})
    print("\ntargets:", json.dumps(TARGETS, indent=1))


if __name__ == "__main__":
    main()
