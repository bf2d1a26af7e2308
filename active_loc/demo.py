"""``make demo``: train PPO on ``ActiveLoc/LandmarkEKF-v0`` and compare it with random actions.

Trains a stable-baselines3 PPO policy for a few minutes, then runs the trained policy and a
uniformly random policy on the same seeded episodes and prints mean return, mean final entropy
and success rate of each. Run ``python -m active_loc.demo --help`` for the options.
"""

from __future__ import annotations

import argparse
import time
from dataclasses import dataclass

import gymnasium as gym
import numpy as np

import active_loc  # noqa: F401  (registers the env ids)
from active_loc.agents import RandomAgent


@dataclass
class EpisodeStats:
    """Means over the evaluation episodes of one policy."""

    name: str
    mean_return: float
    mean_final_entropy: float
    success_rate: float
    mean_length: float


def evaluate(env_id: str, policy: object, seeds: list[int], name: str) -> EpisodeStats:
    """Run ``policy.act(obs, view)`` on one episode per seed; means of the outcomes."""
    env = gym.make(env_id)
    returns, entropies, successes, lengths = [], [], [], []
    for seed in seeds:
        obs, info = env.reset(seed=seed)
        done, total, steps = False, 0.0, 0
        while not done:
            action = policy.act(obs, env.unwrapped.planner_view())  # type: ignore[attr-defined]
            obs, reward, terminated, truncated, info = env.step(action)
            total += float(reward)
            steps += 1
            done = terminated or truncated
        returns.append(total)
        entropies.append(info["entropy"])
        successes.append(info["is_success"])
        lengths.append(steps)
    env.close()
    return EpisodeStats(
        name,
        float(np.mean(returns)),
        float(np.mean(entropies)),
        float(np.mean(successes)),
        float(np.mean(lengths)),
    )


class PolicyAgent:
    """A trained stable-baselines3 model behind the agent interface (deterministic actions)."""

    def __init__(self, model: object) -> None:
        self.model = model

    def act(self, observation: np.ndarray, view: object) -> np.ndarray:
        action, _ = self.model.predict(observation, deterministic=True)  # type: ignore[attr-defined]
        return action


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--env", default="ActiveLoc/LandmarkEKF-v0")
    parser.add_argument("--timesteps", type=int, default=1_000_000)
    parser.add_argument("--n-envs", type=int, default=8)
    parser.add_argument("--episodes", type=int, default=100)
    parser.add_argument("--seed", type=int, default=0)
    args = parser.parse_args(argv)

    import torch
    from stable_baselines3 import PPO
    from stable_baselines3.common.env_util import make_vec_env

    torch.set_num_threads(1)
    vec_env = make_vec_env(args.env, n_envs=args.n_envs, seed=args.seed)
    model = PPO(
        "MlpPolicy", vec_env, n_steps=512, batch_size=256, n_epochs=5, gamma=0.98,
        learning_rate=3e-4, ent_coef=0.0, seed=args.seed, device="cpu", verbose=0,
    )
    print(f"training PPO on {args.env} for {args.timesteps} steps ({args.n_envs} envs) ...")
    start = time.perf_counter()
    model.learn(total_timesteps=args.timesteps, progress_bar=True)
    minutes = (time.perf_counter() - start) / 60
    print(f"trained in {minutes:.1f} min")

    seeds = [10_000 + i for i in range(args.episodes)]
    rows = [
        evaluate(args.env, PolicyAgent(model), seeds, "PPO (trained)"),
        evaluate(args.env, RandomAgent(seed=args.seed), seeds, "random"),
    ]
    print(f"\n{args.env}, {args.episodes} episodes, seeds {seeds[0]}..{seeds[-1]} (same for both)")
    header = f"{'policy':<15} {'mean return':>12} {'final entropy (nats)':>21}"
    print(f"{header} {'success':>8} {'steps':>6}")
    for row in rows:
        print(
            f"{row.name:<15} {row.mean_return:>12.2f} {row.mean_final_entropy:>21.2f} "
            f"{row.success_rate:>8.2f} {row.mean_length:>6.1f}"
        )


if __name__ == "__main__":
    main()
