"""The ``active-loc`` command: ``active-loc demo|render|envs``.

* ``demo``: train PPO on LandmarkEKF-v0 and compare it with a random policy
  (:mod:`active_loc.demo`; options after ``demo`` go to it).
* ``render``: run one episode with an agent and write it as a GIF or MP4.
* ``envs``: list the registered env ids.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import gymnasium as gym

import active_loc
from active_loc.agents import RandomAgent, TextbookAgent

AGENTS = {"random": RandomAgent, "textbook": TextbookAgent}


def render_episode(env_id: str, agent_name: str, out: Path, seed: int, fps: int) -> int:
    """Run one seeded episode of ``agent_name`` and write its frames to ``out``."""
    import imageio.v2 as imageio

    env = gym.make(env_id, render_mode="rgb_array")
    agent = RandomAgent(seed) if agent_name == "random" else AGENTS[agent_name]()
    obs, info = env.reset(seed=seed)
    frames = [env.render()]
    done = False
    while not done:
        obs, _, terminated, truncated, info = env.step(agent.act(obs, env.unwrapped.planner_view()))
        frames.append(env.render())
        done = terminated or truncated
    env.close()
    out.parent.mkdir(parents=True, exist_ok=True)
    if out.suffix == ".gif":
        imageio.mimsave(out, frames, duration=1000 / fps, loop=0)
    else:
        imageio.mimsave(out, frames, fps=fps)
    print(
        f"{out}: {len(frames)} frames; final pose error {info['pose_error']:.3f} m, "
        f"entropy {info['entropy']:.2f} nats, success {info['is_success']}"
    )
    return 0


def main(argv: list[str] | None = None) -> int:
    argv = sys.argv[1:] if argv is None else argv
    if argv[:1] == ["demo"]:
        from active_loc.demo import main as demo_main

        demo_main(argv[1:])
        return 0
    parser = argparse.ArgumentParser(prog="active-loc", description=__doc__.splitlines()[0])
    sub = parser.add_subparsers(dest="command", required=True)
    sub.add_parser("demo", help="train PPO on LandmarkEKF-v0 and compare with random")
    sub.add_parser("envs", help="list the registered env ids")
    render = sub.add_parser("render", help="write one episode as a GIF or MP4")
    render.add_argument("--env", default="ActiveLoc/Textbook-v0")
    render.add_argument("--agent", choices=sorted(AGENTS), default="textbook")
    render.add_argument("--out", type=Path, default=Path("reports/episode.gif"))
    render.add_argument("--seed", type=int, default=0)
    render.add_argument("--fps", type=int, default=10)
    args = parser.parse_args(argv)
    if args.command == "envs":
        for env_id, scenario, max_steps in active_loc.ENV_IDS:
            print(f"{env_id:<28} scenario={scenario:<18} max_episode_steps={max_steps}")
        return 0
    return render_episode(args.env, args.agent, args.out, args.seed, args.fps)


if __name__ == "__main__":
    raise SystemExit(main())
