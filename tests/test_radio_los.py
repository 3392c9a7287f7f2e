"""Line of sight and walls crossed: the vectorised traversal against brute-force references."""

import math

import numpy as np
import pytest

from netsim.world import los
from netsim.world.los import first_blocked, line_of_sight, walls_crossed
from netsim.world.maps import OccupancyMap
from tests.oracles import radio as oracle


def _map(blocked, resolution=1.0, origin=(0.0, 0.0)):
    blocked = np.asarray(blocked, dtype=bool)
    return OccupancyMap(blocked, ~blocked, resolution, origin)


def _cell(u, v, w, h):
    return min(max(math.floor(u), 0), w - 1), min(max(math.floor(v), 0), h - 1)


def _crossed_lines(a, b):
    """Integer lines L that a coordinate going from a to b crosses (half-open cells)."""
    lo, hi = math.floor(min(a, b)) - 1, math.ceil(max(a, b)) + 1
    if b > a:
        return [L for L in range(lo, hi + 1) if a < L <= b]
    if b < a:
        return [L for L in range(lo, hi + 1) if b < L <= a]
    return []


def reference(blocked, u0, v0, u1, v1):
    """Walls and first-hit parameter, by a different method: sort every crossing time, look at
    the cell of the midpoint of each interval between crossings, and at a vertex (a vertical
    and a horizontal line crossed at the same time) at all four cells around it."""
    h, w = blocked.shape
    du, dv = u1 - u0, v1 - v0
    length = math.hypot(du, dv)
    xs = [((L - u0) / du, "x", L) for L in _crossed_lines(u0, u1)]
    ys = [((L - v0) / dv, "y", L) for L in _crossed_lines(v0, v1)]
    events = sorted(xs + ys)
    # Group crossings that meet at a vertex (within the traversal's tolerance).
    groups = []
    for e in events:
        if groups and groups[-1][-1][1] != e[1] and abs(e[0] - groups[-1][-1][0]) * length <= 1e-9 * 1.5:
            groups[-1].append(e)
        else:
            groups.append([e])

    def at(t):
        return _cell(u0 + t * du, v0 + t * dv, w, h)

    seq = [(0.0, bool(blocked[at(0.0)[1], at(0.0)[0]]))]
    times = [g[0][0] for g in groups]
    for n, g in enumerate(times):
        nxt = times[n + 1] if n + 1 < len(times) else 1.0
        if len(groups[n]) == 2:
            x = next(e[2] for e in groups[n] if e[1] == "x")
            y = next(e[2] for e in groups[n] if e[1] == "y")
            four = [blocked[min(max(y - dy, 0), h - 1), min(max(x - dx, 0), w - 1)] for dx in (0, 1) for dy in (0, 1)]
            seq.append((g, bool(any(four))))
        mid = at(0.5 * (g + nxt)) if nxt > g else at(g)
        if nxt <= g:  # a crossing at the very end: the end point's cell
            mid = at(1.0)
        seq.append((g, bool(blocked[mid[1], mid[0]])))
    states = [s for _, s in seq]
    walls = int(states[0]) + sum(1 for a, b in zip(states, states[1:]) if b and not a)
    first = next((t for t, s in seq if s), math.inf)
    return walls, first


def sampled(blocked, u0, v0, u1, v1, m=20001):
    h, w = blocked.shape
    t = np.linspace(0.0, 1.0, m)
    i = np.clip(np.floor(u0 + t * (u1 - u0)).astype(int), 0, w - 1)
    j = np.clip(np.floor(v0 + t * (v1 - v0)).astype(int), 0, h - 1)
    keep = np.r_[True, (np.diff(i) != 0) | (np.diff(j) != 0)]
    s = blocked[j[keep], i[keep]]
    return int(s[0]) + int((s[1:] & ~s[:-1]).sum())


def _random_case(rng, w=23, h=17, k=300, lattice=False):
    blocked = rng.random((h, w)) < 0.3
    if lattice:
        # End points on grid lines, vertices and half cells: the edge cases.
        p = rng.integers(0, 2 * min(w, h), (k, 2)) / 2.0
        q = rng.integers(0, 2 * min(w, h), (k, 2)) / 2.0
    else:
        p = rng.uniform(0, 1, (k, 2)) * [w, h]
        q = rng.uniform(0, 1, (k, 2)) * [w, h]
    return blocked, p, q


@pytest.fixture(params=["compiled", "plain"])
def implementation(request, monkeypatch):
    """Run a test with the traversal compiled and as plain Python."""
    monkeypatch.setenv("NETSIM_COMPILED", "1" if request.param == "compiled" else "0")
    return request.param


@pytest.mark.parametrize("lattice", [False, True])
def test_walls_equal_exact_reference_on_random_maps(lattice, implementation):
    """Walls and first hits equal a sort-and-midpoint reference, for generic segments and for
    segments with ends on grid lines and vertices (along lines, through corners)."""
    rng = np.random.default_rng(3 if lattice else 4)
    for _ in range(3):
        blocked, p, q = _random_case(rng, lattice=lattice)
        m = _map(blocked)
        walls = walls_crossed(m, p, q)
        first = first_blocked(m, p, q)
        for n in range(len(p)):
            if np.array_equal(p[n], q[n]):
                continue
            ref_w, ref_t = reference(blocked, *p[n], *q[n])
            assert walls[n] == ref_w, (p[n], q[n])
            assert first[n] == pytest.approx(ref_t, abs=1e-12), (p[n], q[n])


def test_walls_match_dense_sampling(implementation):
    """Dense sampling sees a sub-sequence of the cells (it can step over a corner clip), so it
    never counts more walls, and on random segments it nearly always counts the same."""
    rng = np.random.default_rng(5)
    blocked, p, q = _random_case(rng, k=400)
    walls = walls_crossed(_map(blocked), p, q)
    dense = np.array([sampled(blocked, *p[n], *q[n]) for n in range(len(p))])
    assert (walls >= dense).all()
    assert (walls == dense).mean() >= 0.97


def test_traversal_equals_the_oracle_exactly(implementation):
    """The traversal's loop (plain and compiled) does the oracle's arithmetic: identical walls
    and first hits."""
    rng = np.random.default_rng(8)
    for lattice in (False, True, False, True):
        blocked, p, q = _random_case(rng, k=500, lattice=lattice)
        a = oracle.trace(blocked, 0.5, (-3.0, 2.0), p * 0.5 - 3.0 + [0, 5], q * 0.5 - 3.0 + [0, 5], True)
        b = los._trace(blocked, 0.5, (-3.0, 2.0), p * 0.5 - 3.0 + [0, 5], q * 0.5 - 3.0 + [0, 5], True)
        assert np.array_equal(a[0], b[0]) and np.array_equal(a[1], b[1])


def test_walls_are_symmetric(implementation):
    """Reciprocity: the walls between two robots do not depend on who sends."""
    rng = np.random.default_rng(6)
    for lattice in (False, True):
        blocked, p, q = _random_case(rng, lattice=lattice)
        m = _map(blocked)
        assert np.array_equal(walls_crossed(m, p, q), walls_crossed(m, q, p))


def test_segment_along_a_grid_line_is_in_the_cells_above_it(implementation):
    """A point on a grid line belongs to the cell above (right of) it, and so does a segment."""
    below = np.zeros((4, 6), dtype=bool)
    below[1, 2] = True  # the row under the line y = 2
    above = np.zeros((4, 6), dtype=bool)
    above[2, 2] = True
    p, q = [[0.5, 2.0]], [[5.5, 2.0]]
    assert line_of_sight(_map(below), p, q).tolist() == [True]
    assert line_of_sight(_map(above), p, q).tolist() == [False]
    # Vertical, along x = 3: the column to the right.
    left = np.zeros((4, 6), dtype=bool)
    left[2, 2] = True
    right = np.zeros((4, 6), dtype=bool)
    right[2, 3] = True
    assert line_of_sight(_map(left), [[3.0, 0.5]], [[3.0, 3.5]]).tolist() == [True]
    assert line_of_sight(_map(right), [[3.0, 0.5]], [[3.0, 3.5]]).tolist() == [False]


def test_diagonal_staircase_wall_does_not_leak_at_its_corners(implementation):
    """A wall of pixels touching only at corners blocks a segment through those corners."""
    stair = np.zeros((6, 6), dtype=bool)
    for c in range(6):
        stair[5 - c, c] = True  # the anti-diagonal
    m = _map(stair)
    # Along the main diagonal, through the vertex (3, 3) where cells (2, 3) and (3, 2) touch.
    assert walls_crossed(m, [[0.5, 0.5]], [[5.5, 5.5]]).tolist() == [1]
    assert walls_crossed(m, [[5.5, 5.5]], [[0.5, 0.5]]).tolist() == [1]


def test_vertex_with_one_blocked_side_cell_blocks(implementation):
    """Through a vertex, any of the four cells around it blocks."""
    one = np.zeros((4, 4), dtype=bool)
    one[1, 2] = True  # beside the diagonal step from (1, 1) to (2, 2)
    assert line_of_sight(_map(one), [[0.5, 0.5]], [[3.5, 3.5]]).tolist() == [False]
    # A hair off the vertex the segment clips only one of the two side cells.
    assert line_of_sight(_map(one), [[0.5, 0.5 + 1e-6]], [[3.5, 3.5 + 1e-6]]).tolist() == [True]
    assert line_of_sight(_map(one), [[0.5 + 1e-6, 0.5]], [[3.5 + 1e-6, 3.5]]).tolist() == [False]


def test_each_run_of_occupied_cells_is_one_wall(implementation):
    """Two walls two cells thick: two walls; a thick wall is one wall; the ends count."""
    g = np.zeros((3, 10), dtype=bool)
    g[:, 2:4] = True
    g[:, 6] = True
    m = _map(g)
    assert walls_crossed(m, [[0.5, 1.5]], [[9.5, 1.5]]).tolist() == [2]
    assert walls_crossed(m, [[2.5, 1.5]], [[9.5, 1.5]]).tolist() == [2]  # starting inside a wall
    assert walls_crossed(m, [[0.5, 1.5]], [[1.5, 1.5]]).tolist() == [0]
    assert walls_crossed(m, [[3.5, 1.5]], [[3.5, 1.5]]).tolist() == [1]  # a point in a wall


def test_world_coordinates_use_resolution_and_origin():
    """The traversal works in world metres: resolution and origin place the cells."""
    g = np.zeros((4, 4), dtype=bool)
    g[:, 2] = True  # x in [origin + 2 res, origin + 3 res)
    m = _map(g, resolution=0.5, origin=(-1.0, 10.0))
    assert walls_crossed(m, [[-0.9, 10.5]], [[0.9, 10.5]]).tolist() == [1]
    assert walls_crossed(m, [[-0.9, 10.5]], [[-0.05, 10.5]]).tolist() == [0]  # stops short of x = 0
    assert walls_crossed(m, [[-0.9, 10.5]], [[0.0, 10.5]]).tolist() == [1]  # x = 0 is in the wall


def test_far_edge_belongs_to_last_cell(implementation):
    """A robot exactly on the map's far edge is in the last cell, not off the map."""
    g = np.zeros((2, 2), dtype=bool)
    g[1, 1] = True
    m = _map(g)
    assert walls_crossed(m, [[0.5, 0.5]], [[2.0, 2.0]]).tolist() == [1]
    assert walls_crossed(m, [[0.5, 0.5], [0.5, 0.5]], [[2.0, 0.5], [0.5, 0.9]]).tolist() == [0, 0]


def test_first_blocked_is_where_the_wall_starts(implementation):
    g = np.zeros((1, 10), dtype=bool)
    g[0, 6] = True
    m = _map(g)
    t = first_blocked(m, [[0.0, 0.5], [9.5, 0.5], [0.0, 0.5]], [[10.0, 0.5], [0.5, 0.5], [5.0, 0.5]])
    assert t[0] == pytest.approx(0.6)
    assert t[1] == pytest.approx(2.5 / 9.0)  # from the right, the wall's cell ends at x = 7
    assert t[2] == np.inf


def test_empty_batch(implementation):
    m = _map(np.zeros((2, 2), dtype=bool))
    assert walls_crossed(m, np.empty((0, 2)), np.empty((0, 2))).tolist() == []


@pytest.mark.parametrize("implementation", ["compiled", pytest.param("plain", marks=pytest.mark.slow)], indirect=True)
def test_walls_at_a_robot_on_a_grid_corner_are_symmetric(implementation):
    """A robot standing on a grid corner given in world metres (a rounding step or a few off
    it): the walls between it and another robot (anywhere, on another corner, or on the
    same grid line) are the same both ways."""
    rng = np.random.default_rng(9)
    for res, origin in ((0.05, (0.0, 0.0)), (0.1, (-3.0, 2.0)), (0.3, (0.7, -1.1)), (0.07, (0.0, 0.0))):
        blocked = rng.random((12, 12)) < 0.4
        m = _map(blocked, res, origin)
        k = 3000
        o = np.asarray(origin)
        p = rng.integers(1, 11, (k, 2)) * res + o
        q = rng.uniform(0.5, 11.5, (k, 2)) * res + o
        q[::3] = rng.integers(1, 11, (len(q[::3]), 2)) * res + o
        q[1::3, 0] = p[1::3, 0]
        q[2::6, 1] = p[2::6, 1]
        # Each given a few rounding steps off, as a position computed another way would be.
        off = np.array([0.0, 1e-14, -1e-14, 1e-12, -1e-12]) * res
        p = p + rng.choice(off, p.shape)
        q = q + rng.choice(off, q.shape)
        assert np.array_equal(walls_crossed(m, p, q), walls_crossed(m, q, p))
