"""Line of sight and walls crossed, for many segments at once, by exact grid traversal.

A segment from ``p`` to ``q`` visits, in order, every cell that contains one of its points
(cells are half-open, ``[i, i + 1) x [j, j + 1)`` in grid units, as in
:mod:`netsim.world.maps`). It changes cell only where it crosses a grid line, so the cells it
visits are known from those crossings alone (Amanatides and Woo, 1987): the crossings of the
vertical lines and of the horizontal lines, each located exactly by where the segment meets
the line. This module computes them for all segments in one set of numpy operations, with no
loop over segments or cells: the crossings of a batch are laid end to end (a ragged array),
the cells on both sides of each crossing looked up in the grid, and the counts summed per
segment. The cost is proportional to the number of cells crossed.

**Walls crossed** is the number of separate runs of blocked cells met along the segment: the
cell of ``p`` if blocked, plus each crossing from a clear cell into a blocked one. A segment
is **clear** (line of sight) when it meets no blocked cell.

Conventions, where a segment meets the grid at its edges:

- along a grid line, a segment is in the cells on the upper (or right) side of it, as a point
  on that line is;
- through a grid *vertex* (a horizontal and a vertical line crossed at the same point), the
  segment is taken to touch all four cells around it: it is blocked there if any of them is
  (so a wall drawn as a diagonal staircase of pixels, whose cells touch only at corners, has
  no leak). A segment passing within ``1e-9`` cell of a vertex counts as passing through it.
- both ends count: a robot standing in a blocked cell has no line of sight to anyone;
- between robots (the map's walls, no ``blocked`` given), an end within ``1e-9`` cell of a
  grid line is on it, so that a robot standing on a grid corner given in world metres is
  on the corner, and its walls are the same both ways. Motion (``blocked`` given, and
  :func:`first_blocked`) traces the ends as they are: a robot stopped just short of a wall
  stays out of it.

Segments must lie on the map (within its closed extent); a point on the far edge belongs to
the last cell. Walls are symmetric: ``walls(p, q) == walls(q, p)``.

>>> from netsim.world.maps import OccupancyMap
>>> wall = np.zeros((4, 6), dtype=bool); wall[:, 3] = True; wall[0, 3] = False  # a door at the bottom
>>> m = OccupancyMap(wall, ~wall, 1.0, (0.0, 0.0))
>>> walls_crossed(m, [[0.5, 2.5], [0.5, 0.5]], [[5.5, 2.5], [5.5, 0.5]]).tolist()
[1, 0]
"""

from __future__ import annotations

import numpy as np

VERTEX_TOLERANCE_CELLS = 1e-9


def _snap(g: np.ndarray) -> np.ndarray:
    """Grid coordinates within the vertex tolerance of a grid line put on it: a robot on a
    grid corner (in world metres, which the division by the resolution may leave a rounding
    step off it) is on the corner, whichever way the segment is traced."""
    r = np.rint(g)
    return np.where(np.abs(g - r) <= VERTEX_TOLERANCE_CELLS, r, g)


def _trace_numpy(blocked: np.ndarray, resolution_m: float, origin_m, p, q, first: bool = False, snap: bool = False):
    """Walls crossed by each segment ``p[k] -> q[k]`` (and, with ``first``, the parameter in
    ``[0, 1]`` at which it first meets a blocked cell, ``inf`` if never); with ``snap``, ends
    within the vertex tolerance of a grid line put on it."""
    p = np.asarray(p, dtype=float).reshape(-1, 2)
    q = np.asarray(q, dtype=float).reshape(-1, 2)
    k = len(p)
    h, w = blocked.shape
    flat = blocked.ravel()
    origin = np.asarray(origin_m, dtype=float)
    g0 = (p - origin) / resolution_m
    g1 = (q - origin) / resolution_m
    if snap:
        g0, g1 = _snap(g0), _snap(g1)
    # Two halves: rows 0..k-1 cross vertical lines (primary axis u), rows k..2k-1 cross
    # horizontal lines (primary axis v, the coordinates swapped). One pass serves both.
    G0 = np.concatenate([g0, g0[:, ::-1]])
    G1 = np.concatenate([g1, g1[:, ::-1]])
    c0 = np.floor(G0).astype(np.int64)
    c1 = np.floor(G1).astype(np.int64)
    start = flat[np.minimum(np.maximum(c0[:k, 1], 0), h - 1) * w + np.minimum(np.maximum(c0[:k, 0], 0), w - 1)]
    n = np.abs(c1[:, 0] - c0[:, 0])
    total = int(n.sum())
    if total == 0:
        walls = start.astype(np.int64)
        return (walls, np.where(start, 0.0, np.inf)) if first else walls

    seg = np.repeat(np.arange(2 * k), n)
    step = np.arange(total) - np.repeat(np.cumsum(n) - n, n)
    d = G1 - G0
    fwd = (c1[:, 0] > c0[:, 0])[seg]
    line = c0[seg, 0] + np.where(fwd, step + 1, -step)
    dp, ds = d[seg, 0], d[seg, 1]
    t = (line - G0[seg, 0]) / dp
    sc = G0[seg, 1] + t * ds  # the secondary coordinate where the line is crossed
    s_lo = np.minimum(c0[seg, 1], c1[seg, 1])
    s_hi = np.maximum(c0[seg, 1], c1[seg, 1])
    s_cell = np.minimum(np.maximum(np.floor(sc).astype(np.int64), s_lo), s_hi)
    p_after = line - ~fwd
    p_before = line - fwd
    half1 = seg >= k
    p_max = np.where(half1, h - 1, w - 1)
    s_max = np.where(half1, w - 1, h - 1)

    def index(pc, sc_, sel=slice(None)):
        pc = np.minimum(np.maximum(pc, 0), p_max[sel])
        sc_ = np.minimum(np.maximum(sc_, 0), s_max[sel])
        return np.where(half1[sel], pc * w + sc_, sc_ * w + pc)

    # A vertex: the crossing lies on a secondary line that the segment also crosses.
    y = np.rint(sc)
    length = np.hypot(d[:, 0], d[:, 1])[seg]
    vertex = (np.abs(sc - y) * np.abs(dp) <= VERTEX_TOLERANCE_CELLS * length) & (y > s_lo) & (y <= s_hi)
    if vertex.any():
        yi = y.astype(np.int64)
        up = ds > 0
        s_before = np.where(vertex, yi - up, s_cell)
        s_after = np.where(vertex, yi - ~up, s_cell)
    else:
        s_before = s_after = s_cell
    occ_before = flat[index(p_before, s_before)]
    hit = flat[index(p_after, s_after)]
    if vertex.any():
        vx = np.flatnonzero(vertex & ~half1)
        # The four cells around a vertex: the two beside the diagonal step count too.
        sides = flat[index(p_after[vx], s_before[vx], vx)] | flat[index(p_before[vx], s_after[vx], vx)]
        hit[vx] |= sides
    rise = hit & ~occ_before
    if vertex.any():
        # Each vertex is met by both halves; the vertical-line half alone counts it.
        rise[vertex & half1] = False
    seg0 = seg - k * half1
    walls = start + np.bincount(seg0, weights=rise, minlength=k).astype(np.int64)
    if not first:
        return walls
    first_t = np.where(start, 0.0, np.inf)
    np.minimum.at(first_t, seg0[hit], t[hit])
    return walls, first_t


_KERNEL: list = []


def _kernel():
    """The compiled traversal (:mod:`netsim.world._kernels`), or None without numba.

    Imported on first use: numba takes a second to import, which a run without a map
    should not pay.
    """
    if not _KERNEL:
        try:
            from netsim.compiled import compiled_copy

            trace = compiled_copy("netsim.world._kernels").trace
        except ImportError:  # pragma: no cover - numba is a dependency; kept optional for exotic platforms
            trace = None
        _KERNEL.append(trace)
    return _KERNEL[0]


_NO_LIMIT = np.iinfo(np.int64).max


def _trace(
    blocked: np.ndarray,
    resolution_m: float,
    origin_m,
    p,
    q,
    first: bool = False,
    limit: int = _NO_LIMIT,
    snap: bool = False,
):
    """``_trace_numpy``, compiled; the compiled loop may stop counting past ``limit`` walls
    (the count is then ``limit + 1``, the first blocked point still exact)."""
    kernel = _kernel()
    if kernel is None:
        return _trace_numpy(blocked, resolution_m, origin_m, p, q, first, snap)
    p = np.asarray(p, dtype=float).reshape(-1, 2)
    q = np.asarray(q, dtype=float).reshape(-1, 2)
    origin = np.asarray(origin_m, dtype=float)
    walls = np.empty(len(p), dtype=np.int64)
    first_t = np.empty(len(p))
    h, w = blocked.shape
    points = ((p - origin) / resolution_m, (q - origin) / resolution_m)
    kernel((blocked.ravel(), h, w), points, VERTEX_TOLERANCE_CELLS, (walls, first_t), limit, snap)
    return (walls, first_t) if first else walls


def walls_crossed(occupancy, p, q, blocked: np.ndarray | None = None) -> np.ndarray:
    """Number of walls (runs of occupied cells) on each segment ``p[k] -> q[k]`` (world metres).

    ``blocked`` replaces the map's occupied cells (e.g. ``~occupancy.free`` for motion).
    """
    grid = occupancy.occupied if blocked is None else blocked
    return _trace(grid, occupancy.resolution_m, occupancy.origin_m, p, q, snap=blocked is None)


def line_of_sight(occupancy, p, q, blocked: np.ndarray | None = None) -> np.ndarray:
    """Whether each segment meets no occupied (or ``blocked``) cell (tracing stops at the first)."""
    grid = occupancy.occupied if blocked is None else blocked
    return _trace(grid, occupancy.resolution_m, occupancy.origin_m, p, q, limit=0, snap=blocked is None) == 0


def first_blocked(occupancy, p, q, blocked: np.ndarray | None = None) -> np.ndarray:
    """For each segment, the fraction ``t`` of the way from ``p`` to ``q`` at which it first
    enters a blocked cell (0 when ``p`` is in one), ``inf`` when it never does.

    On a crossing into a blocked cell the point at ``t`` already belongs to that cell: stop
    short of it.
    """
    grid = occupancy.occupied if blocked is None else blocked
    return _trace(grid, occupancy.resolution_m, occupancy.origin_m, p, q, first=True)[1]
