"""Compiled loops of the world's geometry (:mod:`netsim.world.los`,
:mod:`netsim.world.free_space`): the traversal of a segment through a map's cells, and
destinations drawn over the free space. Plain Python when a run is small
(:func:`netsim.compiled.load`).
"""

from __future__ import annotations

import numpy as np

from netsim.compiled import jit

# Counting walls without a stop (``limit`` of :func:`trace_one`); a kernel passes it as
# ``int(NO_LIMIT)``, a value, not a literal (docs/architecture.md, the compiled cache).
NO_LIMIT = np.iinfo(np.int64).max


@jit(nogil=True, inline="always")
def on_grid(x_m, origin_m, resolution_m):
    """A coordinate in metres in the map grid's units, where cell ``i`` spans ``[i, i + 1)``
    (:mod:`netsim.world.maps`): the one conversion every loop over a map makes."""
    return (x_m - origin_m) / resolution_m


@jit(nogil=True)
def grid_coords(points_m, ox, oy, resolution_m, u, v):
    """:func:`on_grid` of every point of ``points_m`` (``(k, 2)``), written to ``u`` and ``v``."""
    for k in range(points_m.shape[0]):
        u[k] = on_grid(points_m[k, 0], ox, resolution_m)
        v[k] = on_grid(points_m[k, 1], oy, resolution_m)


@jit(nogil=True)
def on_map(u, v, h, w):
    """Whether grid coordinates ``(u, v)`` lie on a map of ``h`` rows and ``w`` columns (its
    closed extent)."""
    return u >= 0 and u <= w and v >= 0 and v <= h


@jit(nogil=True)
def cell_index(u, size):
    """The cell of a grid coordinate on an axis of ``size`` cells, the far edge in the last."""
    return min(np.int64(np.floor(u)), size - 1)


@jit(nogil=True, inline="always")
def clamped(k, size):
    """Index ``k`` moved onto an axis of ``size`` cells: into ``0 .. size - 1``."""
    return min(max(k, 0), size - 1)


@jit(nogil=True)
def clamped_cell(u, size):
    """The cell of a grid coordinate on an axis of ``size`` cells, a coordinate off the grid
    in the nearest cell at its edge."""
    return clamped(np.int64(np.floor(u)), size)


@jit(nogil=True)
def clamped_cells(u, v, h, w, i, j):
    """:func:`clamped_cell` of every point's grid coordinates ``(u, v)`` on a map of ``h``
    rows and ``w`` columns: its column into ``i`` and row into ``j``."""
    for k in range(u.shape[0]):
        i[k] = clamped_cell(u[k], w)
        j[k] = clamped_cell(v[k], h)


@jit(nogil=True)
def free_at(free_flat, h, w, u, v):
    """Whether grid coordinates ``(u, v)`` lie on the map in a free cell."""
    if not on_map(u, v, h, w):
        return False
    return free_flat[cell_index(v, h) * w + cell_index(u, w)]


@jit(nogil=True)
def map_cells(free_flat, h, w, u, v, on, free, i, j):
    """For every point's grid coordinates: on the map (:func:`on_map`), in a free cell
    (:func:`free_at`), and its cell's column and row (:func:`cell_index`)."""
    for k in range(u.shape[0]):
        on[k] = on_map(u[k], v[k], h, w)
        free[k] = free_at(free_flat, h, w, u[k], v[k])
        i[k] = cell_index(u[k], w)
        j[k] = cell_index(v[k], h)


@jit(nogil=True)
def cell(flat, w, half, pc, sc, p_max, s_max):
    pc = clamped(pc, p_max + 1)
    sc = clamped(sc, s_max + 1)
    return flat[pc * w + sc] if half == 1 else flat[sc * w + pc]


@jit(nogil=True)
def _snap(g, eps):
    r = np.rint(g)
    return r if abs(g - r) <= eps else g


@jit(nogil=True)
def trace_one(cells, u0, v0, u1, v1, eps, limit):
    """Walls crossed by one segment (grid units) and where it first meets a blocked cell;
    ``cells``: the grid's ``(flat, h, w)``, its blocked cells row-major.

    Stops as soon as the count exceeds ``limit`` (it only grows): enough to decide a link.
    """
    flat, h, w = cells
    i0 = clamped_cell(u0, w)
    j0 = clamped_cell(v0, h)
    count = 0
    ft = np.inf
    if flat[j0 * w + i0]:
        count = 1
        ft = 0.0
        if count > limit:
            return count, ft
    for half in range(2):
        if half == 0:
            P0, S0, P1, S1, p_max, s_max = u0, v0, u1, v1, w - 1, h - 1
        else:
            P0, S0, P1, S1, p_max, s_max = v0, u0, v1, u1, h - 1, w - 1
        c0 = np.int64(np.floor(P0))
        c1 = np.int64(np.floor(P1))
        n = abs(c1 - c0)
        if n == 0:
            continue
        fwd = c1 > c0
        dp = P1 - P0
        ds = S1 - S0
        s0 = np.int64(np.floor(S0))
        s1 = np.int64(np.floor(S1))
        s_lo, s_hi = min(s0, s1), max(s0, s1)
        length = np.hypot(dp, ds) if half == 0 else np.hypot(ds, dp)
        for a in range(n):
            line = c0 + a + 1 if fwd else c0 - a
            t = (line - P0) / dp
            sc = S0 + t * ds
            y = np.rint(sc)
            vertex = abs(sc - y) * abs(dp) <= eps * length and y > s_lo and y <= s_hi
            p_after = line if fwd else line - 1
            p_before = line - 1 if fwd else line
            if vertex:
                yi = np.int64(y)
                s_before = yi - 1 if ds > 0 else yi
                s_after = yi if ds > 0 else yi - 1
            else:
                s_before = s_after = min(max(np.int64(np.floor(sc)), s_lo), s_hi)
            before = cell(flat, w, half, p_before, s_before, p_max, s_max)
            hit = cell(flat, w, half, p_after, s_after, p_max, s_max)
            if vertex and half == 0:
                hit = (
                    hit
                    or cell(flat, w, half, p_after, s_before, p_max, s_max)
                    or cell(flat, w, half, p_before, s_after, p_max, s_max)
                )
            if hit and not before and not (vertex and half == 1):
                count += 1
                if count > limit:
                    return count, min(ft, t)
            if hit and t < ft:
                ft = t
    return count, ft


@jit(nogil=True)
def walls_one(cells, u0, v0, u1, v1, eps, limit):
    """The walls of :func:`trace_one` between two robots: ends within ``eps`` of a grid line
    are put on it first (``netsim.world.los._snap``), so that walls at a robot on a grid
    corner are the same both ways."""
    count, _ = trace_one(cells, _snap(u0, eps), _snap(v0, eps), _snap(u1, eps), _snap(v1, eps), eps, limit)
    return count


@jit(nogil=True)
def trace(cells, placement, ends_m, eps, out, limit, snap):
    """Every segment's walls (counting stops once past ``limit``) and first blocked point,
    ``out``: ``(walls, first_t)``, filled; the segments from ``p`` to ``q`` (``ends_m``,
    metres) on the grid ``cells``, ``(flat, h, w)``, placed by ``placement``, ``(origin_x,
    origin_y, resolution_m)``. With ``snap``, the ends snapped as :func:`walls_one` does."""
    p, q = ends_m
    ox, oy, res = placement
    walls, first_t = out
    for s in range(p.shape[0]):
        u0, v0 = on_grid(p[s, 0], ox, res), on_grid(p[s, 1], oy, res)
        u1, v1 = on_grid(q[s, 0], ox, res), on_grid(q[s, 1], oy, res)
        if snap:
            u0, v0, u1, v1 = _snap(u0, eps), _snap(v0, eps), _snap(u1, eps), _snap(v1, eps)
        walls[s], first_t[s] = trace_one(cells, u0, v0, u1, v1, eps, limit)


@jit(nogil=True)
def first_above(cdf, x):
    """``np.searchsorted(cdf, x, side="right")``: the first index whose value exceeds ``x``
    (``cdf`` non-decreasing). The search starts where ``x`` would fall were the steps equal
    (on a map, most cells are whole: nearly so) and gallops out from there, so that it
    touches a few entries of a long table instead of twenty scattered ones."""
    n = cdf.shape[0]
    if n == 0:
        return 0
    total = cdf[n - 1]
    guess = n - 1
    if total > 0.0 and x < total:
        guess = min(max(np.int64(x / total * n), 0), n - 1)
    # Bracket [lo, hi): cdf[lo - 1] <= x (or lo = 0) and cdf[hi] > x (or hi = n).
    step = 1
    if cdf[guess] <= x:
        lo, hi = guess + 1, guess + 1
        while hi < n and cdf[hi] <= x:
            lo = hi + 1
            hi = min(hi + step, n)
            step *= 2
    else:
        lo, hi = guess, guess
        while lo > 0 and cdf[lo - 1] > x:
            hi = lo - 1
            lo = max(lo - step, 0)
            step *= 2
    while lo < hi:
        mid = (lo + hi) // 2
        if cdf[mid] <= x:
            lo = mid + 1
        else:
            hi = mid
    return lo


@jit(nogil=True, inline="always")
def free_point(cells, grid, draw_cell, draw_uv):
    """A point uniform over the free cells ``cells`` from the uniforms ``draw_cell`` and
    ``draw_uv`` (a cell by area, a point in it); a point that rounding put outside a free
    cell moved to its cell's centre. ``cells`` and ``grid`` as in :func:`free_destinations`."""
    cdf, x0, x1, y0, y1 = cells.cdf, cells.x0, cells.x1, cells.y0, cells.y1
    free_flat, h, w, ox, oy, res = grid.free_flat, grid.h, grid.w, grid.origin_x, grid.origin_y, grid.resolution_m
    last = cdf.shape[0] - 1
    cell = min(first_above(cdf, draw_cell * cdf[last]), last)
    x = x0[cell] + draw_uv[0] * (x1[cell] - x0[cell])
    y = y0[cell] + draw_uv[1] * (y1[cell] - y0[cell])
    if not free_at(free_flat, h, w, on_grid(x, ox, res), on_grid(y, oy, res)):
        x = 0.5 * (x0[cell] + x1[cell])
        y = 0.5 * (y0[cell] + y1[cell])
    return x, y


@jit(nogil=True)
def free_points(cells, grid, draw_cell, draw_uv, out):
    """:func:`free_point` of every draw, into ``out`` (:func:`netsim.world.free_space.sample_free`)."""
    for c in range(draw_cell.shape[0]):
        x, y = free_point(cells, grid, draw_cell[c], draw_uv[c])
        out[c, 0] = x
        out[c, 1] = y


@jit(nogil=True)
def free_destinations(cells, grid, draws, here, batch, eps, out):
    """One round of :func:`netsim.world.free_space.draw_destinations` for robots at ``here``:
    robot ``k``'s ``batch`` candidates are drawn as ``sample_free`` draws them
    (:func:`free_point`), and the first whose straight leg from ``here[k]`` stays in free
    cells is kept (``got[k]``). Legs after the first free one are not traced.

    Read by name: ``cells``, the free cells to draw from
    (:class:`netsim.world.free_space.FreeCells`), and ``grid``, the map
    (:class:`netsim.world.free_space.DrawGrid`); ``draws``: ``(draw_cell, draw_uv)``;
    ``out``: ``(picked, got)``, filled."""
    not_free_flat, h, w = grid.not_free_flat, grid.h, grid.w
    ox, oy, res = grid.origin_x, grid.origin_y, grid.resolution_m
    draw_cell, draw_uv = draws
    picked, got = out
    for k in range(here.shape[0]):
        got[k] = False
        hu = on_grid(here[k, 0], ox, res)
        hv = on_grid(here[k, 1], oy, res)
        for b in range(batch):
            c = k * batch + b
            x, y = free_point(cells, grid, draw_cell[c], draw_uv[c])
            u = on_grid(x, ox, res)
            v = on_grid(y, oy, res)
            walls, _ = trace_one((not_free_flat, h, w), hu, hv, u, v, eps, int(0))
            if walls == 0:
                picked[k, 0] = x
                picked[k, 1] = y
                got[k] = True
                break
