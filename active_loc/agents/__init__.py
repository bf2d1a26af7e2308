"""Agents: ``agent.act(observation, view) -> action``, ``view = env.unwrapped.planner_view()``."""

from active_loc.agents.random_agent import RandomAgent
from active_loc.agents.textbook import TextbookAgent

__all__ = ["RandomAgent", "TextbookAgent"]
