"""Maze files (``active_loc.maps.maze``): the paper's ``.npy`` test-data layout and
``MazeSet.save``'s ``.npz``, read by ``load_maze_set``.

The paper's layout is checked on a hand-drawn maze whose cells and start pose are known one
by one, and against the paper's own rules (its ``Maze2D``: position ``(row, col)``, north is
``row - 1``, turning left adds 1 to the orientation) replayed here in plain Python.
"""

from __future__ import annotations

import zipfile
from pathlib import Path

import numpy as np
import pytest

from active_loc.maps.map_image import MapFileError, MapFileNotFoundError
from active_loc.maps.maze import (
    HEADING_STEPS,
    MazeSet,
    load_maze_set,
    maze_test_set,
)

#: a 7 x 7 maze as the paper stores it: row 0 is the TOP row, "#" = 1 (wall), "." = 0
PICTURE = (
    "#######",
    "#...#.#",
    "#.#.#.#",
    "#.#...#",
    "#.###.#",
    "#.....#",
    "#######",
)
#: the paper's (row, col) offset of each orientation code: 0 east, 1 north, 2 west, 3 south
ANL_STEPS = {0: (0, 1), 1: (-1, 0), 2: (0, -1), 3: (1, 0)}


def anl_map() -> np.ndarray:
    """``M[r, c]`` float64, 1.0 = wall, row 0 at the top."""
    return np.array([[1.0 if ch == "#" else 0.0 for ch in line] for line in PICTURE])


def anl_row(m: np.ndarray, row: int, col: int, orientation: int) -> np.ndarray:
    """One maze in the paper's layout (float64, as its ``np.concatenate`` makes it)."""
    return np.concatenate([m.flatten(), np.array([row, col]), np.array([orientation])])


def anl_rows() -> np.ndarray:
    m = anl_map()
    return np.stack([anl_row(m, 1, 1, 0), anl_row(m, 5, 1, 1), anl_row(m, 3, 5, 3)])


def anl_depth(m: np.ndarray, row: int, col: int, orientation: int) -> int:
    """The paper's depth: free cells from the robot's own, straight ahead."""
    dr, dc = ANL_STEPS[orientation]
    depth = 0
    while 0 <= row < m.shape[0] and 0 <= col < m.shape[1] and m[row, col] == 0:
        depth += 1
        row, col = row + dr, col + dc
    return depth


def our_depth(walls: np.ndarray, ix: int, iy: int, h: int) -> int:
    dx, dy = HEADING_STEPS[h]
    depth = 0
    while not walls[iy, ix]:
        depth += 1
        ix, iy = ix + dx, iy + dy
    return depth


# --- the paper's layout -----------------------------------------------------------------------


def test_the_paper_layout_maps_cell_by_cell_onto_walls_iy_ix_with_row_0_at_the_bottom() -> None:
    maze_set = MazeSet.from_anl(anl_rows())
    assert len(maze_set) == 3 and maze_set.size == 7
    walls = maze_set.walls[0]
    for r, line in enumerate(PICTURE):
        for c, ch in enumerate(line):
            assert walls[6 - r, c] == (ch == "#"), (r, c)
    # spot checks in our frame: the top row of the picture is iy = 6, a wall border
    assert walls[6].all() and walls[0].all()
    assert not walls[5, 1] and walls[5, 4]  # picture row 1: "#...#.#"
    assert not walls[1, 4]  # picture row 5: "#.....#"
    assert np.array_equal(walls, anl_map()[::-1].astype(bool))


def test_start_row_col_and_orientation_map_onto_ix_iy_and_heading() -> None:
    maze_set = MazeSet.from_anl(anl_rows())
    # (row, col, orientation) -> (ix = col, iy = n - 1 - row, heading = orientation)
    assert maze_set.starts.tolist() == [[1, 5, 0], [1, 1, 1], [5, 3, 3]]
    walls = maze_set.walls[0]
    # row 1, col 1 facing east: "#...#" -> 3 cells; our (1, 5) heading east reads the same
    assert anl_depth(anl_map(), 1, 1, 0) == our_depth(walls, 1, 5, 0) == 3
    # row 5, col 1 facing north (toward row 0): col 1 is free from row 5 up to row 1 -> 5
    assert anl_depth(anl_map(), 5, 1, 1) == our_depth(walls, 1, 1, 1) == 5
    # row 3, col 5 facing south (toward the bottom row): rows 3, 4, 5 -> 3
    assert anl_depth(anl_map(), 3, 5, 3) == our_depth(walls, 5, 3, 3) == 3


def test_every_pose_and_heading_reads_the_papers_depth() -> None:
    """The orientation codes are our headings: every free pose of a test set reads, in our
    frame, the depth the paper's rules give at the corresponding (row, col, orientation)."""
    maze_set = MazeSet.from_anl(maze_test_set(15, 3, seed=4).to_anl())
    rows = maze_set.to_anl()
    n = 15
    for k in range(len(maze_set)):
        m = rows[k, : n * n].reshape(n, n)
        for r in range(n):
            for c in range(n):
                if m[r, c] == 0:
                    for o in range(4):
                        assert anl_depth(m, r, c, o) == our_depth(maze_set.walls[k], c, n - 1 - r,
                                                                  o)


def test_anl_rows_to_maze_set_and_back_are_exact(tmp_path: Path) -> None:
    rows = anl_rows()
    again = MazeSet.from_anl(rows).to_anl()
    assert again.dtype == np.float64 and np.array_equal(again, rows)
    path = tmp_path / "m7_n3.npy"
    np.save(path, rows)
    loaded = load_maze_set(path)
    assert loaded.source == str(path)
    loaded.save_anl(tmp_path / "back.npy")
    back = np.load(tmp_path / "back.npy", allow_pickle=False)
    assert back.dtype == np.float64 and np.array_equal(back, rows)
    # integer rows (a file written by another tool) give the same set
    as_int = load_maze_set(_save(tmp_path / "int.npy", rows.astype(np.int64)))
    assert np.array_equal(as_int.walls, loaded.walls)
    assert np.array_equal(as_int.starts, loaded.starts)


def test_maze_set_to_anl_and_back_is_exact_for_generated_sets(tmp_path: Path) -> None:
    maze_set = maze_test_set(21, 4, seed=11)
    maze_set.save_anl(tmp_path / "m21.npy")
    loaded = load_maze_set(tmp_path / "m21.npy")
    assert np.array_equal(loaded.walls, maze_set.walls)
    assert np.array_equal(loaded.starts, maze_set.starts)
    assert loaded.to_anl().shape == (4, 21 * 21 + 3)


def test_a_paper_row_reads_as_the_papers_maze2d_reads_it() -> None:
    """``Maze2D.reset``: orientation ``maze[-1]``, position ``(maze[-3], maze[-2])``, map
    ``maze[:-3].reshape(n, n)``; written by ``to_anl``, they are our start and walls."""
    maze_set = maze_test_set(7, 5, seed=2)
    for k, maze in enumerate(maze_set.to_anl()):
        m = maze[:-3].reshape(7, 7)
        row, col, orientation = int(maze[-3]), int(maze[-2]), int(maze[-1])
        ix, iy, h = maze_set.starts[k].tolist()
        assert (col, 6 - row, orientation) == (ix, iy, h)
        assert np.array_equal(m[::-1] == 1, maze_set.walls[k])


# --- MazeSet's own archive ----------------------------------------------------------------------


@pytest.mark.parametrize("seed", [7, None])
def test_npz_round_trip_keeps_walls_starts_and_seed(tmp_path: Path, seed: int | None) -> None:
    original = maze_test_set(15, 3, seed=1)
    maze_set = MazeSet(original.walls, original.starts, seed)
    path = tmp_path / "set.npz"
    maze_set.save(path)
    loaded = load_maze_set(str(path))
    assert np.array_equal(loaded.walls, maze_set.walls) and loaded.walls.dtype == np.bool_
    assert np.array_equal(loaded.starts, maze_set.starts) and loaded.starts.dtype == np.int64
    assert loaded.seed == seed and loaded.source == str(path)
    assert not loaded.walls.flags.writeable


def test_save_refuses_another_suffix(tmp_path: Path) -> None:
    maze_set = maze_test_set(7, 2, seed=0)
    with pytest.raises(ValueError, match=r"set\.npy: a maze file must end in \.npz"):
        maze_set.save(tmp_path / "set.npy")
    with pytest.raises(ValueError, match=r"set\.npz: a maze file must end in \.npy"):
        maze_set.save_anl(tmp_path / "set.npz")
    assert not list(tmp_path.iterdir())


# --- bad files ----------------------------------------------------------------------------------


def _save(path: Path, array: np.ndarray) -> Path:
    np.save(path, array, allow_pickle=True)
    return path


def _with(rows: np.ndarray, k: int, column: int, value: float) -> np.ndarray:
    rows = rows.copy()
    rows[k, column] = value
    return rows


BAD_ROWS = [
    (anl_rows()[0], r"2-D array with one row per maze.*got shape \(52,\)"),
    (anl_rows()[:0], r"count >= 1.*got shape \(0, 52\)"),
    (anl_rows()[None], r"2-D array"),
    (anl_rows()[:, :-2], r"rows of 50 entries are not n \* n \+ 3 for an integer n"),
    (np.zeros((1, 39)), r"rows of 39 entries hold 6 x 6 maps; n must be an odd integer"),
    (_with(anl_rows(), 2, 10, 2.0), r"maze 2 \(row 2 of the array\) has a map value other than 0"),
    (_with(anl_rows(), 1, 3, 0.5), r"maze 1 .* map value other than 0 \(free\) and 1 \(wall\)"),
    (_with(anl_rows(), 0, 20, np.nan), r"maze 0 .* non-finite"),
    (_with(anl_rows(), 1, 50, np.inf), r"maze 1 .* non-finite"),
    (_with(anl_rows(), 0, 49, 1.5), r"maze 0 .* start row, col or orientation that is not an "
     "integer"),
    (_with(anl_rows(), 0, 49, 7.0), r"maze 0 .* start row or col outside 0\.\.6"),
    (_with(anl_rows(), 2, 50, -1.0), r"maze 2 .* start row or col outside"),
    (_with(anl_rows(), 1, 51, 4.0), r"maze 1 .* orientation not in 0\.\.3 \(0 east, 1 north"),
    (_with(anl_rows(), 0, 49, 0.0), r"maze 0 .* starts on a wall"),
    (_with(anl_rows(), 2, 50, 2.0), r"maze 2 .* starts on a wall"),  # row 3, col 2
    (np.array([["a"] * 52]), r"must hold numbers"),
    (anl_rows().astype(np.complex128), r"must hold numbers"),
]


@pytest.mark.parametrize(("rows", "message"), BAD_ROWS)
def test_bad_paper_rows_are_refused_naming_the_file_and_the_maze(
    tmp_path: Path, rows: np.ndarray, message: str
) -> None:
    path = _save(tmp_path / "bad.npy", rows)
    with pytest.raises(MapFileError, match=r"bad\.npy: .*" + message):
        load_maze_set(path)


def test_object_arrays_are_refused_without_unpickling(tmp_path: Path) -> None:
    rows = anl_rows().astype(object)
    path = _save(tmp_path / "objects.npy", rows)
    with pytest.raises(MapFileError, match=r"objects\.npy: holds Python objects .*allow_pickle"):
        load_maze_set(path)
    archive = tmp_path / "objects.npz"
    np.savez(archive, walls=np.array([None], dtype=object), starts=np.zeros((1, 3), int))
    with pytest.raises(MapFileError, match=r"objects\.npz: holds Python objects"):
        load_maze_set(archive)


@pytest.mark.parametrize(
    ("name", "content", "message"),
    [
        ("maze.txt", b"0 1 0", r"maze\.txt: a maze file must end in \.npy or \.npz"),
        ("maze", b"", r"maze: a maze file must end in"),
        ("maze.npy", b"not numpy at all", r"maze\.npy: not a NumPy \.npy file"),
        ("maze.npy", b"\x93NUMPY\x01\x00garbage", r"maze\.npy: cannot be read"),
        ("maze.npz", b"not a zip", r"maze\.npz: not a NumPy \.npz archive"),
        ("maze.npz", b"PK\x03\x04truncated", r"maze\.npz: cannot be read"),
    ],
)
def test_unreadable_files_are_refused_naming_the_file(
    tmp_path: Path, name: str, content: bytes, message: str
) -> None:
    path = tmp_path / name
    path.write_bytes(content)
    with pytest.raises(MapFileError, match=message):
        load_maze_set(path)


def test_an_archive_named_npy_and_an_array_named_npz_are_refused(tmp_path: Path) -> None:
    archive = tmp_path / "set.npy"
    with zipfile.ZipFile(archive, "w") as zf:
        zf.writestr("walls.npy", b"")
    with pytest.raises(MapFileError, match=r"set\.npy: is an \.npz archive"):
        load_maze_set(archive)
    array = tmp_path / "rows.npz"
    array.write_bytes((_save(tmp_path / "rows.npy", anl_rows())).read_bytes())
    with pytest.raises(MapFileError, match=r"rows\.npz: not a NumPy \.npz archive"):
        load_maze_set(array)


def test_missing_files_folders_and_non_paths(tmp_path: Path) -> None:
    with pytest.raises(MapFileNotFoundError, match=r"nowhere\.npy: no such maze file"):
        load_maze_set(tmp_path / "nowhere.npy")
    with pytest.raises(FileNotFoundError):
        load_maze_set(tmp_path / "nowhere.npz")
    (tmp_path / "folder.npy").mkdir()
    with pytest.raises(MapFileError, match=r"folder\.npy: is not a file"):
        load_maze_set(tmp_path / "folder.npy")
    for bad in (3, None, b"maze.npy", anl_rows()):
        with pytest.raises(TypeError, match=r"must be a str or os\.PathLike"):
            load_maze_set(bad)  # type: ignore[arg-type]


def test_bad_archives_are_refused_naming_the_file(tmp_path: Path) -> None:
    good = maze_test_set(7, 2, seed=0)
    cases = [
        ({"walls": good.walls}, r"missing \['starts'\]"),
        ({"walls": good.walls, "starts": good.starts, "extra": np.zeros(1)},
         r"unknown \['extra'\]"),
        ({"walls": good.walls.astype(np.uint8), "starts": good.starts}, r"walls must be bool"),
        ({"walls": good.walls, "starts": good.starts.astype(float)}, r"MazeSet\.starts must be "
         "integers"),
        ({"walls": good.walls, "starts": good.starts, "seed": np.array([1, 2])},
         r"seed must be one integer"),
        ({"walls": good.walls, "starts": np.array([[0, 0, 0], [1, 1, 0]])},
         r"MazeSet\.starts must lie on free cells; entry 0"),
        ({"walls": good.walls[:, :6, :6], "starts": good.starts}, r"MazeSet\.walls"),
    ]
    for k, (arrays, message) in enumerate(cases):
        path = tmp_path / f"bad{k}.npz"
        np.savez(path, **arrays)
        with pytest.raises(MapFileError, match=rf"bad{k}\.npz: .*{message}"):
            load_maze_set(path)


def test_files_over_the_size_limit_are_refused_before_reading(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    from active_loc.maps import maze

    path = _save(tmp_path / "big.npy", anl_rows())
    monkeypatch.setattr(maze, "MAX_MAZE_FILE_BYTES", 100)
    with pytest.raises(MapFileError, match=r"big\.npy: larger than 100 bytes"):
        load_maze_set(path)
