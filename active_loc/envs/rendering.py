"""Matplotlib rendering of the localization tasks (``rgb_array`` and ``human`` modes).

Two scenes share one drawing core (pose markers, belief, particles, paths, text, caching):

``LandmarkRenderer`` draws a :class:`LandmarkFrame`, in map coordinates (m):

* the map bounds (rectangle) and the landmarks (stars; the ones seen this step are filled),
* the true robot pose (green triangle), its sensor field of view (faint wedge) and rays from the
  true pose to the landmarks seen this step,
* optionally the particles of a particle filter (see below),
* the belief mean (blue arrow), its 95 % position ellipse (chi-square, 2 dof) and a wedge of
  +/- 2 sigma of heading uncertainty,
* the true and believed trajectories, and a text line with the step and the belief entropy.

``GridRenderer`` draws a :class:`GridFrame` on an occupancy-grid map: the grid (free white,
occupied black, unknown grey; off the map a pale blue-grey), the lidar scan as beams from the
TRUE pose (returns solid with a dot at the end point, max-range "no return" readings lighter and
dashed), the particles or a grid belief's x-y marginal as a heat map over the map (cells
shaded light to dark pink and more opaque as their mass approaches the largest cell's; cells
without mass transparent), the true pose, the belief (mean, ellipse, heading wedge), both paths,
the step / entropy line, and a red "KIDNAPPED" flag plus a ring around the true pose on the
frame of a kidnapping.

Particles are shaded by weight, light pink (weight 0) to dark purple (the largest weight;
``weights=None`` is uniform, all dark), drawn heaviest on top, under the paths and the robot
and belief markers. Up to :data:`MAX_HEADING_TICKS` particles are small needles pointing along
their heading (base at the particle, 10 px long whatever the map size, heading rounded to 5
degrees); more are plain dots.

Both renderers build their figure and artists once and only update their data each frame; the
static layer (axes, ticks, legend, title and, for grids, the map image) is drawn once per map
(about 0.1 s) and then blitted, so a 600 x 600 frame costs about 10 ms (landmarks, no particles)
to 15 ms (grid, 1000 particles, 60 beams), whatever the size of the grid. Matplotlib is
imported lazily: importing this module never needs it, constructing a renderer does
(``pip install 'active-loc[render]'``). ``render_rgb`` never touches pyplot (safe in headless
workers and subprocess vector envs); only ``show`` does.

``ImageWindow`` is the ``human`` mode of an env that draws its own RGB frames (``Maze-v0``):
it shows each frame in a pyplot window the way ``show`` does (non-blocking, only drawn on a
non-interactive backend).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any, Generic, TypeVar

import numpy as np
from numpy.typing import NDArray

if TYPE_CHECKING:
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    from active_loc.maps.occupancy import OccupancyGrid

CHI2_95_2DOF = 5.991  # 95 % quantile of chi-square with 2 dof: the position ellipse
HEADING_SIGMAS = 2.0  # the heading wedge spans mean +/- 2 sigma (about 95 %)
DPI = 100.0
MAX_HEADING_TICKS = 2000  # particles are heading needles up to this many, plain dots beyond
_NEEDLE_BINS = 72  # needle headings are rounded to 360 / 72 = 5 degrees
_NEEDLE_SIZE = 36.0  # scatter size (pt^2) of a needle: the marker unit is 6 pt
_DOT_SIZE = 5.0  # scatter size (pt^2) of a dot (more than MAX_HEADING_TICKS particles)
# A beam reading at least max_range * (1 - this) is a max reading ("no return"), as in lidar.py.
_MAX_READING_TOL = 1e-6
# Backends that cannot show a window: ``show`` then only draws (no event loop, no warning).
_NON_INTERACTIVE_BACKENDS = frozenset({"agg", "cairo", "pdf", "pgf", "ps", "svg", "template"})

_TRUE_COLOR = "tab:green"
_BELIEF_COLOR = "tab:blue"
_RAY_COLOR = "tab:orange"
_FOV_COLOR = "gold"
_KIDNAP_COLOR = "tab:red"
_PEOPLE_COLOR = "tab:purple"  # people and other obstacles the map does not hold
_HEAT_MAX_ALPHA = 0.8  # opacity of the heat map's heaviest cell (a grid belief's marginal)
_OFF_MAP_COLOR = "#e3e9f0"  # grid scene: axes background outside the map
# Grid cell colours (RGB uint8): free white, occupied black, unknown map_saver's grey (205).
_FREE_RGB, _OCCUPIED_RGB, _UNKNOWN_RGB = (255, 255, 255), (0, 0, 0), (205, 205, 205)
# Particle shading: the part of matplotlib's "RdPu" colormap from light pink to dark purple.
_PARTICLE_CMAP_RANGE = (0.3, 1.0)
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
    particles: NDArray | None = None  # (K, 3) particle poses x, y, theta, or None: none drawn
    weights: NDArray | None = None  # (K,) normalized particle weights, or None: uniform


@dataclass(frozen=True)
class GridFrame:
    """One rendered frame on an occupancy-grid map (float64 numpy arrays, SI units, radians).

    The map image is drawn once per grid *object* (compared by identity, not by contents):
    reuse the same :class:`~active_loc.maps.occupancy.OccupancyGrid` instance from frame to
    frame to keep rendering fast.
    """

    grid: OccupancyGrid  # the map
    true_pose: NDArray  # (3,) x, y, theta of the robot
    mean: NDArray  # (3,) belief mean
    cov: NDArray  # (3, 3) belief covariance (x, y, theta)
    particles: NDArray | None  # (K, 3) particle poses, or None: none drawn
    weights: NDArray | None  # (K,) normalized particle weights, or None: uniform
    beam_angles: NDArray  # (M,) lidar beam directions relative to the heading (rad)
    ranges: NDArray  # (M,) the current scan (m), drawn from the TRUE pose; NaN beams are skipped
    max_range: float  # lidar maximum range (m): readings at it are "no return"
    true_path: NDArray  # (T, 2) trajectory so far of the true robot
    belief_path: NDArray  # (T, 2) trajectory so far of the belief mean
    step: int
    entropy: float  # nats
    title: str = ""
    kidnapped: bool = False  # the robot was kidnapped (teleported) this step: flagged in red
    people: NDArray | None = None  # (P, 3) centre x, y and radius (m) of unmapped obstacles
    # a grid belief's mass per cell, (X, Y) indexed [ix, iy], on cells of belief_cell_size m
    # laid over the map from its origin (and yaw): drawn as a heat map; None: none drawn
    belief_map: NDArray | None = None
    belief_cell_size: float = 0.0


_FrameT = TypeVar("_FrameT", LandmarkFrame, GridFrame)


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


def _particle_data(
    particles: NDArray | None, weights: NDArray | None
) -> tuple[NDArray, NDArray] | None:
    """Particles to draw, lightest first: ``(poses (K', 3), shade (K',) in [0, 1])``, or None.

    ``shade`` is weight / max weight. Particles with a non-finite pose are dropped; non-finite
    or negative weights count as 0; all-zero (or None) weights are uniform (shade 1).

    Raises:
        ValueError: ``particles`` is not (K, 3) or ``weights`` is not (K,).
    """
    if particles is None:
        return None
    poses = np.asarray(particles, dtype=np.float64)
    if poses.ndim != 2 or poses.shape[1] != 3:
        raise ValueError(f"particles must have shape (K, 3), got {poses.shape}")
    if weights is None:
        w = np.ones(poses.shape[0])
    else:
        w = np.asarray(weights, dtype=np.float64)
        if w.shape != (poses.shape[0],):
            raise ValueError(
                f"weights must have shape ({poses.shape[0]},) like the particles, got {w.shape}"
            )
        w = np.where(np.isfinite(w) & (w > 0.0), w, 0.0)
    ok = np.all(np.isfinite(poses), axis=1)
    if not ok.all():
        poses, w = poses[ok], w[ok]
    w_max = float(w.max(initial=0.0))
    shade = w / w_max if w_max > 0.0 else np.ones(poses.shape[0])
    order = np.argsort(shade, kind="stable")  # heaviest drawn last, on top
    return poses[order], shade[order]


def _needle_paths() -> list[Any]:
    """``_NEEDLE_BINS`` marker paths of a particle needle, heading ``2 pi i / _NEEDLE_BINS``.

    A narrow kite in marker units (1 = sqrt(scatter size) pt): the particle sits at the
    origin, the tip lies 1 unit ahead along the heading.
    """
    from matplotlib.path import Path
    from matplotlib.transforms import Affine2D

    kite = Path(
        [(-0.2, 0.0), (0.0, -0.16), (1.0, 0.0), (0.0, 0.16), (-0.2, 0.0)],
        [Path.MOVETO, Path.LINETO, Path.LINETO, Path.LINETO, Path.CLOSEPOLY],
    )
    step = 2.0 * math.pi / _NEEDLE_BINS
    return [Affine2D().rotate(i * step).transform_path(kite) for i in range(_NEEDLE_BINS)]


def _dot_path() -> Any:
    """Marker path of a particle dot: an octagon of diameter 1 marker unit (cheap to fill)."""
    from matplotlib.path import Path

    angles = np.arange(8) * (math.pi / 4.0)
    ring = 0.5 * np.column_stack([np.cos(angles), np.sin(angles)])
    return Path(np.vstack([ring, ring[:1]]), closed=True)


def _grid_rgb(grid: OccupancyGrid) -> NDArray[np.uint8]:
    """The map image ``(ny, nx, 3)`` uint8, row 0 at the bottom (for ``origin='lower'``)."""
    from active_loc.maps.occupancy import OCCUPIED, UNKNOWN

    values = grid.values
    rgb = np.empty((*values.shape, 3), dtype=np.uint8)
    rgb[...] = _FREE_RGB
    rgb[values == OCCUPIED] = _OCCUPIED_RGB
    rgb[values == UNKNOWN] = _UNKNOWN_RGB
    return rgb


def _grid_corners(grid: OccupancyGrid, cells: tuple[int, int, int, int] | None = None) -> NDArray:
    """World corners ``(4, 2)`` (m), counter-clockwise, of the cell block ``cells`` =
    ``(ix0, iy0, ix1, iy1)`` (half-open; None: the whole map)."""
    ny, nx = grid.shape
    ix0, iy0, ix1, iy1 = (0, 0, nx, ny) if cells is None else cells
    res = grid.resolution
    ox, oy, yaw = grid.origin
    c, s = math.cos(yaw), math.sin(yaw)
    local = res * np.array([[ix0, iy0], [ix1, iy0], [ix1, iy1], [ix0, iy1]], dtype=np.float64)
    return np.array([ox, oy]) + local @ np.array([[c, -s], [s, c]]).T


def _known_bounds(grid: OccupancyGrid) -> tuple[float, float, float, float]:
    """World axis-aligned box ``(x_min, y_min, x_max, y_max)`` (m) around the cells that are
    not UNKNOWN (the whole map's :attr:`~OccupancyGrid.bounds` if all are unknown)."""
    from active_loc.maps.occupancy import UNKNOWN

    known = grid.values != UNKNOWN
    if not known.any():
        return grid.bounds
    rows = np.flatnonzero(known.any(axis=1))
    cols = np.flatnonzero(known.any(axis=0))
    corners = _grid_corners(grid, (cols[0], rows[0], cols[-1] + 1, rows[-1] + 1))
    x_min, y_min = corners.min(axis=0)
    x_max, y_max = corners.max(axis=0)
    return float(x_min), float(y_min), float(x_max), float(y_max)


class _Scene:
    """The artists of one frame, built once on a figure and then only updated.

    This base class holds what both tasks show (true pose, belief, particles, paths, text) and
    the cached drawing; subclasses add their map and sensor artists, then call
    :meth:`_finish`.

    With ``blit=True`` (the Agg path) everything that moves is an *animated* artist: a full draw
    renders only the static layer (frame, ticks, legend, title, grid image), which is cached and
    restored each frame before the moving artists are drawn over it. Text layout of the ticks
    and legend is most of matplotlib's cost, so this keeps a frame to a few ms of actual drawing.
    Whatever changes the static layer must call :meth:`_invalidate`.
    """

    def __init__(self, fig: Figure, blit: bool) -> None:
        import matplotlib
        from matplotlib.colors import ListedColormap
        from matplotlib.patches import Ellipse, Polygon, Wedge

        self.fig = fig
        self.blit = blit
        self._background: Any = None
        self._limits_key: tuple[float, ...] | None = None
        self.span = 1.0  # largest side of the shown area (m): pose markers scale with it

        # Fixed layout (no tight_layout per frame), margins in pixels since the fonts have a
        # fixed size in points: title on top, tick labels and a legend strip at the bottom.
        width_px, height_px = fig.bbox.width, fig.bbox.height
        left, right = min(_MARGIN_PX["left"] / width_px, 0.3), _MARGIN_PX["right"] / width_px
        bottom, top = min(_MARGIN_PX["bottom"] / height_px, 0.4), _MARGIN_PX["top"] / height_px
        ax = fig.add_axes((left, bottom, max(1.0 - left - right, 0.1), max(1 - bottom - top, 0.1)))
        ax.set_aspect("equal", adjustable="box")
        ax.set_autoscale_on(False)  # limits are set explicitly per map
        ax.tick_params(labelsize=7)
        ax.set_xlabel("x (m)", fontsize=8, labelpad=1)
        ax.set_ylabel("y (m)", fontsize=8, labelpad=1)
        self.ax = ax

        lo, hi = _PARTICLE_CMAP_RANGE
        cmap = ListedColormap(matplotlib.colormaps["RdPu"](np.linspace(lo, hi, 256)))
        self.particle_cmap = cmap
        # One scatter for all particles, with one marker path per particle: a needle along
        # its heading (one of _NEEDLE_BINS pre-rotated paths, shared, so setting them per
        # frame is just a list of references) or, for many particles, a plain dot.
        self._needles = _needle_paths()
        self._dot = _dot_path()
        self.particles = ax.scatter(
            np.zeros(0), np.zeros(0), c=np.zeros(0), s=_NEEDLE_SIZE, cmap=cmap, vmin=0.0,
            vmax=1.0, linewidths=0.0, zorder=1.8,
        )  # fmt: skip

        tri = np.zeros((3, 2))
        (self.true_path,) = ax.plot([], [], color=_TRUE_COLOR, lw=1.3, zorder=2)
        (self.belief_path,) = ax.plot([], [], color=_BELIEF_COLOR, lw=1.3, ls="--", zorder=2)
        self.heading = Wedge((0, 0), 1, 0, 360, fc=_BELIEF_COLOR, ec="none", alpha=0.2, zorder=3.4)
        self.ellipse = Ellipse(
            (0, 0), 0, 0, fc=_BELIEF_COLOR, ec=_BELIEF_COLOR, alpha=0.25, lw=1.0, zorder=3.5
        )
        # The (larger) true triangle lies under the belief arrow, so both stay visible when
        # the belief is right on top of the truth.
        self.true = Polygon(tri, closed=True, fc=_TRUE_COLOR, ec="black", lw=0.6, zorder=4)
        self.mean = Polygon(tri, closed=True, fc=_BELIEF_COLOR, ec="white", lw=0.6, zorder=5)
        for patch in (self.heading, self.ellipse, self.true, self.mean):
            ax.add_patch(patch)
        box = {"boxstyle": "round,pad=0.2", "facecolor": "white", "alpha": 0.8, "ec": "none"}
        self.info = ax.text(
            0.015, 0.985, "", transform=ax.transAxes, ha="left", va="top", fontsize=8, bbox=box,
            zorder=6,
        )  # fmt: skip
        self.title = fig.text(0.5, 1.0 - 4.0 / height_px, "", ha="center", va="top", fontsize=9)
        self.moving: list[Any] = [
            self.particles, self.true_path, self.belief_path, self.heading, self.ellipse,
            self.true, self.mean, self.info,
        ]  # fmt: skip

    def particle_handle(self) -> Any:
        """A legend proxy for the particles (the scatter itself has no colour until drawn)."""
        from matplotlib.lines import Line2D

        return Line2D(
            [], [], ls="none", marker=self._needles[0], markersize=9.0, mew=0,
            color=self.particle_cmap(0.75),
        )  # fmt: skip

    def _finish(self, legend: list[tuple[Any, str]], moving: list[Any]) -> None:
        """Add the figure legend and the subclass's ``moving`` artists; animate for blitting."""
        self.fig.legend(
            *zip(*legend, strict=True), loc="lower center", ncol=4, fontsize=7, frameon=False,
            handlelength=1.6, columnspacing=1.0, borderaxespad=0.2,
        )  # fmt: skip
        self.moving = sorted(self.moving + moving, key=lambda artist: artist.get_zorder())
        if self.blit:  # only after the legend: its entries copy the handles' properties
            for artist in self.moving:
                artist.set_animated(True)

    def _invalidate(self) -> None:
        """The static layer changed: the next :meth:`draw_agg` redraws it."""
        self._background = None

    def _set_limits(self, bounds: tuple[float, float, float, float]) -> bool:
        """Show ``bounds`` (x_min, y_min, x_max, y_max) (m) plus a 4 % margin; True if new."""
        x_min, y_min, x_max, y_max = (float(b) for b in bounds)
        self.span = max(x_max - x_min, y_max - y_min, 1e-6)
        if self._limits_key == (x_min, y_min, x_max, y_max):
            return False
        self._limits_key = (x_min, y_min, x_max, y_max)
        margin = 0.04 * self.span
        self.ax.set_xlim(x_min - margin, x_max + margin)
        self.ax.set_ylim(y_min - margin, y_max + margin)
        self._invalidate()
        return True

    def _set_title(self, title: str) -> None:
        if self.title.get_text() != title:
            self.title.set_text(title)
            self._invalidate()

    def _marker_size(self) -> float:
        """Pose-marker size (m): scales with the map so it reads at any map size."""
        return 0.045 * self.span

    def _update_true(self, true_pose: NDArray) -> NDArray | None:
        """Place the true-pose triangle; returns the (3,) pose, or None if not finite."""
        pose = np.asarray(true_pose, dtype=np.float64).reshape(3)
        ok = bool(np.all(np.isfinite(pose)))
        self.true.set_visible(ok)
        if ok:
            self.true.set_xy(_pose_polygon(_TRIANGLE, pose, 1.15 * self._marker_size()))
        return pose if ok else None

    def _update_belief(self, mean: NDArray, cov: NDArray) -> None:
        """Belief arrow, 95 % ellipse and heading wedge; hidden parts for non-finite input."""
        mean = np.asarray(mean, dtype=np.float64).reshape(3)
        cov = np.asarray(cov, dtype=np.float64).reshape(3, 3)
        size = self._marker_size()
        mean_ok = bool(np.all(np.isfinite(mean)))
        self.mean.set_visible(mean_ok)
        self.ellipse.set_visible(False)
        self.heading.set_visible(False)
        if not mean_ok:
            return
        self.mean.set_xy(_pose_polygon(_ARROW, mean, size))
        ellipse = _ellipse_params(cov[:2, :2], cap=20.0 * self.span)
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

    def _update_particles(self, particles: NDArray | None, weights: NDArray | None) -> int:
        """Move the particle markers (shaded by weight); returns how many particles there are."""
        data = _particle_data(particles, weights)
        if data is None or data[0].shape[0] == 0:
            self.particles.set_visible(False)
            return 0 if data is None else int(np.asarray(particles).shape[0])
        poses, shade = data
        if poses.shape[0] <= MAX_HEADING_TICKS:
            bins = np.rint(poses[:, 2] * (_NEEDLE_BINS / (2.0 * math.pi))).astype(np.int64)
            needles = self._needles
            self.particles.set_paths([needles[b] for b in (bins % _NEEDLE_BINS).tolist()])
            self.particles.set_sizes([_NEEDLE_SIZE])
        else:
            self.particles.set_paths([self._dot])
            self.particles.set_sizes([_DOT_SIZE])
        self.particles.set_offsets(poses[:, :2])
        self.particles.set_array(shade)
        self.particles.set_visible(True)
        return int(np.asarray(particles).shape[0])

    def _update_paths_and_text(self, frame: LandmarkFrame | GridFrame, n_particles: int) -> None:
        self._set_path(self.true_path, frame.true_path)
        self._set_path(self.belief_path, frame.belief_path)
        text = f"step {int(frame.step)}   H = {float(frame.entropy):.2f} nats"
        if n_particles:
            text += f"   {n_particles} particles"
        self.info.set_text(text)

    def draw_agg(self, canvas: FigureCanvasAgg) -> None:
        """Draw the current state into ``canvas`` (blitting scene): cached background + movers."""
        if self._background is None:
            canvas.draw()  # animated artists are skipped: this is the static layer only
            self._background = canvas.copy_from_bbox(self.fig.bbox)
        else:
            canvas.restore_region(self._background)
        for artist in self.moving:
            if artist.get_visible():
                self.ax.draw_artist(artist)

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


class _LandmarkScene(_Scene):
    """Landmark map: bounds rectangle, landmarks, sensor wedge and rays to the seen landmarks."""

    def __init__(self, fig: Figure, blit: bool) -> None:
        super().__init__(fig, blit)
        from matplotlib.collections import LineCollection
        from matplotlib.patches import Rectangle, Wedge

        ax = self.ax
        line = {"linestyle": "none", "marker": "*", "markersize": 10, "markeredgewidth": 0.8}
        self.map_rect = Rectangle((0, 0), 1, 1, fill=False, edgecolor="black", lw=1.2, zorder=1)
        self.fov = Wedge((0, 0), 1, 0, 360, fc=_FOV_COLOR, ec="none", alpha=0.2, zorder=1.5)
        self.rays = LineCollection([], colors=_RAY_COLOR, linewidths=1.0, zorder=2.5)
        (self.landmarks,) = ax.plot([], [], mfc="white", mec="black", zorder=3, **line)
        (self.seen,) = ax.plot([], [], mfc=_RAY_COLOR, mec="black", zorder=3.1, **line)
        ax.add_patch(self.map_rect)
        ax.add_patch(self.fov)
        ax.add_collection(self.rays)
        legend = [
            (self.true, "true pose"), (self.mean, "belief mean"), (self.ellipse, "95% belief"),
            (self.landmarks, "landmark"), (self.seen, "observed"), (self.fov, "sensor FOV"),
            (self.true_path, "true path"), (self.belief_path, "belief path"),
        ]  # fmt: skip
        self._finish(legend, [self.fov, self.rays, self.landmarks, self.seen])

    def update(self, frame: LandmarkFrame) -> None:
        """Move every artist to ``frame`` (no drawing)."""
        if self._set_limits(frame.bounds):
            x_min, y_min, x_max, y_max = self._limits_key  # type: ignore[misc]
            self.map_rect.set_bounds(x_min, y_min, x_max - x_min, y_max - y_min)
        self._set_title(frame.title)

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

        true_pose = self._update_true(frame.true_pose)
        self.rays.set_visible(true_pose is not None)
        self.fov.set_visible(False)
        if true_pose is not None:
            self.rays.set_segments([np.array([true_pose[:2], lm]) for lm in seen])
            self._update_fov(true_pose, frame.fov, frame.max_range)

        n_particles = self._update_particles(frame.particles, frame.weights)
        self._update_belief(frame.mean, frame.cov)
        self._update_paths_and_text(frame, n_particles)

    def _update_fov(self, pose: NDArray, fov: float, max_range: float) -> None:
        """Faint sensor wedge; an unlimited range is drawn out to the map's diagonal."""
        fov, max_range = float(fov), float(max_range)
        full_circle = fov >= 2.0 * math.pi - 1e-9
        if math.isinf(max_range) and full_circle:
            return  # sees the whole map: a tint over everything would carry no information
        radius = min(max_range, math.sqrt(2.0) * self.span)
        if not (radius > 0.0 and fov > 0.0):  # also rejects NaN
            return
        self._set_wedge(self.fov, pose, fov, radius)


class _GridScene(_Scene):
    """Occupancy-grid map (static image), lidar beams from the true pose, kidnapping flag.

    The map image is drawn in world coordinates: ``extent`` in the map frame, then rotated
    about the origin by the grid's yaw (an ``Affine2D`` before ``transData``), so a yawed map
    shows tilted. The view is the world box around the map's *known* (not UNKNOWN) cells plus
    a 4 % margin: a SLAM map that is mostly unknown is shown zoomed on its explored part. The
    image belongs to the static layer: drawn once per grid object, then blitted.
    """

    def __init__(self, fig: Figure, blit: bool) -> None:
        super().__init__(fig, blit)
        from matplotlib.collections import LineCollection, PatchCollection
        from matplotlib.lines import Line2D
        from matplotlib.patches import Circle, Polygon

        ax = self.ax
        ax.set_facecolor(_OFF_MAP_COLOR)
        self._grid: OccupancyGrid | None = None  # strong reference: keeps id(grid) unique
        self.image = ax.imshow(
            np.zeros((1, 1, 3), dtype=np.uint8), origin="lower", extent=(0.0, 1.0, 0.0, 1.0),
            interpolation="antialiased", zorder=0,
        )  # fmt: skip
        # a grid belief's x-y marginal, RGBA per belief cell, over the map and under the beams
        self.heat = ax.imshow(
            np.zeros((1, 1, 4), dtype=np.uint8), origin="lower", extent=(0.0, 1.0, 0.0, 1.0),
            interpolation="nearest", zorder=1.0,
        )  # fmt: skip
        self.heat.set_visible(False)
        self._heat_legend = False  # whether the legend names the heat map (else particles)
        ax.set_aspect("equal", adjustable="box")  # imshow may have reset it
        ax.set_autoscale_on(False)
        self.outline = Polygon(np.zeros((4, 2)), closed=True, fill=False, ec="black", lw=0.8)
        self.outline.set_zorder(0.5)
        ax.add_patch(self.outline)

        self.beams = LineCollection([], linewidths=0.7, zorder=1.6)
        ax.add_collection(self.beams)
        (self.hits,) = ax.plot(
            [], [], ls="none", marker="o", markersize=2.2, mew=0, color=_RAY_COLOR, zorder=1.7
        )
        self.kidnap_ring = Circle(
            (0, 0), 1, fill=False, ec=_KIDNAP_COLOR, lw=1.8, ls="--", zorder=4.5
        )
        ax.add_patch(self.kidnap_ring)
        self.people = PatchCollection([], facecolor=_PEOPLE_COLOR, edgecolor="none", alpha=0.8,
                                      zorder=1.5)
        ax.add_collection(self.people)
        box = {"boxstyle": "round,pad=0.25", "facecolor": _KIDNAP_COLOR, "ec": "none"}
        self.kidnap_text = ax.text(
            0.985, 0.985, "KIDNAPPED", transform=ax.transAxes, ha="right", va="top", fontsize=9,
            fontweight="bold", color="white", bbox=box, zorder=6,
        )  # fmt: skip
        self._beam_rgba = {
            True: np.array(self._rgba(_RAY_COLOR, 0.3)),  # max reading: lighter, dashed
            False: np.array(self._rgba(_RAY_COLOR, 0.6)),
        }
        self._beam_styles: tuple[bool, ...] | None = None  # max-reading mask of the last frame
        no_return = Line2D([], [], color=_RAY_COLOR, alpha=0.45, lw=0.8, ls=(0, (3, 2)))
        beam = Line2D([], [], color=_RAY_COLOR, lw=0.8, marker="o", markersize=2.2, mew=0)
        legend = [
            (self.true, "true pose"), (self.mean, "belief mean"), (self.ellipse, "95% belief"),
            (self.particle_handle(), "particles"), (beam, "lidar return"),
            (no_return, "no return"), (self.true_path, "true path"),
            (self.belief_path, "belief path"), (self.people, "people (not in the map)"),
        ]  # fmt: skip
        self._finish(legend, [self.beams, self.hits, self.kidnap_ring, self.kidnap_text,
                              self.people, self.heat])
        self._particle_entry = 3  # index of the particles' entry in the legend

    @staticmethod
    def _rgba(color: str, alpha: float) -> tuple[float, float, float, float]:
        from matplotlib.colors import to_rgba

        return to_rgba(color, alpha)

    def _set_grid(self, grid: OccupancyGrid) -> None:
        """Show a new map: image, extent, yaw transform, outline and limits."""
        from matplotlib.transforms import Affine2D

        self._grid = grid
        ox, oy, yaw = grid.origin
        width, height = grid.size_m
        self.image.set_data(_grid_rgb(grid))
        self.image.set_extent((ox, ox + width, oy, oy + height))
        if yaw == 0.0:
            transform = self.ax.transData
        else:
            transform = Affine2D().rotate_around(ox, oy, yaw) + self.ax.transData
        self.image.set_transform(transform)
        self.heat.set_transform(transform)  # the belief's cells are laid over the map's frame
        self.outline.set_xy(_grid_corners(grid))
        self._set_limits(_known_bounds(grid))
        self._invalidate()

    def update(self, frame: GridFrame) -> None:
        """Move every artist to ``frame`` (no drawing)."""
        if frame.grid is not self._grid:  # identity: hashing a big grid every frame is slow
            self._set_grid(frame.grid)
        self._set_title(frame.title)

        true_pose = self._update_true(frame.true_pose)
        self._update_beams(true_pose, frame.beam_angles, frame.ranges, frame.max_range)
        kidnapped = bool(frame.kidnapped)
        self.kidnap_text.set_visible(kidnapped)
        self.kidnap_ring.set_visible(kidnapped and true_pose is not None)
        if kidnapped and true_pose is not None:
            self.kidnap_ring.set_center((true_pose[0], true_pose[1]))
            self.kidnap_ring.set_radius(1.4 * self._marker_size())

        self._update_people(frame.people)
        self._update_heat(frame.belief_map, frame.belief_cell_size)
        n_particles = self._update_particles(frame.particles, frame.weights)
        self._update_belief(frame.mean, frame.cov)
        self._update_paths_and_text(frame, n_particles)

    def _update_heat(self, belief_map: NDArray | None, cell_size: float) -> None:
        """A grid belief's mass ``(X, Y)`` per cell of ``cell_size`` m as a heat map: colour
        and opacity grow with the mass relative to the heaviest cell (opacity as its square
        root, so that a spread-out belief still shows); cells without mass are transparent."""
        heat = belief_map is not None
        if heat != self._heat_legend:
            self._set_heat_legend(heat)
        if belief_map is None:
            self.heat.set_visible(False)
            return
        mass = np.asarray(belief_map, dtype=np.float64)
        if mass.ndim != 2 or mass.size == 0:
            raise ValueError(f"belief_map must have shape (X, Y), got {mass.shape}")
        cell_size = float(cell_size)
        if not (math.isfinite(cell_size) and cell_size > 0.0):
            raise ValueError(f"belief_cell_size must be finite and > 0 (m), got {cell_size}")
        mass = np.where(np.isfinite(mass) & (mass > 0.0), mass, 0.0)
        top = float(mass.max())
        level = mass.T / top if top > 0.0 else mass.T  # (Y, X): image rows are y
        rgba = self.particle_cmap(level, bytes=True)
        rgba[..., 3] = np.round(255.0 * _HEAT_MAX_ALPHA * np.sqrt(level)).astype(np.uint8)
        assert self._grid is not None
        ox, oy, _ = self._grid.origin
        nx, ny = mass.shape
        self.heat.set_data(rgba)
        self.heat.set_extent((ox, ox + nx * cell_size, oy, oy + ny * cell_size))
        self.heat.set_visible(True)

    def _set_heat_legend(self, heat: bool) -> None:
        """Name the heat map (a square) or the particles (a needle) in the legend."""
        legend = self.fig.legends[0]
        handle = legend.legend_handles[self._particle_entry]
        text = legend.get_texts()[self._particle_entry]
        if heat:
            text.set_text("belief (grid cells)")
            handle.set_marker("s")
            handle.set_markersize(7.0)
        else:
            text.set_text("particles")
            handle.set_marker(self._needles[0])
            handle.set_markersize(9.0)
        self._heat_legend = heat
        self._invalidate()

    def _update_people(self, people: NDArray | None) -> None:
        """Discs ``(P, 3)`` (x, y, radius) of the obstacles the map does not hold."""
        from matplotlib.patches import Circle

        if people is None or len(people) == 0:
            self.people.set_visible(False)
            return
        discs = np.asarray(people, dtype=np.float64).reshape(-1, 3)
        self.people.set_paths([Circle((x, y), r) for x, y, r in discs])
        self.people.set_visible(True)

    def _update_beams(
        self, pose: NDArray | None, beam_angles: NDArray, ranges: NDArray, max_range: float
    ) -> None:
        """Beams from ``pose`` (3,): returns solid with an end dot, max readings light dashed."""
        angles = np.asarray(beam_angles, dtype=np.float64).reshape(-1)
        r = np.asarray(ranges, dtype=np.float64).reshape(-1)
        if angles.shape != r.shape:
            raise ValueError(
                f"ranges has {r.shape[0]} entries but there are {angles.shape[0]} beam angles"
            )
        ok = np.isfinite(r) & np.isfinite(angles) & (r >= 0.0)
        if pose is None or not ok.any():
            self.beams.set_visible(False)
            self.hits.set_visible(False)
            return
        angles, r = angles[ok] + pose[2], r[ok]
        max_range = float(max_range)
        if math.isfinite(max_range) and max_range > 0.0:
            is_max = r >= max_range * (1.0 - _MAX_READING_TOL)
            r = np.minimum(r, max_range)
        else:
            is_max = np.zeros(r.shape, dtype=bool)
        ends = pose[:2] + r[:, None] * np.column_stack([np.cos(angles), np.sin(angles)])
        segments = np.empty((r.shape[0], 2, 2))
        segments[:, 0] = pose[:2]
        segments[:, 1] = ends
        self.beams.set_segments(segments)
        styles = tuple(is_max.tolist())
        if styles != self._beam_styles:  # dash patterns are parsed per segment: only on change
            self._beam_styles = styles
            self.beams.set_color(
                np.where(is_max[:, None], self._beam_rgba[True], self._beam_rgba[False])
            )
            self.beams.set_linestyle([(0, (3, 2)) if m else "solid" for m in styles])
        self.beams.set_visible(True)
        hit_ends = ends[~is_max]
        self.hits.set_data(hit_ends[:, 0], hit_ends[:, 1])
        self.hits.set_visible(hit_ends.shape[0] > 0)


class _Renderer(Generic[_FrameT]):
    """Draws frames to RGB arrays (Agg, no pyplot) or to a live pyplot window.

    Args:
        size_px: (width, height) of the rendered image in pixels.
    """

    _scene_cls: type[_Scene]

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
        self._scene: Any = None
        self._canvas: FigureCanvasAgg | None = None
        self._window: Figure | None = None  # pyplot figure of ``show``
        self._window_scene: Any = None
        self._build()

    def _build(self) -> None:
        width, height = self.size_px
        fig = self._figure_cls(figsize=(width / DPI, height / DPI), dpi=DPI)
        self._canvas = self._canvas_cls(fig)
        self._scene = self._scene_cls(fig, blit=True)

    def render_rgb(self, frame: _FrameT) -> NDArray[np.uint8]:
        """Render ``frame`` to an (H, W, 3) uint8 image, H, W = ``size_px[1]``, ``size_px[0]``.

        The shape is the same for every frame of a renderer, whatever the map.
        """
        if self._scene is None:  # rendering after close() simply rebuilds the figure
            self._build()
        assert self._scene is not None and self._canvas is not None
        self._scene.update(frame)
        self._scene.draw_agg(self._canvas)
        rgba = np.asarray(self._canvas.buffer_rgba())  # reused by the next draw: copy out
        width, height = self.size_px
        # Figure inches x dpi can round down one pixel for some sizes: pad (white) or crop.
        out = np.empty((height, width, 3), dtype=np.uint8)
        h, w = min(height, rgba.shape[0]), min(width, rgba.shape[1])
        if (h, w) != (height, width):
            out.fill(255)
        for channel in range(3):  # 5x faster than copying the strided rgba[..., :3] at once
            out[:h, :w, channel] = rgba[:h, :w, channel]
        return out

    def show(self, frame: _FrameT) -> None:
        """Draw ``frame`` into an interactive pyplot window, without blocking.

        The window is (re)opened on first use or after the user closed it. On a non-interactive
        backend (e.g. Agg on a headless machine) the figure is drawn but nothing is shown.
        """
        import matplotlib.pyplot as plt

        if self._window is None or not plt.fignum_exists(self._window.number):
            plt.ion()
            width, height = self.size_px
            self._window = plt.figure(figsize=(width / DPI, height / DPI), dpi=DPI)
            self._window_scene = self._scene_cls(self._window, blit=False)
            self._window.show(warn=False)  # warn=False: no UserWarning on non-GUI backends
        assert self._window_scene is not None
        self._window_scene.update(frame)
        _refresh_window(self._window)

    def close(self) -> None:
        """Close the ``show`` window and drop the figures. Idempotent."""
        if self._window is not None:
            import matplotlib.pyplot as plt

            plt.close(self._window)
        self._window = None
        self._window_scene = None
        self._scene = None
        self._canvas = None


def _refresh_window(figure: Figure) -> None:
    """Redraw a pyplot window and let its GUI process events, without blocking; on a
    non-interactive backend (e.g. Agg on a headless machine) only draw."""
    import matplotlib

    canvas = figure.canvas
    canvas.draw_idle()
    if matplotlib.get_backend().lower() not in _NON_INTERACTIVE_BACKENDS:
        # What plt.pause does, but for this figure rather than pyplot's "current" one.
        canvas.start_event_loop(1e-3)


class ImageWindow:
    """Shows ready-made RGB frames in a pyplot window, without blocking: the ``human`` mode of
    an env that draws its own ``rgb_array`` frames (``Maze-v0``), so both modes show the same
    picture, one image pixel per screen pixel.

    Args:
        title: the window's title.
    """

    def __init__(self, title: str = "") -> None:
        try:
            import matplotlib  # noqa: F401
        except ImportError as exc:
            raise ImportError(
                "rendering needs matplotlib: pip install 'active-loc[render]'"
            ) from exc
        self.title = title
        self.figure: Figure | None = None  # the pyplot figure, while the window is open
        self._image: Any = None  # its AxesImage

    def show(self, image: NDArray[np.uint8]) -> None:
        """Draw ``image`` ``(H, W, 3)`` uint8 into the window, (re)opened on first use, after
        the user closed it, or when the frame's shape changes."""
        import matplotlib.pyplot as plt

        image = np.asarray(image)
        if image.ndim != 3 or image.shape[2] != 3 or image.dtype != np.uint8:
            raise ValueError(f"image must be (H, W, 3) uint8, got {image.shape} {image.dtype}")
        open_ = self.figure is not None and plt.fignum_exists(self.figure.number)
        if not open_ or self._image.get_array().shape != image.shape:
            self.close()
            plt.ion()
            height, width = image.shape[:2]
            self.figure = plt.figure(figsize=(width / DPI, height / DPI), dpi=DPI)
            manager = self.figure.canvas.manager
            if manager is not None and self.title:
                manager.set_window_title(self.title)
            axes = self.figure.add_axes((0.0, 0.0, 1.0, 1.0))
            axes.set_axis_off()
            self._image = axes.imshow(image, interpolation="nearest")
            self.figure.show(warn=False)  # warn=False: no UserWarning on non-GUI backends
        else:
            self._image.set_data(image)
        assert self.figure is not None
        _refresh_window(self.figure)

    def close(self) -> None:
        """Close the window. Idempotent."""
        if self.figure is not None:
            import matplotlib.pyplot as plt

            plt.close(self.figure)
        self.figure = None
        self._image = None


class LandmarkRenderer(_Renderer[LandmarkFrame]):
    """Draws :class:`LandmarkFrame` s to RGB arrays (Agg, no pyplot) or to a live pyplot window.

    Args:
        size_px: (width, height) of the rendered image in pixels.
    """

    _scene_cls = _LandmarkScene


class GridRenderer(_Renderer[GridFrame]):
    """Draws :class:`GridFrame` s to RGB arrays (Agg, no pyplot) or to a live pyplot window.

    The map image is part of the cached static layer: it is rebuilt only when a frame brings
    a different grid object (identity), so the size of the grid does not matter per frame.

    Args:
        size_px: (width, height) of the rendered image in pixels.
    """

    _scene_cls = _GridScene
