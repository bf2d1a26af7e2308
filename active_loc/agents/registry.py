"""Agents by name, for the command line: ``make_agent("greedy", env, seed)``, or with
parameters: ``make_agent("horizon[horizon=1,hold=5]", env, seed)``."""

from __future__ import annotations

import inspect
import json
from collections.abc import Mapping
from typing import Any

import gymnasium as gym

from active_loc.agents.greedy import GreedyInfoGainAgent
from active_loc.agents.horizon import HorizonPlannerAgent
from active_loc.agents.passive import WallFollowerAgent, WandererAgent
from active_loc.agents.random_agent import RandomAgent
from active_loc.agents.targets import TargetPlannerAgent
from active_loc.agents.textbook import TextbookAgent

#: the class of each name but ``passive``, which stands for one of them
AGENT_CLASSES: dict[str, type] = {
    "random": RandomAgent, "greedy": GreedyInfoGainAgent, "horizon": HorizonPlannerAgent,
    "targets": TargetPlannerAgent, "textbook": TextbookAgent, "wanderer": WandererAgent,
    "wall_follower": WallFollowerAgent,
}

#: the names :func:`make_agent` takes (and ``sb3:PATH``)
AGENT_NAMES = ("passive", *AGENT_CLASSES)


def split_top_level(text: str, separator: str = ",") -> list[str]:
    """``text`` split at each ``separator`` outside square brackets, parts stripped:
    ``"random,horizon[horizon=1,hold=5]"`` -> ``["random", "horizon[horizon=1,hold=5]"]``."""
    parts, depth, start = [], 0, 0
    for i, char in enumerate(text):
        if char == "[":
            depth += 1
        elif char == "]":
            depth -= 1
        elif char == separator and depth == 0:
            parts.append(text[start:i].strip())
            start = i + 1
    parts.append(text[start:].strip())
    return parts


def parse_agent_spec(spec: str) -> tuple[str, dict[str, Any]]:
    """The name and the parameters of ``"name"`` or ``"name[key=value,...]"``.

    Values are JSON (``3``, ``0.5``, ``true``, ``[0.4, 1.0]``):
    ``"horizon[horizon=1,hold=5]"`` -> ``("horizon", {"horizon": 1, "hold": 5})``.

    Raises:
        ValueError: unbalanced brackets, a parameter without ``=``, named twice, or a value
            that is not JSON.
    """
    spec = spec.strip()
    if "[" not in spec and "]" not in spec:
        return spec, {}
    name, _, rest = spec.partition("[")
    if not rest.endswith("]") or rest.count("[") != rest.count("]") - 1:
        raise ValueError(f"agent {spec!r}: parameters go in one pair of brackets at the end, "
                         "as in 'horizon[horizon=1,hold=5]'")
    params: dict[str, Any] = {}
    body = rest[:-1].strip()
    for item in split_top_level(body) if body else []:
        key, equals, text = item.partition("=")
        key = key.strip()
        if not equals or not key:
            raise ValueError(f"agent {spec!r}: {item!r} is not key=value")
        if key in params:
            raise ValueError(f"agent {spec!r}: parameter {key!r} given twice")
        try:
            params[key] = json.loads(text)
        except json.JSONDecodeError as exc:
            raise ValueError(f"agent {spec!r}: the value of {key!r}, {text.strip()!r}, is not "
                             "a number, true/false or a [list]") from exc
    return name.strip(), params


def _wrong_type(default: Any, value: Any) -> str | None:
    """What ``value`` should be to stand in for ``default`` (an int for an int, a number for a
    float, a list of numbers as long as a tuple), or None if it fits."""
    def is_number(v: Any) -> bool:
        return isinstance(v, (int, float)) and not isinstance(v, bool)

    if isinstance(default, bool):
        return None if isinstance(value, bool) else "true or false"
    if isinstance(default, int):
        return None if isinstance(value, int) and not isinstance(value, bool) else "an integer"
    if isinstance(default, float):
        return None if is_number(value) else "a number"
    if isinstance(default, tuple) and not (
        isinstance(value, list) and len(value) == len(default) and all(map(is_number, value))
    ):
        return f"a list of {len(default)} numbers"
    return None


def _check_params(label: str, parameters: Mapping[str, inspect.Parameter],
                  params: dict[str, Any]) -> None:
    """Every key of ``params`` is one of the constructor's ``parameters`` other than ``seed``
    (which the evaluation sets), and its value fits the parameter's default
    (:func:`_wrong_type`). ``label`` names the agent in the messages."""
    defaults = {key: p.default for key, p in parameters.items() if key != "seed"}
    for key, value in params.items():
        if key == "seed":
            raise ValueError(f"agent {label!r}: its seed comes from the evaluation (--seed), "
                             "not from its parameters")
        if key not in defaults:
            takes = ", ".join(defaults) or "no parameters"
            raise ValueError(f"agent {label!r} has no parameter {key!r} (it takes {takes})")
        want = _wrong_type(defaults[key], value)
        if want is not None:
            raise ValueError(f"agent {label!r}: {key} must be {want}, got {value!r}")


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
    PPO and A2C); its spaces must be the env's. Model files are trusted input only: loading
    one unpickles it, which can run code. A name may carry its agent's constructor parameters
    in brackets (see :func:`parse_agent_spec`): ``"greedy[n_hypotheses=8]"``,
    ``"horizon[horizon=1,hold=5]"``; those not given keep their defaults, and ``seed`` is
    always ``seed``.

    Raises:
        ValueError: an unknown name or parameter, a value of the wrong type or range, or an
            agent that cannot drive this env.
    """
    kind = _kind(env)
    if spec.startswith(("sb3:", "sb3-sample:")):
        from active_loc.agents.sb3 import SB3Agent

        kind_of_sb3, path = spec.split(":", 1)
        agent = SB3Agent.load(path, deterministic=kind_of_sb3 == "sb3", seed=seed)
        agent.check_env(env, name=f"the model {path}")
        return agent
    requested, params = parse_agent_spec(spec)
    name = requested
    if name == "passive":
        if kind == "maze":
            raise ValueError("no passive agent for Maze-v0: its only reading, the depth, "
                             "reaches agents through the belief")
        name = {"textbook": "textbook", "lidar": "wall_follower"}.get(kind, "wanderer")
    if name not in AGENT_CLASSES:
        raise ValueError(
            f"unknown agent {spec!r}: one of {AGENT_NAMES} (with [key=value,...] parameters "
            "or not), 'sb3:PATH' or 'sb3-sample:PATH'"
        )
    if name == "targets" and kind != "lidar":
        raise ValueError("agent 'targets' plans paths on a grid map: it needs a grid env "
                         "with a lidar")
    if name in ("textbook", "wanderer", "wall_follower"):
        if kind == "maze":
            raise ValueError(f"agent {name!r} drives a unicycle robot; Maze-v0 has none")
        if name == "wall_follower" and kind != "lidar":
            raise ValueError("agent 'wall_follower' needs a grid env with a lidar")
    cls = AGENT_CLASSES[name]
    parameters = inspect.signature(cls).parameters
    _check_params(name if name == requested else f"{requested} ({name} here)", parameters,
                  params)
    if "seed" in parameters:
        params["seed"] = seed
    return cls(**params)
