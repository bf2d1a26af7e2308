"""Pose beliefs: the localization filters and their common entropy."""

from active_loc.beliefs.base import Belief
from active_loc.beliefs.ekf import EKFBelief
from active_loc.beliefs.ekf_filterpy import FilterpyEKFBelief
from active_loc.beliefs.entropy import gaussian_entropy
from active_loc.beliefs.grid import GridBelief
from active_loc.beliefs.mcl import FreeSpace, MCLBelief, landmark_log_likelihood

__all__ = [
    "Belief",
    "EKFBelief",
    "FilterpyEKFBelief",
    "FreeSpace",
    "GridBelief",
    "MCLBelief",
    "gaussian_entropy",
    "landmark_log_likelihood",
]
