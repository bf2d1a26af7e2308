"""active_loc: Gymnasium environments for active robot localization.

``import active_loc`` registers the env ids of the ``ActiveLoc`` namespace::

    import gymnasium as gym
    import active_loc  # noqa: F401

    env = gym.make("ActiveLoc/LandmarkEKF-v0")
"""

from active_loc.envs.registration import ENV_IDS, register_envs

__version__ = "0.1.0"

register_envs()

__all__ = ["ENV_IDS", "__version__", "register_envs"]
