"""Tests of the matplotlib renderer: fixed image shape, images that follow the frame, robustness."""

from __future__ import annotations

import dataclasses
import math
import sys
import warnings

import numpy as np
import pytest

matplotlib = pytest.importorskip("matplotlib")
matplotlib.use("Agg", force=True)  # before pyplot is imported anywhere in this process

from active_loc.envs.rendering import (  # noqa: E402
    CHI2_95_2DOF,
    MAX_HEADING_TICKS,
    GridFrame,
    GridRenderer,
    LandmarkFrame,
    LandmarkRenderer,
    _ellipse_params,
    _particle_data,
)
from active_loc.maps.generators import rooms_map  # noqa: E402
from active_loc.maps.occupancy import OCCUPIED, UNKNOWN, OccupancyGrid  # noqa: E402
from active_loc.sensors.lidar import LidarSensor  # noqa: E402


def make_frame(seed: int = 0, bounds: tuple[float, float, float, float] = (0, 0, 20, 20)):
    """A plausible mid-episode frame inside ``bounds``."""
    rng = np.random.default_rng(seed)
    x0, y0, x1, y1 = bounds
    landmarks = np.column_stack([rng.uniform(x0, x1, 10), rng.uniform(y0, y1, 10)])
    t = np.linspace(0.0, 1.0, 25)
    true_path = np.column_stack(
        [x0 + (x1 - x0) * (0.2 + 0.5 * t), y0 + (y1 - y0) * (0.3 + 0.2 * t)]
    )
    belief_path = true_path + rng.normal(0.0, 0.05 * (x1 - x0), true_path.shape)
    true_pose = np.array([*true_path[-1], 0.4])
    mean = np.array([*belief_path[-1], 0.3])
    cov = np.array([[1.0, 0.3, 0.0], [0.3, 0.5, 0.01], [0.0, 0.01, 0.04]])
    visible = np.zeros(10, dtype=bool)
    visible[[1, 4, 7]] = True
    return LandmarkFrame(
        bounds=bounds,
        landmarks=landmarks,
        visible=visible,
        true_pose=true_pose,
        mean=mean,
        cov=cov,
        true_path=true_path,
        belief_path=belief_path,
        fov=2.0 * math.pi / 3.0,
        max_range=8.0,
        step=24,
        entropy=1.5,
        title="test",
    )


@pytest.fixture(scope="module")
def renderer():
    r = LandmarkRenderer((300, 240))
    yield r
    r.close()


def n_changed(a: np.ndarray, b: np.ndarray) -> int:
    return int(np.count_nonzero(np.any(a != b, axis=-1)))


def test_shape_and_dtype_constant_across_frames(renderer):
    frames = [
        make_frame(0),
        make_frame(1, bounds=(-5.0, -5.0, 5.0, 5.0)),
        make_frame(2, bounds=(0.0, 0.0, 100.0, 10.0)),  # very wide map
        make_frame(3, bounds=(0.0, 0.0, 3.0, 50.0)),  # very tall map
        dataclasses.replace(make_frame(4), landmarks=np.zeros((0, 2)), visible=np.zeros(0, bool)),
        dataclasses.replace(
            make_frame(5), true_path=np.zeros((0, 2)), belief_path=np.zeros((0, 2))
        ),
    ]
    for frame in frames:
        img = renderer.render_rgb(frame)
        assert img.shape == (240, 300, 3)
        assert img.dtype == np.uint8
        assert img.flags.c_contiguous and img.flags.owndata  # a copy, not the Agg buffer


@pytest.mark.parametrize("size", [(600, 600), (641, 479), (333, 517)])
def test_exact_pixel_size(size):
    r = LandmarkRenderer(size)
    assert r.render_rgb(make_frame()).shape == (size[1], size[0], 3)
    r.close()


def test_image_follows_true_pose(renderer):
    frame = make_frame()
    moved = dataclasses.replace(frame, true_pose=frame.true_pose + np.array([3.0, -2.0, 1.0]))
    a = renderer.render_rgb(frame)
    b = renderer.render_rgb(moved)
    assert n_changed(a, b) > 100


def test_rendering_is_deterministic_and_cache_safe(renderer):
    """The cached static background must never leak one frame or map into the next."""
    small = make_frame(7, bounds=(-5.0, -5.0, 5.0, 5.0))
    big = make_frame(8)
    first = renderer.render_rgb(small)
    renderer.render_rgb(big)
    renderer.render_rgb(dataclasses.replace(big, title="another title"))
    again = renderer.render_rgb(small)
    np.testing.assert_array_equal(first, again)
    fresh = LandmarkRenderer((300, 240))
    np.testing.assert_array_equal(fresh.render_rgb(small), first)
    fresh.close()


def test_visible_rays_change_the_image(renderer):
    frame = make_frame()
    none_seen = dataclasses.replace(frame, visible=np.zeros(10, dtype=bool))
    all_seen = dataclasses.replace(frame, visible=np.ones(10, dtype=bool))
    a = renderer.render_rgb(none_seen)
    b = renderer.render_rgb(frame)
    c = renderer.render_rgb(all_seen)
    assert n_changed(a, b) > 50
    assert n_changed(b, c) > 50


def test_covariance_changes_the_image(renderer):
    frame = make_frame()
    wider = dataclasses.replace(frame, cov=frame.cov * 4.0)
    assert n_changed(renderer.render_rgb(frame), renderer.render_rgb(wider)) > 100


@pytest.mark.parametrize(
    "cov",
    [
        np.zeros((3, 3)),
        np.diag([1e-300, 1e-300, 1e-300]),
        np.array([[4.0, 4.0 - 1e-12, 0.0], [4.0 - 1e-12, 4.0, 0.0], [0.0, 0.0, 1e-9]]),
        np.array([[1.0, 1.0 + 1e-6, 0.0], [1.0 + 1e-6, 1.0, 0.0], [0.0, 0.0, 0.1]]),  # not PSD
        np.diag([1e12, 1e-6, 1e6]),
        np.diag([1e300, 1e300, 1e300]),
        np.full((3, 3), 1.7e308),
        np.diag([5e-324, 5e-324, 5e-324]),
        np.full((3, 3), np.nan),
        np.diag([np.inf, 1.0, np.inf]),
    ],
)
def test_degenerate_covariances_render(renderer, cov):
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        img = renderer.render_rgb(dataclasses.replace(make_frame(), cov=cov))
    assert img.shape == (240, 300, 3)


@pytest.mark.parametrize(
    ("fov", "max_range"),
    [(2 * math.pi, math.inf), (2 * math.pi, 5.0), (math.pi / 3, math.inf), (1e-3, 0.0)],
)
def test_sensor_variants_render(renderer, fov, max_range):
    frame = dataclasses.replace(make_frame(), fov=fov, max_range=max_range)
    assert renderer.render_rgb(frame).shape == (240, 300, 3)


def test_non_finite_poses_render(renderer):
    nan3 = np.full(3, np.nan)
    frame = dataclasses.replace(make_frame(), true_pose=nan3, mean=nan3)
    assert renderer.render_rgb(frame).shape == (240, 300, 3)


def test_visible_mask_must_match_landmarks(renderer):
    frame = dataclasses.replace(make_frame(), visible=np.ones(3, dtype=bool))
    with pytest.raises(ValueError, match="visible"):
        renderer.render_rgb(frame)


def test_ellipse_params_match_the_chi_square_quantile():
    width, height, angle = _ellipse_params(np.diag([4.0, 1.0]), cap=1e9)
    assert width == pytest.approx(2.0 * math.sqrt(CHI2_95_2DOF * 4.0))
    assert height == pytest.approx(2.0 * math.sqrt(CHI2_95_2DOF * 1.0))
    assert angle % 180.0 == pytest.approx(0.0, abs=1e-9)
    # rotated by 90 degrees, and a correlated one along the diagonal
    assert _ellipse_params(np.diag([1.0, 4.0]), cap=1e9)[2] % 180.0 == pytest.approx(90.0)
    _, _, diag_angle = _ellipse_params(np.array([[2.0, 1.9], [1.9, 2.0]]), cap=1e9)
    assert diag_angle % 180.0 == pytest.approx(45.0)
    assert _ellipse_params(np.diag([1e12, 1.0]), cap=50.0)[0] == 50.0
    assert _ellipse_params(np.full((2, 2), np.nan), cap=50.0) is None


def test_show_under_agg_and_close():
    import matplotlib.pyplot as plt

    r = LandmarkRenderer((300, 240))
    before = set(plt.get_fignums())
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # e.g. no "FigureCanvasAgg is non-interactive" warning
        r.show(make_frame(0))
        r.show(make_frame(1))
    assert len(set(plt.get_fignums()) - before) == 1  # one window, reused
    r.close()
    assert set(plt.get_fignums()) == before
    r.close()  # idempotent
    # rendering after close rebuilds the figure
    assert r.render_rgb(make_frame()).shape == (240, 300, 3)
    r.close()


def test_missing_matplotlib_gives_a_helpful_error(monkeypatch):
    monkeypatch.setitem(sys.modules, "matplotlib.figure", None)
    with pytest.raises(ImportError, match=r"active-loc\[render\]"):
        LandmarkRenderer()


def test_rejects_tiny_images():
    with pytest.raises(ValueError, match="size_px"):
        LandmarkRenderer((10, 10))


# --- particles on landmark frames ------------------------------------------------------------


def landmark_particles(seed: int = 0, k: int = 500) -> tuple[np.ndarray, np.ndarray]:
    """(K, 3) particles around the belief of ``make_frame`` and normalized weights (K,)."""
    rng = np.random.default_rng(seed)
    frame = make_frame()
    particles = frame.mean + rng.normal(0.0, [1.0, 1.0, 0.5], (k, 3))
    weights = rng.random(k)
    return particles, weights / weights.sum()


def test_landmark_frame_with_particles(renderer):
    plain = make_frame()
    particles, weights = landmark_particles()
    with_particles = dataclasses.replace(plain, particles=particles, weights=weights)
    uniform = dataclasses.replace(plain, particles=particles)  # weights None: uniform
    a = renderer.render_rgb(plain)
    b = renderer.render_rgb(with_particles)
    c = renderer.render_rgb(uniform)
    assert a.shape == b.shape == c.shape == (240, 300, 3)
    assert n_changed(a, b) > 200
    assert n_changed(b, c) > 50  # the shading follows the weights
    # no particles (None, the default, or an empty array) draws exactly the old frame
    empty = dataclasses.replace(plain, particles=np.zeros((0, 3)), weights=np.zeros(0))
    np.testing.assert_array_equal(renderer.render_rgb(empty), a)
    np.testing.assert_array_equal(renderer.render_rgb(plain), a)


def test_particle_shapes_are_checked(renderer):
    particles, weights = landmark_particles()
    with pytest.raises(ValueError, match="particles"):
        renderer.render_rgb(dataclasses.replace(make_frame(), particles=particles[:, :2]))
    with pytest.raises(ValueError, match="weights"):
        renderer.render_rgb(
            dataclasses.replace(make_frame(), particles=particles, weights=weights[:-1])
        )


def test_particle_data_shading_and_order():
    particles = np.array([[0.0, 0.0, 0.0], [1.0, 1.0, 1.0], [np.nan, 0.0, 0.0], [2.0, 2, 2]])
    weights = np.array([0.2, 0.0, 0.5, np.nan])
    poses, shade = _particle_data(particles, weights)
    # the NaN pose is dropped, a NaN weight counts as 0, lightest first, shade = w / max w
    np.testing.assert_array_equal(shade, [0.0, 0.0, 1.0])
    np.testing.assert_array_equal(poses[-1], particles[0])
    _, uniform = _particle_data(particles[:2], None)
    np.testing.assert_array_equal(uniform, [1.0, 1.0])
    _, all_zero = _particle_data(particles[:2], np.zeros(2))
    np.testing.assert_array_equal(all_zero, [1.0, 1.0])
    assert _particle_data(None, None) is None


# --- occupancy grids ---------------------------------------------------------------------------


@pytest.fixture(scope="module")
def rooms():
    return rooms_map(np.random.default_rng(0))


@pytest.fixture(scope="module")
def grid_renderer():
    r = GridRenderer((300, 240))
    yield r
    r.close()


def make_grid_frame(
    grid: OccupancyGrid, seed: int = 0, k: int = 300, n_beams: int = 60, max_range: float = 6.0
) -> GridFrame:
    """A plausible frame on ``grid``: particles in free space, a ray-cast scan, short paths."""
    rng = np.random.default_rng(seed)
    sensor = LidarSensor(n_beams=n_beams, max_range=max_range)
    true_pose = np.array([*grid.sample_free(rng, 1)[0], 0.5])
    particles = np.column_stack([grid.sample_free(rng, k), rng.uniform(-np.pi, np.pi, k)])
    particles[: k // 4] = true_pose + rng.normal(0.0, [0.2, 0.2, 0.1], (k // 4, 3))
    weights = np.exp(-np.sum((particles[:, :2] - true_pose[:2]) ** 2, axis=1))
    ranges = sensor.expected_ranges(true_pose[None], grid.kernel_arrays())[0]
    path = true_pose[:2] - np.linspace(1.0, 0.0, 10)[:, None] * np.array([1.0, 0.5])
    return GridFrame(
        grid=grid,
        true_pose=true_pose,
        mean=true_pose + np.array([0.2, -0.1, 0.05]),
        cov=np.diag([0.2, 0.1, 0.02]),
        particles=particles,
        weights=weights / weights.sum(),
        beam_angles=sensor.beam_angles,
        ranges=ranges,
        max_range=max_range,
        true_path=path,
        belief_path=path + 0.1,
        step=9,
        entropy=2.5,
        title="grid",
    )


def unknown_grid() -> OccupancyGrid:
    """A small map with walls, free space and an unknown block (and an unknown border)."""
    border = ["?" * 40, "?" + "#" * 38 + "?"]
    inside = ["?#" + "." * 20 + "?" * 8 + "." * 8 + "#?" for _ in range(20)]
    return OccupancyGrid.from_ascii(
        [*border, *inside, *border[::-1]], 0.25, origin=(-3.0, 2.0, 0.0)
    )


def yawed(grid: OccupancyGrid, yaw: float = 0.6) -> OccupancyGrid:
    return OccupancyGrid(grid.values, grid.resolution, origin=(1.5, -2.0, yaw))


def test_grid_shape_constant_across_grids_and_frames(grid_renderer, rooms):
    wide = rooms_map(np.random.default_rng(1), size_m=(60.0, 30.0), resolution=0.1)  # 600 x 300
    frames = [
        make_grid_frame(rooms),
        make_grid_frame(rooms, seed=1, k=0),
        make_grid_frame(wide),
        make_grid_frame(unknown_grid()),
        make_grid_frame(yawed(rooms)),
        make_grid_frame(rooms, k=MAX_HEADING_TICKS + 500),  # dots instead of needles
        dataclasses.replace(make_grid_frame(rooms), particles=None, weights=None),
        dataclasses.replace(
            make_grid_frame(rooms),
            beam_angles=np.zeros(0),
            ranges=np.zeros(0),
            true_path=np.zeros((0, 2)),
            belief_path=np.zeros((0, 2)),
        ),
    ]
    for frame in frames:
        img = grid_renderer.render_rgb(frame)
        assert img.shape == (240, 300, 3)
        assert img.dtype == np.uint8
        assert img.flags.c_contiguous and img.flags.owndata


def test_grid_image_follows_particles(grid_renderer, rooms):
    frame = make_grid_frame(rooms)
    moved = frame.particles + np.array([0.5, -0.3, 1.0])
    a = grid_renderer.render_rgb(frame)
    b = grid_renderer.render_rgb(dataclasses.replace(frame, particles=moved))
    c = grid_renderer.render_rgb(dataclasses.replace(frame, particles=None, weights=None))
    assert n_changed(a, b) > 200
    assert n_changed(a, c) > 200


def test_grid_image_follows_beams(grid_renderer, rooms):
    frame = make_grid_frame(rooms)
    a = grid_renderer.render_rgb(frame)
    shorter = grid_renderer.render_rgb(dataclasses.replace(frame, ranges=0.5 * frame.ranges))
    no_return = np.full_like(frame.ranges, frame.max_range)
    all_max = grid_renderer.render_rgb(dataclasses.replace(frame, ranges=no_return))
    assert n_changed(a, shorter) > 50
    assert n_changed(a, all_max) > 50
    turned = dataclasses.replace(
        frame, beam_angles=frame.beam_angles[:30], ranges=frame.ranges[:30]
    )
    assert n_changed(a, grid_renderer.render_rgb(turned)) > 20
    nan_beams = frame.ranges.copy()
    nan_beams[::2] = np.nan  # skipped, not an error
    assert grid_renderer.render_rgb(dataclasses.replace(frame, ranges=nan_beams)).shape[2] == 3


def test_zero_weight_particles_still_render(grid_renderer, rooms):
    frame = make_grid_frame(rooms, k=400)
    weights = np.zeros(400)
    weights[0] = 1.0  # one particle carries all the weight, 399 have weight 0
    only_heavy = dataclasses.replace(frame, particles=frame.particles[:1], weights=weights[:1])
    a = grid_renderer.render_rgb(dataclasses.replace(frame, weights=weights))
    b = grid_renderer.render_rgb(only_heavy)
    assert n_changed(a, b) > 400  # the 399 zero-weight particles are drawn (light)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        grid_renderer.render_rgb(dataclasses.replace(frame, weights=np.zeros(400)))


def pixel_of(renderer: GridRenderer, xy: tuple[float, float]) -> tuple[int, int]:
    """(row, column) of the image pixel showing world point ``xy`` (m)."""
    x_disp, y_disp = renderer._scene.ax.transData.transform(xy)
    return renderer.size_px[1] - 1 - int(y_disp), int(x_disp)


@pytest.mark.parametrize("yaw", [0.0, 0.6, -2.5])
def test_map_is_drawn_in_world_coordinates(yaw):
    """Occupied, free and unknown cells show black, white and grey where they lie in the world."""
    values = np.zeros((30, 40), dtype=np.int8)
    values[[0, -1], :] = OCCUPIED
    values[:, [0, -1]] = OCCUPIED
    values[5:12, 6:14] = OCCUPIED  # a block
    values[18:26, 25:35] = UNKNOWN
    grid = OccupancyGrid(values, 0.2, origin=(3.0, -1.0, yaw))
    r = GridRenderer((400, 400))
    frame = dataclasses.replace(
        make_grid_frame(grid), particles=None, true_path=np.zeros((0, 2)),
        belief_path=np.zeros((0, 2)), true_pose=np.full(3, np.nan), mean=np.full(3, np.nan),
    )  # fmt: skip
    img = r.render_rgb(frame).astype(int)
    expected = {(9, 8): 0, (30, 21): 205, (22, 8): 255}  # (ix, iy) cell centre: grey level
    for cell, level in expected.items():
        row, col = pixel_of(r, tuple(grid.cell_to_world(cell)))
        np.testing.assert_allclose(img[row, col], level, atol=30, err_msg=f"cell {cell}")
    r.close()


def test_unknown_and_yawed_grids_render(grid_renderer, rooms):
    grey = np.array([205, 205, 205])
    img = grid_renderer.render_rgb(make_grid_frame(unknown_grid()))
    assert np.count_nonzero(np.all(img == grey, axis=-1)) > 100
    straight = grid_renderer.render_rgb(make_grid_frame(rooms))
    tilted = grid_renderer.render_rgb(make_grid_frame(yawed(rooms)))
    assert tilted.shape == straight.shape
    assert n_changed(straight, tilted) > 1000


def test_view_zooms_on_the_known_part_of_the_map():
    values = np.full((200, 200), UNKNOWN, dtype=np.int8)
    values[80:100, 120:150] = OCCUPIED
    values[82:98, 122:148] = 0
    grid = OccupancyGrid(values, 0.05, origin=(-5.0, -5.0, 0.0))
    r = GridRenderer((300, 300))
    r.render_rgb(make_grid_frame(grid, k=20))
    x_lo, x_hi = r._scene.ax.get_xlim()
    assert -5.0 + 120 * 0.05 - 0.2 < x_lo < -5.0 + 120 * 0.05  # 4 % margin around the room
    assert -5.0 + 150 * 0.05 < x_hi < -5.0 + 150 * 0.05 + 0.2
    r.close()


def test_kidnapped_flag_is_drawn(grid_renderer, rooms):
    frame = make_grid_frame(rooms)
    a = grid_renderer.render_rgb(frame)
    b = grid_renderer.render_rgb(dataclasses.replace(frame, kidnapped=True))
    assert n_changed(a, b) > 200
    red = (b[..., 0].astype(int) - b[..., 1] > 100) & (b[..., 0].astype(int) - b[..., 2] > 100)
    assert np.count_nonzero(red) > 200
    np.testing.assert_array_equal(grid_renderer.render_rgb(frame), a)  # gone the next frame


def test_grid_rendering_is_deterministic_and_cache_safe(grid_renderer, rooms):
    first = grid_renderer.render_rgb(make_grid_frame(rooms))
    grid_renderer.render_rgb(make_grid_frame(unknown_grid()))
    grid_renderer.render_rgb(make_grid_frame(yawed(rooms)))
    np.testing.assert_array_equal(grid_renderer.render_rgb(make_grid_frame(rooms)), first)
    fresh = GridRenderer((300, 240))
    np.testing.assert_array_equal(fresh.render_rgb(make_grid_frame(rooms)), first)
    fresh.close()


def test_map_layer_is_drawn_once_per_grid_object(rooms, monkeypatch):
    r = GridRenderer((300, 240))
    full_draws = []
    canvas = r._canvas
    original = canvas.draw
    monkeypatch.setattr(canvas, "draw", lambda: (full_draws.append(1), original())[1])
    for seed in range(5):
        r.render_rgb(make_grid_frame(rooms, seed=seed))
    assert len(full_draws) == 1
    same_contents = OccupancyGrid(rooms.values, rooms.resolution, rooms.origin)
    r.render_rgb(make_grid_frame(same_contents))  # another object: identity, not contents
    r.render_rgb(make_grid_frame(same_contents, seed=1))
    assert len(full_draws) == 2
    r.close()


def test_grid_beam_lengths_must_match(grid_renderer, rooms):
    frame = make_grid_frame(rooms)
    with pytest.raises(ValueError, match="beam"):
        grid_renderer.render_rgb(dataclasses.replace(frame, ranges=frame.ranges[:-1]))


def test_grid_non_finite_poses_render(grid_renderer, rooms):
    nan3 = np.full(3, np.nan)
    frame = dataclasses.replace(make_grid_frame(rooms), true_pose=nan3, mean=nan3, kidnapped=True)
    assert grid_renderer.render_rgb(frame).shape == (240, 300, 3)


def test_grid_show_under_agg_and_close(rooms):
    import matplotlib.pyplot as plt

    r = GridRenderer((300, 240))
    before = set(plt.get_fignums())
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        r.show(make_grid_frame(rooms))
        r.show(dataclasses.replace(make_grid_frame(yawed(rooms), seed=1), kidnapped=True))
    assert len(set(plt.get_fignums()) - before) == 1
    r.close()
    assert set(plt.get_fignums()) == before
    assert r.render_rgb(make_grid_frame(rooms)).shape == (240, 300, 3)
    r.close()


@pytest.mark.parametrize("size", [(600, 600), (641, 479)])
def test_grid_exact_pixel_size(size, rooms):
    r = GridRenderer(size)
    assert r.render_rgb(make_grid_frame(rooms)).shape == (size[1], size[0], 3)
    r.close()


def test_grid_belief_heat_map_follows_the_mass(grid_renderer, rooms):
    """A grid belief's x-y marginal is drawn over the map: a spread-out belief changes much of
    the image, a peaked one a patch that moves with the peak; frames without it are drawn as
    before (the legend names the particles again)."""
    base = dataclasses.replace(make_grid_frame(rooms), particles=None, weights=None)
    spread = np.ones((40, 40))  # 20 m at 0.5 m cells
    peak = np.zeros((40, 40))
    peak[10, 30] = 1.0
    peak[11, 30] = 0.2
    moved = np.roll(peak, 12, axis=0)
    a = grid_renderer.render_rgb(base)
    b = grid_renderer.render_rgb(dataclasses.replace(base, belief_map=spread, belief_cell_size=0.5))
    c = grid_renderer.render_rgb(dataclasses.replace(base, belief_map=peak, belief_cell_size=0.5))
    d = grid_renderer.render_rgb(dataclasses.replace(base, belief_map=moved, belief_cell_size=0.5))
    assert n_changed(a, b) > 5 * n_changed(a, c) > 0
    assert n_changed(c, d) > 0
    assert np.array_equal(grid_renderer.render_rgb(base), a)


def test_grid_heat_map_on_a_yawed_map_and_bad_maps(grid_renderer, rooms):
    frame = dataclasses.replace(make_grid_frame(yawed(rooms)), belief_map=np.eye(40),
                                belief_cell_size=0.5)
    assert grid_renderer.render_rgb(frame).shape == (240, 300, 3)
    with pytest.raises(ValueError, match="belief_map"):
        grid_renderer.render_rgb(dataclasses.replace(frame, belief_map=np.ones(40)))
    with pytest.raises(ValueError, match="belief_cell_size"):
        grid_renderer.render_rgb(dataclasses.replace(frame, belief_cell_size=0.0))
