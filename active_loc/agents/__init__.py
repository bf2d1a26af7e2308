"""Agents: ``agent.act(observation, view) -> action``, ``view = env.unwrapped.planner_view()``.

No agent reads the true pose: the view holds the belief, the map, the models and the actions.
"""

from active_loc.agents.greedy import GreedyInfoGainAgent
from active_loc.agents.horizon import HorizonPlannerAgent
from active_loc.agents.passive import WallFollowerAgent, WandererAgent
from active_loc.agents.random_agent import RandomAgent
from active_loc.agents.registry import AGENT_NAMES, make_agent
from active_loc.agents.targets import TargetPlannerAgent
from active_loc.agents.textbook import TextbookAgent


def __getattr__(name: str) -> object:
    # SB3Agent imports stable-baselines3 (and torch): only when asked for
    if name == "SB3Agent":
        from active_loc.agents.sb3 import SB3Agent

        return SB3Agent
    raise AttributeError(f"module 'active_loc.agents' has no attribute {name!r}")


__all__ = [
    "AGENT_NAMES",
    "GreedyInfoGainAgent",
    "HorizonPlannerAgent",
    "RandomAgent",
    "SB3Agent",
    "TargetPlannerAgent",
    "TextbookAgent",
    "WallFollowerAgent",
    "WandererAgent",
    "make_agent",
]
