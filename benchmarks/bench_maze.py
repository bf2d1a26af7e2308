"""Maze-v0: steps per second against CartPole-v1, and the random policy's success rate.

Both envs run through ``gymnasium.make`` (with its default wrappers) on random actions drawn
up front from a seeded Generator, resetting when an episode ends; each figure is the best of
``--repeats`` timings. Then a uniformly random policy (a seeded Generator) runs one episode on
every maze of the fixed test sets ``maze_test_set(n, count, seed)``: n = 7 with L = 15 (the
setting of the Active Neural Localization paper's first table), and n = 15 with L = 20.
Success is the paper's: at the end of the episode the belief's maximum is 1 at the true pose.
It measures; it asserts nothing.

    python benchmarks/bench_maze.py [--steps 50000] [--repeats 3] [--count 1000] [--seed 0]
"""

from __future__ import annotations

import argparse
import math
import time

import gymnasium as gym
import numpy as np

import active_loc  # noqa: F401  (registers the ids)
from active_loc.maps.maze import maze_test_set


def steps_per_second(env_id: str, steps: int, repeats: int, **kwargs: object) -> float:
    """Best-of-``repeats`` steps per second of ``gymnasium.make(env_id, **kwargs)``."""
    env = gym.make(env_id, **kwargs)
    assert isinstance(env.action_space, gym.spaces.Discrete)
    actions = np.random.default_rng(0).integers(env.action_space.n, size=steps).tolist()
    env.reset(seed=0)
    for action in actions[:1000]:  # warm-up: numba caches, first maze
        if any(env.step(action)[2:4]):
            env.reset()
    best = math.inf
    for _ in range(repeats):
        env.reset(seed=1)
        start = time.perf_counter()
        for action in actions:
            _, _, terminated, truncated, _ = env.step(action)
            if terminated or truncated:
                env.reset()
        best = min(best, time.perf_counter() - start)
    env.close()
    return steps / best


def random_policy_success(size: int, length: int, count: int, seed: int) -> tuple[float, float]:
    """Success rate of a uniformly random policy over ``maze_test_set(size, count, seed)`` with
    episodes of ``length`` steps, and the seconds it took."""
    start = time.perf_counter()
    env = gym.make(
        "ActiveLoc/Maze-v0", size=size, episode_length=length,
        test_set=maze_test_set(size, count, seed),
    )  # fmt: skip
    rng = np.random.default_rng(seed)
    successes = 0
    for _ in range(count):
        env.reset()
        truncated = False
        while not truncated:
            _, _, _, truncated, info = env.step(int(rng.integers(3)))
        successes += bool(info["is_success"])
    env.close()
    return successes / count, time.perf_counter() - start


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--steps", type=int, default=50_000)
    parser.add_argument("--repeats", type=int, default=3)
    parser.add_argument("--count", type=int, default=1000, help="mazes per test set")
    parser.add_argument("--seed", type=int, default=0, help="seed of the test sets and policy")
    args = parser.parse_args()

    cartpole = steps_per_second("CartPole-v1", args.steps, args.repeats)
    print(f"{'CartPole-v1':34s} {cartpole:10.0f} steps/s")
    for size in (7, 15, 21):
        rate = steps_per_second("ActiveLoc/Maze-v0", args.steps, args.repeats, size=size)
        name = f"ActiveLoc/Maze-v0 size={size}"
        print(f"{name:34s} {rate:10.0f} steps/s   ratio to CartPole {rate / cartpole:.3f}")

    for size, length in ((7, 15), (15, 20)):
        rate, seconds = random_policy_success(size, length, args.count, args.seed)
        se = math.sqrt(rate * (1 - rate) / args.count)
        print(
            f"random policy, maze_test_set({size}, {args.count}, seed={args.seed}), L={length}: "
            f"success {rate:.3f} (+/- {se:.3f} s.e.)  [{seconds:.1f} s]"
        )


if __name__ == "__main__":
    main()
