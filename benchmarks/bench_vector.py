"""Env-steps per second of the native vector env, against CartPole-v1 and SyncVectorEnv.

* ``LandmarkEKF-v0`` through ``make_vec(..., vectorization_mode="vector_entry_point")`` at
  n = 1, 16, 256 and 1024, in env-steps per second (n per call), as a ratio to a single
  CartPole-v1 env's steps per second timed just before each size.
* Each MCL id at n = 16: the native vector env against gymnasium's ``SyncVectorEnv`` of the
  same id, both with NEXT_STEP autoreset, over the same episodes (seeds, actions and number
  of calls), the three variants timed in turn within each repeat.

Both with one worker thread and with two (the kernels release the GIL; the batched EKF splits
the batch from n = 128 on), to show what the second core adds.

Actions are drawn up front from a seeded Generator, autoreset is part of the timed loop, and
each figure is the best of ``--repeats`` timings. It measures; it asserts nothing.

    python benchmarks/bench_vector.py [--repeats 3] [--budget 4] [--json out.json]
"""

from __future__ import annotations

import argparse
import json
import platform
import time
from typing import Any

import gymnasium as gym
import numpy as np
from bench_steps import steps_per_second  # this folder: the single-env timing, CartPole's too

import active_loc  # noqa: F401  (registers the ids)

EKF_ID = "ActiveLoc/LandmarkEKF-v0"
EKF_SIZES = (1, 16, 256, 1024)
MCL_IDS = (
    "ActiveLoc/LandmarkMCL-v0",
    "ActiveLoc/GridMCL-v0",
    "ActiveLoc/GridMCLKidnapped-v0",
    "ActiveLoc/GridMCLDynamic-v0",
)
MCL_N = 16


def batch_actions(space: gym.Space, calls: int, seed: int = 0) -> list[Any]:
    """``calls`` batches of actions of a vector action space, drawn up front."""
    rng = np.random.default_rng(seed)
    if isinstance(space, gym.spaces.MultiDiscrete):
        return list(rng.integers(0, space.nvec, (calls, *space.shape)))
    assert isinstance(space, gym.spaces.Box)
    return list(rng.uniform(space.low, space.high, (calls, *space.shape)).astype(space.dtype))


def warm_up(envs: gym.vector.VectorEnv) -> None:
    """Reset and step a few calls: numba compilation, caches."""
    envs.reset(seed=0)
    for actions in batch_actions(envs.action_space, 20):
        envs.step(actions)


def calls_within(envs: gym.vector.VectorEnv, budget_s: float) -> int:
    """How many calls fit in ``budget_s`` (from a probe of 20 calls; at least 20)."""
    probe = batch_actions(envs.action_space, 20)
    start = time.perf_counter()
    for actions in probe:
        envs.step(actions)
    return max(20, int(budget_s * len(probe) / (time.perf_counter() - start)))


def timed_run(envs: gym.vector.VectorEnv, actions: list[Any]) -> float:
    """Seconds to step ``actions`` from ``reset(seed=1)`` (autoresets included)."""
    envs.reset(seed=1)
    start = time.perf_counter()
    for batch in actions:
        envs.step(batch)
    return time.perf_counter() - start


def vector_rate(envs: gym.vector.VectorEnv, repeats: int, budget_s: float) -> float:
    """Best-of-``repeats`` env-steps per second (``num_envs`` per call) of a vector env, each
    timing as many calls as fit in ``budget_s``."""
    warm_up(envs)
    actions = batch_actions(envs.action_space, calls_within(envs, budget_s), seed=1)
    best = min(timed_run(envs, actions) for _ in range(repeats))
    envs.close()
    return len(actions) * envs.num_envs / best


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeats", type=int, default=3)
    parser.add_argument("--budget", type=float, default=4.0, help="seconds per timing")
    parser.add_argument("--json", default=None, help="also write the figures to this file")
    parser.add_argument("--part", choices=("all", "ekf", "mcl"), default="all",
                        help="time only the EKF sizes or only the MCL ids")
    args = parser.parse_args()

    print(f"machine: {platform.processor() or platform.machine()}, "
          f"python {platform.python_version()}, best of {args.repeats}\n")
    results: dict[str, Any] = {}
    if args.part != "mcl":
        results.update(ekf_rates(args.repeats, args.budget))
    if args.part != "ekf":
        results.update(mcl_rates(args.repeats, args.budget))
    if args.json:
        with open(args.json, "w") as f:
            json.dump(results, f, indent=2)


def ekf_rates(repeats: int, budget: float) -> dict[str, float]:
    """The EKF id's native vector env at every size, 1 and 2 threads, each size against a
    CartPole-v1 baseline timed just before it (the machine's speed drifts over minutes)."""
    results = {}
    print(f"{EKF_ID} native vector env, env-steps/s (x CartPole-v1 timed just before)")
    print(f"{'n':>6} {'CartPole-v1':>12} {'1 thread':>18} {'2 threads':>18}")
    for n in EKF_SIZES:
        baseline = steps_per_second("CartPole-v1", 50_000, repeats)
        results[f"CartPole-v1 before n={n}"] = baseline
        cells = []
        for workers in (1, 2):
            envs = gym.make_vec(EKF_ID, n, vectorization_mode="vector_entry_point",
                                workers=workers)
            rate = vector_rate(envs, repeats, budget)
            results[f"{EKF_ID} native n={n} workers={workers}"] = rate
            cells.append(f"{rate:>9.0f} ({rate / baseline:>5.2f})")
        print(f"{n:>6} {baseline:>12.0f} {cells[0]:>18} {cells[1]:>18}")
    return results


def mcl_rates(repeats: int, budget: float) -> dict[str, dict[str, float]]:
    """Each MCL id at n = MCL_N: SyncVectorEnv against the native env (printed as well)."""
    results = {}
    print(f"\nMCL ids at n = {MCL_N}, env-steps/s: native against SyncVectorEnv")
    print(f"{'env':<32} {'sync':>7} {'native 1':>9} {'native 2':>9} {'2 / sync':>9}")
    for env_id in MCL_IDS:
        variants = {"sync": gym.make_vec(env_id, MCL_N, vectorization_mode="sync")}
        for workers in (1, 2):
            variants[f"native {workers}"] = gym.make_vec(
                env_id, MCL_N, vectorization_mode="vector_entry_point", workers=workers)
        for envs in variants.values():
            warm_up(envs)
        # the same episodes and calls for all three (a particle step costs 100 times more at
        # an episode's start, with 100000 particles, than once KLD sampling has shrunk the
        # set), and the three timed in turn within each repeat, so that a machine slower for a
        # while slows all three
        actions = batch_actions(variants["sync"].action_space,
                                calls_within(variants["sync"], budget), seed=1)
        best = {name: float("inf") for name in variants}
        for _ in range(repeats):
            for name, envs in variants.items():
                best[name] = min(best[name], timed_run(envs, actions))
        for envs in variants.values():
            envs.close()
        rates = {name: len(actions) * MCL_N / seconds for name, seconds in best.items()}
        results[f"{env_id} n={MCL_N}"] = rates
        print(f"{env_id:<32} {rates['sync']:>7.0f} {rates['native 1']:>9.0f} "
              f"{rates['native 2']:>9.0f} {rates['native 2'] / rates['sync']:>9.2f}")
    return results


if __name__ == "__main__":
    main()
