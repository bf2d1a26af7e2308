"""Agents by name, for the command line: ``make_agent("greedy", env, seed)``."""

from __future__ import annotations

from typing import Any

import gymnasium as gym

from active_loc.agents.greedy import GreedyInfoGainAgent
from active_loc.agents.horizon import HorizonPlannerAgent
from active_loc.agents.passive import WallFollowerAgent, WandererAgent
from active_loc.agents.random_agent import RandomAgent
from active_loc.agents.targets import TargetPlannerAgent
from active_loc.agents.textbook import TextbookAgent

#: the names :func:`make_agent` takes (and ``sb3:PATH``)
AGENT_NAMES = ("random", "passive", "greedy", "horizon", "targets", "textbook", "wanderer",
               "wall_follower")


def _kind(env: gym.Env) -> str:
    """``"maze"``, ``"lidar"``, ``"textbook"`` or ``"landmarks"``."""
    base = env.unwrapped
    config = getattr(base, "config", None)
    if config is None or not hasattr(config, "sensor"):
        return "maze"
    if config.sensor == "lidar":
        return "lidar"
    return "textbook" if isinstance(config.map, str) and config.map == "textbook" else "landmarks"


def make_agent(spec: str, env: gym.Env, seed: int = 0) -> Any:
    """The agent named ``spec`` for ``env``.

    ``"passive"`` is the env's passive baseline: the exercise's controls on ``Textbook-v0``, a
    wall follower on grid maps, a constant-curvature wanderer on landmark maps. ``"sb3:PATH"``
    loads a saved stable-baselines3 model that takes its most likely action;
    ``"sb3-sample:PATH"`` one that samples its actions (with the agent's seeded Generator for
    PPO and A2C).

    Raises:
        ValueError: an unknown name, or an agent that cannot drive this env.
    """
    kind = _kind(env)
    if spec.startswith(("sb3:", "sb3-sample:")):
        from active_loc.agents.sb3 import SB3Agent

        kind_of_sb3, path = spec.split(":", 1)
        return SB3Agent.load(path, deterministic=kind_of_sb3 == "sb3", seed=seed)
    if spec == "passive":
        if kind == "maze":
            raise ValueError("no passive agent for Maze-v0: its only reading, the depth, "
                             "reaches agents through the belief")
        spec = {"textbook": "textbook", "lidar": "wall_follower"}.get(kind, "wanderer")
    if spec == "random":
        return RandomAgent(seed)
    if spec == "greedy":
        return GreedyInfoGainAgent(seed=seed)
    if spec == "horizon":
        return HorizonPlannerAgent(seed=seed)
    if spec == "targets":
        if kind != "lidar":
            raise ValueError("agent 'targets' plans paths on a grid map: it needs a grid env "
                             "with a lidar")
        return TargetPlannerAgent(seed=seed)
    if spec in ("textbook", "wanderer", "wall_follower"):
        if kind == "maze":
            raise ValueError(f"agent {spec!r} drives a unicycle robot; Maze-v0 has none")
        if spec == "wall_follower" and kind != "lidar":
            raise ValueError("agent 'wall_follower' needs a grid env with a lidar")
        return {"textbook": TextbookAgent, "wanderer": WandererAgent,
                "wall_follower": WallFollowerAgent}[spec]()
    raise ValueError(
        f"unknown agent {spec!r}: one of {AGENT_NAMES}, 'sb3:PATH' or 'sb3-sample:PATH'"
    )
