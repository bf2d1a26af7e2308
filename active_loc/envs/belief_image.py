"""The ``"image"`` observation: the belief itself as a picture over the map, for CNN policies.

With ``observation="image"`` (MCL and grid beliefs) an env observes a ``Dict``:

- ``"image"``: ``Box(0, 1, (H + 1, R, R), float32)``, ``R = image_size`` cells laid over the
  map's box (column ``i`` from ``x_min``, row ``j`` from ``y_min``: row 0 is the bottom, as in
  a ROS map), ``H = image_headings``. Channel ``h < H`` holds the belief's mass in each cell
  with a heading in ``[-pi + 2 pi h / H, -pi + 2 pi (h + 1) / H)``; together these channels sum
  to 1. Channel ``H`` is the map: the share of each cell's map cells that are not free (walls
  and unknown space; 1 off the map), or 1 where a landmark lies.
- ``"vector"``: the ``"belief"`` observation vector (belief summary, 8 x 8 histogram, scan).

A multi-modal belief is a picture a convolution reads directly: where each hypothesis is,
which way it faces, and which walls are near it. Everything comes from the belief and the
map, never from the true pose.
"""

from __future__ import annotations

import math
from typing import Any

import gymnasium as gym
import numba
import numpy as np
from numpy.typing import NDArray

from active_loc.maps import LandmarkMap, OccupancyGrid
from active_loc.maps.occupancy import FREE

IMAGE_KEY = "image"
VECTOR_KEY = "vector"


def image_shape(size: int, headings: int) -> tuple[int, int, int]:
    """``(C, R, R)`` of the image: ``headings`` belief channels and the map channel."""
    return headings + 1, size, size


def image_observation_space(size: int, headings: int, vector_size: int) -> gym.spaces.Dict:
    """The ``Dict`` observation space of ``observation="image"``."""
    return gym.spaces.Dict({
        IMAGE_KEY: gym.spaces.Box(0.0, 1.0, image_shape(size, headings), dtype=np.float32),
        VECTOR_KEY: gym.spaces.Box(-1.0, 1.0, (vector_size,), dtype=np.float32),
    })


@numba.njit(cache=True, nogil=True, inline="always")
def _bin(value: float, low: float, width: float, n: int) -> int:
    """The bin of ``value`` among ``n`` of ``width`` from ``low``, clamped to the end bins."""
    return min(max(math.floor((value - low) / width), 0), n - 1)


@numba.njit(cache=True, nogil=True, inline="always")
def _clip_to_one(values: NDArray[np.float32]) -> None:
    """Rounding may leave a cell that holds all the mass a hair above 1: back into the box."""
    for i in range(values.shape[0]):
        if values[i] > 1.0:
            values[i] = 1.0


@numba.njit(cache=True, nogil=True)
def particle_image(
    particles: NDArray[np.float64], weights: NDArray[np.float64], bounds: NDArray,
    out: NDArray[np.float32],
) -> None:
    """The belief channels ``out[:H]`` ``(H, R, R)`` of particles ``(K, 3)`` (m, m, rad) with
    normalized weights ``(K,)``, over the box ``bounds`` ``(4,)`` (particles outside fall into
    the border cells). The map channel ``out[H]`` is left as it is."""
    n_headings = out.shape[0] - 1
    ny, nx = out.shape[1], out.shape[2]
    out[:n_headings] = 0.0
    cell_w = (bounds[2] - bounds[0]) / nx
    cell_h = (bounds[3] - bounds[1]) / ny
    bin_w = 2.0 * math.pi / n_headings
    for k in range(particles.shape[0]):
        ix = _bin(particles[k, 0], bounds[0], cell_w, nx)
        iy = _bin(particles[k, 1], bounds[1], cell_h, ny)
        heading = (particles[k, 2] + math.pi) % (2.0 * math.pi) - math.pi
        ih = _bin(heading, -math.pi, bin_w, n_headings)
        out[ih, iy, ix] += weights[k]
    _clip_to_one(out[:n_headings].reshape(-1))


@numba.njit(cache=True, nogil=True)
def pooled_grid_image(
    prob: NDArray[np.float64], cell_index: NDArray[np.int64], heading_index: NDArray[np.int64],
    out: NDArray[np.float32],
) -> None:
    """The belief channels ``out[:H]`` ``(H, R, R)`` of one grid belief ``prob`` ``(X, Y, Hg)``:
    grid cell ``(x, y)`` goes to the image's flat cell ``cell_index[x * Y + y]`` and its
    heading bin ``g`` to channel ``heading_index[g]`` (:func:`grid_image_index`)."""
    n_headings = out.shape[0] - 1
    size = out.shape[1] * out.shape[2]
    flat = out.reshape(n_headings + 1, size)
    flat[:n_headings] = 0.0
    nx, ny, ng = prob.shape
    for x in range(nx):
        for y in range(ny):
            cell = cell_index[x * ny + y]
            for g in range(ng):
                p = prob[x, y, g]
                if p != 0.0:
                    flat[heading_index[g], cell] += p
    _clip_to_one(flat[:n_headings].reshape(-1))


def grid_image_index(
    centres_x: NDArray[np.float64], centres_y: NDArray[np.float64],
    headings: NDArray[np.float64], bounds: tuple[float, ...], size: int, n_headings: int,
) -> tuple[NDArray[np.int64], NDArray[np.int64]]:
    """Where :func:`pooled_grid_image` puts each grid cell and heading bin.

    Args:
        centres_x, centres_y: ``(X, Y)`` world centres of the grid belief's cells (m).
        headings: ``(Hg,)`` the headings of its bins (rad).
        bounds: the image's box ``(x_min, y_min, x_max, y_max)`` (m).
        size: R.
        n_headings: H.

    Returns:
        ``(X Y,)`` the flat image cell ``iy R + ix`` of each grid cell, and ``(Hg,)`` the image
        channel of each heading bin.
    """
    cells = _flat_cells(np.ravel(centres_x), np.ravel(centres_y), bounds, size)
    wrapped = (np.asarray(headings) + np.pi) % (2.0 * np.pi) - np.pi
    return cells, _bins(wrapped, -np.pi, np.pi, n_headings)


def _bins(values: NDArray[np.float64], low: float, high: float, n: int) -> NDArray[np.int64]:
    """The bin of each value among ``n`` equal bins over ``[low, high)``, clamped to the end
    bins (:func:`_bin`'s rule, over arrays)."""
    return np.clip(np.floor((values - low) / (high - low) * n), 0, n - 1).astype(np.int64)


def _flat_cells(x: NDArray[np.float64], y: NDArray[np.float64], bounds: tuple[float, ...],
                size: int) -> NDArray[np.int64]:
    """The flat image cell ``iy R + ix`` of each point ``(x, y)`` (m) over ``bounds``."""
    x_min, y_min, x_max, y_max = bounds
    return _bins(y, y_min, y_max, size) * size + _bins(x, x_min, x_max, size)


def map_channel(
    lmap: LandmarkMap | OccupancyGrid, bounds: tuple[float, ...], size: int
) -> NDArray[np.float32]:
    """``(R, R)`` the image's map channel over ``bounds``: on a grid the share of each image
    cell's map cells that are not free (1 where no map cell falls, as off a yawed map); on a
    landmark map 1 in the cells that hold a landmark, 0 elsewhere."""
    if isinstance(lmap, LandmarkMap):
        points = np.asarray(lmap.positions, dtype=np.float64).reshape(-1, 2)
        blocked = np.ones(len(points))
        total = None
    else:
        ny, nx = lmap.shape
        iy, ix = np.mgrid[0:ny, 0:nx]
        points = lmap.cell_to_world(np.stack([ix.ravel(), iy.ravel()], axis=-1))
        blocked = (lmap.values.ravel() != FREE).astype(np.float64)
        total = np.ones(len(points))
    flat = _flat_cells(points[:, 0], points[:, 1], bounds, size)
    hits = np.bincount(flat, weights=blocked, minlength=size * size)
    if total is None:
        return np.minimum(hits, 1.0).reshape(size, size).astype(np.float32)
    counts = np.bincount(flat, weights=total, minlength=size * size)
    share = np.divide(hits, counts, out=np.ones_like(hits), where=counts > 0)
    return share.reshape(size, size).astype(np.float32)


def copy_observations(obs: Any) -> Any:
    """A copy of a batch of observations: an array, or a dict of arrays (``"image"``)."""
    if isinstance(obs, dict):
        return {key: value.copy() for key, value in obs.items()}
    return obs.copy()


def copy_observation(obs: Any, b: int) -> Any:
    """A copy of row ``b`` of a batch of observations (an array, or a dict of arrays)."""
    if isinstance(obs, dict):
        return {key: value[b].copy() for key, value in obs.items()}
    return obs[b].copy()


def observation_vector(observation: Any) -> NDArray[np.float32]:
    """The observation vector of one observation: itself, or an image observation's
    ``"vector"``."""
    if isinstance(observation, dict):
        return observation[VECTOR_KEY]
    return observation
