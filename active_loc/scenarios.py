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
#: of 90 degrees and 6 m: where the robot looks decides what it learns. The robot starts where
#: no landmark is in view, so that no episode is over before the agent has looked.
LANDMARK_TRACKING: MappingProxyType[str, Any] = MappingProxyType({"start": "unseen"})

#: LandmarkEKF-v0's pose tracking with identical-looking landmarks (the chapter's Algorithm
#: 3): the scan carries no identities, each landmark in view is missed with probability 0.1,
#: and about one false detection per scan (Poisson, mean 1) appears anywhere in the field of
#: view; the EKF associates every detection by maximum likelihood under the predicted belief
#: and leaves out those beyond the 99% chi-square gate. Association needs a prediction that
#: tells neighbouring landmarks (1.5 m apart or more) apart, so the prior is tighter than
#: LandmarkEKF-v0's (0.5 m, 0.3 rad), under which most episodes start with a wrong match:
#: 0.2 m and 0.05 rad (about 0.3 m of bearing at 6 m).
LANDMARK_UNKNOWN: MappingProxyType[str, Any] = MappingProxyType(
    {
        "known_correspondences": False,
        "miss_probability": 0.1,
        "clutter_rate": 1.0,
        "association_gate": 0.99,
        "initial_error_std": (0.2, 0.2, 0.05),
        "initial_belief_std": (0.2, 0.2, 0.05),
        "start": "unseen",
    }
)

#: Global localization on landmark maps: the belief starts uniform over the map, mixture MCL
#: with recovery (augmented MCL's rate), a 180-degree range-bearing sensor of 8 m. The sensor is
#: precise (0.1 m, 2 degrees), so the posterior after the first scan is a sliver of the pose
#: space: plain MCL with a few thousand particles puts none of them in it, one takes all the
#: weight and the filter converges, confidently, on a pose up to a metre off (it needed 100000
#: particles). Mixture MCL draws a fifth of every update's particles from the detections, so
#: 5000 at the start suffice (KLD sampling brings them down to 500 as the belief narrows); the
#: likelihood stays tempered.
LANDMARK_GLOBAL: MappingProxyType[str, Any] = MappingProxyType(
    {
        "belief": "mcl",
        "initial_belief": "uniform",
        "n_particles": 5000,
        "proposal": "mixture",
        "kld": True,
        "min_particles": 500,
        "likelihood_exponent": 0.1,
        "augmented": True,
        "fov": math.pi,
        "max_range": 8.0,
        "horizon": 300,
    }
)

#: Global localization on generated office-like grid maps (12 m x 12 m) with a 270-degree,
#: 60-beam lidar of 8 m and the likelihood field; as in AMCL, the particle count adapts by KLD
#: sampling (5000 down to 500) and the scan likelihood is tempered (beams are not
#: independent). Mixture MCL draws a fifth of every update's particles from the scan's lattice
#: (plain MCL needed 50000 particles), and recovers with such poses where AMCL injects random
#: ones. The recovery averages run faster than AMCL's
#: defaults (0.001, 0.1), which are sized for hours of operation, not episodes of 300 steps;
#: and they inject only once the short-term average falls below half the long-term one, so
#: that the dips of a belief that is right (a turn in an open room) do not keep scattering it.
GRID_GLOBAL: MappingProxyType[str, Any] = MappingProxyType(
    {
        "belief": "mcl",
        "sensor": "lidar",
        "map": "rooms",
        "map_size": (12.0, 12.0),
        "initial_belief": "uniform",
        "n_particles": 5000,
        "proposal": "mixture",
        "kld": True,
        "min_particles": 500,
        "likelihood_exponent": 0.05,
        "augmented": True,
        "recovery_alpha_slow": 0.05,
        "recovery_alpha_fast": 0.5,
        "recovery_threshold": 0.5,
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

#: A dynamic environment: pose tracking on generated office maps with 10 people (discs of
#: 0.25 m walking at 0.8 m/s between free points) that the map does not hold; they occlude
#: beams, giving short readings, and block the robot. The likelihood field skips the beams
#: that most particles cannot explain by the map (AMCL's beam skipping, its values), and, as
#: in AMCL's defaults, no random particles are injected.
GRID_DYNAMIC: MappingProxyType[str, Any] = MappingProxyType(
    {
        **GRID_GLOBAL,
        "initial_belief": "gaussian",
        "augmented": False,
        "dynamic_obstacles": (10, 0.8, 0.25),
        "lidar_beam_skip": (0.5, 0.3, 0.9),
        "horizon": 300,
    }
)

#: Global localization with the grid Markov filter (the chapter's Algorithm 1) on generated
#: office maps of 8 m x 8 m: a histogram over 0.25 m cells x 36 heading bins of 10 degrees
#: (about 33 000 free poses), uniform over the free space at the start, the same lidar as
#: GridMCL-v0 (270 degrees, 60 beams, 8 m, likelihood field) scored at every free cell pose
#: and tempered as there (0.05): beams are not independent, and a cell pose is up to half a
#: cell and half a bin (5 degrees: 0.4 m at 5 m) away from the robot it stands for; at 0.1 a
#: passive robot settled on a wrong, similar-looking place in 2 of 40 seeded episodes.
#: Localized means a heading std of at most 0.1 rad: a bin's own spread is 0.05 rad.
GRID_MARKOV: MappingProxyType[str, Any] = MappingProxyType(
    {
        "belief": "grid",
        "sensor": "lidar",
        "map": "rooms",
        "map_size": (8.0, 8.0),
        "initial_belief": "uniform",
        "grid_cell_size": 0.25,
        "grid_headings": 36,
        "likelihood_exponent": 0.05,
        "fov": 1.5 * math.pi,
        "max_range": 8.0,
        "localized_heading_std": 0.1,
        "horizon": 300,
    }
)

SCENARIOS: MappingProxyType[str, MappingProxyType[str, Any]] = MappingProxyType(
    {
        "textbook": TEXTBOOK,
        "landmark_tracking": LANDMARK_TRACKING,
        "landmark_unknown": LANDMARK_UNKNOWN,
        "landmark_global": LANDMARK_GLOBAL,
        "grid_global": GRID_GLOBAL,
        "grid_kidnapped": GRID_KIDNAPPED,
        "grid_dynamic": GRID_DYNAMIC,
        "grid_markov": GRID_MARKOV,
    }
)


def scenario_kwargs(name: str) -> dict[str, Any]:
    """The config overrides of a named scenario."""
    if name not in SCENARIOS:
        raise ValueError(f"scenario={name!r} is not one of {tuple(SCENARIOS)}")
    return dict(SCENARIOS[name])
