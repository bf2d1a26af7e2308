"""Tests of ``active_loc.maps.maze``: Eller's mazes, the symmetry filter and the test sets.

The structural checks (border, perfect maze) use scipy's connected components, independent of
the generator; the probability checks compare frequencies with values worked out by hand from
the algorithm's rules (joins with probability 2/3, optional passages down with 1/3).
"""

from __future__ import annotations

import pickle

import numpy as np
import pytest
from scipy import ndimage

from active_loc.maps import generators
from active_loc.maps.maze import (
    P_DOWN,
    P_JOIN,
    TEST_SET_SEED,
    MazeSet,
    eller_maze,
    is_rotation_symmetric,
    maze_test_set,
    maze_to_grid,
    random_maze,
    random_start,
)
from active_loc.maps.occupancy import FREE, OCCUPIED

SIZES = (5, 7, 9, 15, 21)


def passages(walls: np.ndarray) -> int:
    """Open cells between Eller cells (one even and one odd index)."""
    open_ = ~walls
    iy, ix = np.nonzero(open_)
    return int(np.sum((iy % 2) != (ix % 2)))


@pytest.mark.parametrize("n", SIZES)
def test_mazes_have_a_wall_border_and_are_perfect(n: int) -> None:
    rng = np.random.default_rng(n)
    m = (n - 1) // 2
    for _ in range(40):
        walls = eller_maze(n, rng)
        assert walls.shape == (n, n) and walls.dtype == np.bool_
        assert walls[0].all() and walls[-1].all() and walls[:, 0].all() and walls[:, -1].all()
        assert not walls[1::2, 1::2].any()  # every Eller cell is free
        assert walls[::2, ::2].all()  # lattice corners are always walls
        # all free cells connected (4-connectivity: the robot's moves)...
        _, components = ndimage.label(~walls)
        assert components == 1
        # ... by a spanning tree: m^2 cells need exactly m^2 - 1 passages (no loop)
        assert passages(walls) == m * m - 1


def test_same_seed_same_maze_and_seeds_differ() -> None:
    a = eller_maze(15, np.random.default_rng(3))
    b = eller_maze(15, np.random.default_rng(3))
    assert np.array_equal(a, b)
    distinct = {eller_maze(15, np.random.default_rng(s)).tobytes() for s in range(10)}
    assert len(distinct) == 10


def test_a_maze_draws_a_fixed_number_of_uniforms() -> None:
    n, m = 9, 4
    rng, ref = np.random.default_rng(5), np.random.default_rng(5)
    eller_maze(n, rng)
    ref.random(2 * m * (m - 1))
    assert rng.random() == ref.random()


def test_extreme_probabilities_give_the_predicted_mazes() -> None:
    """p_join = 0, p_down = 1: only vertical corridors, then the last row joins every column
    (each cell there is the last of its set): a comb. p_join = 1, p_down = 0: full rows, each
    continuing down only at its rightmost cell (the one its set must open)."""
    n = 9
    comb = eller_maze(n, np.random.default_rng(0), p_join=0.0, p_down=1.0)
    expected = np.ones((n, n), dtype=bool)
    expected[1 : n - 1, 1::2] = False  # the columns of Eller cells, top to bottom
    expected[1, 1 : n - 1] = False  # the bottom row (the last carved) fully joined
    assert np.array_equal(comb, expected)

    snake = eller_maze(n, np.random.default_rng(0), p_join=1.0, p_down=0.0)
    expected = np.ones((n, n), dtype=bool)
    expected[1::2, 1 : n - 1] = False  # every Eller row fully joined
    expected[2 : n - 1 : 2, n - 2] = False  # passages down at the right end only
    assert np.array_equal(snake, expected)


def test_join_and_passage_frequencies_match_the_algorithm() -> None:
    """Top row of a 7 x 7 maze (3 Eller cells): each pair joins with probability 2/3; the
    left cell opens its passage down with probability 1/3 when joined to its neighbour (its
    set can continue elsewhere) and always when alone: 2/3 * 1/3 + 1/3 = 5/9."""
    rng = np.random.default_rng(11)
    count = 20_000
    mazes = np.stack([eller_maze(7, rng) for _ in range(count)])
    top = 5  # array row of the top Eller row
    sigma = np.sqrt(0.25 / count)
    assert abs((~mazes[:, top, 2]).mean() - P_JOIN) < 5 * sigma
    assert abs((~mazes[:, top, 4]).mean() - P_JOIN) < 5 * sigma
    assert abs((~mazes[:, top - 1, 1]).mean() - (P_JOIN * P_DOWN + 1 - P_JOIN)) < 5 * sigma
    # the 3 x 3 grid has 192 spanning trees; the generator reaches them all
    assert len({m.tobytes() for m in mazes}) == 192


def test_rotation_symmetry_is_detected_and_excluded_from_training_mazes() -> None:
    snake = eller_maze(7, np.random.default_rng(0), p_join=1.0, p_down=0.0)
    assert not is_rotation_symmetric(snake)
    # an S: top row open to the right, middle row, bottom row: equal to its 180-degree turn
    s_maze = np.ones((7, 7), dtype=bool)
    s_maze[1::2, 1:6] = False
    s_maze[2, 1] = False
    s_maze[4, 5] = False
    assert np.array_equal(s_maze, np.rot90(s_maze, 2))
    assert is_rotation_symmetric(s_maze)
    cross = np.ones((7, 7), dtype=bool)
    cross[3, 1:6] = False
    cross[1:6, 3] = False
    assert is_rotation_symmetric(cross)  # 90-degree symmetry

    rng = np.random.default_rng(1)
    raw = [eller_maze(7, rng) for _ in range(3000)]
    assert any(is_rotation_symmetric(w) for w in raw)  # they do occur...
    rng = np.random.default_rng(1)
    assert not any(is_rotation_symmetric(random_maze(7, rng)) for _ in range(3000))  # ...not here


def test_random_start_is_a_free_cell_and_a_heading() -> None:
    rng = np.random.default_rng(2)
    walls = eller_maze(7, rng)
    starts = np.array([random_start(walls, rng) for _ in range(2000)])
    assert not walls[starts[:, 1], starts[:, 0]].any()
    assert set(starts[:, 2].tolist()) == {0, 1, 2, 3}
    n_free = int((~walls).sum())
    assert len({(x, y) for x, y, _ in starts.tolist()}) == n_free


def test_maze_test_set_is_reproducible_distinct_and_asymmetric() -> None:
    a = maze_test_set(7, 300, seed=4)
    b = maze_test_set(7, 300, seed=4)
    assert np.array_equal(a.walls, b.walls) and np.array_equal(a.starts, b.starts)
    assert a.walls.shape == (300, 7, 7) and a.starts.shape == (300, 3) and len(a) == 300
    assert a.size == 7 and a.seed == 4
    other = maze_test_set(7, 300, seed=5)
    assert not np.array_equal(a.walls, other.walls)
    prefix = maze_test_set(7, 50, seed=4)
    assert np.array_equal(prefix.walls, a.walls[:50])
    assert np.array_equal(prefix.starts, a.starts[:50])
    keys = {w.tobytes() + s.tobytes() for w, s in zip(a.walls, a.starts, strict=True)}
    assert len(keys) == 300
    assert not any(is_rotation_symmetric(w) for w in a.walls)
    assert not a.walls[np.arange(300), a.starts[:, 1], a.starts[:, 0]].any()
    assert not a.walls.flags.writeable and not a.starts.flags.writeable
    walls, start = a[3]
    assert np.array_equal(walls, a.walls[3]) and np.array_equal(start, a.starts[3])


def test_maze_test_set_is_reexported_and_pickles() -> None:
    assert generators.maze_test_set is maze_test_set
    s = maze_test_set(15, 5, TEST_SET_SEED)
    t = pickle.loads(pickle.dumps(s))
    assert np.array_equal(t.walls, s.walls) and np.array_equal(t.starts, s.starts)
    assert not t.walls.flags.writeable


@pytest.mark.parametrize(
    ("args", "field"),
    [((6, 10, 0), "n"), ((3, 10, 0), "n"), ((7.0, 10, 0), "n"), ((7, 0, 0), "count")],
)
def test_maze_test_set_rejects_bad_arguments(args: tuple, field: str) -> None:
    with pytest.raises(ValueError, match=field):
        maze_test_set(*args)


def test_asking_for_more_distinct_pairs_than_exist_raises() -> None:
    # 5 x 5: four mazes (the U shapes of a 2 x 2 grid), 7 free cells, 4 headings: 112 pairs
    with pytest.raises(ValueError, match="distinct"):
        maze_test_set(5, 113, seed=0)
    assert len(maze_test_set(5, 112, seed=0)) == 112


def test_maze_set_validates_its_arrays() -> None:
    walls = eller_maze(7, np.random.default_rng(0))[None]
    with pytest.raises(ValueError, match="starts"):
        MazeSet(walls, np.array([[0, 0, 0]]))  # a border wall
    with pytest.raises(ValueError, match="starts"):
        MazeSet(walls, np.array([[1, 1, 4]]))  # heading out of range
    with pytest.raises(ValueError, match="walls"):
        MazeSet(walls[:, :6], np.array([[1, 1, 0]]))
    assert len(MazeSet(walls, np.array([[1, 1, 3]]))) == 1


def test_maze_set_errors_name_the_first_bad_entry_and_source_pickles() -> None:
    walls = np.stack([eller_maze(7, np.random.default_rng(k)) for k in range(3)])
    with pytest.raises(ValueError, match=r"entry 2, \(0, 0, 1\), is on a wall"):
        MazeSet(walls, np.array([[1, 1, 0], [1, 1, 1], [0, 0, 1]]))
    with pytest.raises(ValueError, match=r"entry 1 is \(7, 1, 0\)"):
        MazeSet(walls, np.array([[1, 1, 0], [7, 1, 0], [1, 1, 0]]))
    maze_set = MazeSet(walls, np.ones((3, 3), dtype=np.int64), source="mazes.npz")
    clone = pickle.loads(pickle.dumps(maze_set))
    assert clone.source == "mazes.npz" and not clone.starts.flags.writeable
    old_state = {k: v for k, v in maze_set.__dict__.items() if k != "source"}
    restored = MazeSet.__new__(MazeSet)
    restored.__setstate__(old_state)  # pickled before the source field existed
    assert restored.source is None


def test_maze_to_grid_is_the_same_maze_at_one_metre_per_cell() -> None:
    walls = eller_maze(7, np.random.default_rng(8))
    grid = maze_to_grid(walls)
    assert grid.resolution == 1.0 and grid.origin == (0.0, 0.0, 0.0)
    assert np.array_equal(grid.values == OCCUPIED, walls)
    assert np.array_equal(grid.values == FREE, ~walls)
    iy, ix = np.mgrid[0:7, 0:7]
    centres = np.stack([ix + 0.5, iy + 0.5], axis=-1)  # cell (ix, iy) spans [ix, ix + 1) m
    assert np.array_equal(grid.is_free(centres), ~walls)
