"""Line of sight and walls crossed, for many segments at once, by exact grid traversal.

A segment from ``p`` to ``q`` visits, in order, every cell that contains one of its points
(cells are half-open, ``[i, i + 1) x [j, j + 1)`` in grid units, as in
:mod:`netsim.world.maps`). It changes cell only where it crosses a grid line, so the cells it
visits are known from those crossings alone (Amanatides and Woo, 1987): the crossings of the
vertical lines and of the horizontal lines, each located exactly by where the segment meets
the line. One loop (:func:`netsim.world._kernels.trace`) walks each segment's crossings in
order, looks up the cells on both sides of each, and stops as soon as the answer is known.
The cost is proportional to the number of cells crossed; the loop runs compiled at any
team size (:data:`netsim.compiled.WALKS_MAPS`).

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

from netsim.compiled import load
from netsim.world._kernels import NO_LIMIT

VERTEX_TOLERANCE_CELLS = 1e-9


def _trace(
    blocked: np.ndarray,
    resolution_m: float,
    origin_m,
    p,
    q,
    first: bool = False,
    limit: int = NO_LIMIT,
    snap: bool = False,
):
    """Walls crossed by each segment ``p[k] -> q[k]`` (and, with ``first``, the parameter in
    ``[0, 1]`` at which it first meets a blocked cell, ``inf`` if never); with ``snap``, ends
    within the vertex tolerance of a grid line put on it. Counting may stop past ``limit``
    walls (the count is then ``limit + 1``); with ``first`` it never stops early, since the
    kernel walks a segment's crossings of one axis's grid lines before the other's, and the
    first blocked point may lie among those a stopped walk skipped."""
    p = np.asarray(p, dtype=float).reshape(-1, 2)
    q = np.asarray(q, dtype=float).reshape(-1, 2)
    kernel = load("netsim.world._kernels", None, values=len(p)).trace
    placement = (float(origin_m[0]), float(origin_m[1]), float(resolution_m))
    walls = np.empty(len(p), dtype=np.int64)
    first_t = np.empty(len(p))
    h, w = blocked.shape
    stop = NO_LIMIT if first else limit
    kernel((blocked.ravel(), h, w), placement, (p, q), VERTEX_TOLERANCE_CELLS, (walls, first_t), stop, snap)
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
    snap = blocked is None
    return _trace(grid, occupancy.resolution_m, occupancy.origin_m, p, q, limit=0, snap=snap) == 0


def first_blocked(occupancy, p, q, blocked: np.ndarray | None = None) -> np.ndarray:
    """For each segment, the fraction ``t`` of the way from ``p`` to ``q`` at which it first
    enters a blocked cell (0 when ``p`` is in one), ``inf`` when it never does.

    On a crossing into a blocked cell the point at ``t`` already belongs to that cell: stop
    short of it.
    """
    grid = occupancy.occupied if blocked is None else blocked
    return _trace(grid, occupancy.resolution_m, occupancy.origin_m, p, q, first=True)[1]
