"""Occupancy grid maps, in the layout and file format of ROS.

A grid stores one of three values per cell, as ``nav_msgs/OccupancyGrid`` does: ``FREE`` (0),
``OCCUPIED`` (100) and ``UNKNOWN`` (-1). Row ``iy = 0`` is the *bottom* of the map: the grid
lives in the ROS map frame (x right, y up), and ``origin = (x, y, yaw)`` is the world pose of
the bottom-left corner of cell ``(0, 0)``, exactly as map_server's ``origin``. A world point
``p`` has continuous grid coordinates

    (gx, gy) = R(yaw)^T (p - (origin_x, origin_y)) / resolution

and lies in cell ``(ix, iy) = (floor(gx), floor(gy))``; cell ``(ix, iy)`` spans
``[ix, ix + 1) x [iy, iy + 1)`` in grid coordinates and is ``values[iy, ix]``.

Files are map_server's: a YAML description next to an image (see :meth:`OccupancyGrid.load`
and :mod:`active_loc.maps.map_image`), read with PyYAML's safe loader.

The numba kernels :func:`world_to_grid` and :func:`cell_value` are the scalar twins of
:meth:`OccupancyGrid.world_to_cell` and :meth:`OccupancyGrid.value_at`, for ray casting and
particle weighting inside other kernels; they take the plain arrays and numbers of
:meth:`OccupancyGrid.kernel_arrays` and agree with the numpy methods bit for bit.
"""

from __future__ import annotations

import json
import math
import os
import re
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numba
import numpy as np
import yaml
from numpy.typing import ArrayLike, NDArray
from scipy import ndimage

from active_loc.maps.map_image import (
    MapFileError,
    MapImage,
    read_file_bytes,
    read_map_image,
)

FREE, OCCUPIED, UNKNOWN = 0, 100, -1
"""Cell values, as in ROS ``nav_msgs/OccupancyGrid``."""

OFF_MAP = -2
"""What :func:`cell_value` and :meth:`OccupancyGrid.value_at` return outside the grid."""

# map_saver's trinary pixel values and the thresholds it writes next to them
_PGM_FREE, _PGM_OCCUPIED, _PGM_UNKNOWN = 254, 0, 205
_SAVE_OCCUPIED_THRESH, _SAVE_FREE_THRESH = 0.65, 0.196
_MODES = ("trinary", "scale", "raw")
_ASCII = {"#": OCCUPIED, ".": FREE, "?": UNKNOWN}
# non-finite points map to this cell index: far outside any grid, and safe to cast to int64
_FAR = float(2**62)




@dataclass(frozen=True, eq=False)
class OccupancyGrid:
    """A 2-D occupancy grid in the ROS map frame.

    Attributes:
        values: ``(ny, nx)`` int8 array of ``FREE`` / ``OCCUPIED`` / ``UNKNOWN``; row ``iy = 0``
            is the bottom (y grows with the row index). Stored as a read-only C-contiguous copy.
        resolution: cell side (m per cell), finite and > 0.
        origin: ``(x, y, yaw)`` (m, m, rad): world pose of the bottom-left corner of cell
            ``(0, 0)``, as map_server's ``origin``.
        unknown_reflects: whether unknown cells stop lidar beams and count as obstacles in
            :meth:`distance_field`. Motion is always blocked by unknown cells, and they are
            never free for :meth:`is_free` / :meth:`sample_free`.

    The grid is immutable (``copy``/``deepcopy`` return it unchanged); ``==`` compares contents.
    """

    values: NDArray[np.int8]
    resolution: float
    origin: tuple[float, float, float] = (0.0, 0.0, 0.0)
    unknown_reflects: bool = True

    def __post_init__(self) -> None:
        raw = np.asarray(self.values)
        if raw.dtype.kind not in "iuf":
            raise ValueError(
                f"OccupancyGrid.values must be an integer array of FREE (0), OCCUPIED (100) and "
                f"UNKNOWN (-1), got dtype {raw.dtype}"
            )
        if raw.ndim != 2:
            raise ValueError(f"OccupancyGrid.values must be 2-D (ny, nx), got shape {raw.shape}")
        if raw.size == 0:
            raise ValueError(f"OccupancyGrid.values is empty (shape {raw.shape})")
        allowed = (raw == FREE) | (raw == OCCUPIED) | (raw == UNKNOWN)
        if not np.all(allowed):
            bad = np.unique(raw[~allowed])[:5].tolist()
            raise ValueError(
                f"OccupancyGrid.values may only hold FREE (0), OCCUPIED (100) and UNKNOWN (-1), "
                f"found {bad}"
            )
        values = np.array(raw, dtype=np.int8, order="C")  # a private copy
        values.setflags(write=False)

        try:
            resolution = float(self.resolution)
        except (TypeError, ValueError):
            raise ValueError(
                f"OccupancyGrid.resolution must be a positive number (m per cell), got "
                f"{self.resolution!r}"
            ) from None
        if not (math.isfinite(resolution) and resolution > 0.0):
            raise ValueError(
                f"OccupancyGrid.resolution must be finite and > 0 (m per cell), got {resolution}"
            )
        try:
            origin = tuple(float(o) for o in self.origin)
        except (TypeError, ValueError):
            raise ValueError(
                f"OccupancyGrid.origin must be (x, y, yaw) numbers, got {self.origin!r}"
            ) from None
        if len(origin) != 3 or not all(math.isfinite(o) for o in origin):
            raise ValueError(
                f"OccupancyGrid.origin must be 3 finite numbers (x, y, yaw), got {self.origin!r}"
            )
        if not isinstance(self.unknown_reflects, (bool, np.bool_)):
            raise ValueError(
                f"OccupancyGrid.unknown_reflects must be a bool, got {self.unknown_reflects!r}"
            )
        object.__setattr__(self, "values", values)
        object.__setattr__(self, "resolution", resolution)
        object.__setattr__(self, "origin", origin)
        object.__setattr__(self, "unknown_reflects", bool(self.unknown_reflects))
        # computed once here so that numpy methods and kernels use the very same numbers
        object.__setattr__(self, "_cos", math.cos(origin[2]))
        object.__setattr__(self, "_sin", math.sin(origin[2]))

    # --- value semantics of an immutable object ----------------------------------------------

    def __eq__(self, other: object) -> bool:
        if not isinstance(other, OccupancyGrid):
            return NotImplemented
        return (
            self.resolution == other.resolution
            and self.origin == other.origin
            and self.unknown_reflects == other.unknown_reflects
            and np.array_equal(self.values, other.values)
        )

    def __hash__(self) -> int:
        cached = self.__dict__.get("_hash")
        if cached is None:
            cached = hash(
                (self.values.shape, self.values.tobytes(), self.resolution, self.origin,
                 self.unknown_reflects)
            )
            object.__setattr__(self, "_hash", cached)
        return cached

    def __repr__(self) -> str:
        ny, nx = self.shape
        return (
            f"OccupancyGrid(shape=(ny={ny}, nx={nx}), resolution={self.resolution}, "
            f"origin={self.origin}, free_fraction={self.free_fraction:.3f}, "
            f"unknown_reflects={self.unknown_reflects})"
        )

    def __copy__(self) -> OccupancyGrid:
        return self

    def __deepcopy__(self, memo: dict) -> OccupancyGrid:
        return self  # immutable, like a tuple: sharing is safe and keeps the caches

    def __getstate__(self) -> dict[str, Any]:
        # the caches are derived data (the distance field can be megabytes): rebuilt on demand
        return {k: v for k, v in self.__dict__.items() if k in _STATE_KEYS}

    def __setstate__(self, state: dict[str, Any]) -> None:
        for key, value in state.items():
            if isinstance(value, np.ndarray):
                value.setflags(write=False)  # unpickled arrays come back writeable
            object.__setattr__(self, key, value)

    # --- geometry ----------------------------------------------------------------------------

    @property
    def shape(self) -> tuple[int, int]:
        """``(ny, nx)``: rows (y) and columns (x)."""
        ny, nx = self.values.shape
        return int(ny), int(nx)

    @property
    def size_m(self) -> tuple[float, float]:
        """``(width, height)`` of the grid (m), along its own x and y axes."""
        ny, nx = self.shape
        return nx * self.resolution, ny * self.resolution

    @property
    def bounds(self) -> tuple[float, float, float, float]:
        """``(x_min, y_min, x_max, y_max)`` (m): the world axis-aligned box around the map,
        yaw included (for a yawed grid it is larger than the map)."""
        ny, nx = self.shape
        corners = self._grid_to_world(np.array([0.0, nx, 0.0, nx]), np.array([0.0, 0.0, ny, ny]))
        return (
            float(corners[..., 0].min()),
            float(corners[..., 1].min()),
            float(corners[..., 0].max()),
            float(corners[..., 1].max()),
        )

    def world_to_grid(self, points: ArrayLike) -> NDArray[np.float64]:
        """Continuous grid coordinates ``(..., 2)`` ``(gx, gy)`` of world points ``(..., 2)``
        (m); cell ``(ix, iy)`` spans ``[ix, ix + 1) x [iy, iy + 1)``."""
        points = np.asarray(points, dtype=np.float64)
        if points.shape[-1:] != (2,):
            raise ValueError(f"points must have shape (..., 2), got {points.shape}")
        ox, oy, _ = self.origin
        c, s, res = self._cos, self._sin, self.resolution
        dx = points[..., 0] - ox
        dy = points[..., 1] - oy
        # the same operations in the same order as the kernel world_to_grid: identical floats.
        # An infinite coordinate makes 0 * inf = NaN, which is fine here (it is off the map).
        with np.errstate(invalid="ignore"):
            gx = (c * dx + s * dy) / res
            gy = (-s * dx + c * dy) / res
        return np.stack([gx, gy], axis=-1)

    def world_to_cell(self, points: ArrayLike) -> NDArray[np.int64]:
        """Cells ``(..., 2)`` int64 ``(ix, iy)`` containing world points ``(..., 2)`` (m).

        Cells may lie outside the grid (check with :meth:`in_grid`); a NaN or infinite
        coordinate gives an index of magnitude 2**62, far outside any grid.
        """
        grid = np.floor(self.world_to_grid(points))
        grid = np.clip(np.nan_to_num(grid, nan=-_FAR), -_FAR, _FAR)
        return grid.astype(np.int64)

    def cell_to_world(self, cells: ArrayLike) -> NDArray[np.float64]:
        """World centres ``(..., 2)`` (m) of cells ``(..., 2)`` ``(ix, iy)`` (any cell, also
        off-grid ones)."""
        cells = np.asarray(cells, dtype=np.float64)
        if cells.shape[-1:] != (2,):
            raise ValueError(f"cells must have shape (..., 2), got {cells.shape}")
        return self._grid_to_world(cells[..., 0] + 0.5, cells[..., 1] + 0.5)

    def _grid_to_world(self, gx: NDArray, gy: NDArray) -> NDArray[np.float64]:
        ox, oy, _ = self.origin
        c, s, res = self._cos, self._sin, self.resolution
        u, v = gx * res, gy * res
        return np.stack([ox + c * u - s * v, oy + s * u + c * v], axis=-1)

    def in_grid(self, cells: ArrayLike) -> NDArray[np.bool_]:
        """Whether cells ``(..., 2)`` ``(ix, iy)`` lie inside the grid; shape ``(...)``."""
        cells = np.asarray(cells)
        if cells.shape[-1:] != (2,):
            raise ValueError(f"cells must have shape (..., 2), got {cells.shape}")
        ny, nx = self.shape
        ix, iy = cells[..., 0], cells[..., 1]
        return (ix >= 0) & (ix < nx) & (iy >= 0) & (iy < ny)

    def value_at(self, points: ArrayLike) -> NDArray[np.int8]:
        """Cell values ``(...)`` int8 at world points ``(..., 2)`` (m): ``FREE``,
        ``OCCUPIED``, ``UNKNOWN``, or ``OFF_MAP`` outside the grid."""
        cells = self.world_to_cell(points)
        inside = self.in_grid(cells)
        ix = np.where(inside, cells[..., 0], 0)
        iy = np.where(inside, cells[..., 1], 0)
        return np.where(inside, self.values[iy, ix], np.int8(OFF_MAP)).astype(np.int8)

    def is_free(self, points: ArrayLike) -> NDArray[np.bool_]:
        """Whether world points ``(..., 2)`` (m) lie in FREE cells; shape ``(...)``. Unknown,
        occupied and off-map points are not free."""
        return self.value_at(points) == FREE

    # --- free space --------------------------------------------------------------------------

    @property
    def n_free(self) -> int:
        """Number of FREE cells."""
        return int(self._free_flat().shape[0])

    @property
    def free_fraction(self) -> float:
        """Fraction of the grid's cells that are FREE, in [0, 1]."""
        return self.n_free / self.values.size

    def _free_flat(self) -> NDArray[np.int64]:
        cached = self.__dict__.get("_free_flat_cache")
        if cached is None:
            cached = np.flatnonzero(self.values == FREE)
            cached.setflags(write=False)
            object.__setattr__(self, "_free_flat_cache", cached)
        return cached

    def sample_free(self, rng: np.random.Generator, n: int) -> NDArray[np.float64]:
        """``(n, 2)`` world points (m) uniform over free space.

        Each FREE cell is equally likely and the point is uniform inside it (up to a margin of
        1e-6 cell at the cell's edges, so that rounding in the frame transform can never move a
        point into a neighbouring cell). All randomness comes from ``rng``.

        Raises:
            ValueError: ``n`` is negative or the map has no free cell.
        """
        if isinstance(n, bool) or not isinstance(n, (int, np.integer)) or n < 0:
            raise ValueError(f"sample_free: n must be an integer >= 0, got {n!r}")
        free = self._free_flat()
        if free.shape[0] == 0:
            raise ValueError("sample_free: the map has no free cell")
        flat = free[rng.integers(0, free.shape[0], size=int(n))]
        iy, ix = np.divmod(flat, self.shape[1])
        margin = 1e-6
        jitter = margin + (1.0 - 2.0 * margin) * rng.random((int(n), 2))
        return self._grid_to_world(ix + jitter[:, 0], iy + jitter[:, 1])

    def distance_field(self) -> NDArray[np.float64]:
        """``(ny, nx)`` float64, read-only: Euclidean distance (m) from each cell centre to
        the nearest obstacle cell centre (0 on obstacles).

        Obstacles are OCCUPIED cells, and UNKNOWN cells iff ``unknown_reflects``. Cells off
        the grid are not obstacles. A map without obstacles gets the map diagonal everywhere
        (large but finite). Computed once and cached.
        """
        cached = self.__dict__.get("_distance_field")
        if cached is None:
            obstacles = self.values == OCCUPIED
            if self.unknown_reflects:
                obstacles |= self.values == UNKNOWN
            if obstacles.any():
                cached = ndimage.distance_transform_edt(~obstacles, sampling=self.resolution)
                cached = np.ascontiguousarray(cached, dtype=np.float64)
            else:
                cached = np.full(self.shape, math.hypot(*self.size_m))
            cached.setflags(write=False)
            object.__setattr__(self, "_distance_field", cached)
        return cached

    # --- kernels -----------------------------------------------------------------------------

    def kernel_arrays(self) -> tuple[NDArray[np.int8], float, float, float, float, float]:
        """What the numba kernels need: ``(values, resolution, origin_x, origin_y, cos_yaw,
        sin_yaw)``, with ``values`` the read-only C-contiguous ``(ny, nx)`` int8 array.

        Use as ``gx, gy = world_to_grid(x, y, ox, oy, c, s, res)`` then
        ``cell_value(values, gx, gy)``.
        """
        ox, oy, _ = self.origin
        return self.values, self.resolution, ox, oy, self._cos, self._sin

    # --- construction and files ----------------------------------------------------------------

    @classmethod
    def from_ascii(
        cls,
        rows: list[str],
        resolution: float,
        origin: tuple[float, float, float] = (0.0, 0.0, 0.0),
        unknown_reflects: bool = True,
    ) -> OccupancyGrid:
        """A grid drawn as text: ``'#'`` occupied, ``'.'`` free, ``'?'`` unknown. The first
        string is the TOP row (largest y), as the map looks on screen."""
        if isinstance(rows, str) or len(rows) == 0:
            raise ValueError("from_ascii: rows must be a non-empty list of strings")
        width = len(rows[0])
        grid = np.empty((len(rows), width), dtype=np.int8)
        for r, row in enumerate(rows):
            if len(row) != width:
                raise ValueError(
                    f"from_ascii: row {r} has {len(row)} characters, row 0 has {width}"
                )
            for c, ch in enumerate(row):
                if ch not in _ASCII:
                    raise ValueError(
                        f"from_ascii: row {r} column {c}: {ch!r} is not '#', '.' or '?'"
                    )
                grid[r, c] = _ASCII[ch]
        return cls(grid[::-1], resolution, origin, unknown_reflects)

    @classmethod
    def load(cls, path: str | os.PathLike, unknown_reflects: bool = True) -> OccupancyGrid:
        """Read a ROS map_server map: the YAML at ``path`` and the image it names, as nav2's
        map_server reads them.

        YAML fields: ``image`` (relative to the YAML's folder, or absolute), ``resolution``
        (m/cell), ``origin: [x, y, yaw]``, ``occupied_thresh`` and ``free_thresh`` (in [0, 1],
        free < occupied), ``negate`` (0/1, default 0), ``mode`` (``trinary`` default, ``scale``
        or ``raw``). Numbers may be written as YAML 1.2 reads them (``5e-2``). The YAML is at
        most :data:`MAX_YAML_BYTES`, without anchors, aliases or nesting beyond origin's list.

        The image is a PGM (P5 or P2, 8 or 16 bit, parsed exactly) or any format Pillow reads
        (PNG, BMP, JPEG, ...); its row 0 is the TOP of the map. See
        :mod:`active_loc.maps.map_image` for gray, color and alpha, and :func:`_classify` for
        the thresholds: ``p >= occupied_thresh`` is OCCUPIED and ``p <= free_thresh`` FREE, both
        inclusive, so that ``free_thresh: 0.0`` keeps pure white free.

        Raises:
            MapFileNotFoundError: the YAML or the image does not exist (a ValueError and a
                FileNotFoundError).
            MapFileError: a bad YAML field, an unreadable or malformed image, or a file over
                its size limit (a ValueError naming the file).
        """
        yaml_path = Path(path)
        fields = _parse_map_yaml(_read_text(yaml_path), yaml_path)
        image = _require(fields, "image", yaml_path)
        if not isinstance(image, str) or not image.strip():
            raise MapFileError(
                f"{yaml_path}: field 'image' must be a file name, got {_short(repr(image))}"
            )
        resolution = _number(fields, "resolution", yaml_path)
        if not resolution > 0.0:
            raise MapFileError(
                f"{yaml_path}: field 'resolution' must be > 0 (m per cell), got {resolution}"
            )
        origin = _require(fields, "origin", yaml_path)
        origin = [_as_number(o) for o in origin] if isinstance(origin, list) else origin
        if not (
            isinstance(origin, list)
            and len(origin) == 3
            and all(_is_number(o) and math.isfinite(o) for o in origin)
        ):
            raise MapFileError(
                f"{yaml_path}: field 'origin' must be 3 finite numbers [x, y, yaw], got "
                f"{_short(repr(origin))}"
            )
        occupied_thresh = _number(fields, "occupied_thresh", yaml_path)
        free_thresh = _number(fields, "free_thresh", yaml_path)
        for name, value in (("occupied_thresh", occupied_thresh), ("free_thresh", free_thresh)):
            if not 0.0 <= value <= 1.0:
                raise MapFileError(f"{yaml_path}: field '{name}' must be in [0, 1], got {value}")
        if not free_thresh < occupied_thresh:
            raise MapFileError(
                f"{yaml_path}: free_thresh ({free_thresh}) must be < occupied_thresh "
                f"({occupied_thresh})"
            )
        negate = fields.get("negate", 0)
        if isinstance(negate, bool):
            negate = int(negate)
        if negate not in (0, 1) or isinstance(negate, float):
            raise MapFileError(
                f"{yaml_path}: field 'negate' must be 0 or 1, got {_short(repr(negate))}"
            )
        mode = fields.get("mode", "trinary")
        if mode not in _MODES:
            raise MapFileError(
                f"{yaml_path}: field 'mode' must be one of {', '.join(_MODES)}, got "
                f"{_short(repr(mode))}"
            )

        image_path = Path(image)
        if not image_path.is_absolute():
            image_path = yaml_path.parent / image_path
        pixels = read_map_image(image_path, yaml_path)
        values = _classify(pixels, mode, bool(negate), occupied_thresh, free_thresh)
        # image row 0 is the top of the map; grid row 0 is the bottom
        return cls(values[::-1], resolution, tuple(float(o) for o in origin), unknown_reflects)

    def save(self, path: str | os.PathLike) -> Path:
        """Write the map_server YAML at ``path`` and a trinary P5 PGM next to it (same stem,
        ``.pgm``): free 254, occupied 0, unknown 205 (map_saver's values), ``negate: 0``,
        ``occupied_thresh: 0.65``, ``free_thresh: 0.196``. Numbers are written with full
        precision, so :meth:`load` gives back an equal grid (``unknown_reflects``, which the
        format cannot hold, is :meth:`load`'s argument). Returns the YAML path."""
        yaml_path = Path(path)
        pgm_path = yaml_path.with_suffix(".pgm")
        if pgm_path == yaml_path:
            raise ValueError(f"save: {yaml_path} is the image's name; give a .yaml path")
        ny, nx = self.shape
        pixels = np.full(self.shape, _PGM_UNKNOWN, dtype=np.uint8)
        pixels[self.values == FREE] = _PGM_FREE
        pixels[self.values == OCCUPIED] = _PGM_OCCUPIED
        header = f"P5\n# CREATOR: active_loc {self.resolution!r} m/pix\n{nx} {ny}\n255\n"
        pgm_path.write_bytes(header.encode("ascii") + pixels[::-1].tobytes())
        x, y, yaw = self.origin
        lines = [
            f"image: {json.dumps(pgm_path.name)}",
            "mode: trinary",
            f"resolution: {_yaml_float(self.resolution)}",
            f"origin: [{_yaml_float(x)}, {_yaml_float(y)}, {_yaml_float(yaw)}]",
            "negate: 0",
            f"occupied_thresh: {_SAVE_OCCUPIED_THRESH}",
            f"free_thresh: {_SAVE_FREE_THRESH}",
        ]
        yaml_path.write_text("\n".join(lines) + "\n", encoding="utf-8")
        return yaml_path


_STATE_KEYS = frozenset({"values", "resolution", "origin", "unknown_reflects", "_cos", "_sin"})


# --- numba kernels ---------------------------------------------------------------------------


@numba.njit(cache=True, nogil=True)
def world_to_grid(
    x: float,
    y: float,
    origin_x: float,
    origin_y: float,
    cos_yaw: float,
    sin_yaw: float,
    resolution: float,
) -> tuple[float, float]:
    """Continuous grid coordinates ``(gx, gy)`` of the world point ``(x, y)`` (m); cell
    ``(ix, iy)`` spans ``[ix, ix + 1) x [iy, iy + 1)``. The arguments after ``y`` come from
    :meth:`OccupancyGrid.kernel_arrays`."""
    dx = x - origin_x
    dy = y - origin_y
    return (cos_yaw * dx + sin_yaw * dy) / resolution, (-sin_yaw * dx + cos_yaw * dy) / resolution


@numba.njit(cache=True, nogil=True)
def cell_value(values: NDArray, gx: float, gy: float) -> int:
    """Value of the cell holding grid coordinates ``(gx, gy)``: ``FREE``, ``OCCUPIED``,
    ``UNKNOWN``, or ``OFF_MAP`` outside the ``(ny, nx)`` grid (and for NaN)."""
    ny, nx = values.shape
    # written so that NaN fails every comparison and lands off the map
    if gx >= 0.0 and gx < nx and gy >= 0.0 and gy < ny:
        return values[int(gy), int(gx)]  # int() truncates, which is floor for gx >= 0
    return OFF_MAP


# --- map images ------------------------------------------------------------------------------


def _classify(
    image: MapImage, mode: str, negate: bool, occupied_thresh: float, free_thresh: float
) -> NDArray[np.int8]:
    """Three-class values ``(height, width)`` (image rows, top first) of a map image.

    ``trinary`` and ``scale``: a pixel ``v`` has occupancy probability ``p = (maxval - v) /
    maxval`` (``v / maxval`` with ``negate``); ``p >= occupied_thresh`` is OCCUPIED, ``p <=
    free_thresh`` FREE, anything between UNKNOWN. Scale mode's intermediate probabilities
    (map_server keeps them as 1..99) are UNKNOWN too: the grid holds three classes.
    ``raw``: the pixel scaled to 0..255 is the occupancy percentage; ``>= 100 occupied_thresh``
    is OCCUPIED, ``<= 100 free_thresh`` FREE, other values (and above 100) UNKNOWN; ``negate``
    does not apply. A pixel below full opacity is UNKNOWN in every mode.
    """
    pixels, maxval = image.pixels, image.maxval
    out = np.full(pixels.shape, UNKNOWN, dtype=np.int8)
    if mode == "raw":
        percent = (pixels * 255 + maxval // 2) // maxval  # the 0..255 value map_server reads
        valid = percent <= 100
        # p = percent / 100 is correctly rounded, so p == 0.65 exactly when percent == 65
        p = percent / 100.0
        out[valid & (p >= occupied_thresh)] = OCCUPIED
        out[valid & (p <= free_thresh)] = FREE
    else:
        # exact integer numerators keep threshold ties reproducible
        p = (pixels if negate else maxval - pixels) / float(maxval)
        out[p >= occupied_thresh] = OCCUPIED
        out[p <= free_thresh] = FREE  # free_thresh < occupied_thresh: the two never meet
    if image.opaque is not None:
        out[~image.opaque] = UNKNOWN
    return out


# --- the map_server YAML ---------------------------------------------------------------------

#: the largest map YAML read (bytes): map_server files are a few hundred
MAX_YAML_BYTES = 2**20
#: the deepest nesting a map YAML may hold: the mapping of fields, and origin's list in it
_MAX_YAML_DEPTH = 2
#: a YAML 1.2 float or integer, which PyYAML (YAML 1.1) leaves a string when it is written
#: without a '.' or an exponent sign, as ``5e-2`` or ``1e1``
_YAML12_NUMBER = re.compile(r"[-+]?(\.[0-9]+|[0-9]+(\.[0-9]*)?)([eE][-+]?[0-9]+)?")


class _UniqueKeyLoader(yaml.SafeLoader):
    """PyYAML's safe loader, but a key given twice is an error instead of the last one winning."""

    def construct_mapping(self, node: yaml.MappingNode, deep: bool = False) -> dict:
        seen = set()
        for key_node, _ in node.value:
            key = self.construct_object(key_node, deep=deep)
            if key in seen:
                raise yaml.constructor.ConstructorError(
                    None, None, f"field {key!r} appears twice", key_node.start_mark
                )
            seen.add(key)
        return super().construct_mapping(node, deep=deep)


def _check_yaml_shape(text: str, path: Path) -> None:
    """Refuse, from the event stream and before building any value, what a map file never
    holds: anchors and aliases (an alias bomb expands to gigabytes) and nesting deeper than
    :data:`_MAX_YAML_DEPTH` (a deep list exhausts the recursion of the loader)."""
    depth = 0
    try:
        for event in yaml.parse(text, Loader=yaml.SafeLoader):
            if isinstance(event, yaml.AliasEvent) or getattr(event, "anchor", None):
                raise MapFileError(f"{path}: YAML anchors and aliases are not allowed in a "
                                   "map file")
            if isinstance(event, yaml.CollectionStartEvent):
                depth += 1
                if depth > _MAX_YAML_DEPTH:
                    raise MapFileError(
                        f"{path}: YAML nested deeper than a mapping of fields holding lists"
                    )
            elif isinstance(event, yaml.CollectionEndEvent):
                depth -= 1
    except yaml.YAMLError as err:
        raise MapFileError(f"{path}: not valid YAML: {_short(str(err))}") from None


def _read_text(path: Path) -> str:
    try:
        return read_file_bytes(path, MAX_YAML_BYTES).decode("utf-8-sig")
    except UnicodeDecodeError as err:
        raise MapFileError(f"{path}: not a UTF-8 text file ({err.reason})") from None


def _parse_map_yaml(text: str, path: Path) -> dict[str, Any]:
    """The mapping of a map_server YAML file, read with PyYAML's safe loader."""
    _check_yaml_shape(text, path)
    try:
        data = yaml.load(text, Loader=_UniqueKeyLoader)  # a SafeLoader subclass: safe
    except yaml.YAMLError as err:
        raise MapFileError(f"{path}: not valid YAML: {_short(str(err))}") from None
    if data is None:
        raise MapFileError(f"{path}: empty map file: not a YAML mapping of map fields")
    if not isinstance(data, dict):
        raise MapFileError(
            f"{path}: not a YAML mapping of map fields (got a {type(data).__name__})"
        )
    return {str(key): value for key, value in data.items()}


def _short(text: str, limit: int = 200) -> str:
    """``text`` cut to ``limit`` characters, so that a message never repeats a huge value."""
    return text if len(text) <= limit else text[:limit] + f"... ({len(text)} characters)"


def _is_number(value: Any) -> bool:
    return isinstance(value, (int, float)) and not isinstance(value, bool)


def _as_number(value: Any) -> Any:
    """``value``, or the float a YAML 1.2 reader (ROS's yaml-cpp) sees in it where PyYAML
    (YAML 1.1) leaves a string such as ``5e-2``."""
    if isinstance(value, str) and _YAML12_NUMBER.fullmatch(value.strip()):
        return float(value)
    return value


def _require(fields: dict[str, Any], key: str, path: Path) -> Any:
    if key not in fields:
        raise MapFileError(f"{path}: missing field {key!r}")
    return fields[key]


def _number(fields: dict[str, Any], key: str, path: Path) -> float:
    value = _as_number(_require(fields, key, path))
    if not _is_number(value) or not math.isfinite(value):
        raise MapFileError(
            f"{path}: field {key!r} must be a finite number, got {_short(repr(value))}"
        )
    return float(value)


def _yaml_float(value: float) -> str:
    """``repr`` (shortest exact round trip) with a '.' in the mantissa, so that YAML 1.1
    readers (PyYAML) also see a float rather than a string in e.g. ``1e-05``."""
    text = repr(float(value))
    mantissa, sep, exponent = text.partition("e")
    if sep and "." not in mantissa:
        text = f"{mantissa}.0e{exponent}"
    return text
