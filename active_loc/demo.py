"""``make demo``: train PPO where activity matters, then compare it with the baselines.

``ActiveLoc/LandmarkEKF-v0``: a robot with a 90-degree, 6 m range-bearing sensor tracks its
pose with an EKF in a random landmark map; where it looks decides what it learns, so the way
it moves matters. The demo

1. trains PPO with :mod:`active_loc.train` (vectorized envs, evaluations, checkpoints,
   tensorboard, a learning curve) for ``--timesteps`` steps or ``--minutes`` minutes;
2. runs the trained policy, a uniformly random policy, the passive wanderer, the greedy
   information-gain agent and the look-ahead planner on the same seeded episodes with
   :mod:`active_loc.evaluation`;
3. writes ``reports/demo/`` (``results.csv``, ``summary.json``, ``summary.md``, the entropy and
   success plots, and the training run under ``reports/demo/train``) and prints the table,
   with every agent compared episode by episode with the passive one
   (:mod:`active_loc.comparison`).

Run ``python -m active_loc.demo --help`` for the options.
"""

from __future__ import annotations

import argparse
import json
import time
from pathlib import Path

import gymnasium as gym

import active_loc  # noqa: F401  (registers the env ids)
from active_loc.agents import make_agent
from active_loc.evaluation import evaluate, summarize, summary_markdown, write_results
from active_loc.evaluation_plots import write_plots
from active_loc.train import TrainArgs, train

BASELINES = ("random", "passive", "greedy", "horizon")
#: the agent the others are compared with episode by episode
PAIRED_BASELINE = "passive"


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--env", default="ActiveLoc/LandmarkEKF-v0")
    parser.add_argument("--timesteps", type=int, default=1_000_000)
    parser.add_argument("--minutes", type=float, default=10.0,
                        help="wall-clock budget of the training (stops early)")
    parser.add_argument("--n-envs", type=int, default=8)
    parser.add_argument("--episodes", type=int, default=100)
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--eval-seed", type=int, default=10_000,
                        help="seed of the first evaluation episode (apart from training's)")
    parser.add_argument("--out", type=Path, default=Path("reports/demo"))
    args = parser.parse_args(argv)

    out: Path = args.out
    start = time.perf_counter()
    run = train(TrainArgs(
        env=args.env, algo="ppo", total_steps=args.timesteps, n_envs=args.n_envs,
        seed=args.seed, out=out / "train", time_limit_minutes=args.minutes,
        eval_freq=100_000, eval_episodes=50, checkpoint_freq=250_000, n_steps=512,
        batch_size=256, n_epochs=5, gamma=0.98, learning_rate=3e-4, ent_coef=0.0,
    ))
    minutes = (time.perf_counter() - start) / 60
    print(f"trained in {minutes:.1f} min: {run}")

    env = gym.make(args.env)
    agents = {"PPO": make_agent(f"sb3:{run / 'model.zip'}", env, args.seed)}
    agents.update({name: make_agent(name, env, args.seed) for name in BASELINES})
    records = evaluate(args.env, {}, agents, args.episodes, args.eval_seed)
    summary = summarize(records, baseline=PAIRED_BASELINE)
    write_results(records, summary, out)
    write_plots(records, out)
    (out / "train_minutes.json").write_text(json.dumps({"minutes": minutes}) + "\n")
    print()
    print(summary_markdown(summary))
    print(f"\nwritten to {out}/")


if __name__ == "__main__":
    main()
