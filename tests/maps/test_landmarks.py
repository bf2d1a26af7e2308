"""Tests of ``active_loc.maps.landmarks``: LandmarkMap validation and the random map generator."""

from __future__ import annotations

import numpy as np
import pytest

from active_loc.maps import LandmarkMap, random_landmark_map

GOOD_BOUNDS = (0.0, 0.0, 10.0, 10.0)


# --- LandmarkMap ----------------------------------------------------------------------------------


def test_valid_map_holds_a_read_only_copy():
    positions = np.array([[1.0, 2.0], [3.0, 4.0]])
    lmap = LandmarkMap(positions, (0, 0, 5, 6))
    assert lmap.n_landmarks == 2
    assert lmap.size == (5.0, 6.0)
    assert lmap.bounds == (0.0, 0.0, 5.0, 6.0)
    assert all(isinstance(b, float) for b in lmap.bounds)
    positions[0, 0] = 99.0
    assert lmap.positions[0, 0] == 1.0
    with pytest.raises(ValueError):
        lmap.positions[0, 0] = 5.0


def test_map_accepts_lists():
    lmap = LandmarkMap([[1, 2]], [0, 0, 3, 3], walls=False)
    assert lmap.positions.dtype == np.float64
    assert lmap.walls is False


def test_contains_with_margin():
    lmap = LandmarkMap([[1.0, 1.0]], GOOD_BOUNDS)
    points = np.array([[0.0, 0.0], [5.0, 5.0], [10.0, 10.0], [10.01, 5.0], [0.5, 5.0]])
    np.testing.assert_array_equal(lmap.contains(points), [True, True, True, False, True])
    np.testing.assert_array_equal(
        lmap.contains(points, margin=1.0), [False, True, False, False, False]
    )
    assert lmap.contains(np.zeros((3, 4, 2))).shape == (3, 4)


@pytest.mark.parametrize("positions", [np.empty((0, 2)), []], ids=["empty_2d", "empty_list"])
def test_empty_map_raises(positions):
    with pytest.raises(ValueError, match=r"LandmarkMap\.positions"):
        LandmarkMap(positions, GOOD_BOUNDS)


def test_empty_map_message_says_empty():
    with pytest.raises(ValueError, match="empty"):
        LandmarkMap(np.empty((0, 2)), GOOD_BOUNDS)


@pytest.mark.parametrize("bad", [np.nan, np.inf, -np.inf])
def test_non_finite_positions_raise(bad):
    with pytest.raises(ValueError, match=r"LandmarkMap\.positions contains NaN or inf"):
        LandmarkMap([[1.0, 1.0], [bad, 2.0]], GOOD_BOUNDS)


@pytest.mark.parametrize(
    "positions",
    [np.zeros((3, 3)), np.zeros(2), np.zeros((2, 2, 2)), np.zeros((3, 1))],
    ids=["n_by_3", "vector", "3d", "n_by_1"],
)
def test_wrong_position_shape_raises(positions):
    with pytest.raises(ValueError, match=r"LandmarkMap\.positions must have shape \(N, 2\)"):
        LandmarkMap(positions, GOOD_BOUNDS)


def test_ragged_positions_raise_a_clear_error():
    with pytest.raises(ValueError, match=r"LandmarkMap\.positions"):
        LandmarkMap([[1.0, 2.0], [3.0]], GOOD_BOUNDS)


@pytest.mark.parametrize(
    "bounds",
    [
        (1.0, 0.0, 0.0, 1.0),
        (0.0, 1.0, 1.0, 0.0),
        (0.0, 0.0, 0.0, 1.0),
        (np.nan, 0.0, 1.0, 1.0),
        (0.0, 0.0, 1.0, np.nan),
    ],
    ids=["x_inverted", "y_inverted", "zero_width", "nan_min", "nan_max"],
)
def test_bad_bounds_raise(bounds):
    with pytest.raises(ValueError, match=r"LandmarkMap\.bounds must be \(x_min, y_min, x_max"):
        LandmarkMap([[0.5, 0.5]], bounds)


@pytest.mark.parametrize("bounds", [(0.0, 0.0, 1.0), (0.0, 0.0, 1.0, 1.0, 1.0)])
def test_wrong_length_bounds_raise_a_clear_error(bounds):
    with pytest.raises(ValueError, match=r"LandmarkMap\.bounds"):
        LandmarkMap([[0.5, 0.5]], bounds)


def test_infinite_bounds_raise():
    with pytest.raises(ValueError, match=r"LandmarkMap\.bounds"):
        LandmarkMap([[0.5, 0.5]], (-np.inf, -np.inf, np.inf, np.inf))


# --- random_landmark_map --------------------------------------------------------------------------


def pairwise_min_distance(points):
    d = np.hypot(*(points[:, None, :] - points[None, :, :]).transpose(2, 0, 1))
    d[np.diag_indices_from(d)] = np.inf
    return d.min()


def test_random_map_is_reproducible_for_the_same_seed():
    a = random_landmark_map(np.random.default_rng(11))
    b = random_landmark_map(np.random.default_rng(11))
    np.testing.assert_array_equal(a.positions, b.positions)
    assert a.bounds == b.bounds
    c = random_landmark_map(np.random.default_rng(12))
    assert c.positions.shape != a.positions.shape or not np.array_equal(c.positions, a.positions)


@pytest.mark.parametrize("seed", range(30))
def test_random_map_respects_count_margin_and_separation(seed):
    size, margin, sep, counts = (12.0, 9.0), 1.5, 1.0, (3, 9)
    lmap = random_landmark_map(np.random.default_rng(seed), size, counts, sep, margin)
    assert counts[0] <= lmap.n_landmarks <= counts[1]
    assert lmap.bounds == (0.0, 0.0, 12.0, 9.0)
    pos = lmap.positions
    assert np.all(pos >= margin)
    assert np.all(pos[:, 0] <= size[0] - margin)
    assert np.all(pos[:, 1] <= size[1] - margin)
    if lmap.n_landmarks > 1:
        assert pairwise_min_distance(pos) >= sep


def test_random_map_count_range_is_inclusive_and_covered():
    counts = {
        random_landmark_map(np.random.default_rng(s), (20.0, 20.0), (2, 4)).n_landmarks
        for s in range(60)
    }
    assert counts == {2, 3, 4}


def test_random_map_fixed_count_and_walls():
    lmap = random_landmark_map(np.random.default_rng(0), n_landmarks=5, walls=False)
    assert lmap.n_landmarks == 5
    assert lmap.walls is False


def test_random_map_defaults():
    lmap = random_landmark_map(np.random.default_rng(3))
    assert 8 <= lmap.n_landmarks <= 15
    assert lmap.size == (20.0, 20.0)
    assert pairwise_min_distance(lmap.positions) >= 1.5
    assert lmap.contains(lmap.positions, margin=1.0).all()


@pytest.mark.parametrize(
    ("kwargs", "match"),
    [
        ({"size": (2.0, 10.0), "margin": 1.0}, "no room inside margin"),
        ({"n_landmarks": (0, 3)}, "1 <= lo <= hi"),
        ({"n_landmarks": (5, 3)}, "1 <= lo <= hi"),
        ({"n_landmarks": 0}, "n_landmarks must be >= 1"),
        ({"size": (4.0, 4.0), "n_landmarks": 50, "min_separation": 2.0}, "could not place"),
    ],
    ids=["no_room", "zero_low", "inverted_range", "zero_count", "too_crowded"],
)
def test_random_map_bad_arguments_raise(kwargs, match):
    with pytest.raises(ValueError, match=match):
        random_landmark_map(np.random.default_rng(0), **kwargs)
