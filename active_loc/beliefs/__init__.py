"""Pose beliefs: the localization filters and their common entropy."""

from active_loc.beliefs.base import Belief
from active_loc.beliefs.ekf import EKFBelief
from active_loc.beliefs.ekf_filterpy import FilterpyEKFBelief
from active_loc.beliefs.entropy import gaussian_entropy

__all__ = ["Belief", "EKFBelief", "FilterpyEKFBelief", "gaussian_entropy"]
