"""Where robots may be and go on a map: free cells, free straight legs, a push away from walls.

Robots live in **free** cells only (unknown and occupied cells are off limits), inside the
area ``[0, side]^2``. The helpers here are what mobility models need to respect a map:

- :func:`sample_free`: positions uniform over the free part of the area (optionally keeping a
  clearance from anything not free); placement and waypoints draw from it.
- :func:`legs_free`: whether straight legs stay in free cells all along (exact grid
  traversal, vectorised over legs, :mod:`netsim.world.los`).
- :func:`free_fraction`: how far along a leg a robot can go before it would enter a cell that
  is not free (random direction: travel until the wall).
- :func:`draw_destinations`: random waypoint on a map. A destination is drawn uniformly over
  the free space and kept only when the straight leg to it is free; otherwise another is
  drawn. So a robot's next waypoint is uniform over the free space *visible* from where it
  stands. Effect on the stationary distribution: the chain of waypoints is no longer the
  open-space one (no closed form): robots cross between rooms only along straight lines
  through doorways, so a room with a small door is entered and left rarely, and time spent in
  large rooms and long corridors, visible from many places, grows. Robots never cut through
  walls, and legs stay straight, so link events along them stay exact. (A path planner
  would keep the destination law uniform at the price of polylines; not done here.)
- :func:`free_region`: the *free region* of some points, the cells of the area a robot can
  reach from them through free cells (4-connected: two free cells that touch at a corner
  only do not join), the space a team that starts there can use; :func:`region_polygon`
  the same cells as one polygon, for areas covered within it.
- :func:`obstacle_field` and :func:`wall_forces`: a repulsion from walls for virtual-force
  coverage, ``gain * (margin - d)`` away from the nearest cell that is not free, within
  ``margin`` of it (``d`` from the grid's distance transform).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import NamedTuple

import numpy as np

from netsim.area import Bounds, as_bounds
from netsim.compiled import load
from netsim.errors import ConfigError
from netsim.geometry import cell_centres_m, distances_m, in_motion, inside_margin_m
from netsim.world.los import VERTEX_TOLERANCE_CELLS, first_blocked, line_of_sight
from netsim.world.maps import MAP_KEY, OccupancyMap, grid_coords


def clearance_field_m(m: OccupancyMap) -> np.ndarray:
    """Distance (m) from each cell's centre to the nearest centre of a cell that is not free
    (0 on such cells; infinite when every cell is free)."""
    from scipy.ndimage import distance_transform_edt

    if m.free.all():
        return np.full(m.shape, np.inf)
    return distance_transform_edt(m.free) * m.resolution_m


def _eligible_cells(m: OccupancyMap, area: float | Bounds, clearance_m: float):
    """Cells a robot may be drawn in, and the rectangle each shares with the area (computed
    once per map, area and clearance: waypoints draw from it at every leg)."""
    cache = m.__dict__.setdefault("_eligible", {})
    b = as_bounds(area)
    key = (b, float(clearance_m))
    if key not in cache:
        cache[key] = _eligible_cells_now(m, b, clearance_m)
    return cache[key]


def _eligible_cells_now(m: OccupancyMap, b: Bounds, clearance_m: float):
    ok = m.free.copy()
    if clearance_m > 0:
        # Any point of the cell is then at least clearance_m from any point of a cell that is
        # not free (each point lies within res / sqrt(2) of its cell's centre).
        ok &= clearance_field_m(m) - math.sqrt(2.0) * m.resolution_m >= clearance_m
    return free_cells(m, ok, b)


def free_cells(m: OccupancyMap, cells: np.ndarray, b: Bounds) -> FreeCells:
    """The rectangles the map's cells ``cells`` (a mask ``(H, W)``) share with ``b``, those of
    positive size, and their cumulative area: what :func:`draw_free` draws from."""
    j, i = np.nonzero(cells)
    r = m.resolution_m
    x0 = np.maximum(m.origin_m[0] + i * r, b.x_min)
    x1 = np.minimum(m.origin_m[0] + (i + 1) * r, b.x_max)
    y0 = np.maximum(m.origin_m[1] + j * r, b.y_min)
    y1 = np.minimum(m.origin_m[1] + (j + 1) * r, b.y_max)
    keep = (x1 > x0) & (y1 > y0)
    x0, x1, y0, y1 = x0[keep], x1[keep], y0[keep], y1[keep]
    return FreeCells(np.cumsum((x1 - x0) * (y1 - y0)), x0, x1, y0, y1)


def draw_free(m: OccupancyMap, cells: FreeCells, rng: np.random.Generator, n: int) -> np.ndarray:
    """``n`` points uniform over ``cells``: a cell by area, a point in it, its centre where
    rounding left the cell (the kernel :func:`netsim.world._kernels.free_points`). No cells
    is a ``ValueError``: there is nowhere to draw from."""
    if len(cells.cdf) == 0:
        raise ValueError("no free cell to draw a point in")
    draw_cell = rng.random(n)
    draw_uv = rng.random((n, 2))
    pos = np.empty((n, 2))
    load("netsim.world._kernels", None, values=n).free_points(cells, _grid(m), draw_cell, draw_uv, pos)
    return pos


class FreeCells(NamedTuple):
    """The cells a robot may be drawn in, as the draw kernels read them: the cumulative
    area, then each cell's rectangle within the area (metres)."""

    cdf: np.ndarray
    x0: np.ndarray
    x1: np.ndarray
    y0: np.ndarray
    y1: np.ndarray


class DrawGrid(NamedTuple):
    """The map as the draw kernels read it: its free and its not-free cells row-major, its
    size in cells, origin and cell size (metres)."""

    free_flat: np.ndarray
    not_free_flat: np.ndarray
    h: int
    w: int
    origin_x: float
    origin_y: float
    resolution_m: float


def _where(area: float | Bounds) -> str:
    b = as_bounds(area)
    return f"[0, {b.width:g}]^2" if b.is_square_at_origin else str(b.as_list())


def sample_free(
    m: OccupancyMap, rng: np.random.Generator, n: int, area: float | Bounds, clearance_m: float = 0.0
) -> np.ndarray:
    """``n`` positions uniform over the free part of the area (``Bounds``, or the side of
    the square ``[0, side]^2``; with ``clearance_m`` from anything not free, conservatively
    to within 1.4 cells), shape ``(n, 2)``."""
    cells = _eligible_cells(m, area, clearance_m)
    if len(cells.cdf) == 0:
        extra = f" with a clearance of {clearance_m:g} m" if clearance_m > 0 else ""
        raise ConfigError(MAP_KEY, m.source or "<map>", f"has no free cell in the area {_where(area)}{extra}")
    return draw_free(m, cells, rng, n)


def _grid(m: OccupancyMap) -> DrawGrid:
    """The map as the draw kernels read it."""
    h, w = m.shape
    ox, oy = float(m.origin_m[0]), float(m.origin_m[1])
    return DrawGrid(m.free.ravel(), m.not_free.ravel(), int(h), int(w), ox, oy, float(m.resolution_m))


def _cells_in_area(m: OccupancyMap, area: float | Bounds) -> np.ndarray:
    """Free cells that share a part of positive size with the area, shape ``(H, W)``."""
    b = as_bounds(area)
    h, w = m.shape
    r = m.resolution_m
    x0 = m.origin_m[0] + np.arange(w) * r
    y0 = m.origin_m[1] + np.arange(h) * r
    cols = np.minimum(x0 + r, b.x_max) > np.maximum(x0, b.x_min)
    rows = np.minimum(y0 + r, b.y_max) > np.maximum(y0, b.y_min)
    return m.free & rows[:, None] & cols[None, :]


def free_region(m: OccupancyMap, area: float | Bounds, points_m) -> np.ndarray:
    """The free region of ``points_m`` (module notes): mask ``(H, W)`` of the free cells in
    the area joined through free cells in the area (sharing a side) to the cell of one of the
    points. Points not in a free cell of the area add nothing."""
    from scipy.ndimage import label

    cells = _cells_in_area(m, area)
    labels, _ = label(cells)
    p = np.asarray(points_m, dtype=float).reshape(-1, 2)
    p = p[m.contains(p)]
    i, j = m.cells(p)
    seeds = np.unique(labels[j, i])
    return np.isin(labels, seeds[seeds > 0])


def team_region(m: OccupancyMap, area: float | Bounds, points_m):
    """The free region of a team standing at ``points_m`` as one shapely geometry, or None
    when it has no area: what coverage on a map is judged over (docs/model.md 5.3)."""
    region = region_polygon(m, area, free_region(m, area, points_m))
    return region if region.area > 0 else None


def region_polygon(m: OccupancyMap, area: float | Bounds, region: np.ndarray):
    """The cells of ``region`` (a mask of :func:`free_region`) clipped to the area, as one
    shapely geometry: a rectangle per run of cells in a row, runs equal in consecutive rows
    merged, then their union."""
    import shapely

    h, w = region.shape
    r = m.resolution_m
    ox, oy = m.origin_m
    boxes = []
    open_runs: dict[tuple[int, int], int] = {}  # (first column, end column) -> first row
    padded = np.zeros((h + 1, w + 2), dtype=np.int8)
    padded[:h, 1:-1] = region
    for j in range(h + 1):
        edges = np.flatnonzero(np.diff(padded[j]))
        runs = set(zip(edges[::2].tolist(), edges[1::2].tolist()))
        for run in list(open_runs):
            if run not in runs:
                j0 = open_runs.pop(run)
                boxes.append((ox + run[0] * r, oy + j0 * r, ox + run[1] * r, oy + j * r))
        for run in runs:
            open_runs.setdefault(run, j)
    if not boxes:
        return shapely.Polygon()
    b = as_bounds(area)
    x0, y0, x1, y1 = np.array(boxes).T
    union = shapely.union_all(shapely.box(x0, y0, x1, y1))
    return shapely.intersection(union, shapely.box(b.x_min, b.y_min, b.x_max, b.y_max))


def legs_free(m: OccupancyMap, starts, ends) -> np.ndarray:
    """Whether each straight leg ``starts[k] -> ends[k]`` stays in free cells all along"""
    return line_of_sight(m, starts, ends, blocked=m.not_free)


@dataclass(frozen=True)
class Walls:
    """A map's walls as the robot state's motion check asks about them
    (:meth:`netsim.state.RobotState.check_motion`)."""

    map: OccupancyMap

    def legs_free(self, starts, ends) -> np.ndarray:
        return legs_free(self.map, starts, ends)

    def first_blocked(self, starts, ends) -> np.ndarray:
        """The fraction of each leg at which it first enters a cell that is not free."""
        return first_blocked(self.map, starts, ends, blocked=self.map.not_free)

    def is_free(self, points_m) -> np.ndarray:
        return self.map.is_free(points_m)


def short_of_walls(m: OccupancyMap, starts_m: np.ndarray, velocity_mps: np.ndarray, period_s: float) -> np.ndarray:
    """Each robot's velocity scaled so that its step of ``period_s`` from ``starts_m`` ends
    just short of the first cell that is not free (:func:`free_fraction`), in place; rows
    of zero velocity are not traced. What a robot can carry out on a map: the control loop
    makes every step so, and the plans plan with it."""
    moving = np.flatnonzero(in_motion(velocity_mps))
    if len(moving):
        here = starts_m[moving]
        velocity_mps[moving] *= free_fraction(m, here, here + velocity_mps[moving] * period_s)[:, None]
    return velocity_mps


def free_fraction(m: OccupancyMap, starts, ends, margin_m: float = 1e-6) -> np.ndarray:
    """Fraction ``f`` in ``[0, 1]`` of each leg that a robot can travel in free cells: 1 when
    the whole leg is free, else it stops ``margin_m`` short of the first cell that is not free
    (and the leg ``start -> start + f (end - start)`` is free)."""
    s = np.asarray(starts, dtype=float).reshape(-1, 2)
    e = np.asarray(ends, dtype=float).reshape(-1, 2)
    t = first_blocked(m, s, e, blocked=m.not_free)
    length = distances_m(s, e)
    f = np.where(np.isinf(t), 1.0, np.maximum(t - margin_m / np.maximum(length, 1e-300), 0.0))
    for _ in range(60):
        stop = s + f[:, None] * (e - s)
        bad = (f > 0) & ~legs_free(m, s, stop)
        if not bad.any():
            return f
        f[bad] = np.maximum(f[bad] - 4.0 * margin_m / np.maximum(length[bad], 1e-300), 0.0)
        margin_m *= 4.0
    return np.where(legs_free(m, s, s + f[:, None] * (e - s)), f, 0.0)


# Draws a robot in the largest round of :func:`draw_destinations`.
BATCH_MOST = 1 << 16


def draw_destinations(
    m: OccupancyMap,
    rng: np.random.Generator,
    here_m,
    area: float | Bounds,
    batch: int = 64,
    max_rounds: int = 100,
    max_tries: int = 10_000_000,
) -> np.ndarray:
    """A random waypoint for each robot at ``here_m``: uniform over the free space, redrawn
    until the straight leg to it is free (see the module notes). Shape ``(k, 2)``.

    ``max_rounds`` rounds of ``batch`` draws a robot, then rounds twice as large each time,
    up to ``max_tries`` draws a robot: a robot in a pocket or behind a bend sees a small
    part of the free space, but never none (its own cell), so the draws go on rather than
    give up on it."""
    here = np.asarray(here_m, dtype=float).reshape(-1, 2)
    k = len(here)
    out = np.empty((k, 2))
    todo = np.arange(k)
    kernel = load("netsim.world._kernels", None, values=k).free_destinations
    tries = rounds = 0
    while len(todo) and tries < max_tries:
        if rounds >= max_rounds:
            batch = min(2 * batch, BATCH_MOST)
        got = _round(kernel, m, rng, here[todo], area, batch, out, todo)
        todo = todo[~got]
        tries += batch
        rounds += 1
    if len(todo) == 0:
        return out
    x, y = here[todo[0]]
    raise ConfigError(
        MAP_KEY,
        m.source or "<map>",
        f"a robot at ({x:g}, {y:g}) found no destination it can reach in a straight line in {tries:,} tries:"
        " it sees almost none of the free space",
    )


def _round(kernel, m: OccupancyMap, rng, here, area: float | Bounds, batch: int, out, todo) -> np.ndarray:
    """One round of :func:`draw_destinations`: the same draws from ``rng`` as
    :func:`sample_free` makes, the same points and legs, the first free leg kept."""
    cells = _eligible_cells(m, area, 0.0)
    if len(cells.cdf) == 0:
        raise ConfigError(MAP_KEY, m.source or "<map>", f"has no free cell in the area {_where(area)}")
    n = len(here) * batch
    draw_cell = rng.random(n)
    draw_uv = rng.random((n, 2))
    picked = np.empty((len(here), 2))
    got = np.empty(len(here), dtype=bool)
    kernel(cells, _grid(m), (draw_cell, draw_uv), here, batch, VERTEX_TOLERANCE_CELLS, (picked, got))
    out[todo[got]] = picked[got]
    return got


@dataclass(frozen=True)
class ObstacleField:
    """Distance (m) from each cell to the nearest cell that is not free, and the unit vector
    pointing away from it (zero where the distance is flat or infinite)."""

    distance_m: np.ndarray  # (H, W)
    away: np.ndarray  # (H, W, 2)


def obstacle_field(m: OccupancyMap) -> ObstacleField:
    d = clearance_field_m(m)
    finite = np.where(np.isfinite(d), d, 0.0)
    gy, gx = np.gradient(finite, m.resolution_m)
    norm = np.hypot(gx, gy)
    with np.errstate(invalid="ignore", divide="ignore"):
        away = np.where(norm[..., None] > 0, np.stack([gx, gy], axis=-1) / norm[..., None], 0.0)
    return ObstacleField(d, away)


def nearest_free_cells(free, origin_m, cell_m: float, points_m, radius_cells: int) -> tuple[np.ndarray, np.ndarray]:
    """For each point, the free cell of the grid ``free`` (``(h, w)``, cells ``cell_m``
    wide, corner at ``origin_m``) within ``radius_cells`` of the point's own cell whose
    centre is nearest the point (the first found, rows then columns from the lowest, on a
    tie); ``(-1, -1)`` when none is. A free point's own cell can count as blocked: on a
    coarser grid, a cell that holds a wall's edge; on any grid, a point on a wall's lower or
    left face, which the floor puts in the wall's cell. The own cell is the floor on the
    unbounded grid, not the map's cell of a point (which puts every point beyond the far
    edges in the last cell): a point off the grid stays off it, so that the radius bounds
    how far the cell found is, on every side alike."""
    p = np.asarray(points_m, float).reshape(-1, 2)
    h, w = free.shape
    u, v = grid_coords(p, origin_m, cell_m)
    x, y = np.floor(u).astype(np.int64), np.floor(v).astype(np.int64)
    out_x, out_y = np.full(len(p), -1), np.full(len(p), -1)
    best = np.full(len(p), np.inf)
    r = radius_cells
    steps = np.arange(-r, r + 1)
    # Every column and row searched, their centres found once rather than at each offset.
    centres_x = cell_centres_m(origin_m[0], cell_m, x[:, None] + steps)
    centres_y = cell_centres_m(origin_m[1], cell_m, y[:, None] + steps)
    for dy in range(-r, r + 1):
        for dx in range(-r, r + 1):
            cx, cy = x + dx, y + dy
            inside = (cx >= 0) & (cy >= 0) & (cx < w) & (cy < h)
            ok = inside.copy()
            ok[inside] = free[cy[inside], cx[inside]]
            d = distances_m(np.column_stack([centres_x[:, dx + r], centres_y[:, dy + r]]), p)
            better = ok & (d < best)
            best[better] = d[better]
            out_x[better], out_y[better] = cx[better], cy[better]
    return out_x, out_y


def wall_forces(m: OccupancyMap, field: ObstacleField, positions_m, margin_m: float, gain: float) -> np.ndarray:
    """Push from walls on robots at ``positions_m``: ``gain * (margin_m - d)`` away from the
    nearest cell that is not free when ``d < margin_m``, as the border force of coverage
    does for the area's edges. Shape ``(k, 2)``.

    A point whose own cell is not free (on a wall's lower or left face) is read from the
    free cell nearest it (:func:`nearest_free_cells`), so it feels the strongest push, not
    none."""
    i, j = m.nearest_cells(positions_m)
    inside = np.flatnonzero(~m.free[j, i])
    if len(inside):
        fi, fj = nearest_free_cells(m.free, m.origin_m, m.resolution_m, np.asarray(positions_m, float)[inside], 1)
        found = fi >= 0
        i[inside[found]], j[inside[found]] = fi[found], fj[found]
    push = gain * inside_margin_m(field.distance_m[j, i], margin_m)
    return push[:, None] * field.away[j, i]
