"""Matplotlib rendering of the landmark localization task (``rgb_array`` and ``human`` modes).

One frame shows, in map coordinates (m):

* the map bounds (rectangle) and the landmarks (stars; the ones seen this step are filled),
* the true robot pose (green triangle), its sensor field of view (faint wedge) and rays from the
  true pose to the landmarks seen this step,
* the belief mean (blue arrow), its 95 % position ellipse (chi-square, 2 dof) and a wedge of
  +/- 2 sigma of heading uncertainty,
* the true and believed trajectories, and a text line with the step and the belief entropy.

``LandmarkRenderer`` builds its figure and artists once and only updates their data each frame;
the static layer (axes, ticks, legend, title) is drawn once per map and then blitted, so a
600 x 600 frame costs 10-20 ms. Matplotlib is imported lazily: importing this module never needs
it, constructing a renderer does (``pip install 'active-loc[render]'``). ``render_rgb`` never
touches pyplot (safe in headless workers and subprocess vector envs); only ``show`` does.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

import numpy as np
from numpy.typing import NDArray

if TYPE_CHECKING:
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

CHI2_95_2DOF = 5.991  # 95 % quantile of chi-square with 2 dof: the position ellipse
HEADING_SIGMAS = 2.0  # the heading wedge spans mean +/- 2 sigma (about 95 %)
DPI = 100.0
# Backends that cannot show a window: ``show`` then only draws (no event loop, no warning).
_NON_INTERACTIVE_BACKENDS = frozenset({"agg", "cairo", "pdf", "pgf", "ps", "svg", "template"})

_TRUE_COLOR = "tab:green"
_BELIEF_COLOR = "tab:blue"
_RAY_COLOR = "tab:orange"
_FOV_COLOR = "gold"
# Figure margins (px at DPI 100): room for the title, the tick labels and the 2-row legend.
_MARGIN_PX = {"left": 48.0, "right": 14.0, "bottom": 70.0, "top": 22.0}

# Marker outlines in units of the pose-marker size L, heading along +x, centred on the pose.
_TRIANGLE = np.array([[0.6, 0.0], [-0.4, 0.38], [-0.4, -0.38]])
_ARROW = np.array(
    [[-0.5, -0.11], [0.1, -0.11], [0.1, -0.3], [0.55, 0.0], [0.1, 0.3], [0.1, 0.11], [-0.5, 0.11]]
)


@dataclass(frozen=True)
class LandmarkFrame:
    """Everything one rendered frame shows (all float64 numpy arrays, SI units, radians)."""

    bounds: tuple[float, float, float, float]  # x_min, y_min, x_max, y_max of the map (m)
    landmarks: NDArray  # (N, 2) landmark positions (m)
    visible: NDArray  # (N,) bool: landmarks seen this step (rays from the TRUE pose to these)
    true_pose: NDArray  # (3,) x, y, theta of the robot
    mean: NDArray  # (3,) belief mean
    cov: NDArray  # (3, 3) belief covariance (x, y, theta)
    true_path: NDArray  # (T, 2) trajectory so far of the true robot
    belief_path: NDArray  # (T, 2) trajectory so far of the belief mean
    fov: float  # sensor field of view (rad), 2*pi = all round
    max_range: float  # sensor range (m), may be inf
    step: int
    entropy: float  # nats
    title: str = ""


def _pose_polygon(shape: NDArray, pose: NDArray, size: float) -> NDArray:
    """Outline ``shape`` (K, 2) scaled by ``size`` (m), rotated and moved to ``pose`` (3,)."""
    c, s = math.cos(pose[2]), math.sin(pose[2])
    rot = np.array([[c, -s], [s, c]])
    return pose[:2] + size * shape @ rot.T


def _ellipse_params(cov_xy: NDArray, cap: float) -> tuple[float, float, float] | None:
    """95 % ellipse of a 2x2 covariance: (width, height, angle_deg), or None if not finite.

    Negative eigenvalues of a nearly singular (or slightly non-PSD) covariance are clipped to 0,
    and the full axes are capped at ``cap`` (m): past that the ellipse covers the view anyway,
    and astronomically large paths upset Agg.
    """
    sym = 0.5 * cov_xy + 0.5 * cov_xy.T  # halve first: no overflow for entries near 1e308
    if not np.all(np.isfinite(sym)):
        return None
    # Normalise first so that huge or tiny entries neither overflow nor underflow eigh.
    scale = float(np.max(np.abs(sym)))
    if scale == 0.0:
        return 0.0, 0.0, 0.0
    eigval, eigvec = np.linalg.eigh(sym / scale)
    eigval = np.clip(eigval, 0.0, None)
    # axis = 2 sqrt(chi2 * lambda * scale); computed in sqrt space to avoid overflow.
    axes = 2.0 * np.sqrt(CHI2_95_2DOF * eigval) * math.sqrt(scale)
    axes = np.minimum(axes, cap)
    major = eigvec[:, 1]  # eigh sorts ascending: the last column is the major axis
    angle = math.degrees(math.atan2(major[1], major[0]))
    return float(axes[1]), float(axes[0]), angle


class _Scene:
    """The artists of one frame, built once on a figure and then only updated.

    With ``blit=True`` (the Agg path) everything that moves is an *animated* artist: a full draw
    renders only the static layer (frame, ticks, legend, title), which is cached and restored
    each frame before the moving artists are drawn over it. Text layout of the ticks and legend
    is most of matplotlib's cost, so this keeps a frame to a few ms of actual drawing.
    """

    def __init__(self, fig: Figure, blit: bool) -> None:
        from matplotlib.collections import LineCollection
        from matplotlib.patches import Ellipse, Polygon, Rectangle, Wedge

        self.fig = fig
        self.blit = blit
        self._background: Any = None
        self._background_key: tuple[Any, ...] | None = None
        self._limits_key: tuple[float, ...] | None = None

        # Fixed layout (no tight_layout per frame), margins in pixels since the fonts have a
        # fixed size in points: title on top, tick labels and a legend strip at the bottom.
        width_px, height_px = fig.bbox.width, fig.bbox.height
        left, right = min(_MARGIN_PX["left"] / width_px, 0.3), _MARGIN_PX["right"] / width_px
        bottom, top = min(_MARGIN_PX["bottom"] / height_px, 0.4), _MARGIN_PX["top"] / height_px
        ax = fig.add_axes((left, bottom, max(1.0 - left - right, 0.1), max(1 - bottom - top, 0.1)))
        ax.set_aspect("equal", adjustable="box")
        ax.tick_params(labelsize=7)
        ax.set_xlabel("x (m)", fontsize=8, labelpad=1)
        ax.set_ylabel("y (m)", fontsize=8, labelpad=1)
        self.ax = ax

        tri = np.zeros((3, 2))
        line = {"linestyle": "none", "marker": "*", "markersize": 10, "markeredgewidth": 0.8}
        self.map_rect = Rectangle((0, 0), 1, 1, fill=False, edgecolor="black", lw=1.2, zorder=1)
        self.fov = Wedge((0, 0), 1, 0, 360, fc=_FOV_COLOR, ec="none", alpha=0.2, zorder=1.5)
        (self.true_path,) = ax.plot([], [], color=_TRUE_COLOR, lw=1.3, zorder=2)
        (self.belief_path,) = ax.plot([], [], color=_BELIEF_COLOR, lw=1.3, ls="--", zorder=2)
        self.rays = LineCollection([], colors=_RAY_COLOR, linewidths=1.0, zorder=2.5)
        (self.landmarks,) = ax.plot([], [], mfc="white", mec="black", zorder=3, **line)
        (self.seen,) = ax.plot([], [], mfc=_RAY_COLOR, mec="black", zorder=3.1, **line)
        self.heading = Wedge((0, 0), 1, 0, 360, fc=_BELIEF_COLOR, ec="none", alpha=0.2, zorder=3.4)
        self.ellipse = Ellipse(
            (0, 0), 0, 0, fc=_BELIEF_COLOR, ec=_BELIEF_COLOR, alpha=0.25, lw=1.0, zorder=3.5
        )
        # The (larger) true triangle lies under the belief arrow, so both stay visible when
        # the belief is right on top of the truth.
        self.true = Polygon(tri, closed=True, fc=_TRUE_COLOR, ec="black", lw=0.6, zorder=4)
        self.mean = Polygon(tri, closed=True, fc=_BELIEF_COLOR, ec="white", lw=0.6, zorder=5)
        for patch in (self.map_rect, self.fov, self.heading, self.ellipse, self.true, self.mean):
            ax.add_patch(patch)
        ax.add_collection(self.rays)
        box = {"boxstyle": "round,pad=0.2", "facecolor": "white", "alpha": 0.8, "ec": "none"}
        self.info = ax.text(
            0.015, 0.985, "", transform=ax.transAxes, ha="left", va="top", fontsize=8, bbox=box,
            zorder=6,
        )  # fmt: skip
        self.title = fig.text(0.5, 1.0 - 4.0 / height_px, "", ha="center", va="top", fontsize=9)

        legend = [
            (self.true, "true pose"), (self.mean, "belief mean"), (self.ellipse, "95% belief"),
            (self.landmarks, "landmark"), (self.seen, "observed"), (self.fov, "sensor FOV"),
            (self.true_path, "true path"), (self.belief_path, "belief path"),
        ]  # fmt: skip
        fig.legend(
            *zip(*legend, strict=True), loc="lower center", ncol=4, fontsize=7, frameon=False,
            handlelength=1.6, columnspacing=1.0, borderaxespad=0.2,
        )  # fmt: skip

        self.moving = sorted(
            [
                self.fov, self.true_path, self.belief_path, self.rays, self.landmarks, self.seen,
                self.heading, self.ellipse, self.true, self.mean, self.info,
            ],
            key=lambda artist: artist.get_zorder(),
        )  # fmt: skip
        if blit:  # only after the legend: its entries copy the handles' properties
            for artist in self.moving:
                artist.set_animated(True)

    def update(self, frame: LandmarkFrame) -> None:
        """Move every artist to ``frame`` (no drawing)."""
        x_min, y_min, x_max, y_max = (float(b) for b in frame.bounds)
        span = max(x_max - x_min, y_max - y_min, 1e-6)
        if self._limits_key != (x_min, y_min, x_max, y_max):
            self._limits_key = (x_min, y_min, x_max, y_max)
            margin = 0.04 * span
            self.ax.set_xlim(x_min - margin, x_max + margin)
            self.ax.set_ylim(y_min - margin, y_max + margin)
            self.map_rect.set_bounds(x_min, y_min, x_max - x_min, y_max - y_min)
        if self.title.get_text() != frame.title:
            self.title.set_text(frame.title)
        size = 0.045 * span  # pose markers scale with the map so they read at any map size

        landmarks = np.asarray(frame.landmarks, dtype=np.float64).reshape(-1, 2)
        visible = np.asarray(frame.visible, dtype=bool).reshape(-1)
        if visible.shape[0] != landmarks.shape[0]:
            raise ValueError(
                f"visible has {visible.shape[0]} entries but there are "
                f"{landmarks.shape[0]} landmarks"
            )
        self.landmarks.set_data(landmarks[:, 0], landmarks[:, 1])
        seen = landmarks[visible]
        self.seen.set_data(seen[:, 0], seen[:, 1])

        true_pose = np.asarray(frame.true_pose, dtype=np.float64).reshape(3)
        true_ok = bool(np.all(np.isfinite(true_pose)))
        self.true.set_visible(true_ok)
        self.rays.set_visible(true_ok)
        self.fov.set_visible(False)
        if true_ok:
            self.true.set_xy(_pose_polygon(_TRIANGLE, true_pose, 1.15 * size))
            self.rays.set_segments([np.array([true_pose[:2], lm]) for lm in seen])
            self._update_fov(true_pose, frame.fov, frame.max_range, span)

        mean = np.asarray(frame.mean, dtype=np.float64).reshape(3)
        cov = np.asarray(frame.cov, dtype=np.float64).reshape(3, 3)
        mean_ok = bool(np.all(np.isfinite(mean)))
        self.mean.set_visible(mean_ok)
        self.ellipse.set_visible(False)
        self.heading.set_visible(False)
        if mean_ok:
            self.mean.set_xy(_pose_polygon(_ARROW, mean, size))
            ellipse = _ellipse_params(cov[:2, :2], cap=20.0 * span)
            if ellipse is not None:
                width, height, angle = ellipse
                self.ellipse.set_center((mean[0], mean[1]))
                self.ellipse.set_width(width)
                self.ellipse.set_height(height)
                self.ellipse.set_angle(angle)
                self.ellipse.set_visible(True)
            var_theta = float(cov[2, 2])
            if math.isfinite(var_theta):
                half = HEADING_SIGMAS * math.sqrt(max(var_theta, 0.0))
                self._set_wedge(self.heading, mean, 2.0 * half, 1.6 * size)

        self._set_path(self.true_path, frame.true_path)
        self._set_path(self.belief_path, frame.belief_path)
        self.info.set_text(f"step {int(frame.step)}   H = {float(frame.entropy):.2f} nats")

    def draw_agg(self, canvas: FigureCanvasAgg) -> None:
        """Draw the current state into ``canvas`` (blitting scene): cached background + movers."""
        key = (self._limits_key, self.title.get_text())
        if key != self._background_key or self._background is None:
            canvas.draw()  # animated artists are skipped: this is the static layer only
            self._background = canvas.copy_from_bbox(self.fig.bbox)
            self._background_key = key
        else:
            canvas.restore_region(self._background)
        for artist in self.moving:
            self.ax.draw_artist(artist)

    def _update_fov(self, pose: NDArray, fov: float, max_range: float, span: float) -> None:
        """Faint sensor wedge; an unlimited range is drawn out to the map's diagonal."""
        fov, max_range = float(fov), float(max_range)
        full_circle = fov >= 2.0 * math.pi - 1e-9
        if math.isinf(max_range) and full_circle:
            return  # sees the whole map: a tint over everything would carry no information
        radius = min(max_range, math.sqrt(2.0) * span)
        if not (radius > 0.0 and fov > 0.0):  # also rejects NaN
            return
        self._set_wedge(self.fov, pose, fov, radius)

    @staticmethod
    def _set_wedge(wedge: Any, pose: NDArray, width: float, radius: float) -> None:
        """Centre ``wedge`` on ``pose`` (3,), opening ``width`` (rad) about its heading."""
        wedge.set_center((pose[0], pose[1]))
        wedge.set_radius(radius)
        if width >= 2.0 * math.pi - 1e-9:
            wedge.set_theta1(0.0)
            wedge.set_theta2(360.0)  # Wedge draws an exact 360 degree span as a plain circle
        else:
            heading = math.degrees(pose[2])
            half = math.degrees(0.5 * width)
            wedge.set_theta1(heading - half)
            wedge.set_theta2(heading + half)
        wedge.set_visible(True)

    @staticmethod
    def _set_path(line: Any, path: NDArray) -> None:
        """Set a Line2D to a (T, 2) path (m); an empty path draws nothing."""
        xy = np.asarray(path, dtype=np.float64).reshape(-1, 2)
        line.set_data(xy[:, 0], xy[:, 1])


class LandmarkRenderer:
    """Draws ``LandmarkFrame`` s to RGB arrays (Agg, no pyplot) or to a live pyplot window.

    Args:
        size_px: (width, height) of the rendered image in pixels.
    """

    def __init__(self, size_px: tuple[int, int] = (600, 600)) -> None:
        try:
            from matplotlib.backends.backend_agg import FigureCanvasAgg
            from matplotlib.figure import Figure
        except ImportError as exc:
            raise ImportError(
                "rendering needs matplotlib: pip install 'active-loc[render]'"
            ) from exc
        width, height = (int(v) for v in size_px)
        if width < 100 or height < 100:
            raise ValueError(f"size_px must be at least (100, 100) pixels, got {size_px}")
        self.size_px = (width, height)
        self._figure_cls = Figure
        self._canvas_cls = FigureCanvasAgg
        self._scene: _Scene | None = None
        self._canvas: FigureCanvasAgg | None = None
        self._window: Figure | None = None  # pyplot figure of ``show``
        self._window_scene: _Scene | None = None
        self._build()

    def _build(self) -> None:
        width, height = self.size_px
        fig = self._figure_cls(figsize=(width / DPI, height / DPI), dpi=DPI)
        self._canvas = self._canvas_cls(fig)
        self._scene = _Scene(fig, blit=True)

    def render_rgb(self, frame: LandmarkFrame) -> NDArray[np.uint8]:
        """Render ``frame`` to an (H, W, 3) uint8 image, H, W = ``size_px[1]``, ``size_px[0]``.

        The shape is the same for every frame of a renderer, whatever the map.
        """
        if self._scene is None:  # rendering after close() simply rebuilds the figure
            self._build()
        assert self._scene is not None and self._canvas is not None
        self._scene.update(frame)
        self._scene.draw_agg(self._canvas)
        rgb = np.asarray(self._canvas.buffer_rgba())[:, :, :3]
        width, height = self.size_px
        if rgb.shape[:2] != (height, width):
            # Figure inches x dpi can round down one pixel for some sizes: pad or crop.
            out = np.full((height, width, 3), 255, dtype=np.uint8)
            h, w = min(height, rgb.shape[0]), min(width, rgb.shape[1])
            out[:h, :w] = rgb[:h, :w]
            return out
        return rgb.copy()  # the Agg buffer is reused by the next draw

    def show(self, frame: LandmarkFrame) -> None:
        """Draw ``frame`` into an interactive pyplot window, without blocking.

        The window is (re)opened on first use or after the user closed it. On a non-interactive
        backend (e.g. Agg on a headless machine) the figure is drawn but nothing is shown.
        """
        import matplotlib
        import matplotlib.pyplot as plt

        if self._window is None or not plt.fignum_exists(self._window.number):
            plt.ion()
            width, height = self.size_px
            self._window = plt.figure(figsize=(width / DPI, height / DPI), dpi=DPI)
            self._window_scene = _Scene(self._window, blit=False)
            self._window.show(warn=False)  # warn=False: no UserWarning on non-GUI backends
        assert self._window_scene is not None
        self._window_scene.update(frame)
        canvas = self._window.canvas
        canvas.draw_idle()
        if matplotlib.get_backend().lower() not in _NON_INTERACTIVE_BACKENDS:
            # What plt.pause does, but for this figure rather than pyplot's "current" one.
            canvas.start_event_loop(1e-3)

    def close(self) -> None:
        """Close the ``show`` window and drop the figures. Idempotent."""
        if self._window is not None:
            import matplotlib.pyplot as plt

            plt.close(self._window)
        self._window = None
        self._window_scene = None
        self._scene = None
        self._canvas = None
