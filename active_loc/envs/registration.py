"""Env ids of the ``ActiveLoc`` namespace, registered by ``import active_loc``."""

from __future__ import annotations

from gymnasium.envs.registration import register, registry

ENTRY_POINT = "active_loc.envs.localization_env:ActiveLocalizationEnv"
VECTOR_ENTRY_POINT = "active_loc.envs.vector_env:ActiveLocalizationVectorEnv"

#: (id, scenario, max_episode_steps) of the ids served by ``ActiveLocalizationEnv``
ENV_IDS: tuple[tuple[str, str, int], ...] = (
    ("ActiveLoc/Textbook-v0", "textbook", 150),
    ("ActiveLoc/LandmarkEKF-v0", "landmark_tracking", 200),
    ("ActiveLoc/LandmarkEKFUnknown-v0", "landmark_unknown", 200),
    ("ActiveLoc/LandmarkMCL-v0", "landmark_global", 300),
    ("ActiveLoc/GridMCL-v0", "grid_global", 300),
    ("ActiveLoc/GridMCLKidnapped-v0", "grid_kidnapped", 400),
    ("ActiveLoc/GridMCLDynamic-v0", "grid_dynamic", 300),
    ("ActiveLoc/GridMarkov-v0", "grid_markov", 300),
)

#: (id, scenario, max_episode_steps) of the landmark ids with discrete actions
#: (``action_type="discrete"``, six motion primitives), for scripts and libraries that make an
#: env from its id alone: ``ActiveLoc/LandmarkEKFDiscrete-v0`` is ``ActiveLoc/LandmarkEKF-v0``
#: with ``action_type="discrete"``.
DISCRETE_ENV_IDS: tuple[tuple[str, str, int], ...] = tuple(
    (env_id.replace("-v0", "Discrete-v0"), scenario, max_steps)
    for env_id, scenario, max_steps in ENV_IDS
    if scenario.startswith(("textbook", "landmark"))
)

MAZE_ID = "ActiveLoc/Maze-v0"
MAZE_ENTRY_POINT = "active_loc.envs.maze_env:MazeEnv"
MAZE_VECTOR_ENTRY_POINT = "active_loc.envs.vector_env:maze_vector_env"

#: (id, entry point, max_episode_steps) of the ids with an env class of their own. Maze-v0
#: has no TimeLimit: its episode length is the ``episode_length`` kwarg (default by maze
#: size), and the env truncates after exactly that many steps itself, so a registered limit
#: could only disagree with it (a fixed 15 would cut the 21 x 21 mazes' 30-step episodes).
OTHER_ENV_IDS: tuple[tuple[str, str, str, int | None], ...] = (
    (MAZE_ID, MAZE_ENTRY_POINT, MAZE_VECTOR_ENTRY_POINT, None),
)

#: every id of the namespace
ALL_ENV_IDS: tuple[str, ...] = tuple(
    entry[0] for entry in ENV_IDS + DISCRETE_ENV_IDS + OTHER_ENV_IDS
)


def register_envs() -> None:
    """Register every id once; calling again is a no-op."""
    discrete = {env_id for env_id, _, _ in DISCRETE_ENV_IDS}
    for env_id, scenario, max_steps in ENV_IDS + DISCRETE_ENV_IDS:
        if env_id in registry:
            continue
        kwargs = {"scenario": scenario}
        if env_id in discrete:
            kwargs["action_type"] = "discrete"
        register(
            id=env_id,
            entry_point=ENTRY_POINT,
            vector_entry_point=VECTOR_ENTRY_POINT,
            kwargs=kwargs,
            max_episode_steps=max_steps,
        )
    for env_id, entry_point, vector_entry_point, limit in OTHER_ENV_IDS:
        if env_id in registry:
            continue
        register(
            id=env_id, entry_point=entry_point, vector_entry_point=vector_entry_point,
            max_episode_steps=limit,
        )
