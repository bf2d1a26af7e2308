"""The unicycle (velocity) motion model of the chapter, with additive Gaussian noise.

    x'     = x + V cos(theta) dt
    y'     = y + V sin(theta) dt
    theta' = theta + omega dt            (wrapped to [-pi, pi))

plus ``eps ~ N(0, Q)``. Its Jacobian with respect to the pose is

    F = [[1, 0, -V sin(theta) dt],
         [0, 1,  V cos(theta) dt],
         [0, 0,  1]].

The kernels work on one pose; :class:`UnicycleModel` applies them to batches ``(..., 3)``.
Map awareness lives here too, one rule per kind of map: a move that would leave a landmark
map's box is blocked (:func:`move_within_bounds`), and on an occupancy grid a move that would
cross a wall (:func:`move_on_grid`). The simulators move the true robot with them, and the
planner view its hypothetical robot.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass, field

import numba
import numpy as np
from numpy.typing import ArrayLike, NDArray

from active_loc.geometry import wrap_angle, wrap_angle_scalar
from active_loc.maps.occupancy import OccupancyGrid
from active_loc.sensors.lidar import cast_ray


@numba.njit(cache=True, nogil=True)
def unicycle_mean(pose: NDArray, v: float, omega: float, dt: float, out: NDArray) -> None:
    """Noise-free motion f(pose, u) of one pose ``(3,)`` into ``out`` ``(3,)`` (may alias)."""
    theta = pose[2]
    out[0] = pose[0] + v * np.cos(theta) * dt
    out[1] = pose[1] + v * np.sin(theta) * dt
    out[2] = wrap_angle_scalar(theta + omega * dt)


@numba.njit(cache=True, nogil=True)
def unicycle_jacobian(theta: float, v: float, dt: float, out: NDArray) -> None:
    """Jacobian F = df/dpose ``(3, 3)`` at heading ``theta`` (rad) into ``out``."""
    out[:, :] = 0.0
    out[0, 0] = 1.0
    out[1, 1] = 1.0
    out[2, 2] = 1.0
    out[0, 2] = -v * np.sin(theta) * dt
    out[1, 2] = v * np.cos(theta) * dt


@numba.njit(cache=True, nogil=True)
def move_within_bounds(
    pose: NDArray,
    v: float,
    omega: float,
    dt: float,
    noise: NDArray,
    bounds: NDArray,
    walls: bool,
) -> bool:
    """Move the true robot in place: f(pose, u) + noise, blocked at the workspace border.

    Args:
        pose: ``(3,)`` true pose, updated in place.
        noise: ``(3,)`` additive motion noise already drawn from N(0, Q).
        bounds: ``(4,)`` ``x_min, y_min, x_max, y_max`` (m).
        walls: if False the border does not block.

    Returns:
        True when the translation was blocked (a collision); the heading still turns.
    """
    e_x, e_y, e_theta = noise[0], noise[1], noise[2]
    return move_within_bounds_scalar(pose, v, omega, dt, e_x, e_y, e_theta, bounds, walls)


@numba.njit(cache=True, nogil=True)
def move_within_bounds_scalar(
    pose: NDArray,
    v: float,
    omega: float,
    dt: float,
    e_x: float,
    e_y: float,
    e_theta: float,
    bounds: NDArray,
    walls: bool,
) -> bool:
    """:func:`move_within_bounds` with the noise as three scalars (no array on the step path)."""
    theta = pose[2]
    x = pose[0] + v * np.cos(theta) * dt + e_x
    y = pose[1] + v * np.sin(theta) * dt + e_y
    pose[2] = wrap_angle_scalar(theta + omega * dt + e_theta)
    if walls and not (bounds[0] <= x <= bounds[2] and bounds[1] <= y <= bounds[3]):
        return True
    pose[0] = x
    pose[1] = y
    return False


@dataclass(frozen=True)
class UnicycleModel:
    """Unicycle motion with time step ``dt`` (s) and per-step additive noise covariance ``Q``.

    Attributes:
        dt: time step (s), > 0.
        noise_cov: ``(3, 3)`` covariance Q of the additive pose noise per step (m^2, rad^2);
            symmetric positive semi-definite.
    """

    dt: float = 0.1
    noise_cov: NDArray[np.float64] = field(default_factory=lambda: 0.001 * np.eye(3))

    def __post_init__(self) -> None:
        if not (np.isfinite(self.dt) and self.dt > 0):
            raise ValueError(f"UnicycleModel.dt must be a finite number > 0, got {self.dt}")
        q = np.array(self.noise_cov, dtype=np.float64)
        if q.shape != (3, 3) or not np.all(np.isfinite(q)):
            raise ValueError(f"UnicycleModel.noise_cov must be a finite (3, 3) matrix, got {q}")
        if not np.allclose(q, q.T) or np.linalg.eigvalsh(q).min() < -1e-12:
            raise ValueError("UnicycleModel.noise_cov must be symmetric positive semi-definite")
        q.setflags(write=False)
        object.__setattr__(self, "noise_cov", q)
        # a square root of Q for sampling, robust to a singular Q (eigendecomposition)
        w, v = np.linalg.eigh(q)
        root = v * np.sqrt(np.clip(w, 0.0, None))
        root.setflags(write=False)
        object.__setattr__(self, "_noise_root", root)

    @property
    def noise_root(self) -> NDArray[np.float64]:
        """``(3, 3)`` matrix L with L L^T = Q, to turn standard normals into motion noise."""
        return self._noise_root  # type: ignore[attr-defined]

    def mean(self, poses: ArrayLike, controls: ArrayLike) -> NDArray[np.float64]:
        """f(pose, u) for poses ``(..., 3)`` and controls ``(..., 2)`` = (V m/s, omega rad/s)."""
        poses = np.asarray(poses, dtype=np.float64)
        controls = np.asarray(controls, dtype=np.float64)
        theta = poses[..., 2]
        v, omega = controls[..., 0], controls[..., 1]
        return np.stack(
            [
                poses[..., 0] + v * np.cos(theta) * self.dt,
                poses[..., 1] + v * np.sin(theta) * self.dt,
                wrap_angle(theta + omega * self.dt),
            ],
            axis=-1,
        )

    def jacobian(self, poses: ArrayLike, controls: ArrayLike) -> NDArray[np.float64]:
        """F for poses ``(..., 3)`` and controls ``(..., 2)``; shape ``(..., 3, 3)``."""
        poses = np.asarray(poses, dtype=np.float64)
        controls = np.asarray(controls, dtype=np.float64)
        theta = poses[..., 2]
        v = controls[..., 0]
        shape = np.broadcast_shapes(theta.shape, v.shape)
        jac = np.broadcast_to(np.eye(3), (*shape, 3, 3)).copy()
        jac[..., 0, 2] = -v * np.sin(theta) * self.dt
        jac[..., 1, 2] = v * np.cos(theta) * self.dt
        return jac

    def sample(
        self, poses: ArrayLike, controls: ArrayLike, rng: np.random.Generator
    ) -> NDArray[np.float64]:
        """f(pose, u) + eps with eps ~ N(0, Q) drawn from ``rng``; shape ``(..., 3)``."""
        mean = self.mean(poses, controls)
        noise = rng.standard_normal(mean.shape) @ self.noise_root.T
        out = mean + noise
        out[..., 2] = wrap_angle(out[..., 2])
        return out


def move_on_grid(
    pose: NDArray[np.float64],
    v: float,
    omega: float,
    dt: float,
    noise: NDArray[np.float64],
    grid: OccupancyGrid,
    blocked_at: Callable[[NDArray[np.float64]], bool] | None = None,
) -> bool:
    """Move ``pose`` ``(3,)`` (m, m, rad) in place by the unicycle step with additive
    ``noise`` ``(3,)``, on an occupancy grid: the robot always turns, and it translates unless
    the straight move crosses an occupied or unknown cell (no tunnelling), ends off the free
    space, or ``blocked_at(target)`` says something else stands there (people). Returns whether
    the translation was blocked. The simulators move the true robot with it, planners a
    hypothetical one (zero noise)."""
    heading = float(pose[2])
    dx = v * math.cos(heading) * dt + float(noise[0])
    dy = v * math.sin(heading) * dt + float(noise[1])
    pose[2] = wrap_angle_scalar(heading + omega * dt + float(noise[2]))
    distance = math.hypot(dx, dy)
    if distance == 0.0:
        return False
    values, res, ox, oy, c, s = grid.kernel_arrays()
    free_run = cast_ray(values, res, ox, oy, c, s, float(pose[0]), float(pose[1]),
                        math.atan2(dy, dx), distance, True)
    target = np.array([pose[0] + dx, pose[1] + dy])
    if free_run < distance or not grid.is_free(target):
        return True
    if blocked_at is not None and blocked_at(target):
        return True
    pose[0], pose[1] = target
    return False


@numba.njit(cache=True, nogil=True)
def move_on_cells(
    free: NDArray[np.bool_], x: int, y: int, dx: int, dy: int
) -> tuple[int, int, bool]:
    """One move of ``(dx, dy)`` cells from cell ``(x, y)`` on a free mask ``(X, Y)`` (the maze
    world): blocked, staying in place, when the target is off the mask or not free. Returns
    the new cell and whether the move was blocked."""
    tx, ty = x + dx, y + dy
    if 0 <= tx < free.shape[0] and 0 <= ty < free.shape[1] and free[tx, ty]:
        return tx, ty, False
    return x, y, True
