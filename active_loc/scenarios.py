"""The taxonomy of the chapter as presets: keyword overrides of the env configuration.

Each scenario is a dict of :class:`active_loc.envs.config.LocalizationConfig` fields; the env
ids are registered with one of them, and ``gymnasium.make(id, **kwargs)`` overrides any field.
"""

from __future__ import annotations

import math
from types import MappingProxyType
from typing import Any

#: Section 13.8, problem 1, exactly: four landmarks, relative-position measurements of all of
#: them with R = 0.25 I, dt = 0.1, Q = 0.1 dt^2 I, true start (1, 1, 0), initial belief mean =
#: start + N(0, 0.1 I) with covariance I, 150 steps without early termination. The action range
#: puts the exercise's controls (V = 1, omega = sin(k dt)) inside [-1, 1].
TEXTBOOK: MappingProxyType[str, Any] = MappingProxyType(
    {
        "map": "textbook",
        "max_landmarks": 4,
        "n_landmarks": (4, 4),
        "dt": 0.1,
        "motion_noise_std": (math.sqrt(0.1) * 0.1,) * 3,
        "v_min": 0.0,
        "v_max": 2.0,
        "omega_max": 1.0,
        "start": "fixed",
        "start_pose": (1.0, 1.0, 0.0),
        "sensor": "relative_position",
        "position_std": 0.5,
        "fov": 2 * math.pi,
        "max_range": math.inf,
        "initial_error_std": (math.sqrt(0.1),) * 3,
        "initial_belief_std": (1.0, 1.0, 1.0),
        "terminate_when_localized": False,
        "collision_penalty": 0.0,
    }
)

#: Pose tracking in a random 20 m x 20 m map of 8 to 15 landmarks with a range-bearing sensor
#: of 90 degrees and 6 m: where the robot looks decides what it learns.
LANDMARK_TRACKING: MappingProxyType[str, Any] = MappingProxyType({})

#: Global localization on landmark maps: the belief starts uniform over the map, MCL with
#: random-particle injection, a 180-degree range-bearing sensor of 8 m.
LANDMARK_GLOBAL: MappingProxyType[str, Any] = MappingProxyType(
    {
        "belief": "mcl",
        "initial_belief": "uniform",
        "n_particles": 2000,
        "augmented": True,
        "fov": math.pi,
        "max_range": 8.0,
        "horizon": 300,
    }
)

#: Global localization on generated office-like grid maps (12 m x 12 m) with a 270-degree,
#: 60-beam lidar of 8 m and the likelihood field; as in AMCL, the particle count adapts by KLD
#: sampling (50000 down to 500), random particles are injected, and the scan likelihood is
#: tempered (beams are not independent). The recovery averages run faster than AMCL's
#: defaults (0.001, 0.1), which are sized for hours of operation, not episodes of 300 steps.
GRID_GLOBAL: MappingProxyType[str, Any] = MappingProxyType(
    {
        "belief": "mcl",
        "sensor": "lidar",
        "map": "rooms",
        "map_size": (12.0, 12.0),
        "initial_belief": "uniform",
        "n_particles": 50000,
        "kld": True,
        "min_particles": 500,
        "likelihood_exponent": 0.05,
        "augmented": True,
        "recovery_alpha_slow": 0.05,
        "recovery_alpha_fast": 0.5,
        "fov": 1.5 * math.pi,
        "max_range": 8.0,
        "horizon": 300,
    }
)

#: The kidnapped robot: pose tracking on grid maps until, once per episode between 20% and
#: 60% of the 400-step horizon, the robot is carried to a random free pose unannounced.
GRID_KIDNAPPED: MappingProxyType[str, Any] = MappingProxyType(
    {
        **GRID_GLOBAL,
        "initial_belief": "gaussian",
        "kidnap": True,
        "kidnap_window": (0.2, 0.6),
        "horizon": 400,
    }
)

SCENARIOS: MappingProxyType[str, MappingProxyType[str, Any]] = MappingProxyType(
    {
        "textbook": TEXTBOOK,
        "landmark_tracking": LANDMARK_TRACKING,
        "landmark_global": LANDMARK_GLOBAL,
        "grid_global": GRID_GLOBAL,
        "grid_kidnapped": GRID_KIDNAPPED,
    }
)


def scenario_kwargs(name: str) -> dict[str, Any]:
    """The config overrides of a named scenario."""
    if name not in SCENARIOS:
        raise ValueError(f"scenario={name!r} is not one of {tuple(SCENARIOS)}")
    return dict(SCENARIOS[name])
