"""The ``active-loc`` command: ``active-loc train|demo|render|evaluate|compare|envs``.

* ``train``: train a stable-baselines3 agent (:mod:`active_loc.train`, the same as
  ``python train.py``; options after ``train`` go to it).
* ``demo``: train PPO on LandmarkEKF-v0 and compare it with a random policy
  (:mod:`active_loc.demo`; options after ``demo`` go to it).
* ``render``: run one episode with an agent and write it as a GIF or MP4.
* ``evaluate``: run agents on the same seeded episodes; metrics table, CSV, JSON, plots
  (:mod:`active_loc.evaluation`); ``--ray [ADDRESS]`` runs the episodes as Ray tasks;
  ``--baseline NAME`` adds every agent's paired comparison with NAME
  (:mod:`active_loc.comparison`).
* ``compare``: the paired comparison from the ``results.csv`` files of earlier evaluations.
* ``envs``: list the registered env ids.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import gymnasium as gym

import active_loc
from active_loc.agents import AGENT_NAMES, make_agent
from active_loc.agents.registry import split_top_level
from active_loc.envs.registration import DISCRETE_ENV_IDS, OTHER_ENV_IDS

#: the files ``active-loc render`` writes
VIDEO_SUFFIXES = (".gif", ".mp4")


def render_episode(env_id: str, agent_name: str, out: Path, seed: int, fps: int) -> int:
    """Run one seeded episode of ``agent_name`` and write its frames to ``out``; a bad
    argument is one line on stderr and exit status 2, before the episode runs."""
    if fps < 1:
        return _fail(f"--fps must be >= 1, got {fps}", "render")
    if seed < 0:
        return _fail(f"--seed must be >= 0, got {seed}", "render")
    if out.suffix.lower() not in VIDEO_SUFFIXES:
        return _fail(f"--out {out}: the file must end in {' or '.join(VIDEO_SUFFIXES)}",
                     "render")
    if out.exists() and out.is_dir():
        return _fail(f"--out {out}: is a folder, not a video file", "render")
    try:
        import imageio.v2 as imageio
    except ImportError:
        return _fail('rendering needs imageio: pip install "active-loc[render]"', "render")
    try:
        env = gym.make(env_id, render_mode="rgb_array")
    except (gym.error.Error, ValueError, TypeError) as error:
        return _fail(f"--env {env_id}: {error}", "render")
    try:
        agent = make_agent(agent_name, env, seed)
    except (ValueError, TypeError, OSError, ImportError) as error:
        return _fail(str(error), "render")
    try:
        out.parent.mkdir(parents=True, exist_ok=True)
    except OSError as error:
        return _fail(f"--out {out}: cannot write there: {error.strerror or error}", "render")
    obs, info = env.reset(seed=seed)
    frames = [env.render()]
    done = False
    while not done:
        obs, _, terminated, truncated, info = env.step(agent.act(obs, env.unwrapped.planner_view()))
        frames.append(env.render())
        done = terminated or truncated
    env.close()
    try:
        if out.suffix.lower() == ".gif":
            imageio.mimsave(out, frames, duration=1000 / fps, loop=0)
        else:
            imageio.mimsave(out, frames, fps=fps)
    except OSError as error:
        return _fail(f"--out {out}: cannot write the video: {error}", "render")
    print(
        f"{out}: {len(frames)} frames; final pose error {info['pose_error']:.3f} m, "
        f"entropy {info['entropy']:.2f} nats, success {info['is_success']}"
    )
    return 0


def limit_torch_threads(agent_specs: list[str], threads: int) -> None:
    """Run torch on ``threads`` threads when an agent is a stable-baselines3 model: the env
    shares the cores, and torch's default of one thread per core makes each prediction of a
    small policy about 20x slower (17 ms against 0.7 ms on 2 cores)."""
    if any(spec.startswith(("sb3:", "sb3-sample:")) for spec in agent_specs):
        import torch

        torch.set_num_threads(threads)


def _fail(message: str, command: str = "evaluate") -> int:
    print(f"active-loc {command}: error: {message}", file=sys.stderr)
    return 2


def evaluate_command(args: argparse.Namespace) -> int:
    """``active-loc evaluate``: run the agents, write ``results.csv``, ``summary.json``,
    ``summary.md``, the plots and (``--gif``) one GIF per agent into ``--out``.

    Every agent is reseeded before each episode (:func:`active_loc.evaluation.reseed_agent`),
    so ``--ray`` (the episodes as Ray tasks: a local Ray, or the cluster at ``ADDRESS``) writes
    the same ``results.csv`` and ``summary.json`` as the serial run.
    """
    import importlib.util
    import json

    from active_loc.agents import make_agent
    from active_loc.evaluation import (
        RAY_MISSING,
        ResultsStream,
        check_env_kwargs,
        evaluate,
        evaluate_ray,
        reseed_agent,
        summarize,
        write_results,
    )
    from active_loc.evaluation_plots import write_gifs, write_plots

    try:
        env_kwargs = json.loads(args.env_kwargs)
    except json.JSONDecodeError as exc:
        return _fail(f"--env-kwargs is not valid JSON: {exc}")
    if not isinstance(env_kwargs, dict):
        return _fail(f"--env-kwargs must be a JSON object, got {args.env_kwargs!r}")
    try:
        check_env_kwargs(env_kwargs)
    except ValueError as exc:
        return _fail(f"--env-kwargs: {exc}")
    specs = [spec for spec in split_top_level(args.agents) if spec]
    if not specs:
        return _fail("--agents names no agent")
    if len(set(specs)) != len(specs):
        return _fail(f"--agents names an agent twice: {args.agents!r}")
    if args.episodes < 1:
        return _fail(f"--episodes must be >= 1, got {args.episodes}")
    if args.seed < 0:
        return _fail(f"--seed must be >= 0, got {args.seed}")
    if args.baseline is not None and args.baseline not in specs:
        return _fail(f"--baseline {args.baseline!r} is not one of --agents {specs}")
    if args.ray is not None and importlib.util.find_spec("ray") is None:
        return _fail(f"--ray: {RAY_MISSING}")
    if args.torch_threads < 1:
        return _fail(f"--torch-threads must be >= 1, got {args.torch_threads}")
    limit_torch_threads(specs, args.torch_threads)

    def make_agents() -> dict[str, object]:
        env = gym.make(args.env, **env_kwargs)
        try:
            return {spec: make_agent(spec, env, args.seed) for spec in specs}
        finally:
            env.close()

    try:
        agents = make_agents()  # here also when --ray: bad names fail before any task runs
    except (ValueError, TypeError, OSError, ImportError, gym.error.Error) as exc:
        return _fail(str(exc))
    try:
        stream = ResultsStream(args.out)  # before any episode: an unwritable --out fails now
    except OSError as exc:
        return _fail(f"--out {exc}")
    try:
        if args.ray is not None:
            records = evaluate_ray(args.env, env_kwargs, {spec: spec for spec in specs},
                                   args.episodes, args.seed, progress=True,
                                   address=args.ray or None, on_record=stream.add)
        else:
            records = evaluate(args.env, env_kwargs, agents, args.episodes, args.seed,
                               progress=True, on_record=stream.add)
    finally:
        stream.close()
    summary = summarize(records, baseline=args.baseline)
    files = write_results(records, summary, args.out)
    written = [*files.values(), *write_plots(records, args.out)]
    if args.gif:
        gif_agents = make_agents()
        for agent in gif_agents.values():
            reseed_agent(agent, args.seed)  # as in the evaluation's episode 0 (seed S)
        written += write_gifs(args.env, env_kwargs, gif_agents, args.seed, args.out)
    print(files["md"].read_text(encoding="utf-8"))
    for path in written:
        print(f"wrote {path}")
    return 0


def compare_command(args: argparse.Namespace) -> int:
    """``active-loc compare``: print the paired comparison of the agents in ``results.csv``
    files with ``--baseline`` (agents matched by name, episodes by seed)."""
    from active_loc.comparison import comparison_markdown, paired_comparison, read_outcomes

    try:
        outcomes = [o for path in args.results for o in read_outcomes(path)]
        comparison = paired_comparison(outcomes, args.baseline)
    except (OSError, ValueError) as exc:
        return _fail(str(exc), "compare")
    print(comparison_markdown(comparison))
    return 0


def main(argv: list[str] | None = None) -> int:
    argv = sys.argv[1:] if argv is None else argv
    if argv[:1] == ["demo"]:
        from active_loc.demo import main as demo_main

        demo_main(argv[1:])
        return 0
    if argv[:1] == ["train"]:
        from active_loc.train import main as train_main

        train_main(argv[1:], prog="active-loc train")
        return 0
    parser = argparse.ArgumentParser(prog="active-loc", description=__doc__.splitlines()[0])
    sub = parser.add_subparsers(dest="command", required=True)
    sub.add_parser("train", help="train a stable-baselines3 agent (active-loc train --help)")
    sub.add_parser("demo", help="train PPO on LandmarkEKF-v0 and compare with random")
    sub.add_parser("envs", help="list the registered env ids")
    render = sub.add_parser("render", help="write one episode as a GIF or MP4")
    render.add_argument("--env", default="ActiveLoc/Textbook-v0")
    render.add_argument("--agent", default="textbook",
                        help=f"one of {', '.join(AGENT_NAMES)} (parameters in brackets: "
                        "horizon[horizon=1,hold=5]), sb3:PATH or sb3-sample:PATH")
    render.add_argument("--out", type=Path, default=Path("reports/episode.gif"))
    render.add_argument("--seed", type=int, default=0)
    render.add_argument("--fps", type=int, default=10)
    evaluate = sub.add_parser(
        "evaluate", help="run agents on the same seeded episodes: CSV, JSON, Markdown, plots"
    )
    evaluate.add_argument("--env", required=True, help="env id, e.g. ActiveLoc/LandmarkEKF-v0")
    evaluate.add_argument("--env-kwargs", default="{}",
                          help="JSON object of gymnasium.make keyword arguments")
    evaluate.add_argument("--agents", required=True,
                          help="comma-separated: random,passive,greedy,horizon,sb3:PATH,"
                               "sb3-sample:PATH,...; an agent's parameters in brackets: "
                               "greedy[n_hypotheses=8],horizon[horizon=1,hold=5]")
    evaluate.add_argument("--episodes", type=int, default=100, help="episodes per agent")
    evaluate.add_argument("--seed", type=int, default=0, help="episode i is reset with seed + i")
    evaluate.add_argument("--out", type=Path, default=Path("reports/eval"))
    evaluate.add_argument("--gif", action="store_true", help="add one rendered episode per agent")
    evaluate.add_argument(
        "--torch-threads", type=int, default=1, metavar="N",
        help="torch threads for sb3: agents (default 1: the env needs the other cores, and "
        "more threads make a small policy's predictions slower). Ray tasks run torch on the "
        "one CPU Ray gives each",
    )
    evaluate.add_argument(
        "--ray", nargs="?", const="", default=None, metavar="ADDRESS",
        help="run the episodes as Ray tasks (pip install \"active-loc[ray]\"): alone, a local "
        "Ray (ray.init()); with ADDRESS, that cluster (auto, ray://HOST:10001). The results "
        "are the same as without --ray",
    )
    evaluate.add_argument(
        "--baseline", default=None, metavar="NAME",
        help="one of --agents: add every other agent's paired comparison with it (McNemar's "
        "test on success, the sign test on steps to localize) to summary.json and summary.md",
    )
    compare = sub.add_parser(
        "compare", help="paired comparison with a baseline from results.csv files"
    )
    compare.add_argument("results", nargs="+", type=Path,
                         help="results.csv of active-loc evaluate runs on the same env")
    compare.add_argument("--baseline", required=True, metavar="NAME",
                         help="the agent to compare the others with")
    args = parser.parse_args(argv)
    if args.command == "envs":
        for env_id, scenario, max_steps in active_loc.ENV_IDS:
            print(f"{env_id:<40} scenario={scenario:<18} max_episode_steps={max_steps}")
        for env_id, scenario, max_steps in DISCRETE_ENV_IDS:
            print(f"{env_id:<40} scenario={scenario:<18} max_episode_steps={max_steps} "
                  "action_type=discrete")
        for env_id, entry_point, _vector, limit in OTHER_ENV_IDS:
            steps = "set by the env" if limit is None else limit
            print(f"{env_id:<40} {entry_point}  max_episode_steps={steps}")
        return 0
    if args.command == "evaluate":
        return evaluate_command(args)
    if args.command == "compare":
        return compare_command(args)
    return render_episode(args.env, args.agent, args.out, args.seed, args.fps)


if __name__ == "__main__":
    raise SystemExit(main())
