"""Walls crossed by the segment between two robots moving in straight lines, over time, exactly.

The count of :func:`netsim.world.los.walls_crossed` between ``p(t) = p0 + vp t`` and
``q(t) = q0 + vq t`` is piecewise constant in ``t``. It can change only where the cells the
segment meets change in a way that matters:

- the segment passes through a grid **vertex** at which blocked and clear cells meet (a
  vertex whose four cells are alike changes nothing): the vertex and the two ends are
  collinear, ``cross(p(t) - v, q(t) - v) = 0``, a quadratic in ``t``, with the vertex between
  the ends. Where the vertex stays on the segment's line (both robots moving along it), the
  instants where an end passes the vertex's grid lines instead;
- an **end** crosses a grid line between two cells of different state (or at a vertex);
- the segment turns parallel to an axis (the traversal's conventions on a grid line depend on
  its direction).

Candidate vertices come from the region the segment sweeps: it lies in the convex hull of
the ends' first and last positions, whose span along each grid row is searched among that
row's mixed vertices (found once per grid). Most of those lie along straight walls, where a
segment sweeping across changes no count whatever its heading: unless an end passes beside
one, the segment comes near an axis, or the ends move in parallel with the vertex perhaps
on the segment's line, they are passed over without solving their instant (the same
candidates, found with fewer roots). Each instant is solved in closed form; the count
on each interval between consecutive candidates is the traversal's
(:func:`netsim.world._kernels.walls_one`, the arithmetic of ``walls_crossed``) at its
midpoint, and consecutive intervals of equal count are merged.

At an event itself the count may differ from both sides (a segment through a vertex touches
its four cells; so does one within ``1e-9`` cell of it): the rows describe open intervals.

>>> from netsim.world.maps import OccupancyMap
>>> wall = np.zeros((4, 6), dtype=bool); wall[1:, 3] = True  # a wall with a gap at the bottom
>>> # one robot walks up past the wall's lower corner, the other stands beyond the wall
>>> m = OccupancyMap(wall, ~wall, 1.0, (0.0, 0.0))
>>> s = sweep_walls(m, [[0.5, 0.5]], [[0.0, 1.0]], [[5.5, 0.5]], [[0.0, 0.0]], [2.0])
>>> [(float(a), float(b), int(c)) for a, b, c in zip(s.t0_s, s.t1_s, s.walls)]
[(0.0, 1.0, 0), (1.0, 2.0, 1)]
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np

from netsim.compiled import filled, load
from netsim.world._kernels import NO_LIMIT
from netsim.world.los import VERTEX_TOLERANCE_CELLS


class Sweep(NamedTuple):
    """Rows in time order within each pair (pairs in order): on ``(t0_s, t1_s)`` the segment
    of pair ``pair`` crosses ``walls`` walls. Each pair's rows cover ``[0, duration]``."""

    pair: np.ndarray
    t0_s: np.ndarray
    t1_s: np.ndarray
    walls: np.ndarray


class VertexIndex(NamedTuple):
    """The grid vertices at which blocked and clear cells meet, by row: vertex row ``j``'s
    columns are ``cols[row_ptr[j]:row_ptr[j + 1]]``, ascending; ``changing_headings``, for each, the
    headings of a segment across it for which the walls crossed change
    (:func:`netsim.world._sweep_kernels.vertex_headings`). The same for the vertices of each
    heading's bit ``b`` alone: ``corner_cols[corner_ptr[b, j]:corner_ptr[b, j + 1]]``."""

    row_ptr: np.ndarray
    cols: np.ndarray
    changing_headings: np.ndarray
    corner_ptr: np.ndarray
    corner_cols: np.ndarray


def vertex_index(blocked: np.ndarray) -> VertexIndex:
    """The mixed vertices of a grid (cells beyond its edges are taken as the edge's, as the
    traversal takes them)."""
    b = np.asarray(blocked, bool)
    padded = np.pad(b, 1, mode="edge")
    # Vertex (i, j) has the cells (i - 1 .. i, j - 1 .. j) around it.
    quads = (
        padded[:-1, :-1].astype(np.int8) + padded[:-1, 1:] + padded[1:, :-1] + padded[1:, 1:]
    )  # shape (h + 1, w + 1)
    mixed = (quads > 0) & (quads < 4)
    rows, cols = np.nonzero(mixed)
    row_ptr = np.zeros(mixed.shape[0] + 1, np.int64)
    np.cumsum(np.bincount(rows, minlength=mixed.shape[0]), out=row_ptr[1:])
    cols = cols.astype(np.int64)
    changing_headings = np.zeros(len(cols), np.uint8)
    flat = np.ascontiguousarray(b).ravel()
    headings = load("netsim.world._sweep_kernels", None, values=len(cols)).vertex_headings
    headings((flat, b.shape[0], b.shape[1]), row_ptr, cols, changing_headings)
    # Each heading's corners, in one array: heading b's rows are offset past those before it.
    has = (changing_headings[None, :] >> np.arange(4, dtype=np.uint8)[:, None]) & 1 == 1
    corner_ptr = np.zeros((4, mixed.shape[0] + 1), np.int64)
    for bit in range(4):
        corner_ptr[bit, 1:] = np.cumsum(np.bincount(rows[has[bit]], minlength=mixed.shape[0]))
    corner_ptr += np.r_[0, np.cumsum(has.sum(axis=1))[:-1]][:, None]
    corner_cols = np.concatenate([cols[has[bit]] for bit in range(4)])
    return VertexIndex(row_ptr, cols, changing_headings, corner_ptr, corner_cols)


_INDEX: list = []


def cached_vertex_index(blocked: np.ndarray) -> VertexIndex:
    """:func:`vertex_index`, kept for the last grid asked for (a run's map)."""
    # Keyed by the array itself, which the cache keeps alive.
    if _INDEX and _INDEX[0][0] is blocked:
        return _INDEX[0][1]
    index = vertex_index(blocked)
    _INDEX[:] = [(blocked, index)]
    return index


class MapGrid(NamedTuple):
    """A map as the sweep's kernels read it (:mod:`netsim.world._sweep_kernels`' ``grid``,
    read by name): the cells that block, row-major, of an ``h`` by ``w`` grid,
    the vertices where blocked and clear cells meet (:class:`VertexIndex`), the grid's
    origin and cell size (metres)."""

    flat: np.ndarray
    h: int
    w: int
    row_ptr: np.ndarray
    cols: np.ndarray
    changing_headings: np.ndarray
    corner_ptr: np.ndarray
    corner_cols: np.ndarray
    origin_x: float
    origin_y: float
    resolution_m: float


class PairMotion(NamedTuple):
    """The two robots of each pair on straight legs, as the sweep's kernels read them:
    ``p0[k] + vp[k] t`` and ``q0[k] + vq[k] t`` (metres, m/s; rows of shape ``(k, 2)``)."""

    p0: np.ndarray
    vp: np.ndarray
    q0: np.ndarray
    vq: np.ndarray


def map_grid(occupancy, blocked: np.ndarray | None = None) -> MapGrid:
    """The :class:`MapGrid` of a map; ``blocked`` replaces its occupied cells."""
    grid = np.ascontiguousarray(occupancy.occupied if blocked is None else blocked)
    index = cached_vertex_index(occupancy.occupied if blocked is None else blocked)
    h, w = grid.shape
    ox, oy = (float(c) for c in occupancy.origin_m)
    return MapGrid(
        grid.ravel(),
        int(h),
        int(w),
        index.row_ptr,
        index.cols,
        index.changing_headings,
        index.corner_ptr,
        index.corner_cols,
        ox,
        oy,
        float(occupancy.resolution_m),
    )


def sweep_walls(
    occupancy,
    p0,
    vp,
    q0,
    vq,
    duration_s,
    blocked: np.ndarray | None = None,
    limit: int | None = None,
) -> Sweep:
    """Walls crossed between ``p0[k] + vp[k] t`` and ``q0[k] + vq[k] t`` (metres, m/s) for
    ``t`` in ``[0, duration_s[k]]``, as rows of constant count (module notes).

    ``blocked`` replaces the map's occupied cells; with ``limit``, counts above it are
    reported as ``limit + 1`` (enough to decide a link, and cheaper).
    """
    grid = map_grid(occupancy, blocked)
    p0, vp, q0, vq = (np.ascontiguousarray(np.asarray(a, float).reshape(-1, 2)) for a in (p0, vp, q0, vq))
    sweep = load("netsim.world._sweep_kernels", None, values=len(p0)).sweep
    duration = filled(duration_s, (len(p0),))
    motion = PairMotion(p0, vp, q0, vq)
    limit = NO_LIMIT if limit is None else int(limit)
    pair, t0, t1, walls = sweep(grid, motion, duration, VERTEX_TOLERANCE_CELLS, limit)
    return Sweep(pair, t0, t1, walls)
