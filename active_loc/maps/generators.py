"""Random occupancy maps: offices, exactly symmetric arenas, and mazes.

Every generator takes the ``numpy.random.Generator`` it draws from (nothing else is random),
returns an :class:`~active_loc.maps.occupancy.OccupancyGrid` with origin ``(0, 0, 0)`` and
only FREE / OCCUPIED cells, and surrounds the map with a wall. Sizes in metres are rounded to
whole cells. The layouts are built on integer cell indices, so that the symmetric arenas are
symmetric cell for cell, not merely up to rounding.

Which map to use:

- :func:`rooms_map`: an office, irregular enough that a lidar can localize globally.
- :func:`symmetric_arena`: identical copies of a room, or a lattice of identical pillars,
  so that several poses see exactly the same thing: the ambiguity active localization has to
  resolve (or cannot, with a 180-degree-symmetric arena).
- :func:`maze_map`: a perfect maze (one path between any two cells).

:data:`GENERATORS` maps the names the envs accept (``map="rooms"``) to callables ``fn(rng)``.
"""

from __future__ import annotations

import functools
import math
from collections.abc import Callable

import numpy as np
from numpy.typing import NDArray

# the maze benchmark's fixed test sets (active_loc.maps.maze), re-exported
from active_loc.maps.maze import maze_test_set  # noqa: F401
from active_loc.maps.occupancy import FREE, OCCUPIED, OccupancyGrid

IntRange = int | tuple[int, int]
FloatRange = float | tuple[float, float]


# --- small helpers ---------------------------------------------------------------------------


def _cells(length_m: float, resolution: float, name: str, minimum: int = 1) -> int:
    """A length (m) as a whole number of cells, at least ``minimum``."""
    cells = round(float(length_m) / resolution)
    if not math.isfinite(length_m) or cells < minimum:
        raise ValueError(
            f"{name} = {length_m} m is under {minimum} cell(s) at resolution {resolution} m"
        )
    return int(cells)


def _check_resolution(resolution: float, where: str) -> float:
    resolution = float(resolution)
    if not (math.isfinite(resolution) and resolution > 0.0):
        raise ValueError(f"{where}: resolution must be finite and > 0 (m), got {resolution}")
    return resolution


def _draw_int(rng: np.random.Generator, spec: IntRange, name: str, low: int = 1) -> int:
    """A fixed int, or one drawn uniformly from the inclusive range ``(lo, hi)``."""
    if isinstance(spec, tuple):
        lo, hi = (int(v) for v in spec)
        if not low <= lo <= hi:
            raise ValueError(f"{name} range must satisfy {low} <= lo <= hi, got {spec}")
        return int(rng.integers(lo, hi + 1))
    value = int(spec)
    if value < low:
        raise ValueError(f"{name} must be >= {low}, got {spec}")
    return value


def _draw_float(rng: np.random.Generator, spec: FloatRange, name: str) -> float:
    """A fixed float, or one drawn uniformly from ``[lo, hi]``; positive and finite."""
    if isinstance(spec, tuple):
        lo, hi = (float(v) for v in spec)
        if not (math.isfinite(lo) and math.isfinite(hi) and 0.0 < lo <= hi):
            raise ValueError(f"{name} range must satisfy 0 < lo <= hi, got {spec}")
        return float(rng.uniform(lo, hi))
    value = float(spec)
    if not (math.isfinite(value) and value > 0.0):
        raise ValueError(f"{name} must be finite and > 0, got {spec}")
    return value


def _walled(ny: int, nx: int, wall: int) -> NDArray[np.int8]:
    """A ``(ny, nx)`` free grid with a border wall ``wall`` cells thick."""
    values = np.full((ny, nx), OCCUPIED, dtype=np.int8)
    values[wall : ny - wall, wall : nx - wall] = FREE
    return values


def _split(
    rng: np.random.Generator, total: int, parts: int, minimum: int, maximum: int
) -> list[int]:
    """Random integer sizes in ``[minimum, maximum]`` summing to ``total``; needs
    ``parts minimum <= total <= parts maximum``."""
    spare = total - parts * minimum
    cap = maximum - minimum
    for _ in range(16):  # uniform random cut points, retried while a part is too long
        cuts = np.sort(rng.integers(0, spare + 1, size=parts - 1))
        extra = np.diff(np.concatenate([[0], cuts, [spare]]))
        if extra.max() <= cap:
            return [minimum + int(e) for e in extra]
    # a tight fit: as even as possible
    extra = np.full(parts, spare // parts)
    extra[: spare - int(extra.sum())] += 1
    return [minimum + int(e) for e in extra]


def _furnish(
    rng: np.random.Generator,
    values: NDArray[np.int8],
    room: tuple[int, int, int, int],
    count: int,
    size: tuple[int, int],
    clearance: int,
) -> None:
    """Place up to ``count`` rectangular blocks (sides in ``size`` cells, inclusive range) in
    the room ``(x0, y0, x1, y1)`` (free interior, half-open), each at least ``clearance``
    cells from the room's walls and from the other blocks.

    Blocks separated from every wall and from each other cannot cut the room's free space
    apart or block a doorway, so connectivity survives furnishing.
    """
    x0, y0, x1, y1 = room
    placed: list[tuple[int, int, int, int]] = []
    for _ in range(8 * count):  # bounded rejection sampling
        if len(placed) == count:
            break
        w, h = (int(v) for v in rng.integers(size[0], size[1] + 1, size=2))
        lo_x, hi_x = x0 + clearance, x1 - clearance - w
        lo_y, hi_y = y0 + clearance, y1 - clearance - h
        if hi_x < lo_x or hi_y < lo_y:
            continue
        bx = int(rng.integers(lo_x, hi_x + 1))
        by = int(rng.integers(lo_y, hi_y + 1))
        block = (bx, by, bx + w, by + h)
        if all(
            block[0] >= q[2] + clearance
            or q[0] >= block[2] + clearance
            or block[1] >= q[3] + clearance
            or q[1] >= block[3] + clearance
            for q in placed
        ):
            placed.append(block)
            values[by : by + h, bx : bx + w] = OCCUPIED


# --- office ----------------------------------------------------------------------------------


def rooms_map(
    rng: np.random.Generator,
    size_m: tuple[float, float] = (20.0, 20.0),
    resolution: float = 0.1,
    n_rooms: IntRange = (4, 8),
    corridor_width_m: FloatRange = (1.2, 2.0),
    door_width_m: float = 1.0,
    wall_thickness_m: float = 0.2,
    min_room_m: float = 2.5,
    max_room_m: float = 8.0,
    furniture_prob: float = 0.6,
) -> OccupancyGrid:
    """An office: corridors, rectangular rooms with doorways, furniture in some rooms.

    Layout (all positions random): a horizontal corridor across the whole map splits it into
    a lower and an upper wing; each wing may get a vertical corridor joining the main one
    (probability 0.6 each, at independent positions), which splits the wing into blocks. Each
    block is cut by walls into rooms of random widths that all face the main corridor and have
    a doorway onto it; a deep room may be split again into a front and a back room joined by
    a door. With probability ``furniture_prob`` a room gets 1-3 blocks of furniture kept
    ``0.6 m`` from walls and from each other. Irregular room sizes, door positions and
    furniture make the map asymmetric, so a lidar can localize globally in it.

    Args:
        rng: the only source of randomness.
        size_m: ``(width, height)`` (m).
        resolution: cell side (m).
        n_rooms: number of rooms facing the corridor (before front/back splits), fixed or an
            inclusive range; raised so that every block has a room and no room is wider than
            ``max_room_m``, and capped by what fits.
        corridor_width_m: corridor width (m), fixed or a range (drawn per corridor).
        door_width_m: doorway width (m).
        wall_thickness_m: wall thickness (m), also of the border.
        min_room_m: smallest room side (m).
        max_room_m: widest room (m) along the corridor, when the block allows it.
        furniture_prob: probability that a room is furnished, in [0, 1].

    Free space is connected. Raises ValueError when ``size_m`` cannot hold the layout.
    """
    res = _check_resolution(resolution, "rooms_map")
    if not 0.0 <= float(furniture_prob) <= 1.0:
        raise ValueError(f"rooms_map: furniture_prob must be in [0, 1], got {furniture_prob}")
    nx = _cells(size_m[0], res, "rooms_map: size_m[0]")
    ny = _cells(size_m[1], res, "rooms_map: size_m[1]")
    t = _cells(wall_thickness_m, res, "rooms_map: wall_thickness_m")
    door = _cells(door_width_m, res, "rooms_map: door_width_m")
    min_room = _cells(min_room_m, res, "rooms_map: min_room_m")
    min_room = max(min_room, door + 2)  # a doorway needs a wall segment on each side
    max_room = _cells(max_room_m, res, "rooms_map: max_room_m")
    if max_room < min_room:
        raise ValueError(
            f"rooms_map: max_room_m ({max_room_m}) must be >= min_room_m ({min_room_m}) and "
            f"leave room for a door of {door_width_m} m"
        )
    corridor = _cells(_draw_float(rng, corridor_width_m, "corridor_width_m"), res,
                      "rooms_map: corridor_width_m")
    wanted_rooms = _draw_int(rng, n_rooms, "rooms_map: n_rooms")
    if ny < 2 * min_room + corridor + 4 * t or nx < min_room + 2 * t:
        raise ValueError(
            f"rooms_map: size_m {size_m} is too small for rooms of {min_room_m} m on both "
            f"sides of a {corridor * res:.2f} m corridor"
        )
    values = _walled(ny, nx, t)

    # main corridor rows [hy, hy + corridor), with a wing of depth >= min_room on each side
    lo = t + min_room + t
    hi = ny - t - min_room - t - corridor
    hy = int(rng.integers(lo, hi + 1))
    values[hy - t : hy, t : nx - t] = OCCUPIED  # corridor's lower wall
    values[hy + corridor : hy + corridor + t, t : nx - t] = OCCUPIED  # its upper wall
    wings = [  # (row range of the wing's free space, row range of the wall facing the corridor)
        ((t, hy - t), (hy - t, hy)),
        ((hy + corridor + t, ny - t), (hy + corridor, hy + corridor + t)),
    ]

    # blocks: (x0, x1, y0, y1, corridor-wall rows); a wing is split by an optional corridor
    blocks: list[tuple[int, int, int, int, tuple[int, int]]] = []
    for (y0, y1), wall_rows in wings:
        spans = [(t, nx - t)]
        v_width = _cells(_draw_float(rng, corridor_width_m, "corridor_width_m"), res,
                         "rooms_map: corridor_width_m")
        v_lo, v_hi = t + min_room + t, nx - t - min_room - t - v_width
        if rng.random() < 0.6 and v_hi >= v_lo:
            vx = int(rng.integers(v_lo, v_hi + 1))
            values[y0:y1, vx - t : vx] = OCCUPIED
            values[y0:y1, vx + v_width : vx + v_width + t] = OCCUPIED
            values[y0:y1, vx : vx + v_width] = FREE
            values[wall_rows[0] : wall_rows[1], vx : vx + v_width] = FREE  # join the corridor
            spans = [(t, vx - t), (vx + v_width + t, nx - t)]
        blocks.extend((x0, x1, y0, y1, wall_rows) for x0, x1 in spans)

    # rooms per block: enough that none is wider than max_room, then more in proportion to
    # the block widths until there are n_rooms
    widths = np.array([b[1] - b[0] for b in blocks])
    capacity = np.maximum((widths + t) // (min_room + t), 1)
    counts = np.minimum(-(-(widths + t) // (max_room + t)), capacity)
    for _ in range(max(0, wanted_rooms - int(counts.sum()))):
        room_left = counts < capacity
        if not room_left.any():
            break
        weights = np.where(room_left, widths / counts, 0.0)
        counts[rng.choice(len(blocks), p=weights / weights.sum())] += 1

    clearance = _cells(0.6, res, "furniture clearance")
    furniture = (max(1, round(0.4 / res)), max(1, round(1.2 / res)))
    for (x0, x1, y0, y1, wall_rows), count in zip(blocks, counts, strict=True):
        # widths between walls; max_room gives way where min_room leaves no other choice
        span = (x1 - x0) - (count - 1) * t
        room_widths = _split(rng, span, int(count), min_room, max(max_room, -(-span // count)))
        x = x0
        for k, width in enumerate(room_widths):
            rx0, rx1 = x, x + width
            if k < count - 1:
                values[y0:y1, rx1 : rx1 + t] = OCCUPIED  # wall to the next room
            x = rx1 + t
            # doorway onto the main corridor, away from the room's corners
            dx = int(rng.integers(rx0 + 1, rx1 - door))
            values[wall_rows[0] : wall_rows[1], dx : dx + door] = FREE
            rooms = [(rx0, y0, rx1, y1)]
            depth = y1 - y0
            if depth >= 2 * min_room + t and rng.random() < 0.5:
                # front room (on the corridor side) and back room, joined by a door
                split_lo, split_hi = y0 + min_room, y1 - min_room - t
                sy = int(rng.integers(split_lo, split_hi + 1))
                values[sy : sy + t, rx0:rx1] = OCCUPIED
                inner = int(rng.integers(rx0 + 1, rx1 - door))
                values[sy : sy + t, inner : inner + door] = FREE
                rooms = [(rx0, y0, rx1, sy), (rx0, sy + t, rx1, y1)]
            for room in rooms:
                if rng.random() < furniture_prob:
                    n_blocks = int(rng.integers(1, 4))
                    _furnish(rng, values, room, n_blocks, furniture, clearance)
    return OccupancyGrid(values, res)


# --- symmetric arenas ------------------------------------------------------------------------


def symmetric_arena(
    rng: np.random.Generator,
    kind: str = "rooms",
    size_m: tuple[float, float] = (20.0, 10.0),
    resolution: float = 0.1,
    n_copies: IntRange = (2, 3),
    corridor_width_m: FloatRange = (1.5, 2.5),
    door_width_m: float = 1.0,
    wall_thickness_m: float = 0.2,
    furniture_prob: float = 0.7,
    n_pillars: tuple[IntRange, IntRange] = ((2, 5), (1, 3)),
    pillar_size_m: FloatRange = (0.3, 0.8),
    min_gap_m: float = 1.0,
    marker_m: float = 0.0,
) -> OccupancyGrid:
    """An arena of identical copies, so that several poses see exactly the same thing.

    ``kind="rooms"``: a corridor across the middle with a row of ``n_copies`` identical rooms
    (same size, same doorway onto the corridor, same furniture) below it, and the same row
    rotated by 180 degrees above it. The map equals itself rotated by 180 degrees (``values ==
    np.rot90(values, 2)``), and all ``2 n_copies`` rooms look the same from inside. The width
    is rounded down to a whole number of rooms (at most ``n_copies - 1`` cells narrower).

    ``kind="pillars"``: a rectangular arena with a regular ``nx_p x ny_p`` lattice of identical
    pillars (like the TurtleBot3 world), symmetric under 180-degree rotation and under both
    reflections, cell for cell. With an odd number of pillars along an axis the middle pillar
    must sit exactly in the middle, so a pillar's side may be one cell longer along that axis
    (pillars stay identical to each other). Pillar counts are capped so that gaps between
    pillars, and between pillars and walls, are at least ``min_gap_m``.

    Args:
        rng: the only source of randomness (dimensions, counts, door and furniture positions).
        kind: ``"rooms"`` or ``"pillars"``.
        size_m: ``(width, height)`` (m).
        resolution: cell side (m).
        n_copies: rooms per row ("rooms"), fixed or an inclusive range.
        corridor_width_m: width of the middle corridor ("rooms"), fixed or a range.
        door_width_m: doorway width ("rooms").
        wall_thickness_m: wall thickness, also of the border.
        furniture_prob: probability that the (shared) room layout is furnished ("rooms").
        n_pillars: pillars along x and along y ("pillars"), each fixed or an inclusive range.
        pillar_size_m: pillar side ("pillars"), fixed or a range.
        min_gap_m: smallest free gap around a pillar ("pillars").
        marker_m: side of a square block against the middle of the corridor's left end wall
            ("rooms"; 0: none). It breaks the 180-degree symmetry, and only there: the rooms
            stay identical, so a robot in a room cannot tell where it is until it looks down
            the corridor. The classic set-up of active localization, where where to look
            decides what the robot learns.
    """
    res = _check_resolution(resolution, "symmetric_arena")
    nx = _cells(size_m[0], res, "symmetric_arena: size_m[0]")
    ny = _cells(size_m[1], res, "symmetric_arena: size_m[1]")
    t = _cells(wall_thickness_m, res, "symmetric_arena: wall_thickness_m")
    if kind == "rooms":
        values = _symmetric_rooms(
            rng, nx, ny, t, res, n_copies, corridor_width_m, door_width_m, furniture_prob
        )
        if marker_m > 0.0:
            _mark_corridor_end(values, t, _cells(marker_m, res, "symmetric_arena: marker_m"))
    elif kind == "pillars":
        values = _pillar_arena(rng, nx, ny, t, res, n_pillars, pillar_size_m, min_gap_m)
    else:
        raise ValueError(f"symmetric_arena: kind must be 'rooms' or 'pillars', got {kind!r}")
    return OccupancyGrid(values, res)


def _symmetric_rooms(
    rng: np.random.Generator,
    nx: int,
    ny: int,
    t: int,
    res: float,
    n_copies: IntRange,
    corridor_width_m: FloatRange,
    door_width_m: float,
    furniture_prob: float,
) -> NDArray[np.int8]:
    if not 0.0 <= float(furniture_prob) <= 1.0:
        raise ValueError(
            f"symmetric_arena: furniture_prob must be in [0, 1], got {furniture_prob}"
        )
    copies = _draw_int(rng, n_copies, "symmetric_arena: n_copies")
    door = _cells(door_width_m, res, "symmetric_arena: door_width_m")
    corridor = _cells(_draw_float(rng, corridor_width_m, "corridor_width_m"), res,
                      "symmetric_arena: corridor_width_m")
    room_w = (nx - (copies + 1) * t) // copies
    half = (ny - corridor) // 2  # rows of the lower row of rooms, walls included
    room_d = half - 2 * t
    if room_w < door + 2 or room_d < door + 2:
        raise ValueError(
            f"symmetric_arena: {copies} rooms and a {corridor * res:.2f} m corridor do not fit "
            f"in {nx * res:.2f} x {ny * res:.2f} m"
        )
    nx = copies * room_w + (copies + 1) * t  # exact tiling: no leftover column breaks symmetry

    # one room tile, walls included on its left and below / above: (half, room_w + t)
    tile = np.full((half, room_w + t), OCCUPIED, dtype=np.int8)
    tile[t : t + room_d, t:] = FREE
    dx = int(rng.integers(t + 1, t + room_w - door))
    tile[t + room_d :, dx : dx + door] = FREE  # doorway through the wall onto the corridor
    if rng.random() < furniture_prob:
        clearance = _cells(0.6, res, "furniture clearance")
        size = (max(1, round(0.4 / res)), max(1, round(1.2 / res)))
        _furnish(rng, tile, (t, t, t + room_w, t + room_d), int(rng.integers(1, 4)), size,
                 clearance)

    values = np.full((ny, nx), FREE, dtype=np.int8)
    lower = np.full((half, nx), OCCUPIED, dtype=np.int8)
    for k in range(copies):
        lower[:, k * (room_w + t) : (k + 1) * (room_w + t)] = tile
    values[:half] = lower
    values[ny - half :] = np.rot90(lower, 2)
    # the corridor's end walls (and the middle row when ny - corridor is odd): symmetric too
    values[:, :t] = OCCUPIED
    values[:, nx - t :] = OCCUPIED
    return values


def _mark_corridor_end(values: NDArray[np.int8], t: int, side: int) -> None:
    """A ``side`` x ``side`` block against the middle of the left end wall (in place)."""
    column = values[:, t] == FREE
    middle = values.shape[0] // 2  # the map's middle row lies in the corridor
    low = high = middle
    while low > 0 and column[low - 1]:
        low -= 1
    while high < column.size - 1 and column[high + 1]:
        high += 1
    if high - low + 1 < side + 2:
        raise ValueError("symmetric_arena: marker_m does not fit in the corridor")
    start = (low + high + 1 - side) // 2
    values[start : start + side, t : t + side] = OCCUPIED


def _pillar_axis(
    rng: np.random.Generator, n: int, t: int, count_spec: IntRange, side: int, gap: int,
    name: str,
) -> tuple[list[int], int]:
    """Low edges (cells) of the pillars along one axis of ``n`` cells with a ``t``-cell wall
    at each end, and the pillar side used along this axis. The layout is a palindrome (a
    pillar at ``e`` has its twin at ``n - side - e``), with equal gaps of >= ``gap - 1``
    cells between pillars and walls (rounding to cells may take one cell off a gap)."""
    interior = n - 2 * t
    # side + 1: the parity fix below may lengthen the pillar by one cell
    fits = (interior - gap) // (side + 1 + gap)  # one gap per pillar, plus one more
    if fits < 1:
        raise ValueError(
            f"symmetric_arena: no pillar fits along {name} with {gap - 1}-cell gaps"
        )
    if isinstance(count_spec, tuple):
        lo, hi = (int(v) for v in count_spec)
        if not 1 <= lo <= hi:
            raise ValueError(
                f"symmetric_arena: n_pillars range must be 1 <= lo <= hi, got {count_spec}"
            )
        count = int(rng.integers(min(lo, fits), min(hi, fits) + 1))
    else:
        count = int(count_spec)
        if not 1 <= count <= fits:
            raise ValueError(
                f"symmetric_arena: {count} pillars along {name} do not fit (at most {fits})"
            )
    if count % 2 == 1 and (n - side) % 2 == 1:
        side += 1  # the middle pillar must be centred exactly
    spacing = (interior - count * side) / (count + 1)  # the equal free gap
    edges = [round(t + spacing * (k + 1) + side * k) for k in range(count // 2)]
    mirrored = [n - side - e for e in reversed(edges)]
    middle = [(n - side) // 2] if count % 2 == 1 else []
    return edges + middle + mirrored, side


def _pillar_arena(
    rng: np.random.Generator,
    nx: int,
    ny: int,
    t: int,
    res: float,
    n_pillars: tuple[IntRange, IntRange],
    pillar_size_m: FloatRange,
    min_gap_m: float,
) -> NDArray[np.int8]:
    side = _cells(_draw_float(rng, pillar_size_m, "pillar_size_m"), res,
                  "symmetric_arena: pillar_size_m")
    gap = _cells(min_gap_m, res, "symmetric_arena: min_gap_m")
    # rounding the evenly spaced pillars to cells may shorten a gap by one: ask for one more
    xs, side_x = _pillar_axis(rng, nx, t, n_pillars[0], side, gap + 1, "x")
    ys, side_y = _pillar_axis(rng, ny, t, n_pillars[1], side, gap + 1, "y")
    values = _walled(ny, nx, t)
    for x0 in xs:
        for y0 in ys:
            values[y0 : y0 + side_y, x0 : x0 + side_x] = OCCUPIED
    return values


# --- maze ------------------------------------------------------------------------------------


def maze_map(
    rng: np.random.Generator,
    n_cells: IntRange = (7, 7),
    cell_size_m: float = 1.0,
    resolution: float = 0.1,
    wall_thickness_m: float = 0.1,
    size_m: tuple[float, float] | None = None,
) -> OccupancyGrid:
    """A perfect maze (recursive backtracker): exactly one path between any two maze cells.

    Maze cell ``(i, j)`` (column i from the left, row j from the bottom) spans grid columns
    ``[i p, (i + 1) p + w)`` with pitch ``p = cell_size_m`` and wall ``w = wall_thickness_m``
    (in cells), walls included: the map is ``n_cells[0] p + w`` by ``n_cells[1] p + w`` cells
    and the passages are ``p - w`` cells wide.

    Args:
        rng: the only source of randomness (start cell and the order of the walk).
        n_cells: maze cells ``(nx, ny)``, or one int for a square maze.
        cell_size_m: pitch of the maze lattice (m), walls included.
        resolution: cell side (m).
        wall_thickness_m: wall thickness (m); at least one grid cell.
        size_m: ``(width, height)`` (m) the maze must fit in, as the other generators take
            it; given, it replaces ``n_cells`` by as many maze cells as fit along each axis.
    """
    res = _check_resolution(resolution, "maze_map")
    pitch = _cells(cell_size_m, res, "maze_map: cell_size_m", minimum=2)
    w = _cells(wall_thickness_m, res, "maze_map: wall_thickness_m")
    if size_m is not None:
        fits = [(_cells(side, res, f"maze_map: size_m[{axis}]") - w) // pitch
                for axis, side in enumerate(size_m)]
        if min(fits) < 1:
            raise ValueError(f"maze_map: size_m {size_m} cannot hold one maze cell of "
                             f"{cell_size_m} m")
        n_cells = (int(fits[0]), int(fits[1]))
    if isinstance(n_cells, tuple):
        mx, my = (int(v) for v in n_cells)
    else:
        mx = my = int(n_cells)
    if mx < 1 or my < 1:
        raise ValueError(f"maze_map: n_cells must be >= 1 along both axes, got {n_cells}")
    if w >= pitch:
        raise ValueError(
            f"maze_map: wall_thickness_m ({wall_thickness_m}) leaves no passage in cells of "
            f"{cell_size_m} m"
        )
    east, north = _backtracker(rng, mx, my)

    values = np.full((my * pitch + w, mx * pitch + w), OCCUPIED, dtype=np.int8)
    for i in range(mx):
        for j in range(my):
            x0, y0 = i * pitch + w, j * pitch + w  # free interior of the maze cell
            values[y0 : y0 + pitch - w, x0 : x0 + pitch - w] = FREE
            if east[i, j]:
                values[y0 : y0 + pitch - w, x0 + pitch - w : x0 + pitch] = FREE
            if north[i, j]:
                values[y0 + pitch - w : y0 + pitch, x0 : x0 + pitch - w] = FREE
    return OccupancyGrid(values, res)


def _backtracker(
    rng: np.random.Generator, mx: int, my: int
) -> tuple[NDArray[np.bool_], NDArray[np.bool_]]:
    """Open passages of a perfect maze: ``east[i, j]`` joins ``(i, j)``-``(i + 1, j)``,
    ``north[i, j]`` joins ``(i, j)``-``(i, j + 1)``; both ``(mx, my)``."""
    east = np.zeros((mx, my), dtype=bool)
    north = np.zeros((mx, my), dtype=bool)
    visited = np.zeros((mx, my), dtype=bool)
    # drawn up front: the start, then one uniform per forward step (mx my - 1 of them)
    start_u = rng.random(2)
    uniforms = rng.random(mx * my)
    start = (min(int(start_u[0] * mx), mx - 1), min(int(start_u[1] * my), my - 1))
    stack = [start]
    visited[start] = True
    step = 0
    while stack:
        i, j = stack[-1]
        options = [
            (a, b)
            for a, b in ((i + 1, j), (i - 1, j), (i, j + 1), (i, j - 1))
            if 0 <= a < mx and 0 <= b < my and not visited[a, b]
        ]
        if not options:
            stack.pop()
            continue
        a, b = options[min(int(uniforms[step] * len(options)), len(options) - 1)]
        step += 1
        if a != i:
            east[min(a, i), j] = True
        else:
            north[i, min(b, j)] = True
        visited[a, b] = True
        stack.append((a, b))
    return east, north


GENERATORS: dict[str, Callable[..., OccupancyGrid]] = {
    "rooms": rooms_map,
    "symmetric_rooms": functools.partial(symmetric_arena, kind="rooms"),
    "marked_rooms": functools.partial(symmetric_arena, kind="rooms", marker_m=0.4),
    "pillars": functools.partial(symmetric_arena, kind="pillars"),
    # 2 m maze cells (1.9 m passages) leave a lidar robot room to turn and to see down them
    "maze": functools.partial(maze_map, cell_size_m=2.0),
}
"""Map generators by name; each is callable as ``fn(rng)`` (and takes its keyword arguments)."""
