"""Exactness of the world's geometry against independent oracles: walls swept over a step
against the traversal at many instants of every row, on small random maps and motions
chosen to sit on the grid's degenerate cases; a link's state at a chunk's ends; the map's
closed edges; the traversal stopped at its limit; the free region against a flood fill;
draws with a clearance against the exact distance to every cell that is not free."""

import numpy as np
import pytest

from netsim.compiled import load
from netsim.world.los import VERTEX_TOLERANCE_CELLS, first_blocked, line_of_sight, walls_crossed
from netsim.world.maps import OccupancyMap
from netsim.world.sweep import PairMotion, map_grid, sweep_walls


def _random_map(rng, h=12, w=12, density=0.3):
    blocked = rng.random((h, w)) < density
    return OccupancyMap(blocked, ~blocked, 1.0, (0.0, 0.0))


def _row_mismatches(occupancy, p0, vp, q0, vq, duration, rng, per_row=40, away=1e-7):
    """Instants inside each row (uniform, and near both of its ends) at which the row's
    count differs from the traversal's at that instant."""
    s = sweep_walls(occupancy, p0, vp, q0, vq, duration)
    rows, times = [], []
    for r, (a, b) in enumerate(zip(s.t0_s, s.t1_s, strict=True)):
        span = b - a
        if span <= 2 * away:
            continue
        inner = a + away + (span - 2 * away) * rng.random(per_row)
        edges = np.array([a + away, b - away, a + 1e-4 * span, b - 1e-4 * span])
        t = np.concatenate([inner, edges])
        rows.append(np.full(len(t), r))
        times.append(t)
    row = np.concatenate(rows)
    pair = s.pair[row]
    t = np.concatenate(times)[:, None]
    truth = walls_crossed(occupancy, p0[pair] + vp[pair] * t, q0[pair] + vq[pair] * t)
    return int(np.count_nonzero(truth != s.walls[row])), len(t)


def _axis_sweeps(rng, k, h=12, w=12):
    """Segments lying along a grid axis (both ends at one height, or one column), moved
    across the grid's lines perpendicular to themselves; some a rounding step off the axis."""
    p0 = np.empty((k, 2))
    q0 = np.empty((k, 2))
    v = np.empty((k, 2))
    for n in range(k):
        x0, x1 = np.sort(rng.uniform(0.5, w - 0.5, 2))
        y = rng.uniform(1.0, h - 4.0)
        tilt = (0.0, 1e-9, -1e-9, 1e-7)[n % 4]
        speed = rng.uniform(0.5, 2.0) * rng.choice([-1.0, 1.0])
        if n % 2:
            p0[n], q0[n], v[n] = (x0, y), (x1, y + tilt), (0.0, abs(speed))
        else:
            p0[n], q0[n], v[n] = (y, x0), (y + tilt, x1), (abs(speed), 0.0)
    return p0, v, q0, v.copy(), np.full(k, 1.5)


def _vertex_passes(occupancy, rng, k):
    """Pairs whose segment runs through a mixed grid vertex at a random instant, with ends
    at random distances from it (some at the vertex, some within a cell of it)."""
    b = np.pad(occupancy.occupied, 1, mode="edge").astype(int)
    around = b[:-1, :-1] + b[:-1, 1:] + b[1:, :-1] + b[1:, 1:]
    vy, vx = np.nonzero((around > 0) & (around < 4))
    h, w = occupancy.shape
    inner = (vx >= 3) & (vx <= w - 3) & (vy >= 3) & (vy <= h - 3)
    vx, vy = vx[inner], vy[inner]
    p0, vp, q0, vq = (np.empty((k, 2)) for _ in range(4))
    duration = np.full(k, 1.0)
    for n in range(k):
        m = rng.integers(len(vx))
        corner = np.array([vx[m], vy[m]], float)
        u = rng.normal(size=2)
        u /= np.hypot(*u)
        near = (0.0, 0.3, 0.9, 1.2, rng.uniform(1.5, 2.5))[n % 5]
        pc, qc = corner - u * near, corner + u * rng.uniform(0.5, 2.5)
        vp[n], vq[n] = rng.uniform(-1, 1, (2, 2))
        tc = rng.uniform(0.1, 0.9)
        p0[n], q0[n] = pc - vp[n] * tc, qc - vq[n] * tc
    return p0, vp, q0, vq, duration


@pytest.mark.parametrize("seed", range(4))
def test_sweep_rows_hold_their_count_throughout_on_random_maps(seed):
    """Every row's count is the traversal's at every instant inside the row (the sweep
    misses no change), for random motions, segments along the axes swept across the grid's
    lines, and segments through the vertices where blocked and clear cells meet."""
    rng = np.random.default_rng(seed)
    occupancy = _random_map(rng)
    h, w = occupancy.shape
    k = 40
    generic = (
        rng.uniform(2, w - 2, (k, 2)),
        rng.uniform(-1, 1, (k, 2)),
        rng.uniform(2, h - 2, (k, 2)),
        rng.uniform(-1, 1, (k, 2)),
        np.full(k, 1.5),
    )
    for motion in (generic, _axis_sweeps(rng, k), _vertex_passes(occupancy, rng, k)):
        wrong, seen = _row_mismatches(occupancy, *motion, rng)
        assert seen > 1000
        assert wrong == 0


def _link_chunks(occupancy, p0, vp, q0, vq, duration, radii):
    kernels = load("netsim.world._sweep_kernels", 0)
    motion = PairMotion(*(np.ascontiguousarray(np.asarray(a, float).reshape(-1, 2)) for a in (p0, vp, q0, vq)))
    return kernels.link_chunks(
        map_grid(occupancy), motion, np.asarray(duration, float), VERTEX_TOLERANCE_CELLS, np.asarray(radii, float)
    )


def _open_map():
    free = np.ones((10, 20), dtype=bool)
    return OccupancyMap(~free, free, 1.0, (0.0, 0.0))


def test_a_link_leaving_the_range_at_the_chunks_start_is_down_just_after_it():
    """Up is ``distance <= radius``: a pair exactly at the range and moving apart is down
    just after the start, with no change inside the chunk."""
    first, pair, t, up = _link_chunks(_open_map(), [2.5, 5.5], [0.0, 0.0], [5.5, 5.5], [1.0, 0.0], [4.0], [3.0])
    assert first.tolist() == [False]
    assert len(pair) == 0


def test_a_link_leaving_the_range_at_the_chunks_end_changes_only_inside_it():
    """A pair that comes into range inside the chunk and is back at the range exactly at
    its end: one change, up, inside; the chunk's end is not inside it."""
    first, pair, t, up = _link_chunks(_open_map(), [2.5, 5.5], [0.0, 0.0], [7.5, 5.5], [-1.0, 0.0], [8.0], [3.0])
    assert first.tolist() == [False]
    assert t.tolist() == [2.0]
    assert up.tolist() == [True]


@pytest.mark.parametrize("boundary", [True, False])
def test_a_rows_first_chunk_unlike_the_state_before_changes_at_its_start_on_a_boundary(boundary):
    """Solved in blocks, a row whose first chunk starts in a state other than the one the
    previous block ended in changes at that chunk's start; a stretch's first chunk has no
    state before it."""
    assemble = load("netsim.world._sweep_kernels", 0).assemble
    none_i, none_t, none_b = np.empty(0, np.int64), np.empty(0), np.empty(0, bool)
    chunk, t, up, start, end = assemble(
        np.array([True, True]), none_i, none_t, none_b, np.array([5.0, 7.0]), np.array([2]), np.array([False]), boundary
    )
    assert chunk.tolist() == ([0] if boundary else [])
    assert t.tolist() == ([5.0] if boundary else [])
    assert up.tolist() == ([True] if boundary else [])
    assert start.tolist() == [True] and end.tolist() == [True]


def test_points_on_the_maps_closed_edges_are_on_it_and_in_its_edge_cells():
    """The map is its closed extent: a point on any edge or corner is on it, in the cell at
    that edge (the far edges in the last cells); a hair outside is off it."""
    free = np.ones((3, 4), dtype=bool)
    free[2, 3] = False
    m = OccupancyMap(~free, free, 0.5, (-1.0, 2.0))
    x0, x1, y0, y1 = -1.0, 1.0, 2.0, 3.5
    on = np.array([[x0, y0], [x1, y0], [x0, y1], [x1, y1], [x1, 2.25], [0.0, y1], [x0, 3.0], [0.0, y0]])
    assert m.contains(on).all()
    i, j = m.cells(on)
    assert i.tolist() == [0, 3, 0, 3, 3, 2, 0, 2]
    assert j.tolist() == [0, 0, 2, 2, 0, 2, 2, 0]
    assert m.is_free(on).tolist() == [True, True, True, False, True, True, True, True]
    off = on + np.array([[-1e-9, 0], [1e-9, 0], [0, 1e-9], [1e-9, 0], [1e-9, 0], [0, 1e-9], [-1e-9, 0], [0, -1e-9]])
    assert not m.contains(off).any()
    assert not m.is_free(off).any()


def _flood_region(free, origin, res, bounds, points):
    """Free cells sharing a part of positive size with ``bounds``, reached from the points'
    cells through such cells that share a side: a breadth-first flood."""
    h, w = free.shape
    x_min, y_min, x_max, y_max = bounds

    def usable(i, j):
        x0, y0 = origin[0] + i * res, origin[1] + j * res
        return free[j, i] and min(x0 + res, x_max) > max(x0, x_min) and min(y0 + res, y_max) > max(y0, y_min)

    region = np.zeros_like(free)
    todo = []
    for x, y in points:
        i, j = min(int((x - origin[0]) // res), w - 1), min(int((y - origin[1]) // res), h - 1)
        if 0 <= i < w and 0 <= j < h and usable(i, j) and not region[j, i]:
            region[j, i] = True
            todo.append((i, j))
    while todo:
        i, j = todo.pop()
        for a, b in ((i + 1, j), (i - 1, j), (i, j + 1), (i, j - 1)):
            if 0 <= a < w and 0 <= b < h and not region[b, a] and usable(a, b):
                region[b, a] = True
                todo.append((a, b))
    return region


@pytest.mark.parametrize("seed", range(3))
def test_free_region_and_its_area_equal_a_flood_through_cells_sharing_a_side(seed):
    """The team's free region is the flood from its cells through free cells of the area
    that share a side (cells touching at a corner only do not join), and its polygon's area
    the sum of those cells' parts inside the area."""
    from netsim.area import Bounds
    from netsim.world.free_space import free_region, region_polygon

    rng = np.random.default_rng(seed)
    free = rng.random((14, 17)) < 0.55
    res, origin = 0.5, (-1.0, 0.5)
    m = OccupancyMap(~free, free, res, origin)
    bounds = (-0.3, 1.2, 7.5, 7.3)
    # Points off the map too (left of it, below it): they seed nothing.
    off = np.column_stack([np.full(14, -1.2), 0.75 + 0.5 * np.arange(14)])
    points = np.vstack([rng.uniform((-1.0, 0.5), (7.5, 7.5), (6, 2)), off, [[3.0, 0.2], [3.0, 7.7]]])
    area = Bounds(*bounds)
    want = _flood_region(free, origin, res, bounds, points)
    got = free_region(m, area, points)
    assert np.array_equal(got, want)
    j, i = np.nonzero(want)
    x0, y0 = origin[0] + i * res, origin[1] + j * res
    clipped = (np.minimum(x0 + res, bounds[2]) - np.maximum(x0, bounds[0])) * (
        np.minimum(y0 + res, bounds[3]) - np.maximum(y0, bounds[1])
    )
    assert region_polygon(m, area, got).area == pytest.approx(clipped.sum(), rel=1e-12, abs=1e-12)


def test_a_sweep_over_given_blocked_cells_finds_their_corners():
    """``blocked`` replaces the occupied cells for the sweep's vertices too: a wall of
    unknown cells (not occupied) changes the count at its corner, as an occupied one does."""
    unknown = np.zeros((4, 6), dtype=bool)
    unknown[1:, 3] = True
    m = OccupancyMap(np.zeros_like(unknown), ~unknown, 1.0, (0.0, 0.0))
    s = sweep_walls(m, [[0.5, 0.5]], [[0.0, 1.0]], [[5.5, 0.5]], [[0.0, 0.0]], [2.0], blocked=m.not_free)
    assert s.t1_s.tolist() == [1.0, 2.0]
    assert s.walls.tolist() == [0, 1]
    assert sweep_walls(m, [[0.5, 0.5]], [[0.0, 1.0]], [[5.5, 0.5]], [[0.0, 0.0]], [2.0]).walls.tolist() == [0]


def _limited_traces(limit):
    """The kernel's traces of random segments, walked whole and stopped past ``limit``
    walls: ``(walls, first_t)`` each."""
    from netsim.world import los

    rng = np.random.default_rng(3)
    blocked = rng.random((15, 15)) < 0.3
    p = rng.uniform(0.0, 7.5, (400, 2))
    q = rng.uniform(0.0, 7.5, (400, 2))
    kernel = load("netsim.world._kernels", 0).trace
    traces = []
    for stop in (los.NO_LIMIT, limit):
        out = (np.empty(len(p), np.int64), np.empty(len(p)))
        kernel((blocked.ravel(), 15, 15), (0.0, 0.0, 0.5), (p, q), los.VERTEX_TOLERANCE_CELLS, out, stop, False)
        traces.append(out)
    return traces, (blocked, p, q)


@pytest.mark.parametrize("limit", [0, 1, 2])
def test_a_trace_stopped_past_its_limit_counts_limit_plus_one_and_meets_a_blocked_cell(limit):
    """Counting stops once past the limit: counts above it come out as ``limit + 1``, the
    rest exactly, and a segment with walls still reports a point in a blocked cell, no
    earlier than the first."""
    ((full_walls, full_t), (walls, t)), _ = _limited_traces(limit)
    assert np.array_equal(walls, np.minimum(full_walls, limit + 1))
    assert (full_walls > limit + 1).sum() > 20
    assert np.array_equal(np.isinf(t), full_walls == 0)
    assert (t >= full_t).all()


def test_a_trace_asked_for_its_first_blocked_point_finds_it_whatever_the_limit():
    """``los._trace`` with ``first``: the first blocked point is exact whatever ``limit``
    (the kernel walks one axis's grid lines before the other's, so a walk stopped at the
    limit could miss it), and so is the count."""
    from netsim.world import los

    ((full_walls, full_t), (_, stopped_t)), (blocked, p, q) = _limited_traces(0)
    assert not np.array_equal(stopped_t, full_t)  # the case that needs it
    walls, t = los._trace(blocked, 0.5, (0.0, 0.0), p, q, first=True, limit=0)
    assert np.array_equal(t, full_t)
    assert np.array_equal(walls, full_walls)


def test_walls_swept_between_robots_at_rest_on_grid_corners_are_the_walls_between_them():
    """The sweep counts walls as ``walls_crossed`` does between robots, ends within the
    vertex tolerance of a grid line put on it: robots at rest on grid corners given in
    metres (a rounding step off) cross the same walls swept as traced, both ways, and see
    each other exactly when no wall is crossed."""
    rng = np.random.default_rng(11)
    res, origin = 0.1, np.array([-3.0, 2.0])
    blocked = rng.random((12, 12)) < 0.4
    m = OccupancyMap(blocked, ~blocked, res, tuple(origin))
    k = 600
    p = rng.integers(1, 11, (k, 2)) * res + origin
    q = rng.uniform(0.5, 11.5, (k, 2)) * res + origin
    q[::2] = rng.integers(1, 11, (len(q[::2]), 2)) * res + origin
    off = np.array([0.0, 1e-14, -1e-14, 1e-12, -1e-12]) * res
    p = p + rng.choice(off, p.shape)
    q = q + rng.choice(off, q.shape)
    still = np.zeros((k, 2))
    for a, b in ((p, q), (q, p)):
        s = sweep_walls(m, a, still, b, still, np.ones(k))
        assert np.array_equal(s.pair, np.arange(k))
        assert np.array_equal(s.walls, walls_crossed(m, a, b))
        assert np.array_equal(line_of_sight(m, a, b), s.walls == 0)


def test_a_point_drawn_at_a_free_cells_far_edge_stays_in_a_free_cell():
    """A draw of a uniform just below 1 can round onto the far edge of its cell, in the
    wall beyond: the point is then moved into its cell, so every draw is free."""
    from netsim.area import Bounds
    from netsim.world.free_space import _grid, free_cells

    res, origin = 0.05, (0.3, -0.7)
    free = np.zeros((5, 5), dtype=bool)
    free[1:4, 1:4] = True
    m = OccupancyMap(~free, free, res, origin)
    cells = free_cells(m, free, Bounds(origin[0], origin[1], origin[0] + 5 * res, origin[1] + 5 * res))
    n = 90
    below_one = 1.0 - 2.0**-53
    draw_cell = (np.arange(n) + 0.5) / n
    draw_uv = np.full((n, 2), below_one)
    naive = np.column_stack(
        [cells.x0 + below_one * (cells.x1 - cells.x0), cells.y0 + below_one * (cells.y1 - cells.y0)]
    )
    assert not m.is_free(naive).all()
    out = np.empty((n, 2))
    load("netsim.world._kernels", 0).free_points(cells, _grid(m), draw_cell, draw_uv, out)
    assert m.is_free(out).all()


def test_first_blocked_traces_the_ends_as_they_are():
    """Motion is traced without putting ends on grid lines: a robot a hair below a wall's
    lower face stands in the free cell and, moving away, never enters the wall; between
    robots the same hair is the wall's face."""
    wall = np.zeros((4, 3), dtype=bool)
    wall[2, :] = True
    m = OccupancyMap(wall, ~wall, 1.0, (0.0, 0.0))
    p = [[1.5, 2.0 - 1e-11]]
    assert first_blocked(m, p, [[1.5, 0.5]]).tolist() == [np.inf]
    assert first_blocked(m, p, [[1.5, 0.5]], blocked=~m.free).tolist() == [np.inf]
    assert walls_crossed(m, p, [[1.5, 0.5]]).tolist() == [1]


def test_points_drawn_with_a_clearance_keep_it_from_every_cell_not_free():
    """``sample_free`` with a clearance: every point lies at least that far from every point
    of every cell that is not free (the exact distance to each such cell's square)."""
    from netsim.world.free_space import sample_free

    rng = np.random.default_rng(4)
    free = np.ones((24, 24), dtype=bool)
    free[8:11, 5:15] = False
    free[15:, 12] = False
    free[3, 20] = False
    res, clearance = 0.25, 0.8
    m = OccupancyMap(~free, free, res, (0.0, 0.0))
    points = sample_free(m, rng, 3000, 6.0, clearance_m=clearance)
    j, i = np.nonzero(~free)
    gap_x = np.maximum(np.maximum(i * res - points[:, :1], points[:, :1] - (i + 1) * res), 0.0)
    gap_y = np.maximum(np.maximum(j * res - points[:, 1:], points[:, 1:] - (j + 1) * res), 0.0)
    assert np.hypot(gap_x, gap_y).min() >= clearance


def test_the_nearest_free_cell_on_a_tie_is_the_first_by_rows_then_columns():
    """Free cells whose centres are equally near: the lowest row wins, then the lowest
    column."""
    from netsim.world.free_space import nearest_free_cells

    free = np.zeros((5, 5), dtype=bool)
    free[2, 1] = free[2, 3] = True  # left and right of the centre cell
    i, j = nearest_free_cells(free, (0.0, 0.0), 1.0, [[2.5, 2.5]], 1)
    assert (i.tolist(), j.tolist()) == ([1], [2])
    free[1, 2] = free[3, 2] = True  # below and above it too
    i, j = nearest_free_cells(free, (0.0, 0.0), 1.0, [[2.5, 2.5]], 1)
    assert (i.tolist(), j.tolist()) == ([2], [1])


def test_free_fraction_stops_its_margin_short_of_the_first_cell_not_free():
    """A leg into a wall ends ``margin_m`` short of the wall's face, not farther back."""
    from netsim.world.free_space import free_fraction

    free = np.ones((4, 20), dtype=bool)
    free[:, 10] = False
    m = OccupancyMap(~free, free, 1.0, (0.0, 0.0))
    f = free_fraction(m, [[5.5, 1.5]], [[14.5, 1.5]], margin_m=1e-6)
    assert 5.5 + 9.0 * f[0] == pytest.approx(10.0 - 1e-6, abs=1e-9)
