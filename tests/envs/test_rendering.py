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
    LandmarkFrame,
    LandmarkRenderer,
    _ellipse_params,
)


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
