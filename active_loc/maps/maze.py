"""Mazes of the Active Neural Localization benchmark (Chaplot, Parisotto, Salakhutdinov, ICLR
2018), carved by Eller's algorithm as in the paper's released code.

Layout. An ``n x n`` maze (``n`` odd, >= 5) is a boolean array ``walls[iy, ix]`` (True = wall),
row ``iy = 0`` at the *bottom*, exactly like :attr:`OccupancyGrid.values
<active_loc.maps.occupancy.OccupancyGrid.values>` (one maze cell = one 1 m grid cell). Its
``m x m`` Eller cells (``m = (n - 1) // 2``) are the cells with odd ``ix`` and ``iy``; the even
rows and columns hold the border and the walls between Eller cells, and a passage is an even
cell opened between two Eller cells. Every maze is *perfect*: its ``m^2`` Eller cells are joined
by exactly ``m^2 - 1`` passages, so there is one path between any two free cells.

Eller's algorithm carves the rows from the top (``iy = n - 2``) down:

1. In every row but the last, each pair of horizontal neighbours in different sets is joined
   (the wall between them opened, the sets merged) with probability ``p_join = 2/3``.
2. Then each cell opens the wall below it with probability ``p_down = 1/3``, except that a set
   whose cells have all declined so far must open it at its rightmost cell (so every set
   continues into the next row). Cells without a passage below start new sets.
3. In the last row, neighbours in different sets are joined with probability ``p_join``, and
   always when the left one is the rightmost cell of its set in the row, which connects all
   sets.

All randomness is drawn up front: ``m (m - 1)`` uniforms for the joins and ``(m - 1) m`` for
the passages down, per maze, from the Generator passed in, then carved by a numba kernel.

Training mazes exclude mazes that equal their own 90- or 180-degree rotation (on those the
pose can never be told apart from its rotated twin). :func:`maze_test_set` gives the fixed,
reproducible evaluation set: ``count`` distinct (maze, start pose) pairs, symmetric mazes
excluded, as the paper's test data (1000 per size).

Files. :func:`load_maze_set` reads a :class:`MazeSet` from either of two layouts, told apart
by the suffix (read with ``allow_pickle=False``, checked before anything is built from them):

* ``.npy``, the layout of the paper's released test data (``test_data/m7_n1000.npy`` of
  Active Neural Localization): a 2-D array with one row per maze of ``n * n + 3`` numbers,
  the flattened map ``M[r, c]`` (1 = wall, 0 = free, row ``r = 0`` at the *top*), then the
  start's ``row``, ``col`` and ``orientation`` (0 east = ``col + 1``, 1 north = ``row - 1``,
  2 west, 3 south; turning left adds 1). Read as ``walls[iy, ix] = M[n - 1 - iy, ix]``, start
  ``(ix, iy, h) = (col, n - 1 - row, orientation)``: the orientation codes are this module's
  headings (:data:`HEADING_STEPS`), because the paper's north, toward row 0, is +y here.
  :meth:`MazeSet.to_anl` and :meth:`MazeSet.save_anl` write it back (float64, as the released
  files are), so ANL rows -> :class:`MazeSet` -> ANL rows is exact.
* ``.npz``, :meth:`MazeSet.save`'s archive: ``walls`` ``(count, n, n)`` bool in this module's
  layout, ``starts`` ``(count, 3)`` int64 ``(ix, iy, heading)``, and ``seed`` (int64, absent
  when the set has none).
"""

from __future__ import annotations

import functools
import math
import os
import zipfile
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numba
import numpy as np
from numpy.typing import ArrayLike, NDArray

from active_loc.maps.map_image import MapFileError, MapFileNotFoundError
from active_loc.maps.occupancy import FREE, OCCUPIED, OccupancyGrid

#: probability that two neighbours of different sets in a row are joined (the paper's 2/3)
P_JOIN = 2.0 / 3.0
#: probability that a cell opens the wall below it when its set does not need it (the paper's
#: code keeps the wall with probability 2/3)
P_DOWN = 1.0 / 3.0
#: the seed of the standard test sets (what :class:`~active_loc.envs.maze_env.MazeEnv` replays
#: when given a maze index or a test-set size)
TEST_SET_SEED = 2018
#: heading h -> unit step (dx, dy) in cells: 0 east (+x), 1 north (+y), 2 west, 3 south;
#: turning left is h + 1 (mod 4)
HEADING_STEPS = np.array([[1, 0], [0, 1], [-1, 0], [0, -1]], dtype=np.int64)
HEADING_STEPS.setflags(write=False)

_MAX_ATTEMPTS_PER_MAZE = 200
#: the most entries a generated test set may hold (at n = 21, 10**5 entries take about 6 s
#: and 44 MB)
MAX_TEST_SET_COUNT = 100_000
#: draws in a row without a new (maze, start) pair after which a size is taken to have no more
#: (small mazes have few: at n = 7 about 13 000)
_STALL_DRAWS = 5000
#: the suffix of the paper's test-data layout and of :meth:`MazeSet.save`'s archive
ANL_SUFFIX = ".npy"
MAZE_SET_SUFFIX = ".npz"
#: the largest maze file read (bytes): 10**5 mazes of 21 x 21 in the paper's float64 rows take
#: 355 MB
MAX_MAZE_FILE_BYTES = 2**30
#: the first bytes of a NumPy ``.npy`` file and of a zip archive (``.npz``)
_NPY_MAGIC = b"\x93NUMPY"
_ZIP_MAGIC = b"PK"


@numba.njit(cache=True, nogil=True)
def _same_set_right(labels: NDArray, i: int) -> bool:
    """Whether a cell right of ``i`` in the row shares its set."""
    for k in range(i + 1, labels.shape[0]):
        if labels[k] == labels[i]:
            return True
    return False


@numba.njit(cache=True, nogil=True)
def _merge(labels: NDArray, keep: int, drop: int) -> None:
    for k in range(labels.shape[0]):
        if labels[k] == drop:
            labels[k] = keep


@numba.njit(cache=True, nogil=True)
def eller_carve(
    u_join: NDArray, u_down: NDArray, p_join: float, p_down: float, walls: NDArray
) -> None:
    """Carve a maze into ``walls`` ``(n, n)`` bool (all True on entry), rows top to bottom.

    Args:
        u_join: ``(m, m - 1)`` uniforms in [0, 1): the join decisions, row by row.
        u_down: ``(m - 1, m)`` uniforms: the passage-down decisions of every row but the last.
        p_join, p_down: the probabilities of an optional join and an optional passage down.
        walls: ``(n, n)`` bool, ``n = 2 m + 1``, row 0 at the bottom; written in place.
    """
    m = u_join.shape[0]
    n = walls.shape[0]
    for r in range(m):
        for i in range(m):
            walls[n - 2 - 2 * r, 2 * i + 1] = False
    labels = np.arange(m)
    down = np.zeros(m, dtype=np.bool_)
    fresh = m
    for r in range(m):
        iy = n - 2 - 2 * r  # array row of Eller row r (row 0 is the top of the maze)
        last = r == m - 1
        for i in range(m - 1):
            if labels[i] == labels[i + 1]:
                continue
            if last:
                join = (not _same_set_right(labels, i)) or u_join[r, i] < p_join
            else:
                join = u_join[r, i] < p_join
            if join:
                walls[iy, 2 * i + 2] = False
                _merge(labels, labels[i], labels[i + 1])
        if last:
            break
        for i in range(m):
            other = _same_set_right(labels, i)
            for k in range(i):
                if down[k] and labels[k] == labels[i]:
                    other = True
            down[i] = (not other) or u_down[r, i] < p_down
            if down[i]:
                walls[iy - 1, 2 * i + 1] = False
        for i in range(m):
            if not down[i]:
                labels[i] = fresh
                fresh += 1


def _check_size(n: int, where: str) -> int:
    if isinstance(n, (bool, np.bool_)) or not isinstance(n, (int, np.integer)):
        raise ValueError(f"{where}: n must be an odd integer >= 5, got {n!r}")
    n = int(n)
    if n < 5 or n % 2 == 0:
        raise ValueError(f"{where}: n must be an odd integer >= 5, got {n}")
    return n


def eller_maze(
    n: int, rng: np.random.Generator, p_join: float = P_JOIN, p_down: float = P_DOWN
) -> NDArray[np.bool_]:
    """One ``n x n`` Eller maze: ``(n, n)`` bool, True = wall, ``walls[iy, ix]``, row 0 at the
    bottom, with a wall border. Draws ``2 m (m - 1)`` uniforms from ``rng``.

    Raises:
        ValueError: ``n`` is not an odd integer >= 5, or a probability is outside [0, 1].
    """
    n = _check_size(n, "eller_maze")
    for name, p in (("p_join", p_join), ("p_down", p_down)):
        if not 0.0 <= float(p) <= 1.0:
            raise ValueError(f"eller_maze: {name} must be in [0, 1], got {p}")
    m = (n - 1) // 2
    u_join = rng.random((m, m - 1))
    u_down = rng.random((m - 1, m))
    walls = np.ones((n, n), dtype=np.bool_)
    eller_carve(u_join, u_down, float(p_join), float(p_down), walls)
    return walls


def is_rotation_symmetric(walls: ArrayLike) -> bool:
    """Whether a square maze equals its own 90- or 180-degree rotation (then 270 too)."""
    walls = np.asarray(walls)
    if walls.ndim != 2 or walls.shape[0] != walls.shape[1]:
        raise ValueError(f"is_rotation_symmetric: walls must be square (n, n), got {walls.shape}")
    # w[::-1, ::-1] is the 180-degree rotation, w.T[::-1] the 90-degree one (np.rot90)
    return bool((walls == walls[::-1, ::-1]).all() or (walls == walls.T[::-1]).all())


def random_maze(n: int, rng: np.random.Generator) -> NDArray[np.bool_]:
    """An Eller maze that is not rotation-symmetric (symmetric draws are redrawn): a training
    maze. ``(n, n)`` bool, True = wall, row 0 at the bottom."""
    for _ in range(_MAX_ATTEMPTS_PER_MAZE):
        walls = eller_maze(n, rng)
        if not is_rotation_symmetric(walls):
            return walls
    raise RuntimeError(
        f"random_maze: no asymmetric {n} x {n} maze in {_MAX_ATTEMPTS_PER_MAZE} draws"
    )


def random_start(walls: NDArray[np.bool_], rng: np.random.Generator) -> NDArray[np.int64]:
    """A start pose ``(3,)`` int64 ``(ix, iy, heading)``: a free cell uniformly, then one of the
    4 headings uniformly (two draws from ``rng``)."""
    iy, ix = np.nonzero(~walls)
    k = int(rng.integers(ix.shape[0]))
    heading = int(rng.integers(4))
    return np.array([ix[k], iy[k], heading], dtype=np.int64)


def maze_to_grid(walls: ArrayLike) -> OccupancyGrid:
    """The maze as an :class:`OccupancyGrid` (walls OCCUPIED, the rest FREE), resolution 1 m,
    origin ``(0, 0, 0)``: maze cell ``(ix, iy)`` spans ``[ix, ix + 1) x [iy, iy + 1)`` m."""
    walls = np.asarray(walls, dtype=bool)
    return OccupancyGrid(np.where(walls, OCCUPIED, FREE).astype(np.int8), 1.0)


@dataclass(frozen=True, eq=False)
class MazeSet:
    """A fixed list of (maze, start pose) pairs, to replay episodes exactly.

    Attributes:
        walls: ``(count, n, n)`` bool, True = wall, ``walls[k, iy, ix]`` with row 0 at the
            bottom. Stored read-only.
        starts: ``(count, 3)`` int64 ``(ix, iy, heading)`` start poses, each on a free cell,
            heading in 0..3 (0 east, 1 north, 2 west, 3 south). Stored read-only.
        seed: the seed it was generated from (information only; ``None`` if built by hand).
        source: the file it was read from (information only; ``None`` if built in memory).
    """

    walls: NDArray[np.bool_]
    starts: NDArray[np.int64]
    seed: int | None = None
    source: str | None = None

    def __post_init__(self) -> None:
        walls = np.array(self.walls, dtype=bool)
        starts = np.array(self.starts)
        if walls.ndim != 3 or walls.shape[1] != walls.shape[2] or walls.shape[0] < 1:
            raise ValueError(
                f"MazeSet.walls must have shape (count >= 1, n, n), got {walls.shape}"
            )
        count, n, _ = walls.shape
        _check_size(n, "MazeSet.walls")
        if starts.shape != (count, 3) or starts.dtype.kind not in "iu":
            raise ValueError(
                f"MazeSet.starts must be integers of shape ({count}, 3), got {starts.shape} "
                f"{starts.dtype}"
            )
        starts = starts.astype(np.int64)
        ix, iy, h = starts[:, 0], starts[:, 1], starts[:, 2]
        inside = (ix >= 0) & (ix < n) & (iy >= 0) & (iy < n)
        bad = ~inside | (h < 0) | (h > 3)
        if bad.any():
            k = int(np.argmax(bad))
            raise ValueError(
                f"MazeSet.starts must be (ix, iy, heading) in the {n} x {n} maze, heading 0..3; "
                f"entry {k} is {tuple(starts[k].tolist())}"
            )
        on_wall = walls[np.arange(count), iy, ix]
        if on_wall.any():
            k = int(np.argmax(on_wall))
            raise ValueError(
                f"MazeSet.starts must lie on free cells; entry {k}, {tuple(starts[k].tolist())}, "
                "is on a wall"
            )
        walls.setflags(write=False)
        starts.setflags(write=False)
        object.__setattr__(self, "walls", walls)
        object.__setattr__(self, "starts", starts)

    def __len__(self) -> int:
        return int(self.walls.shape[0])

    @property
    def size(self) -> int:
        """n, the side of the mazes (cells)."""
        return int(self.walls.shape[1])

    def __getitem__(self, k: int) -> tuple[NDArray[np.bool_], NDArray[np.int64]]:
        """Maze ``k``: its walls ``(n, n)`` and start pose ``(3,)`` (read-only views)."""
        return self.walls[k], self.starts[k]

    def __getstate__(self) -> dict:
        return dict(self.__dict__)

    def __setstate__(self, state: dict) -> None:
        for value in state.values():
            if isinstance(value, np.ndarray):
                value.setflags(write=False)  # unpickled arrays come back writeable
        self.__dict__.setdefault("source", None)  # pickled before the field existed
        self.__dict__.update(state)

    # -- the paper's layout (see the module docstring) -------------------------------------------

    @classmethod
    def from_anl(cls, rows: ArrayLike, source: str | None = None) -> MazeSet:
        """The set held by rows in the layout of the paper's test data: ``(count, n * n + 3)``
        numbers per maze, the map (1 = wall, 0 = free, row 0 at the top), then the start's
        row, col and orientation (0 east, 1 north, 2 west, 3 south).

        Raises:
            ValueError: the rows are not that layout (the message names ``source`` and, where
                one is at fault, the maze by its index).
        """
        where = source if source is not None else "ANL maze rows"
        maps, start = _anl_rows(np.asarray(rows), where)
        n = maps.shape[1]
        row, col, orientation = start.T
        starts = np.stack([col, n - 1 - row, orientation], axis=1)
        return cls(maps[:, ::-1, :], starts, source=source)

    def to_anl(self) -> NDArray[np.float64]:
        """The set in the layout of the paper's test data: ``(count, n * n + 3)`` float64 (as
        the released files), each row the flattened map ``M[r, c]`` (1.0 wall, row 0 at the
        top) then the start's row, col and orientation; the inverse of :meth:`from_anl`."""
        n = self.size
        maps = self.walls[:, ::-1, :].reshape(len(self), n * n)
        ix, iy, h = self.starts.T
        start = np.stack([n - 1 - iy, ix, h], axis=1)
        return np.concatenate([maps, start], axis=1).astype(np.float64)

    # -- files ----------------------------------------------------------------------------------

    def save(self, path: str | os.PathLike[str]) -> None:
        """Write the set to ``path`` (ending in ``.npz``) as :func:`load_maze_set` reads it:
        ``walls``, ``starts`` and (when not None) ``seed``, compressed."""
        target = _maze_file_path(path, MAZE_SET_SUFFIX)
        arrays = {"walls": self.walls, "starts": self.starts}
        if self.seed is not None:
            arrays["seed"] = np.int64(self.seed)
        np.savez_compressed(target, **arrays)

    def save_anl(self, path: str | os.PathLike[str]) -> None:
        """Write :meth:`to_anl` to ``path`` (ending in ``.npy``): the paper's test-data file."""
        np.save(_maze_file_path(path, ANL_SUFFIX), self.to_anl())


def _anl_rows(rows: NDArray, where: str) -> tuple[NDArray[np.bool_], NDArray[np.int64]]:
    """The maps ``(count, n, n)`` bool (``M[k, r, c]``, row 0 at the top) and starts
    ``(count, 3)`` int64 ``(row, col, orientation)`` of rows in the paper's layout, checked.

    Raises:
        ValueError: naming ``where`` and what is wrong.
    """
    if rows.dtype.kind not in "biuf":
        raise ValueError(f"{where}: must hold numbers (bool, integer or float), got dtype "
                         f"{rows.dtype}")
    if rows.ndim != 2 or rows.shape[0] < 1:
        raise ValueError(f"{where}: must be a 2-D array with one row per maze, (count >= 1, "
                         f"n * n + 3), got shape {rows.shape}")
    length = rows.shape[1]
    n = math.isqrt(max(length - 3, 0))
    if n * n != length - 3:
        raise ValueError(f"{where}: rows of {length} entries are not n * n + 3 for an integer n "
                         "(the n x n map, then the start's row, col and orientation)")
    if n < 5 or n % 2 == 0:
        raise ValueError(f"{where}: rows of {length} entries hold {n} x {n} maps; n must be an "
                         "odd integer >= 5")
    _first_bad(~np.isfinite(rows).all(axis=1), where, "holds a non-finite value (NaN or inf)")
    maps = rows[:, : n * n]
    _first_bad(((maps != 0) & (maps != 1)).any(axis=1), where,
               "has a map value other than 0 (free) and 1 (wall)")
    start = rows[:, n * n :]
    _first_bad((start != np.round(start)).any(axis=1), where,
               "has a start row, col or orientation that is not an integer")
    row, col, orientation = start.T  # ranges checked before the cast to integers
    _first_bad((row < 0) | (row >= n) | (col < 0) | (col >= n), where,
               f"has a start row or col outside 0..{n - 1}")
    _first_bad((orientation < 0) | (orientation > 3), where,
               "has an orientation not in 0..3 (0 east, 1 north, 2 west, 3 south)")
    start = start.astype(np.int64)
    row, col = start[:, 0], start[:, 1]
    maps = maps.reshape(-1, n, n).astype(bool)
    _first_bad(maps[np.arange(maps.shape[0]), row, col], where, "starts on a wall")
    return maps, start


def _first_bad(bad: NDArray[np.bool_], where: str, what: str) -> None:
    """Raise for the first maze (row of the file) where ``bad`` ``(count,)`` holds."""
    if bad.any():
        k = int(np.argmax(bad))
        raise ValueError(f"{where}: maze {k} (row {k} of the array) {what}")


def load_maze_set(path: str | os.PathLike[str]) -> MazeSet:
    """Read a :class:`MazeSet` from a ``.npy`` file in the layout of the paper's test data or
    from a ``.npz`` archive of :meth:`MazeSet.save` (see the module docstring). Both are read
    with ``allow_pickle=False`` and checked whole before the set is built.

    Raises:
        TypeError: ``path`` is not a str or os.PathLike.
        MapFileNotFoundError: no such file (a ValueError and a FileNotFoundError).
        MapFileError: a ValueError naming the file and what is wrong: another suffix, not a
            NumPy file of that kind, larger than :data:`MAX_MAZE_FILE_BYTES`, Python objects,
            or arrays that are not a maze set.
    """
    file = _maze_file_path(path, ANL_SUFFIX, MAZE_SET_SUFFIX)
    if not file.exists():
        raise MapFileNotFoundError(f"{file}: no such maze file")
    if not file.is_file():
        raise MapFileError(f"{file}: is not a file")
    if file.stat().st_size > MAX_MAZE_FILE_BYTES:
        raise MapFileError(f"{file}: larger than {MAX_MAZE_FILE_BYTES} bytes")
    try:
        if file.suffix.lower() == ANL_SUFFIX:
            return MazeSet.from_anl(_read_npy(file), source=str(file))
        return _from_archive(_read_npz(file), file)
    except MapFileError:
        raise
    except ValueError as error:
        message = str(error)
        prefix = f"{file}: "
        raise MapFileError(message if message.startswith(prefix) else prefix + message) from None


def _maze_file_path(path: str | os.PathLike[str], *suffixes: str) -> Path:
    """``path`` as a Path, refused unless it is a str or os.PathLike ending in ``suffixes``."""
    if not isinstance(path, (str, os.PathLike)) or isinstance(os.fspath(path), bytes):
        raise TypeError(f"a maze file path must be a str or os.PathLike, got "
                        f"{type(path).__name__}: {path!r}")
    file = Path(path)
    if file.suffix.lower() not in suffixes:
        raise MapFileError(f"{file}: a maze file must end in {' or '.join(suffixes)} (the "
                           "paper's test-data layout, or MazeSet.save's archive)")
    return file


def _magic(file: Path) -> bytes:
    with file.open("rb") as handle:
        return handle.read(len(_NPY_MAGIC))


def _read_npy(file: Path) -> NDArray:
    """The array in a ``.npy`` file (no pickles)."""
    head = _magic(file)
    if head.startswith(_ZIP_MAGIC):
        raise MapFileError(f"{file}: is an .npz archive (a zip file), not an .npy array; "
                           "name it .npz if it was written by MazeSet.save")
    if head != _NPY_MAGIC:
        raise MapFileError(f"{file}: not a NumPy .npy file (no .npy header)")
    return _checked_load(file)


def _read_npz(file: Path) -> dict[str, NDArray]:
    """The arrays in a ``.npz`` archive (no pickles)."""
    if not _magic(file).startswith(_ZIP_MAGIC):
        raise MapFileError(f"{file}: not a NumPy .npz archive (not a zip file)")
    return _checked_load(file)


def _checked_load(file: Path) -> Any:
    """``np.load(file, allow_pickle=False)``, every array read, errors naming the file."""
    try:
        loaded = np.load(file, allow_pickle=False)
        if isinstance(loaded, np.lib.npyio.NpzFile):
            with loaded:
                return {name: loaded[name] for name in loaded.files}
        return loaded
    except ValueError as error:
        if "allow_pickle" in str(error):
            raise MapFileError(f"{file}: holds Python objects (an object array); maze files "
                               "hold numbers only and are read with allow_pickle=False") from None
        raise MapFileError(f"{file}: cannot be read: {error}") from None
    except (OSError, EOFError, zipfile.BadZipFile) as error:
        raise MapFileError(f"{file}: cannot be read: {error}") from None


_ARCHIVE_KEYS = ("walls", "starts", "seed")


def _from_archive(arrays: dict[str, NDArray], file: Path) -> MazeSet:
    """The :class:`MazeSet` of :meth:`MazeSet.save`'s arrays."""
    missing = [key for key in _ARCHIVE_KEYS[:2] if key not in arrays]
    unknown = sorted(set(arrays) - set(_ARCHIVE_KEYS))
    if missing or unknown:
        raise MapFileError(f"{file}: a MazeSet archive holds walls, starts and optionally seed; "
                           f"missing {missing}, unknown {unknown}")
    walls, starts = arrays["walls"], arrays["starts"]
    if walls.dtype != np.bool_:
        raise MapFileError(f"{file}: walls must be bool (True = wall), got dtype {walls.dtype}")
    seed = arrays.get("seed")
    if seed is not None and (seed.shape != () or seed.dtype.kind not in "iu"):
        raise MapFileError(f"{file}: seed must be one integer, got {seed.dtype} {seed.shape}")
    return MazeSet(walls, starts, None if seed is None else int(seed), source=str(file))


def maze_test_set(n: int, count: int, seed: int) -> MazeSet:
    """The fixed evaluation set: ``count`` distinct (maze, start pose) pairs of size ``n``.

    Each entry is an Eller maze that is not rotation-symmetric, a free start cell drawn
    uniformly and a heading drawn uniformly; an exact repeat of an earlier (maze, start) pair is
    redrawn. Entries are generated in order from ``numpy.random.default_rng(seed)``, so the
    first ``k`` entries of a set are the set of ``count = k``: the same seed always gives the
    same list. Results are cached (the set is immutable).

    Raises:
        ValueError: ``n`` is not an odd integer >= 5, ``count`` is not in
            ``[1, MAX_TEST_SET_COUNT]``, or there are fewer than ``count`` distinct pairs to be
            found (:data:`_STALL_DRAWS` draws in a row found no new one).
    """
    n = _check_size(n, "maze_test_set")
    if isinstance(count, (bool, np.bool_)) or not isinstance(count, (int, np.integer)):
        raise ValueError(f"maze_test_set: count must be an integer >= 1, got {count!r}")
    if not 1 <= count <= max_test_set_count(n):
        raise ValueError(
            f"maze_test_set: count must be an integer in [1, {max_test_set_count(n)}] for "
            f"{n} x {n} mazes (no more distinct (maze, start) pairs, or the cap "
            f"{MAX_TEST_SET_COUNT}), got {count}"
        )
    return _cached_test_set(n, int(count), int(seed))


def max_test_set_count(n: int) -> int:
    """The largest ``count`` :func:`maze_test_set` takes for ``n x n`` mazes:
    :data:`MAX_TEST_SET_COUNT`, or fewer where the size has fewer distinct (maze, start)
    pairs (at most 13056 at n = 7)."""
    return int(min(MAX_TEST_SET_COUNT, _pairs_at_most(_check_size(n, "max_test_set_count"))))


def _pairs_at_most(n: int) -> float:
    """An upper bound on the distinct (maze, start) pairs of ``n x n`` perfect mazes: the
    spanning trees of the ``m x m`` lattice of maze cells, ``m = (n - 1) / 2`` (the
    matrix-tree theorem), times the ``2 m^2 - 1`` free cells of each, times 4 headings.
    Infinite from ``n = 11``, where it exceeds :data:`MAX_TEST_SET_COUNT` a millionfold."""
    m = (n - 1) // 2
    if m > 4:
        return math.inf
    index = np.arange(m * m).reshape(m, m)
    laplacian = np.zeros((m * m, m * m))
    for a, b in ((index[:, :-1], index[:, 1:]), (index[:-1, :], index[1:, :])):
        laplacian[a.ravel(), b.ravel()] = laplacian[b.ravel(), a.ravel()] = -1.0
    laplacian[np.diag_indices(m * m)] = -laplacian.sum(axis=1)
    _, log_trees = np.linalg.slogdet(laplacian[1:, 1:])
    return float(np.exp(log_trees)) * (2 * m * m - 1) * 4


@functools.lru_cache(maxsize=16)
def _cached_test_set(n: int, count: int, seed: int) -> MazeSet:
    rng = np.random.default_rng(seed)
    walls = np.empty((count, n, n), dtype=bool)
    starts = np.empty((count, 3), dtype=np.int64)
    seen: set[bytes] = set()
    k = stalled = 0
    while k < count:
        if stalled >= _STALL_DRAWS:
            raise ValueError(
                f"maze_test_set: {n} x {n} mazes gave only {k} distinct (maze, start) pairs "
                f"({_STALL_DRAWS} draws in a row found no new one); ask for fewer than {count} "
                "or a larger n"
            )
        stalled += 1
        maze = eller_maze(n, rng)
        start = random_start(maze, rng)
        if is_rotation_symmetric(maze):
            continue
        key = np.packbits(maze).tobytes() + start.tobytes()
        if key in seen:
            continue
        seen.add(key)
        stalled = 0
        walls[k] = maze
        starts[k] = start
        k += 1
    return MazeSet(walls, starts, seed)
