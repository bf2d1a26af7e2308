"""Steps per second of every env id through ``gymnasium.make``, as a ratio to CartPole-v1.

Each env runs the same number of steps with random actions drawn up front from a seeded
Generator (so sampling cost is not timed for either side), resetting when an episode ends;
resets are part of the timed loop. CartPole-v1 is measured in the same run, and each figure is
the best of ``--repeats`` timings to damp noise from other processes. It measures; it asserts
nothing.

    python benchmarks/bench_steps.py [--steps 50000] [--repeats 3] [--json out.json]
                                     [--only GridMarkov]
"""

from __future__ import annotations

import argparse
import json
import platform
import time

import gymnasium as gym
import numpy as np

import active_loc
from active_loc.envs.registration import OTHER_ENV_IDS


def random_actions(space: gym.Space, steps: int, seed: int = 0) -> list:
    """``steps`` actions of ``space`` drawn up front from a seeded Generator, so that sampling
    is not part of any timing."""
    rng = np.random.default_rng(seed)
    if isinstance(space, gym.spaces.Discrete):
        return list(rng.integers(space.n, size=steps).tolist())
    draws = rng.uniform(space.low, space.high, (steps, *space.shape))
    return list(draws.astype(space.dtype))


def steps_per_second(
    env_id: str, steps: int, repeats: int, budget_s: float = 5.0, **kwargs: object
) -> float:
    """Best-of-``repeats`` env steps per second of ``gymnasium.make(env_id, **kwargs)``.

    Each timing runs ``steps`` steps, or fewer when a slow env would take longer than
    ``budget_s`` seconds (the count is then set from a short probe), so that particle envs
    at a few milliseconds a step do not hold the run for minutes.
    """
    env = gym.make(env_id, **kwargs)
    actions = random_actions(env.action_space, steps)

    def run(batch: list) -> float:
        start = time.perf_counter()
        for action in batch:
            _, _, terminated, truncated, _ = env.step(action)
            if terminated or truncated:
                env.reset()
        return time.perf_counter() - start

    env.reset(seed=0)
    probe = min(200, steps)
    run(actions[:probe])  # warm-up: numba compilation, caches
    per_step = run(actions[:probe]) / probe
    count = max(probe, min(steps, int(budget_s / per_step)))
    best = float("inf")
    for _ in range(repeats):
        env.reset(seed=1)
        best = min(best, run(actions[:count]))
    env.close()
    return count / best


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--steps", type=int, default=50_000)
    parser.add_argument("--repeats", type=int, default=3)
    parser.add_argument("--json", default=None, help="also write the figures to this file")
    parser.add_argument(
        "--only", default=None,
        help="time only the cases whose label contains this text (CartPole-v1 always runs)",
    )
    args = parser.parse_args()

    cases: list[tuple[str, str, dict[str, object]]] = [("CartPole-v1", "CartPole-v1", {})]
    for env_id, _, _ in active_loc.ENV_IDS:
        cases.append((env_id, env_id, {}))
        cases.append((f"{env_id} discrete", env_id, {"action_type": "discrete"}))
    cases.append(
        ("ActiveLoc/Textbook-v0 filterpy", "ActiveLoc/Textbook-v0", {"ekf_backend": "filterpy"})
    )
    for env_id, _, _, _ in OTHER_ENV_IDS:
        cases.append((env_id, env_id, {}))
    if args.only:
        cases = [c for c in cases if c[0] == "CartPole-v1" or args.only in c[0]]

    machine = platform.processor() or platform.machine()
    print(f"machine: {machine}, python {platform.python_version()}")
    print(f"{args.steps} steps per timing, best of {args.repeats}\n")
    results: dict[str, dict[str, float]] = {}
    baseline = 0.0
    print(f"{'env':<40} {'steps/s':>10} {'x CartPole':>11}")
    for label, env_id, kwargs in cases:
        rate = steps_per_second(env_id, args.steps, args.repeats, **kwargs)
        if label == "CartPole-v1":
            baseline = rate
        results[label] = {"steps_per_second": rate, "ratio_to_cartpole": rate / baseline}
        print(f"{label:<40} {rate:>10.0f} {rate / baseline:>11.4f}")
    if args.json:
        with open(args.json, "w") as f:
            json.dump(results, f, indent=2)


if __name__ == "__main__":
    main()
