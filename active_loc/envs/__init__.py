"""Gymnasium environments of active localization."""

from active_loc.envs.config import LocalizationConfig
from active_loc.envs.localization_env import ActiveLocalizationEnv
from active_loc.envs.planner_view import PlannerView
from active_loc.envs.vector_env import ActiveLocalizationVectorEnv

__all__ = [
    "ActiveLocalizationEnv",
    "ActiveLocalizationVectorEnv",
    "LocalizationConfig",
    "PlannerView",
]
