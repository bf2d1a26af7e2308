"""Where PPO's wall time goes in ``train.py``: inside the training envs, or elsewhere.

Runs ``active_loc.train.train`` (PPO, 8 envs, no evaluations or checkpoints) for a fixed wall
time on each id, with SB3's ``DummyVecEnv`` and with the native vector env, and prints the
split that ``train.py`` records in ``config.json`` (``result.env_time``: seconds inside the
envs' ``reset``/``step`` against the whole run). It measures; it asserts nothing.

    python benchmarks/bench_training_split.py [--minutes 1.5] [--ids LandmarkEKF-v0 ...]
"""

from __future__ import annotations

import argparse
import json
import tempfile
from pathlib import Path

from active_loc.train import TrainArgs, train

IDS = ("LandmarkEKF-v0", "LandmarkMCL-v0")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--minutes", type=float, default=1.5, help="wall time per run")
    parser.add_argument("--ids", nargs="+", default=list(IDS))
    parser.add_argument("--n-envs", type=int, default=8)
    args = parser.parse_args()

    print(f"PPO, {args.n_envs} envs, {args.minutes} min per run\n")
    print(f"{'env':<26} {'vec env':<8} {'steps':>8} {'steps/s':>8} {'env share':>10} "
          f"{'env steps/s':>12}")
    with tempfile.TemporaryDirectory() as tmp:
        for name in args.ids:
            for vec in ("dummy", "native"):
                out = Path(tmp) / f"{name}-{vec}"
                train(TrainArgs(
                    env=f"ActiveLoc/{name}", algo="ppo", total_steps=10**9,
                    n_envs=args.n_envs, vec_env=vec, eval_freq=0, checkpoint_freq=0,
                    time_limit_minutes=args.minutes, progress_bar=False, out=out,
                ))
                result = json.loads((out / "config.json").read_text())["result"]
                split = result["env_time"]
                rate = result["timesteps"] / result["wall_time_s"]
                print(f"{name:<26} {vec:<8} {result['timesteps']:>8} {rate:>8.0f} "
                      f"{100 * split['env_share']:>9.1f}% {split['env_steps_per_s']:>12.0f}")


if __name__ == "__main__":
    main()
