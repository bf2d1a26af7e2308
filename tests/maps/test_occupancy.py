"""Tests of ``active_loc.maps.occupancy``: the OccupancyGrid, its kernels, and ROS map files."""

from __future__ import annotations

import copy
import json
import math
import pickle
import re
from pathlib import Path

import numpy as np
import pytest
from scipy import stats

from active_loc.maps import (
    FREE,
    OCCUPIED,
    OFF_MAP,
    UNKNOWN,
    MapFileError,
    MapFileNotFoundError,
    OccupancyGrid,
    cell_value,
    world_to_grid,
)

SHARED_MAPS = Path(__file__).resolve().parents[3] / "shared" / "maps"
needs_shared_maps = pytest.mark.skipif(
    not (SHARED_MAPS / "testmap.yaml").is_file(),
    reason=f"the real ROS maps are not at {SHARED_MAPS} (CI puts shared/ beside the checkout)",
)

SMALL = [  # first string = top row
    "#####",
    "#..?#",
    "#.#.#",
    "#...#",
    "#####",
]


def _random_grid(rng: np.random.Generator, shape=(13, 17), yaw=0.7) -> OccupancyGrid:
    values = rng.choice(np.array([FREE, OCCUPIED, UNKNOWN], dtype=np.int8), size=shape,
                        p=[0.6, 0.3, 0.1])
    return OccupancyGrid(values, 0.05, (1.25, -3.5, yaw))


# --- construction ------------------------------------------------------------------------------


def test_valid_grid_holds_a_read_only_int8_copy():
    values = np.array([[0, 100], [-1, 0]], dtype=np.int64)
    grid = OccupancyGrid(values, 0.5, (1, 2, 0))
    assert grid.values.dtype == np.int8
    assert grid.values.flags.c_contiguous
    assert grid.origin == (1.0, 2.0, 0.0)
    assert all(isinstance(o, float) for o in grid.origin)
    assert isinstance(grid.resolution, float)
    values[0, 0] = 100
    assert grid.values[0, 0] == FREE
    with pytest.raises(ValueError):
        grid.values[0, 0] = 100
    assert grid.shape == (2, 2)
    assert grid.size_m == (1.0, 1.0)


@pytest.mark.parametrize(
    ("kwargs", "match"),
    [
        ({"values": np.zeros(4)}, r"values must be 2-D"),
        ({"values": np.zeros((2, 2, 2))}, r"values must be 2-D"),
        ({"values": np.zeros((0, 3))}, r"values is empty"),
        ({"values": np.array([[0, 1]])}, r"values may only hold FREE .* found \[1\]"),
        ({"values": np.array([["a"]])}, r"values must be an integer array"),
        ({"resolution": 0.0}, r"resolution must be finite and > 0"),
        ({"resolution": -0.1}, r"resolution must be finite and > 0"),
        ({"resolution": np.nan}, r"resolution must be finite and > 0"),
        ({"resolution": "fine"}, r"resolution must be a positive number"),
        ({"origin": (0.0, 0.0)}, r"origin must be 3 finite numbers"),
        ({"origin": (0.0, np.inf, 0.0)}, r"origin must be 3 finite numbers"),
        ({"origin": ("a", 0, 0)}, r"origin must be \(x, y, yaw\) numbers"),
        ({"unknown_reflects": "yes"}, r"unknown_reflects must be a bool"),
    ],
)
def test_bad_construction_raises(kwargs, match):
    args = {"values": np.zeros((2, 3), dtype=np.int8), "resolution": 0.1}
    args.update(kwargs)
    with pytest.raises(ValueError, match=r"OccupancyGrid\." + match):
        OccupancyGrid(**args)


def test_from_ascii_puts_the_first_string_on_top():
    grid = OccupancyGrid.from_ascii(["#?", ".."], 1.0)
    # top row (largest y) is the last grid row
    np.testing.assert_array_equal(grid.values, [[FREE, FREE], [OCCUPIED, UNKNOWN]])
    assert not grid.is_free([0.5, 1.5])
    assert grid.value_at([1.5, 1.5]) == UNKNOWN
    assert grid.is_free([0.5, 0.5])


@pytest.mark.parametrize(
    ("rows", "match"),
    [([], "non-empty"), ("#.", "non-empty"), (["#.", "#"], "row 1 has 1"),
     (["#x"], "row 0 column 1: 'x'")],
)
def test_from_ascii_rejects_bad_drawings(rows, match):
    with pytest.raises(ValueError, match=match):
        OccupancyGrid.from_ascii(rows, 1.0)


def test_equality_hash_copy_and_pickle():
    grid = _random_grid(np.random.default_rng(0))
    same = OccupancyGrid(grid.values.copy(), grid.resolution, grid.origin)
    assert grid == same and hash(grid) == hash(same)
    assert grid != OccupancyGrid(grid.values, grid.resolution, grid.origin, unknown_reflects=False)
    assert grid != OccupancyGrid(grid.values, 0.1, grid.origin)
    assert copy.deepcopy(grid) is grid and copy.copy(grid) is grid
    grid.distance_field()
    clone = pickle.loads(pickle.dumps(grid))
    assert clone == grid
    assert not clone.values.flags.writeable
    np.testing.assert_array_equal(clone.distance_field(), grid.distance_field())
    assert "shape=(ny=13, nx=17)" in repr(grid)


# --- geometry ------------------------------------------------------------------------------------


def test_cells_and_world_points_without_yaw():
    grid = OccupancyGrid(np.zeros((4, 6), dtype=np.int8), 0.5, (-1.0, 2.0, 0.0))
    np.testing.assert_array_equal(
        grid.world_to_cell([[-1.0, 2.0], [-0.51, 2.49], [-0.5, 2.5], [1.99, 3.99], [-1.01, 2.0]]),
        [[0, 0], [0, 0], [1, 1], [5, 3], [-1, 0]],
    )
    np.testing.assert_allclose(grid.cell_to_world([[0, 0], [5, 3]]), [[-0.75, 2.25], [1.75, 3.75]])
    np.testing.assert_array_equal(
        grid.in_grid([[0, 0], [5, 3], [6, 0], [0, 4], [-1, 2]]), [True, True, False, False, False]
    )
    assert grid.bounds == (-1.0, 2.0, 2.0, 4.0)


def test_yawed_grid_rotates_about_the_origin():
    grid = OccupancyGrid(np.zeros((2, 4), dtype=np.int8), 1.0, (1.0, 1.0, math.pi / 2))
    # grid x points along world +y, grid y along world -x
    np.testing.assert_allclose(grid.cell_to_world([3, 0]), [0.5, 4.5])
    np.testing.assert_array_equal(grid.world_to_cell([0.5, 4.5]), [3, 0])
    np.testing.assert_allclose(grid.bounds, (-1.0, 1.0, 1.0, 5.0), atol=1e-12)


def test_cell_world_round_trip_and_shapes():
    rng = np.random.default_rng(1)
    grid = _random_grid(rng)
    cells = rng.integers(-5, 25, size=(3, 50, 2))
    world = grid.cell_to_world(cells)
    assert world.shape == (3, 50, 2)
    np.testing.assert_array_equal(grid.world_to_cell(world), cells)
    assert grid.world_to_cell(world).dtype == np.int64
    assert grid.is_free(world).shape == (3, 50)
    expected = grid.in_grid(cells) & (
        grid.values[np.clip(cells[..., 1], 0, 12), np.clip(cells[..., 0], 0, 16)] == FREE
    )
    np.testing.assert_array_equal(grid.is_free(world), expected)
    # the bounding box holds every cell centre of the grid
    x_min, y_min, x_max, y_max = grid.bounds
    iy, ix = np.indices(grid.shape)
    centres = grid.cell_to_world(np.stack([ix, iy], axis=-1))
    assert np.all((centres[..., 0] > x_min) & (centres[..., 0] < x_max))
    assert np.all((centres[..., 1] > y_min) & (centres[..., 1] < y_max))


def test_is_free_classes_and_off_map():
    grid = OccupancyGrid.from_ascii(SMALL, 0.1, (2.0, 3.0, 0.0))
    # (free, unknown, occupied, off-map left, off-map above)
    points = [[2.15, 3.35], [2.35, 3.35], [2.25, 3.25], [1.99, 3.25], [2.15, 3.51]]
    np.testing.assert_array_equal(grid.is_free(points), [True, False, False, False, False])
    np.testing.assert_array_equal(
        grid.value_at(points), [FREE, UNKNOWN, OCCUPIED, OFF_MAP, OFF_MAP]
    )
    assert grid.n_free == 7 and grid.free_fraction == pytest.approx(7 / 25)


def test_non_finite_points_are_off_map_without_warnings():
    grid = OccupancyGrid(np.zeros((3, 3), dtype=np.int8), 1.0, (0.0, 0.0, 0.3))
    points = [[np.nan, 1.0], [np.inf, 1.0], [1.0, -np.inf], [1e300, 1.0]]
    assert not grid.is_free(points).any()  # RuntimeWarnings are errors in this suite
    assert not grid.in_grid(grid.world_to_cell(points)).any()


def test_bad_point_shapes_raise():
    grid = OccupancyGrid(np.zeros((3, 3), dtype=np.int8), 1.0)
    with pytest.raises(ValueError, match=r"\(\.\.\., 2\)"):
        grid.is_free(np.zeros((4, 3)))
    with pytest.raises(ValueError, match=r"\(\.\.\., 2\)"):
        grid.cell_to_world([1, 2, 3])


# --- kernels -------------------------------------------------------------------------------------


@pytest.mark.parametrize("yaw", [0.0, 1.0, -2.5])
def test_kernels_agree_with_the_numpy_methods(yaw):
    rng = np.random.default_rng(2)
    grid = _random_grid(rng, yaw=yaw)
    values, res, ox, oy, c, s = grid.kernel_arrays()
    assert values is grid.values and values.flags.c_contiguous and values.dtype == np.int8
    x_min, y_min, x_max, y_max = grid.bounds
    points = rng.uniform([x_min - 0.3, y_min - 0.3], [x_max + 0.3, y_max + 0.3], size=(4000, 2))
    # plus points exactly on cell corners, where floor decides
    iy, ix = np.indices((14, 18))
    corners = np.stack([ix, iy], axis=-1).reshape(-1, 2) - 0.5
    points = np.concatenate([points, grid.cell_to_world(corners), [[np.nan, 0.0]]])
    numpy_grid = grid.world_to_grid(points)
    numpy_values = grid.value_at(points)
    assert (numpy_values == OFF_MAP).sum() > 100 and (numpy_values == FREE).sum() > 100
    for k, (x, y) in enumerate(points):
        gx, gy = world_to_grid(x, y, ox, oy, c, s, res)
        if k < len(points) - 1:
            assert (gx, gy) == (numpy_grid[k, 0], numpy_grid[k, 1])  # bit for bit
        assert cell_value(values, gx, gy) == numpy_values[k]


def test_cell_value_edges():
    values = np.array([[0, 100, -1]], dtype=np.int8)
    assert cell_value(values, 0.0, 0.0) == FREE
    assert cell_value(values, 1.999, 0.999) == OCCUPIED
    assert cell_value(values, 2.5, 0.5) == UNKNOWN
    for gx, gy in [(3.0, 0.5), (-1e-12, 0.5), (0.5, 1.0), (0.5, -0.1), (np.nan, 0.5)]:
        assert cell_value(values, gx, gy) == OFF_MAP


# --- distance field ------------------------------------------------------------------------------


def _brute_force_distance(values: np.ndarray, resolution: float, obstacle) -> np.ndarray:
    obstacles = np.argwhere(obstacle(values))
    out = np.empty(values.shape)
    for iy, ix in np.ndindex(values.shape):
        out[iy, ix] = resolution * np.min(np.hypot(obstacles[:, 0] - iy, obstacles[:, 1] - ix))
    return out


def test_distance_field_matches_brute_force():
    rows = ["........", "..#.....", "......?.", "........", "#.......", "........"]
    grid = OccupancyGrid.from_ascii(rows, 0.25, (3.0, -1.0, 0.4))
    field = grid.distance_field()
    expected = _brute_force_distance(grid.values, 0.25, lambda v: v != FREE)
    np.testing.assert_allclose(field, expected, rtol=0, atol=1e-12)
    assert field.dtype == np.float64 and field.shape == grid.shape
    assert grid.distance_field() is field  # cached
    assert not field.flags.writeable

    blind = OccupancyGrid.from_ascii(rows, 0.25, unknown_reflects=False)
    expected = _brute_force_distance(blind.values, 0.25, lambda v: v == OCCUPIED)
    np.testing.assert_allclose(blind.distance_field(), expected, rtol=0, atol=1e-12)


def test_distance_field_without_obstacles_is_finite():
    grid = OccupancyGrid(np.zeros((3, 4), dtype=np.int8), 0.5)
    field = grid.distance_field()
    assert np.all(np.isfinite(field))
    np.testing.assert_allclose(field, math.hypot(2.0, 1.5))
    unknown_only = OccupancyGrid(np.full((2, 2), UNKNOWN, dtype=np.int8), 1.0,
                                 unknown_reflects=False)
    assert np.all(np.isfinite(unknown_only.distance_field()))


# --- sampling ------------------------------------------------------------------------------------


def test_sample_free_returns_free_points_reproducibly():
    grid = _random_grid(np.random.default_rng(3), shape=(40, 50), yaw=2.2)
    points = grid.sample_free(np.random.default_rng(7), 20000)
    assert points.shape == (20000, 2) and points.dtype == np.float64
    assert grid.is_free(points).all()
    np.testing.assert_array_equal(points, grid.sample_free(np.random.default_rng(7), 20000))
    assert not np.array_equal(points, grid.sample_free(np.random.default_rng(8), 20000))
    assert grid.sample_free(np.random.default_rng(7), 0).shape == (0, 2)


def test_sample_free_uses_only_the_given_generator():
    grid = OccupancyGrid.from_ascii(SMALL, 0.1)
    # the legacy global state is what must stay untouched
    np.random.seed(123)  # noqa: NPY002
    before = np.random.get_state()[1].copy()  # noqa: NPY002
    rng = np.random.default_rng(0)
    state = copy.deepcopy(rng.bit_generator.state)
    grid.sample_free(rng, 10)
    np.testing.assert_array_equal(np.random.get_state()[1], before)  # noqa: NPY002
    assert rng.bit_generator.state != state


def test_sample_free_is_uniform_over_free_cells():
    grid = OccupancyGrid.from_ascii(SMALL, 0.1, (0.5, 0.5, 0.3))
    n = 35000
    points = grid.sample_free(np.random.default_rng(11), n)
    cells = grid.world_to_cell(points)
    flat = cells[:, 1] * grid.shape[1] + cells[:, 0]
    free = np.flatnonzero(grid.values == FREE)
    counts = np.array([(flat == f).sum() for f in free])
    assert counts.sum() == n
    assert stats.chisquare(counts).pvalue > 1e-3
    # and uniform inside the cells
    fraction = grid.world_to_grid(points) - cells
    assert stats.kstest(fraction.ravel(), "uniform").pvalue > 1e-3


def test_sample_free_errors():
    full = OccupancyGrid.from_ascii(["#?", "##"], 1.0)
    with pytest.raises(ValueError, match="no free cell"):
        full.sample_free(np.random.default_rng(0), 3)
    grid = OccupancyGrid.from_ascii(SMALL, 1.0)
    for bad in (-1, 2.5, True):
        with pytest.raises(ValueError, match="n must be an integer >= 0"):
            grid.sample_free(np.random.default_rng(0), bad)


# --- the real ROS maps ---------------------------------------------------------------------------


def _raw_pgm(path: Path) -> np.ndarray:
    """The image rows (top first) of one of the shared PGMs, read independently of the package:
    line-based header (the files put each field on its own line), maxval 255."""
    data = path.read_bytes()
    tokens: list[bytes] = []
    pos = 0
    while len(tokens) < 4:
        end = data.index(b"\n", pos)
        line, pos = data[pos:end], end + 1
        if not line.startswith(b"#"):
            tokens += line.split()
    magic, width, height, maxval = tokens[0], int(tokens[1]), int(tokens[2]), int(tokens[3])
    assert magic == b"P5" and maxval == 255
    return np.frombuffer(data, np.uint8, count=width * height, offset=pos).reshape(height, width)


def _pixel_centre(r: int, c: int, height: int, resolution: float, origin) -> np.ndarray:
    """The README's rule: origin + R(yaw) ((c + 0.5) res, (H - 1 - r + 0.5) res)."""
    x0, y0, yaw = origin
    u, v = (c + 0.5) * resolution, (height - 1 - r + 0.5) * resolution
    return np.array([x0 + math.cos(yaw) * u - math.sin(yaw) * v,
                     y0 + math.sin(yaw) * u + math.cos(yaw) * v])


REAL_MAPS = {  # name: (nx, ny, resolution, origin, free_thresh)
    "depot": (604, 307, 0.05, (0.0, 0.0, 0.0), 0.25),
    "tb3_sandbox": (384, 384, 0.05, (-10.0, -10.0, 0.0), 0.196),
    "testmap": (10, 10, 0.1, (2.0, 3.0, 1.0), 0.196),
}


@needs_shared_maps
@pytest.mark.parametrize("name", sorted(REAL_MAPS))
def test_real_maps_load(name):
    nx, ny, resolution, origin, free_thresh = REAL_MAPS[name]
    grid = OccupancyGrid.load(SHARED_MAPS / f"{name}.yaml")
    assert grid.shape == (ny, nx)
    assert grid.resolution == resolution
    assert grid.origin == origin
    # the whole grid against the README's rule, computed here from the raw pixels
    image = _raw_pgm(SHARED_MAPS / f"{name}.pgm")
    p = (255 - image.astype(np.float64)) / 255
    expected = np.where(p > 0.65, OCCUPIED, np.where(p < free_thresh, FREE, UNKNOWN))
    np.testing.assert_array_equal(grid.values, expected[::-1])
    assert (grid.values == OCCUPIED).any() and (grid.values == FREE).any()
    # pixels of every grey level present: black walls, white free space, grey unknown (which
    # depot's free_thresh of 0.25 turns into free space)
    rng = np.random.default_rng(0)
    for pixel_value in np.unique(image):
        pixels = np.argwhere(image == pixel_value)
        for r, c in pixels[rng.choice(len(pixels), size=5)]:
            centre = _pixel_centre(r, c, ny, resolution, origin)
            assert grid.value_at(centre) == expected[r, c]
            assert grid.is_free(centre) == (expected[r, c] == FREE)
            np.testing.assert_array_equal(grid.world_to_cell(centre), [c, ny - 1 - r])
            np.testing.assert_allclose(grid.cell_to_world([c, ny - 1 - r]), centre, atol=1e-12)
    if name == "tb3_sandbox":
        assert (grid.values == UNKNOWN).any()


@needs_shared_maps
def test_testmap_yaw_transform_by_hand():
    grid = OccupancyGrid.load(SHARED_MAPS / "testmap.yaml")
    # image row 0, column 0 is black: the top-left pixel, grid cell (0, 9), centre at grid
    # coordinates (0.05, 0.95) m, rotated by 1 rad about the origin (2, 3)
    c, s = math.cos(1.0), math.sin(1.0)
    centre = (2 + 0.05 * c - 0.95 * s, 3 + 0.05 * s + 0.95 * c)
    assert centre == pytest.approx((1.227618, 3.555361), abs=1e-6)
    assert grid.value_at(centre) == OCCUPIED
    np.testing.assert_array_equal(grid.world_to_cell(centre), [0, 9])
    # image row 9 (bottom), column 0 is free: grid cell (0, 0) at (0.05, 0.05) m
    free = (2 + 0.05 * c - 0.05 * s, 3 + 0.05 * s + 0.05 * c)
    assert grid.is_free(free)
    np.testing.assert_array_equal(grid.world_to_cell(free), [0, 0])
    # the same point without the yaw would be another cell: the yaw is really applied
    assert grid.world_to_cell([2.05, 3.95]).tolist() != [0, 9]


# --- saving --------------------------------------------------------------------------------------


@pytest.mark.parametrize(
    "origin", [(0.0, 0.0, 0.0), (0.1 + 0.2, -1e-5, 1.0), (-123.456789012345, 7.0, -math.pi)]
)
def test_save_load_round_trip(tmp_path, origin):
    grid = OccupancyGrid(_random_grid(np.random.default_rng(4)).values, 0.05 + 1e-17, origin)
    yaml_path = grid.save(tmp_path / "map.yaml")
    assert yaml_path == tmp_path / "map.yaml"
    assert (tmp_path / "map.pgm").is_file()
    loaded = OccupancyGrid.load(yaml_path)
    assert loaded == grid
    assert loaded.resolution == grid.resolution and loaded.origin == grid.origin
    assert not OccupancyGrid.load(yaml_path, unknown_reflects=False).unknown_reflects


def test_saved_files_are_map_saver_trinary(tmp_path):
    grid = OccupancyGrid.from_ascii(["#.?", "..."], 0.1)
    grid.save(tmp_path / "m.yaml")
    text = (tmp_path / "m.yaml").read_text()
    for line in ('image: "m.pgm"', "mode: trinary", "negate: 0", "occupied_thresh: 0.65",
                 "free_thresh: 0.196", "origin: [0.0, 0.0, 0.0]"):
        assert line in text.splitlines()
    pgm = (tmp_path / "m.pgm").read_bytes()
    assert pgm.startswith(b"P5\n")
    assert pgm.endswith(bytes([0, 254, 205, 254, 254, 254]))  # top row first


@needs_shared_maps
@pytest.mark.parametrize("name", sorted(REAL_MAPS))
def test_real_maps_round_trip(tmp_path, name):
    grid = OccupancyGrid.load(SHARED_MAPS / f"{name}.yaml")
    assert OccupancyGrid.load(grid.save(tmp_path / f"{name}.yaml")) == grid


def test_save_refuses_a_pgm_name(tmp_path):
    with pytest.raises(ValueError, match=r"give a \.yaml path"):
        OccupancyGrid.from_ascii(["."], 1.0).save(tmp_path / "map.pgm")


# --- reading variants ----------------------------------------------------------------------------


def _write_map(folder: Path, yaml_text: str, pgm: bytes | None, name: str = "m") -> Path:
    if pgm is not None:
        (folder / f"{name}.pgm").write_bytes(pgm)
    path = folder / f"{name}.yaml"
    path.write_text(yaml_text)
    return path


GOOD_YAML = (
    "image: m.pgm\nresolution: 0.5\norigin: [1.0, 2.0, 0.0]\nnegate: 0\n"
    "occupied_thresh: 0.65\nfree_thresh: 0.196\n"
)
# 3 x 2 image, top row first: black, white, grey / white, white, black
GOOD_PGM = b"P5\n3 2\n255\n" + bytes([0, 254, 205, 255, 254, 0])
GOOD_VALUES = np.array([[FREE, FREE, OCCUPIED], [OCCUPIED, FREE, UNKNOWN]])


def test_reading_variants(tmp_path):
    # comments everywhere, a block-list origin, quoted fields, a '---' start
    yaml_text = (
        "# a map\n---\nimage: 'm.pgm'  # the image\nresolution: 5e-1\norigin:\n  - 1\n  - 2.0\n"
        "  - 0\nnegate: false\noccupied_thresh: 0.65\nfree_thresh: .196\nmode: \"trinary\"\n"
    )
    pgm = b"P5 # magic\n# size next\n3\n2 # width and height\n255\n" + bytes([0, 254, 205, 255,
                                                                         254, 0])
    grid = OccupancyGrid.load(_write_map(tmp_path, yaml_text, pgm))
    np.testing.assert_array_equal(grid.values, GOOD_VALUES)
    assert grid.origin == (1.0, 2.0, 0.0) and grid.resolution == 0.5
    # ASCII PGM
    (tmp_path / "m.pgm").write_bytes(b"P2\n# ascii\n3 2\n255\n0 254 205\n255 254 0\n")
    np.testing.assert_array_equal(OccupancyGrid.load(tmp_path / "m.yaml").values, GOOD_VALUES)
    # maxval < 255 scales: 15 is white
    (tmp_path / "m.pgm").write_bytes(b"P5\n3 2\n15\n" + bytes([0, 15, 12, 15, 15, 0]))
    np.testing.assert_array_equal(OccupancyGrid.load(tmp_path / "m.yaml").values, GOOD_VALUES)


def test_negate_scale_raw_modes_and_absolute_image(tmp_path):
    (tmp_path / "img").mkdir()
    image = tmp_path / "img" / "m.pgm"
    image.write_bytes(GOOD_PGM)
    base = GOOD_YAML.replace("image: m.pgm", f"image: {json.dumps(str(image))}")
    negated = OccupancyGrid.load(_write_map(tmp_path, base.replace("negate: 0", "negate: 1"),
                                            None))
    np.testing.assert_array_equal(
        negated.values, [[OCCUPIED, OCCUPIED, FREE], [FREE, OCCUPIED, OCCUPIED]]
    )
    scaled = OccupancyGrid.load(_write_map(tmp_path, base + "mode: scale\n", None))
    np.testing.assert_array_equal(scaled.values, GOOD_VALUES)
    # raw: the pixel is the occupancy percentage; 0.196 * 100 = 19.6, 0.65 * 100 = 65
    image.write_bytes(b"P5\n4 2\n255\n" + bytes([0, 19, 20, 64, 65, 100, 101, 255]))
    raw = OccupancyGrid.load(_write_map(tmp_path, base + "mode: raw\n", None))
    np.testing.assert_array_equal(
        raw.values[::-1],
        [[FREE, FREE, UNKNOWN, UNKNOWN], [OCCUPIED, OCCUPIED, UNKNOWN, UNKNOWN]],
    )


# --- bad files -----------------------------------------------------------------------------------

BAD_YAML = {
    "yaml_is_a_list": ("- image: m.pgm\n- resolution: 0.5\n", "not a YAML mapping"),
    "yaml_is_a_scalar": ("just some text\n", "not a YAML mapping"),
    "yaml_is_empty": ("# nothing\n", "empty map file"),
    "missing_image": (GOOD_YAML.replace("image: m.pgm\n", ""), "missing field 'image'"),
    "missing_resolution": (GOOD_YAML.replace("resolution: 0.5\n", ""),
                           "missing field 'resolution'"),
    "missing_origin": (GOOD_YAML.replace("origin: [1.0, 2.0, 0.0]\n", ""),
                       "missing field 'origin'"),
    "missing_threshold": (GOOD_YAML.replace("free_thresh: 0.196\n", ""),
                          "missing field 'free_thresh'"),
    "text_resolution": (GOOD_YAML.replace("0.5", "fine"),
                        "'resolution' must be a finite number, got 'fine'"),
    "zero_resolution": (GOOD_YAML.replace("resolution: 0.5", "resolution: 0"),
                        "'resolution' must be > 0"),
    "nan_resolution": (GOOD_YAML.replace("resolution: 0.5", "resolution: .nan"),
                       "'resolution' must be a finite number"),
    "short_origin": (GOOD_YAML.replace("[1.0, 2.0, 0.0]", "[1.0, 2.0]"),
                     "'origin' must be 3 finite numbers"),
    "text_origin": (GOOD_YAML.replace("[1.0, 2.0, 0.0]", "[a, b, c]"),
                    "'origin' must be 3 finite numbers"),
    "scalar_origin": (GOOD_YAML.replace("[1.0, 2.0, 0.0]", "3"),
                      "'origin' must be 3 finite numbers"),
    "threshold_above_1": (GOOD_YAML.replace("occupied_thresh: 0.65", "occupied_thresh: 65"),
                          "'occupied_thresh' must be in \\[0, 1\\]"),
    "negative_threshold": (GOOD_YAML.replace("free_thresh: 0.196", "free_thresh: -0.1"),
                           "'free_thresh' must be in \\[0, 1\\]"),
    "thresholds_swapped": (GOOD_YAML.replace("free_thresh: 0.196", "free_thresh: 0.7"),
                           "free_thresh \\(0.7\\) must be < occupied_thresh"),
    "unknown_mode": (GOOD_YAML + "mode: ternary\n", "'mode' must be one of"),
    "negate_2": (GOOD_YAML.replace("negate: 0", "negate: 2"), "'negate' must be 0 or 1"),
    "negate_text": (GOOD_YAML.replace("negate: 0", "negate: maybe"), "'negate' must be 0 or 1"),
    "duplicate_field": (GOOD_YAML + "resolution: 0.1\n", "'resolution' appears twice"),
    "bad_line": (GOOD_YAML + "what is this\n", "not valid YAML"),
    "unterminated_list": (GOOD_YAML.replace("[1.0, 2.0, 0.0]", "[1.0, 2.0"), "not valid YAML"),
}


@pytest.mark.parametrize("case", sorted(BAD_YAML))
def test_bad_yaml_names_the_file(tmp_path, case):
    text, match = BAD_YAML[case]
    path = _write_map(tmp_path, text, GOOD_PGM)
    with pytest.raises(MapFileError, match=re.escape(str(path)) + ".*" + match):
        OccupancyGrid.load(path)


BAD_PGM = {
    "png": (b"\x89PNG\r\n\x1a\n" + bytes(20), "not an image map_server reads"),
    "empty": (b"", "not an image map_server reads"),
    "no_space_after_magic": (b"P53 2\n255\n" + bytes(6), "no whitespace after"),
    "text_width": (b"P5\nthree 2\n255\n" + bytes(6), "width is b'three'"),
    "negative_height": (b"P5\n3 -2\n255\n" + bytes(6), "height is b'-2'"),
    "header_cut": (b"P5\n3 2\n", "maxval is missing"),
    "zero_size": (b"P5\n0 2\n255\n", "is empty"),
    "maxval_17_bit": (b"P5\n3 2\n65536\n" + bytes(12), "maxval 65536 is not in 1..65535"),
    "maxval_0": (b"P5\n3 2\n0\n" + bytes(6), "maxval 0 is not in 1..65535"),
    "16_bit_cut": (b"P5\n3 2\n65535\n" + bytes(11), "needs 12 bytes of pixel data"),
    "no_data": (b"P5\n3 2\n255", "no pixel data"),
    "truncated_data": (b"P5\n3 2\n255\n" + bytes(5), "needs 6 bytes of pixel data, found 5"),
    "pixel_above_maxval": (b"P5\n3 2\n100\n" + bytes([0, 0, 0, 0, 0, 200]),
                           "pixel value 200 exceeds maxval 100"),
    "ascii_truncated": (b"P2\n3 2\n255\n0 0 0 0 0\n", "needs 6 pixel values, found 5"),
    "ascii_not_numbers": (b"P2\n3 2\n255\n0 0 0 0 0 x\n", "values must be integers"),
}


@pytest.mark.parametrize("case", sorted(BAD_PGM))
def test_bad_pgm_names_the_file(tmp_path, case):
    data, match = BAD_PGM[case]
    path = _write_map(tmp_path, GOOD_YAML, data)
    with pytest.raises(MapFileError, match=re.escape(str(tmp_path / "m.pgm")) + ".*" + match):
        OccupancyGrid.load(path)


def test_missing_files_name_the_file(tmp_path):
    missing_yaml = tmp_path / "nowhere.yaml"
    with pytest.raises(MapFileNotFoundError, match=re.escape(str(missing_yaml))):
        OccupancyGrid.load(missing_yaml)
    path = _write_map(tmp_path, GOOD_YAML, None)
    with pytest.raises(FileNotFoundError, match=re.escape(str(tmp_path / "m.pgm"))) as info:
        OccupancyGrid.load(path)
    assert isinstance(info.value, ValueError)  # catchable as either
    assert str(path) in str(info.value)  # and says which YAML asked for it
    with pytest.raises(MapFileError, match="not a regular file"):
        OccupancyGrid.load(tmp_path)  # a folder


def test_yaml_that_is_not_text(tmp_path):
    path = tmp_path / "m.yaml"
    path.write_bytes(b"\xff\xfe\x00binary")
    with pytest.raises(MapFileError, match=re.escape(str(path)) + ".*not a UTF-8 text file"):
        OccupancyGrid.load(path)
