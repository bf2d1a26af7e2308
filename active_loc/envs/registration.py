"""Env ids of the ``ActiveLoc`` namespace, registered by ``import active_loc``."""

from __future__ import annotations

from gymnasium.envs.registration import register, registry

ENTRY_POINT = "active_loc.envs.localization_env:ActiveLocalizationEnv"

#: (id, scenario, max_episode_steps)
ENV_IDS: tuple[tuple[str, str, int], ...] = (
    ("ActiveLoc/Textbook-v0", "textbook", 150),
    ("ActiveLoc/LandmarkEKF-v0", "landmark_tracking", 200),
    ("ActiveLoc/LandmarkMCL-v0", "landmark_global", 300),
    ("ActiveLoc/GridMCL-v0", "grid_global", 300),
    ("ActiveLoc/GridMCLKidnapped-v0", "grid_kidnapped", 400),
)


def register_envs() -> None:
    """Register every id once; calling again is a no-op."""
    for env_id, scenario, max_steps in ENV_IDS:
        if env_id in registry:
            continue
        register(
            id=env_id,
            entry_point=ENTRY_POINT,
            kwargs={"scenario": scenario},
            max_episode_steps=max_steps,
        )
