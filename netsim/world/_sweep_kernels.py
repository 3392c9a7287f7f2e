"""Compiled (numba) loops behind :mod:`netsim.world.sweep`.

They call :func:`netsim.world._kernels.walls_one` (numba does not track callees across
files: :mod:`netsim.kernel_cache` keys this module's cache by that one's source too).

What they read by name: ``grid``, the map (:class:`netsim.world.sweep.MapGrid`: the
occupied cells row-major, the vertices where blocked and clear cells meet, the grid's origin
and cell size), whose first three fields, ``cells``, are what a cell's lookup reads;
``motion``, the two robots of each pair on straight legs (:class:`netsim.world.sweep.PairMotion`,
metres and m/s); a :class:`Segment` between two moving points.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np

from netsim._kernels import disk_crossing_times, grown, lower_bound, reaches
from netsim.compiled import jit
from netsim.world._kernels import clamped, on_grid, walls_one

# Where a vertex lies on the segment's line for every t (both factors of the cross product
# vanish): relative to the size of each coefficient.
_DEGENERATE = 1e-12
# How close to a grid line, in cells, an end's crossing of the other axis is taken as a
# crossing at a vertex (then a candidate whatever the cells).
_NEAR_LINE_CELLS = 1e-6
# A segment within this share of its length of an axis is taken as along it, and a vertex
# within this many cells (each axis) of an end as beside it (:func:`_changes_count`).
_ALONG_AXIS = 1e-6
_NEAR_END_CELLS = 1.5


class Segment(NamedTuple):
    """The segment from ``a + va t`` to ``b + vb t`` (grid units, relative to a vertex)."""

    ax: float
    ay: float
    vax: float
    vay: float
    bx: float
    by: float
    vbx: float
    vby: float


@jit(nogil=True)
def _push(buf, n, t):
    if n == buf.shape[0]:
        buf = grown(buf, n)
    buf[n] = t
    return buf, n + 1


@jit(nogil=True)
def _cell(cells, i, j):
    flat, h, w = cells
    return flat[clamped(j, h) * w + clamped(i, w)]


@jit(nogil=True)
def _linear_root(c0, c1, duration, buf, n):
    """``c0 + c1 t = 0`` for ``t`` strictly inside ``(0, duration)``."""
    if c1 != 0.0:
        t = -c0 / c1
        if t > 0.0 and t < duration:
            buf, n = _push(buf, n, t)
    return buf, n


@jit(nogil=True)
def _end_crossings(cells, end, duration, axis, buf, n):
    """Where an end moving along ``e0 + e1 t`` (the axis crossed; ``f0 + f1 t`` the other
    coordinate; ``end``: ``(e0, e1, f0, f1)``) crosses a grid line between cells of
    different state, or near a vertex."""
    e0, e1, f0, f1 = end
    if e1 == 0.0:
        return buf, n
    x_end = e0 + e1 * duration
    lo = min(e0, x_end)
    hi = max(e0, x_end)
    first = np.int64(np.floor(lo)) + 1
    last = np.int64(np.ceil(hi)) - 1
    for line in range(first, last + 1):
        t = (line - e0) / e1
        if not (t > 0.0 and t < duration):
            continue
        f = f0 + f1 * t
        r = np.rint(f)
        if abs(f - r) <= _NEAR_LINE_CELLS:
            buf, n = _push(buf, n, t)
            continue
        j = np.int64(np.floor(f))
        if axis == 0:
            differ = _cell(cells, line - 1, j) != _cell(cells, line, j)
        else:
            differ = _cell(cells, j, line - 1) != _cell(cells, j, line)
        if differ:
            buf, n = _push(buf, n, t)
    return buf, n


@jit(nogil=True)
def _cut(x0, dx, y0, dy, y):
    """Where the line at height ``y`` cuts the edge from ``(x0, y0)`` to ``(x0 + dx, y0 +
    dy)`` (whose ends lie on either side of it)."""
    return x0 + dx * (y - y0) / dy


@jit(nogil=True)
def _hull_span(ys, xs, y):
    """The span in x of the convex hull of four points along the line at height ``y``
    (empty: lo > hi)."""
    lo = np.inf
    hi = -np.inf
    for i in range(4):
        if ys[i] == y:
            lo = min(lo, xs[i])
            hi = max(hi, xs[i])
        for k in range(i + 1, 4):
            y0, y1 = ys[i], ys[k]
            if (y0 < y and y1 > y) or (y0 > y and y1 < y):
                x = _cut(xs[i], xs[k] - xs[i], y0, y1 - y0, y)
                lo = min(lo, x)
                hi = max(hi, x)
    return lo, hi


@jit(nogil=True)
def _edges_across(ys, xs, below, edges):
    """The edges ``(i, k)``, ``i < k``, between four points one of which lies below a line
    and the other above (``below``: bit ``i`` for a point below, none on it), in
    :func:`_hull_span`'s order, as rows ``(x0, dx, y0, dy)`` of ``edges`` (:func:`_cut`'s
    arguments); returns how many."""
    count = 0
    for i in range(4):
        for k in range(i + 1, 4):
            if ((below >> i) & 1) != ((below >> k) & 1):
                edges[count, 0] = xs[i]
                edges[count, 1] = xs[k] - xs[i]
                edges[count, 2] = ys[i]
                edges[count, 3] = ys[k] - ys[i]
                count += 1
    return count


@jit(nogil=True)
def _span_across(edges, count, y):
    """:func:`_hull_span` at a height ``y`` no point lies on (nor within the margin of), the
    edges that cross it known (:func:`_edges_across`): the same cuts."""
    lo = np.inf
    hi = -np.inf
    for e in range(count):
        x = _cut(edges[e, 0], edges[e, 1], edges[e, 2], edges[e, 3], y)
        lo = min(lo, x)
        hi = max(hi, x)
    return lo, hi


@jit(nogil=True)
def _rises(x, y, z):
    return (1 if (y and not x) else 0) + (1 if (z and not y) else 0)


@jit(nogil=True)
def _swap_changes(cells, i, j, bx, by):
    """Whether the walls crossed change as a segment heading from cell ``(i + bx, j + by)``
    to the opposite one of vertex ``(i, j)``'s four swaps the cell it visits between them
    (one beside the diagonal step for the other)."""
    ax = -1 - bx
    ay = -1 - by
    before = _cell(cells, i + bx, j + by)
    after = _cell(cells, i + ax, j + ay)
    side1 = _cell(cells, i + ax, j + by)
    side2 = _cell(cells, i + bx, j + ay)
    return _rises(before, side1, after) != _rises(before, side2, after)


@jit(nogil=True)
def _heading_bit(dx, dy):
    """The bit of :func:`vertex_headings` for a segment heading ``(dx, dy)`` off the axes."""
    return (2 if dx > 0 else 0) + (1 if dy > 0 else 0)


@jit(nogil=True)
def vertex_headings(cells, row_ptr, cols, changing_headings):
    """For each mixed vertex (:class:`netsim.world.sweep.VertexIndex`), into ``changing_headings``: for
    which headings of a segment (bits of :func:`_heading_bit`) sweeping across it away
    from the ends and off the axes the walls crossed change (:func:`_swap_changes`). Along
    a straight wall no heading does: only corners count, which lets a sweep pass over
    the rest unsolved (:func:`candidates`)."""
    for j in range(row_ptr.shape[0] - 1):
        for m in range(row_ptr[j], row_ptr[j + 1]):
            i = cols[m]
            bits = 0
            for dx in (-1.0, 1.0):
                for dy in (-1.0, 1.0):
                    bx = -1 if dx > 0 else 0
                    by = -1 if dy > 0 else 0
                    if _swap_changes(cells, i, j, bx, by):
                        bits |= 1 << _heading_bit(dx, dy)
            changing_headings[m] = bits


@jit(nogil=True)
def _changes_count(cells, vertex, p, q):
    """Whether the walls crossed may change as the segment from ``p`` to ``q`` (``(x, y)``
    relative to ``vertex``, ``(i, j)``, which lies between them) sweeps across the vertex.

    Away from the ends and off the axes, the cells the segment visits change only there:
    the cell before the vertex and the one after stay, and the one between is one of the two
    beside the diagonal step or the other. The walls (rises from a clear cell into a blocked
    one) then change by what that swap changes locally. Elsewhere (an end in or next to the
    vertex's cells, a segment along an axis), it may change."""
    i, j = vertex
    px, py = p
    qx, qy = q
    dx = qx - px
    dy = qy - py
    length = abs(dx) + abs(dy)
    if abs(dx) <= _ALONG_AXIS * length or abs(dy) <= _ALONG_AXIS * length:
        return True
    if max(abs(px), abs(py)) < _NEAR_END_CELLS or max(abs(qx), abs(qy)) < _NEAR_END_CELLS:
        return True
    # Cells around the vertex, relative: (-1 or 0, -1 or 0).
    bx = -1 if dx > 0 else 0
    by = -1 if dy > 0 else 0
    return _swap_changes(cells, i, j, bx, by)


@jit(nogil=True)
def _vertex_roots(cells, vertex, segment, duration, buf, n):
    """When the segment from ``a + va t`` to ``b + vb t`` (relative to ``vertex``, ``(i,
    j)``; ``segment``: a :class:`Segment`) passes through the vertex:
    ``cross(a + va t, b + vb t) = 0`` with the vertex between the ends; those at which the
    walls crossed cannot change left out (:func:`_changes_count`)."""
    ax, ay, vax, vay = segment.ax, segment.ay, segment.vax, segment.vay
    bx, by, vbx, vby = segment.bx, segment.by, segment.vbx, segment.vby
    c0 = ax * by - ay * bx
    c1 = ax * vby - ay * vbx + vax * by - vay * bx
    c2 = vax * vby - vay * vbx
    na = np.hypot(ax, ay)
    nb = np.hypot(bx, by)
    nva = np.hypot(vax, vay)
    nvb = np.hypot(vbx, vby)
    if (
        abs(c0) <= _DEGENERATE * na * nb
        and abs(c1) <= _DEGENERATE * (na * nvb + nva * nb)
        and _parallel_by(c2, nva, nvb)
    ):
        # The vertex stays on the segment's line: which side of it each end is on changes
        # where an end passes the vertex's lines.
        buf, n = _linear_root(ax, vax, duration, buf, n)
        buf, n = _linear_root(ay, vay, duration, buf, n)
        buf, n = _linear_root(bx, vbx, duration, buf, n)
        buf, n = _linear_root(by, vby, duration, buf, n)
        return buf, n
    r0 = np.nan
    r1 = np.nan
    if c2 == 0.0:
        if c1 != 0.0:
            r0 = -c0 / c1
    else:
        disc = c1 * c1 - 4.0 * c2 * c0
        if disc < 0.0:
            # A touch (a double root) that rounding pushed below zero.
            if disc >= -1e-12 * (c1 * c1 + abs(4.0 * c2 * c0)):
                r0 = -c1 / (2.0 * c2)
        else:
            q = -0.5 * (c1 + np.sqrt(disc)) if c1 >= 0.0 else -0.5 * (c1 - np.sqrt(disc))
            if q != 0.0:
                r0 = q / c2
                r1 = c0 / q
            else:
                r0 = 0.0
    for r in (r0, r1):
        if not (r > 0.0 and r < duration):
            continue
        px = ax + vax * r
        py = ay + vay * r
        qx = bx + vbx * r
        qy = by + vby * r
        # Between the ends (with a margin: a spare candidate costs one evaluation).
        if px * qx + py * qy <= 1e-9 * (px * px + py * py + qx * qx + qy * qy) + 1e-12:
            if _changes_count(cells, vertex, (px, py), (qx, qy)):
                buf, n = _push(buf, n, r)
    return buf, n


@jit(nogil=True)
def _steady_heading(segment, duration):
    """The bit of :func:`_heading_bit` the segment keeps throughout ``(0, duration)``, or -1
    where it may come near an axis (:func:`_changes_count`'s tolerance, widened past
    rounding) or the duration is not finite."""
    ax, ay, vax, vay = segment.ax, segment.ay, segment.vax, segment.vay
    bx, by, vbx, vby = segment.bx, segment.by, segment.vbx, segment.vby
    dx0 = bx - ax
    dy0 = by - ay
    dx1 = dx0 + (vbx - vax) * duration
    dy1 = dy0 + (vby - vay) * duration
    # |dx| and |dy| are linear in t without a sign change: least and greatest at the ends.
    length = max(abs(dx0), abs(dx1)) + max(abs(dy0), abs(dy1))
    scale = abs(ax) + abs(ay) + abs(bx) + abs(by) + (abs(vax) + abs(vay) + abs(vbx) + abs(vby)) * duration
    slack = 4.0 * _ALONG_AXIS * length + 1e-12 * scale
    # Written so that a NaN (an infinite duration) fails every test.
    if dx0 * dx1 > 0.0 and dy0 * dy1 > 0.0 and min(abs(dx0), abs(dx1)) > slack and min(abs(dy0), abs(dy1)) > slack:
        return _heading_bit(dx0, dy0)
    return -1


@jit(nogil=True)
def _path_box(x, vx, y, vy, duration, reach):
    """The box an end moving from ``(x, y)`` at ``(vx, vy)`` for ``duration`` stays in,
    widened by ``reach``: ``(x_lo, x_hi, y_lo, y_hi)``."""
    x1 = x + vx * duration
    y1 = y + vy * duration
    return (min(x, x1) - reach, max(x, x1) + reach, min(y, y1) - reach, max(y, y1) + reach)


@jit(nogil=True, inline="always")
def _parallel_by(c2, nva, nvb):
    """Whether velocities of cross product ``c2`` and norms ``nva``, ``nvb`` are parallel,
    as :func:`_vertex_roots` tests it."""
    return abs(c2) <= _DEGENERATE * nva * nvb


@jit(nogil=True)
def _parallel(segment):
    """Whether the ends' velocities are parallel by :func:`_vertex_roots`' test (the same
    floats): only then can a vertex stay on the segment's line."""
    vax, vay, vbx, vby = segment.vax, segment.vay, segment.vbx, segment.vby
    return _parallel_by(vax * vby - vay * vbx, np.hypot(vax, vay), np.hypot(vbx, vby))


@jit(nogil=True)
def _may_stay_on_line(xs, ys, segment, duration):
    """Whether, the velocities parallel and the heading steady (:func:`_steady_heading`), a
    vertex of the hull of ``xs, ys`` off both ends' paths may still push a root by
    :func:`_vertex_roots`' branch for a vertex staying on the segment's line.

    That branch's roots are where an end passes one of the vertex's grid lines, say end
    ``a`` at ``x = 0`` (relative to the vertex). There the test bounds
    ``|a_y b_x| <= _DEGENERATE (|a_0| + |v_a| t)(|b_0| + |v_b| t)``, each factor at most
    the hull's size and twice the end's travel, ``(D + 2 P_a)(D + 2 P_b)``; off ``a``'s path
    ``|a_y| >= _NEAR_END_CELLS``, so ``|dx| = |b_x|`` is at most that bound over
    ``_NEAR_END_CELLS``, which a steady heading keeps above ``4 _ALONG_AXIS`` times the
    length: only where the bound (doubled, past rounding) is not below half of that."""
    vax, vay, vbx, vby = segment.vax, segment.vay, segment.vbx, segment.vby
    dx0 = segment.bx - segment.ax
    dy0 = segment.by - segment.ay
    dx1 = dx0 + (vbx - vax) * duration
    dy1 = dy0 + (vby - vay) * duration
    length = max(abs(dx0), abs(dx1)) + max(abs(dy0), abs(dy1))
    size = (xs.max() - xs.min()) + (ys.max() - ys.min()) + 1.0
    travel_a = (abs(vax) + abs(vay)) * duration
    travel_b = (abs(vbx) + abs(vby)) * duration
    bound = 2.0 * _DEGENERATE * (size + 2.0 * travel_a) * (size + 2.0 * travel_b) / _NEAR_END_CELLS
    return not bound <= 2.0 * _ALONG_AXIS * length


@jit(nogil=True)
def _maybe_on_line(ax, ay, bx, by):
    """Whether the vertex may lie on the line from ``a`` to ``b`` (relative to it) by
    :func:`_vertex_roots`' test (``|c0| <= _DEGENERATE |a| |b|``), bounding each norm by
    the sum of its coordinates' sizes (no root taken)."""
    c0 = ax * by - ay * bx
    return abs(c0) <= 2.0 * _DEGENERATE * (abs(ax) + abs(ay)) * (abs(bx) + abs(by))


@jit(nogil=True)
def candidates(grid, g0, gv, k0, kv, duration, prune):
    """Every instant in ``(0, duration)`` at which the walls crossed by the segment from
    ``g0 + gv t`` to ``k0 + kv t`` (grid units) may change, unsorted. ``prune``: pass over
    the vertices that cannot change the count (every run); false, solve every vertex of the
    swept region, the reference the pruned walk must equal."""
    h, row_ptr, cols, changing_headings = grid.h, grid.row_ptr, grid.cols, grid.changing_headings
    corner_ptr, corner_cols = grid.corner_ptr, grid.corner_cols
    cells = (grid.flat, h, grid.w)
    buf = np.empty(64)
    n = int(0)  # a value, not a literal (docs/architecture.md, the compiled cache)
    ax, ay, vax, vay = g0[0], g0[1], gv[0], gv[1]
    bx, by, vbx, vby = k0[0], k0[1], kv[0], kv[1]
    # The traversal's direction along each axis (and so its conventions) flips where the
    # segment is parallel to it.
    buf, n = _linear_root(bx - ax, vbx - vax, duration, buf, n)
    buf, n = _linear_root(by - ay, vby - vay, duration, buf, n)
    x_axis, y_axis = int(0), int(1)
    buf, n = _end_crossings(cells, (ax, vax, ay, vay), duration, x_axis, buf, n)
    buf, n = _end_crossings(cells, (ay, vay, ax, vax), duration, y_axis, buf, n)
    buf, n = _end_crossings(cells, (bx, vbx, by, vby), duration, x_axis, buf, n)
    buf, n = _end_crossings(cells, (by, vby, bx, vbx), duration, y_axis, buf, n)
    # The segment lies in the convex hull of the ends' first and last positions.
    xs = np.array([ax, ax + vax * duration, bx, bx + vbx * duration])
    ys = np.array([ay, ay + vay * duration, by, by + vby * duration])
    margin = 1e-6
    # Most mixed vertices lie along straight walls, where a segment sweeping across them
    # changes nothing (:func:`vertex_headings`): one with no bit for the segment's heading,
    # held throughout, pushes no root unless an end passes beside it or it may stay on
    # the segment's line, and is passed over unsolved. ``prune`` False solves every vertex
    # and finds each row's span on its own (what the pruned walk must equal).
    motion = Segment(ax, ay, vax, vay, bx, by, vbx, vby)
    heading = _steady_heading(motion, duration) if prune else -1
    bit = 1 << max(heading, 0)
    parallel = _parallel(motion)
    # Beside an end: _changes_count's reach, widened well past the rounding of an end's
    # position taken relative to a vertex.
    reach = _NEAR_END_CELLS + 1e-3 + 1e-12 * (abs(ax) + abs(ay) + abs(bx) + abs(by))
    box_a = _path_box(ax, vax, ay, vay, duration, reach)
    box_b = _path_box(bx, vbx, by, vby, duration, reach)
    j_lo = max(np.int64(np.ceil(ys.min() - margin)), 0)
    j_hi = min(np.int64(np.floor(ys.max() + margin)), h)
    # Between the corners' heights the same edges of the hull cross every row: found once
    # for each band of rows (a NaN, from an infinite duration, takes every row the long way,
    # as does the walk unpruned).
    finite = prune and np.isfinite(xs).all() and np.isfinite(ys).all()
    band = -1
    edges = np.empty((4, 4))
    count = 0
    # Off the ends' paths, only the corners with the heading's bit are solved: where nothing
    # else can push a root (no vertex can stay on the segment's line), they are walked
    # alone, from an index of their own, and the vertices beside an end's path from the
    # full one.
    corners_only = heading >= 0 and not (parallel and _may_stay_on_line(xs, ys, motion, duration))
    c_start = c_stop = 0
    for j in range(j_lo, j_hi + 1):
        start, stop = row_ptr[j], row_ptr[j + 1]
        if start == stop:
            continue
        y = float(j)
        beside_a = y >= box_a[2] and y <= box_a[3]
        beside_b = y >= box_b[2] and y <= box_b[3]
        if corners_only:
            c_start, c_stop = corner_ptr[heading, j], corner_ptr[heading, j + 1]
            if c_start == c_stop and not beside_a and not beside_b:
                continue
        near = not finite
        below = 0
        for i in range(4):
            if abs(ys[i] - y) <= margin:
                near = True
            if ys[i] < y:
                below |= 1 << i
        if near:
            lo, hi = _hull_span(ys, xs, y)
            # Rows within the margin of a corner's height: take the corner's span too.
            for i in range(4):
                if abs(ys[i] - y) <= margin:
                    lo = min(lo, xs[i])
                    hi = max(hi, xs[i])
        else:
            if below != band:
                band = below
                count = _edges_across(ys, xs, below, edges)
            lo, hi = _span_across(edges, count, y)
        if lo > hi:
            continue
        # The vertices visited: columns from ceil(lo - margin) to hi + margin.
        left = np.ceil(lo - margin)
        right = hi + margin
        if corners_only:
            for m in range(lower_bound(corner_cols, c_start, c_stop, left), c_stop):
                x = float(corner_cols[m])
                if x > right:
                    break
                if (beside_a and x >= box_a[0] and x <= box_a[1]) or (beside_b and x >= box_b[0] and x <= box_b[1]):
                    continue  # solved with the end's path below
                segment = Segment(ax - x, ay - y, vax, vay, bx - x, by - y, vbx, vby)
                buf, n = _vertex_roots(cells, (corner_cols[m], j), segment, duration, buf, n)
            if beside_a:
                for m in range(lower_bound(cols, start, stop, max(left, np.ceil(box_a[0]))), stop):
                    x = float(cols[m])
                    if x > right or x > box_a[1]:
                        break
                    segment = Segment(ax - x, ay - y, vax, vay, bx - x, by - y, vbx, vby)
                    buf, n = _vertex_roots(cells, (cols[m], j), segment, duration, buf, n)
            if beside_b:
                for m in range(lower_bound(cols, start, stop, max(left, np.ceil(box_b[0]))), stop):
                    x = float(cols[m])
                    if x > right or x > box_b[1]:
                        break
                    if beside_a and x >= box_a[0] and x <= box_a[1]:
                        continue  # solved with a's path
                    segment = Segment(ax - x, ay - y, vax, vay, bx - x, by - y, vbx, vby)
                    buf, n = _vertex_roots(cells, (cols[m], j), segment, duration, buf, n)
            continue
        for m in range(lower_bound(cols, start, stop, left), stop):
            x = float(cols[m])
            if x > right:
                break
            if (
                heading >= 0
                and not changing_headings[m] & bit
                and not (beside_a and x >= box_a[0] and x <= box_a[1])
                and not (beside_b and x >= box_b[0] and x <= box_b[1])
                and not (parallel and _maybe_on_line(ax - x, ay - y, bx - x, by - y))
            ):
                continue
            segment = Segment(ax - x, ay - y, vax, vay, bx - x, by - y, vbx, vby)
            buf, n = _vertex_roots(cells, (cols[m], j), segment, duration, buf, n)
    return buf[:n]


@jit(nogil=True)
def sweep(grid, motion, duration, eps, limit):
    """Rows ``(pair, t0, t1, walls)`` of every pair (:func:`netsim.world.sweep.sweep_walls`);
    the counts stop at ``limit + 1``."""
    origin_x, origin_y, res = grid.origin_x, grid.origin_y, grid.resolution_m
    cells = (grid.flat, grid.h, grid.w)
    p0, vp, q0, vq = motion.p0, motion.vp, motion.q0, motion.vq
    k = p0.shape[0]
    cap = 4 * k + 16
    pair = np.empty(cap, np.int64)
    t0 = np.empty(cap)
    t1 = np.empty(cap)
    walls = np.empty(cap, np.int64)
    rows = int(0)
    g0 = np.empty(2)
    gv = np.empty(2)
    k0 = np.empty(2)
    kv = np.empty(2)
    for s in range(k):
        g0[0] = on_grid(p0[s, 0], origin_x, res)
        g0[1] = on_grid(p0[s, 1], origin_y, res)
        gv[0] = vp[s, 0] / res
        gv[1] = vp[s, 1] / res
        k0[0] = on_grid(q0[s, 0], origin_x, res)
        k0[1] = on_grid(q0[s, 1], origin_y, res)
        kv[0] = vq[s, 0] / res
        kv[1] = vq[s, 1] / res
        d = duration[s]
        cand = np.sort(candidates(grid, g0, gv, k0, kv, d, True))
        m = cand.shape[0]
        prev = 0.0
        for c in range(m + 1):
            nxt = cand[c] if c < m else d
            if c < m and not nxt > prev:
                continue
            mid = 0.5 * (prev + nxt) if nxt > prev else prev
            u0 = on_grid(p0[s, 0] + vp[s, 0] * mid, origin_x, res)
            v0 = on_grid(p0[s, 1] + vp[s, 1] * mid, origin_y, res)
            u1 = on_grid(q0[s, 0] + vq[s, 0] * mid, origin_x, res)
            v1 = on_grid(q0[s, 1] + vq[s, 1] * mid, origin_y, res)
            count = walls_one(cells, u0, v0, u1, v1, eps, limit)
            if rows > 0 and pair[rows - 1] == s and walls[rows - 1] == count:
                t1[rows - 1] = nxt
            else:
                if rows == pair.shape[0]:
                    pair = grown(pair, rows)
                    walls = grown(walls, rows)
                    t0 = grown(t0, rows)
                    t1 = grown(t1, rows)
                pair[rows] = s
                t0[rows] = prev
                t1[rows] = nxt
                walls[rows] = count
                rows += 1
            prev = nxt
    return pair[:rows], t0[:rows], t1[:rows], walls[:rows]


@jit(nogil=True)
def link_chunks(grid, motion, duration, eps, radii):
    """The link's state over each chunk (the two robots of ``motion`` on straight legs,
    times from the chunk's start): up while ``|q - p| <= radii[walls]`` (``inf``: up whatever
    the distance; walls beyond the table, or a negative radius: down), its crossings
    :func:`netsim._kernels.disk_crossing_times`, a pair at rest in range by
    :func:`netsim._kernels.reaches`. Returns each chunk's state just after its start
    and the changes inside it ``(chunk, t, up)``, in order."""
    p0, vp, q0, vq = motion.p0, motion.vp, motion.q0, motion.vq
    limit = radii.shape[0] - 1
    pair, t0, t1, walls = sweep(grid, motion, duration, eps, limit)
    k = p0.shape[0]
    first = np.zeros(k, np.bool_)
    cap = 16
    c_pair = np.empty(cap, np.int64)
    c_t = np.empty(cap)
    c_up = np.empty(cap, np.bool_)
    n = int(0)
    cur = False
    started = False
    for r in range(pair.shape[0]):
        s = pair[r]
        if r == 0 or pair[r - 1] != s:
            started = False
        ta, tb, wr = t0[r], t1[r], walls[r]
        radius = radii[wr] if wr <= limit else -1.0
        # The row's pieces: (start, state) at most three (down, up, down).
        m = 1
        s0, u0 = ta, False
        s1, u1 = np.inf, False
        s2, u2 = np.inf, False
        if radius == np.inf:
            u0 = True
        elif radius >= 0.0:
            dx = q0[s, 0] - p0[s, 0]
            dy = q0[s, 1] - p0[s, 1]
            wx = vq[s, 0] - vp[s, 0]
            wy = vq[s, 1] - vp[s, 1]
            if wx * wx + wy * wy == 0.0:
                u0 = reaches(dx, dy, radius, 0.0)
            else:
                r_in, r_out = disk_crossing_times(0.0, dx, dy, wx, wy, radius)
                if r_in == r_in:  # not NaN: the path crosses the disk
                    u0 = r_in <= ta and (ta < r_out or (ta == tb and ta <= r_out))
                    if ta < r_in and r_in < tb:
                        s1, u1 = r_in, True
                        m = 2
                        if r_out < tb:
                            s2, u2 = r_out, False
                            m = 3
                    elif u0 and r_out < tb:
                        s1, u1 = r_out, False
                        m = 2
        for piece in range(m):
            if piece == 0:
                st, up = s0, u0
            elif piece == 1:
                st, up = s1, u1
            else:
                st, up = s2, u2
            if not started:
                first[s] = up
                cur = up
                started = True
            elif up != cur:
                if n == c_pair.shape[0]:
                    c_pair = grown(c_pair, n)
                    c_t = grown(c_t, n)
                    c_up = grown(c_up, n)
                c_pair[n] = s
                c_t[n] = st
                c_up[n] = up
                n += 1
                cur = up
    return first, c_pair[:n], c_t[:n], c_up[:n]


@jit(nogil=True)
def assemble(first, c_chunk, c_t, c_up, lo, count, before, boundary):
    """The changes of consecutive chunks (``count[row]`` chunks per row, in order; each
    chunk's state just after its start ``first``, its changes ``c_*`` from
    :func:`link_chunks`, times from its start ``lo``), in time order: ``(chunk, t, up)``,
    and each row's state after the start of its first chunk and at the end of its last.
    A chunk whose first state differs from the previous chunk's last changes at its start;
    so does a row's first chunk against ``before`` when ``boundary``."""
    rows = count.shape[0]
    cap = c_chunk.shape[0] + first.shape[0]
    out_chunk = np.empty(cap, np.int64)
    out_t = np.empty(cap)
    out_up = np.empty(cap, np.bool_)
    start_state = before.copy()
    end_state = before.copy()
    n = 0
    i = 0
    j = 0
    for row in range(rows):
        state = before[row]
        for c in range(count[row]):
            f = first[i]
            if c == 0:
                start_state[row] = f
            if f != state and (c > 0 or boundary):
                out_chunk[n] = i
                out_t[n] = lo[i]
                out_up[n] = f
                n += 1
            state = f
            while j < c_chunk.shape[0] and c_chunk[j] == i:
                out_chunk[n] = i
                out_t[n] = lo[i] + c_t[j]
                out_up[n] = c_up[j]
                n += 1
                state = c_up[j]
                j += 1
            i += 1
        end_state[row] = state
    return out_chunk[:n], out_t[:n], out_up[:n], start_state, end_state
