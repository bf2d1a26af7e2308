"""Feature maps of point landmarks."""

from __future__ import annotations

from dataclasses import dataclass

import numba
import numpy as np
from numpy.typing import ArrayLike, NDArray


@dataclass(frozen=True)
class LandmarkMap:
    """Point landmarks in a rectangular workspace.

    Attributes:
        positions: ``(N, 2)`` landmark positions in the map frame (m); N >= 1.
        bounds: ``(x_min, y_min, x_max, y_max)`` of the workspace (m). Observations are
            normalized by it and, when ``walls`` is set, the robot cannot leave it.
        walls: whether the workspace border blocks motion (a blocked move is a collision).
    """

    positions: NDArray[np.float64]
    bounds: tuple[float, float, float, float]
    walls: bool = True

    def __post_init__(self) -> None:
        try:
            positions = np.array(self.positions, dtype=np.float64)
        except (TypeError, ValueError) as err:
            raise ValueError(
                f"LandmarkMap.positions must be an (N, 2) array of numbers: {err}"
            ) from None
        if positions.ndim != 2 or positions.shape[1] != 2:
            raise ValueError(f"LandmarkMap.positions must have shape (N, 2), got {positions.shape}")
        if positions.shape[0] == 0:
            raise ValueError("LandmarkMap.positions is empty: a landmark map needs >= 1 landmark")
        if not np.all(np.isfinite(positions)):
            raise ValueError("LandmarkMap.positions contains NaN or inf")
        if len(self.bounds) != 4:
            raise ValueError(
                f"LandmarkMap.bounds must be (x_min, y_min, x_max, y_max), got {self.bounds}"
            )
        x_min, y_min, x_max, y_max = (float(b) for b in self.bounds)
        finite = all(np.isfinite((x_min, y_min, x_max, y_max)))
        if not (finite and x_max > x_min and y_max > y_min):
            raise ValueError(
                f"LandmarkMap.bounds must be (x_min, y_min, x_max, y_max), finite, with "
                f"max > min, got {self.bounds}"
            )
        positions.setflags(write=False)
        object.__setattr__(self, "positions", positions)
        object.__setattr__(self, "bounds", (x_min, y_min, x_max, y_max))

    @classmethod
    def trusted(
        cls, positions: NDArray, bounds: tuple[float, float, float, float], walls: bool
    ) -> LandmarkMap:
        """A map from values already known to be valid (a generator's output): no checks, so
        that drawing a map every episode stays cheap."""
        out = cls.__new__(cls)
        positions.setflags(write=False)
        object.__setattr__(out, "positions", positions)
        object.__setattr__(out, "bounds", bounds)
        object.__setattr__(out, "walls", walls)
        return out

    @property
    def n_landmarks(self) -> int:
        return int(self.positions.shape[0])

    @property
    def size(self) -> tuple[float, float]:
        """Workspace width and height (m)."""
        return self.bounds[2] - self.bounds[0], self.bounds[3] - self.bounds[1]

    def contains(self, points: ArrayLike, margin: float = 0.0) -> NDArray[np.bool_]:
        """Whether world points ``(..., 2)`` lie inside the bounds shrunk by ``margin`` (m)."""
        points = np.asarray(points, dtype=np.float64)
        x_min, y_min, x_max, y_max = self.bounds
        return (
            (points[..., 0] >= x_min + margin)
            & (points[..., 0] <= x_max - margin)
            & (points[..., 1] >= y_min + margin)
            & (points[..., 1] <= y_max - margin)
        )


def random_landmark_map(
    rng: np.random.Generator,
    size: tuple[float, float] = (20.0, 20.0),
    n_landmarks: int | tuple[int, int] = (8, 15),
    min_separation: float = 1.5,
    margin: float = 1.0,
    walls: bool = True,
) -> LandmarkMap:
    """Draw a landmark map with the given Generator.

    Landmarks are placed uniformly in ``[margin, size - margin]`` by rejection so that no two are
    closer than ``min_separation`` (m); the count is fixed or drawn from the inclusive range.
    The map spans ``(0, 0)`` to ``size``.
    """
    width, height = (float(s) for s in size)
    if width <= 2 * margin or height <= 2 * margin:
        raise ValueError(f"random_landmark_map: size {size} leaves no room inside margin {margin}")
    if isinstance(n_landmarks, tuple):
        low, high = n_landmarks
        if not 1 <= low <= high:
            raise ValueError(
                f"random_landmark_map: n_landmarks range must be 1 <= lo <= hi, got {n_landmarks}"
            )
        count = int(rng.integers(low, high + 1))
    else:
        count = int(n_landmarks)
        if count < 1:
            raise ValueError(f"random_landmark_map: n_landmarks must be >= 1, got {count}")
    # rejection sampling: uniform candidates accepted greedily in order; a block of 16 per
    # landmark nearly always suffices, and the rare shortfall draws a longer sequence
    uniforms = rng.random((16 * count, 2))
    chosen = _first_separated(uniforms, count, min_separation, margin, width, height)
    for _ in range(4):
        if chosen.shape[0] == count:
            break
        uniforms = np.concatenate([uniforms, rng.random((8 * len(uniforms), 2))])
        chosen = _first_separated(uniforms, count, min_separation, margin, width, height)
    if chosen.shape[0] < count:
        raise ValueError(
            f"random_landmark_map: could not place {count} landmarks {min_separation} m apart "
            f"in {size}"
        )
    return LandmarkMap.trusted(chosen, (0.0, 0.0, width, height), walls)


@numba.njit(cache=True, nogil=True)
def _first_separated(
    uniforms: NDArray, count: int, min_separation: float, margin: float, width: float,
    height: float,
) -> NDArray:
    """Scale ``uniforms`` ``(M, 2)`` in [0, 1) to points in ``[margin, size - margin]`` and
    return the first ``count`` that keep ``min_separation`` (m) from every point accepted before
    them (fewer if the candidates run out)."""
    chosen = np.empty((count, 2))
    n = 0
    limit = min_separation * min_separation
    for i in range(uniforms.shape[0]):
        if n == count:
            break
        x = margin + uniforms[i, 0] * (width - 2 * margin)
        y = margin + uniforms[i, 1] * (height - 2 * margin)
        ok = True
        for j in range(n):
            dx = x - chosen[j, 0]
            dy = y - chosen[j, 1]
            if dx * dx + dy * dy < limit:
                ok = False
                break
        if ok:
            chosen[n, 0] = x
            chosen[n, 1] = y
            n += 1
    return chosen[:n].copy()
