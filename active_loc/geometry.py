"""Planar geometry on batches of poses.

A pose is ``(x, y, theta)`` in metres and radians, in the map frame (ROS: x right, y up).
Every function takes arrays with any leading batch shape ``(...)`` and works elementwise over
it, so ``(B, 3)`` poses and ``(B, K, 3)`` particles go through the same code.

The scalar ``wrap_angle_scalar`` is a numba kernel for use inside other kernels.
"""

from __future__ import annotations

import numba
import numpy as np
from numpy.typing import ArrayLike, NDArray

TWO_PI = 2.0 * np.pi


def wrap_angle(angle: ArrayLike) -> NDArray[np.float64]:
    """Wrap angles (rad) to ``[-pi, pi)``; shape is kept. Angles already in range are
    returned unchanged (bit for bit), so wrapping twice is wrapping once."""
    angle = np.asarray(angle, dtype=np.float64)
    wrapped = (angle + np.pi) % TWO_PI - np.pi
    # float rounding can land exactly on +pi for angles just below -pi
    wrapped = np.where(wrapped >= np.pi, wrapped - TWO_PI, wrapped)
    return np.where((angle >= -np.pi) & (angle < np.pi), angle, wrapped)


@numba.njit(cache=True, nogil=True, inline="always")
def wrap_angle_scalar(angle: float) -> float:
    """Wrap one angle (rad) to ``[-pi, pi)``; the kernel twin of :func:`wrap_angle`."""
    if -np.pi <= angle < np.pi:
        return angle  # the common case, and exact
    wrapped = (angle + np.pi) % TWO_PI - np.pi
    # float rounding can land exactly on +pi for angles just below -pi
    if wrapped >= np.pi:
        wrapped -= TWO_PI
    return wrapped


def rotation_matrix(theta: ArrayLike) -> NDArray[np.float64]:
    """Rotation matrices R(theta), shape ``(..., 2, 2)``, mapping robot frame to map frame."""
    theta = np.asarray(theta, dtype=np.float64)
    c, s = np.cos(theta), np.sin(theta)
    return np.stack([np.stack([c, -s], axis=-1), np.stack([s, c], axis=-1)], axis=-2)


def to_robot_frame(points: ArrayLike, poses: ArrayLike) -> NDArray[np.float64]:
    """Express map-frame points in the robot frame: ``R(theta)^T (m - p)``.

    Args:
        points: ``(..., 2)`` map-frame points (m).
        poses: ``(..., 3)`` robot poses, broadcastable against ``points``.

    Returns:
        ``(..., 2)`` robot-frame coordinates (m).
    """
    points = np.asarray(points, dtype=np.float64)
    poses = np.asarray(poses, dtype=np.float64)
    dx = points[..., 0] - poses[..., 0]
    dy = points[..., 1] - poses[..., 1]
    c, s = np.cos(poses[..., 2]), np.sin(poses[..., 2])
    return np.stack([c * dx + s * dy, -s * dx + c * dy], axis=-1)


def compose(a: ArrayLike, b: ArrayLike) -> NDArray[np.float64]:
    """Pose composition ``a (+) b``: ``b`` given in ``a``'s frame, result in the map frame."""
    a = np.asarray(a, dtype=np.float64)
    b = np.asarray(b, dtype=np.float64)
    c, s = np.cos(a[..., 2]), np.sin(a[..., 2])
    x = a[..., 0] + c * b[..., 0] - s * b[..., 1]
    y = a[..., 1] + s * b[..., 0] + c * b[..., 1]
    return np.stack([x, y, wrap_angle(a[..., 2] + b[..., 2])], axis=-1)


def inverse(a: ArrayLike) -> NDArray[np.float64]:
    """Inverse pose ``(-) a``, so that ``compose(a, inverse(a))`` is the identity."""
    a = np.asarray(a, dtype=np.float64)
    c, s = np.cos(a[..., 2]), np.sin(a[..., 2])
    x = -c * a[..., 0] - s * a[..., 1]
    y = s * a[..., 0] - c * a[..., 1]
    return np.stack([x, y, wrap_angle(-a[..., 2])], axis=-1)


def relative(a: ArrayLike, b: ArrayLike) -> NDArray[np.float64]:
    """Pose of ``b`` seen from ``a``: ``(-) a (+) b``."""
    return compose(inverse(a), b)


def circular_mean(
    angles: ArrayLike, weights: ArrayLike | None = None, axis: int = -1
) -> NDArray[np.float64]:
    """Weighted circular mean of angles (rad) along ``axis``, in ``[-pi, pi)``.

    Weights need not be normalized; they default to uniform.
    """
    angles = np.asarray(angles, dtype=np.float64)
    if weights is None:
        weights = np.ones_like(angles)
    weights = np.asarray(weights, dtype=np.float64)
    s = np.sum(weights * np.sin(angles), axis=axis)
    c = np.sum(weights * np.cos(angles), axis=axis)
    return wrap_angle(np.arctan2(s, c))
