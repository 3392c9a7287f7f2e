"""The loops (kernels) of the engine core's hot paths: the range query of a transmission,
the grid of candidate pairs (range index, link solvers, snapshots) and the pairs in reach of
a sample; and the one rule of in range (:func:`reaches`) and the one torus wrap
(:func:`nearest_image`) that every part asks. Compiled or plain Python as
:func:`netsim.compiled.load` decides.

One item at a time: for the tens of candidates of one query, numpy's cost per operation,
not the arithmetic, is what a call costs. The tests compare them, plain and compiled, with
numpy oracles (tests/oracles/).
"""

from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np

from netsim.compiled import jit


class Motion(NamedTuple):
    """The robots' motion (:class:`netsim.state.RobotState`'s legs): where each leg started,
    its velocity and when, and the torus (``side_m``) when ``torus``. The one record every
    kernel that places robots reads, by field."""

    origin_m: np.ndarray
    velocity_mps: np.ndarray
    t0_s: np.ndarray
    torus: bool
    side_m: float


@jit(nogil=True, inline="always")
def lower_bound(a, lo, hi, x):
    """The first position in ascending ``a[lo:hi]`` whose item is not below ``x`` (``hi``
    if none, and for a NaN ``x``, which sorts last as in numpy): ``lo +
    np.searchsorted(a[lo:hi], x)``, without making the view."""
    while lo < hi:
        mid = (lo + hi) >> 1
        if not a[mid] >= x:
            lo = mid + 1
        else:
            hi = mid
    return lo


@jit(nogil=True)
def position(origin_m, velocity_mps, t0_s, i, t, torus, side_m):
    """Robot ``i``'s position at ``t`` (:meth:`netsim.state.RobotState.position`)."""
    dt = t - t0_s[i]
    x = origin_m[i, 0] + velocity_mps[i, 0] * dt
    y = origin_m[i, 1] + velocity_mps[i, 1] * dt
    if torus:
        x, y = fold(x, side_m), fold(y, side_m)
    return x, y


@jit(nogil=True)
def fold(x, side_m):
    """A coordinate on a torus of side ``side_m``, in ``[0, side_m)``: ``x mod side``, and 0
    where that rounds up to the side itself (a tiny negative ``x``), so that a point has one
    representation. One expression for a number or an array of them
    (:func:`netsim.geometry.in_box`)."""
    r = x % side_m
    return r - side_m * (r >= side_m)


@jit(nogil=True)
def positions(origin_m, velocity_mps, t0_s, rows, t, torus, side_m, out):
    """Robots ``rows``' positions at ``t`` into ``out``, shape ``(k, 2)``: :func:`position`
    row by row (:meth:`netsim.state.RobotState.positions_at`). Returns the first ``k`` whose
    row names no robot (-1: none); nothing is written from there."""
    n = t0_s.shape[0]
    for k in range(rows.size):
        i = rows[k]
        if i < -n or i >= n:
            return k
        x, y = position(origin_m, velocity_mps, t0_s, i, t, torus, side_m)
        out[k, 0] = x
        out[k, 1] = y
    return -1


@jit(nogil=True, inline="always")
def travel(odometer_m, speed_mps, t0_s, i, t):
    """Robot ``i``'s path length at ``t`` on its current leg: its odometer (the legs before)
    plus its speed (the state's ``speed_mps``, numpy's ``abs`` of its velocity) times the
    time on the leg. The shadowing's clock runs on it (``netsim.radio._kernels.pair_clock``)."""
    return odometer_m[i] + speed_mps[i] * (t - t0_s[i])


@jit(nogil=True)
def travels(odometer_m, speed_mps, t0_s, rows, t, out):
    """:func:`travel` of robots ``rows`` at ``t`` into ``out``
    (:meth:`netsim.state.RobotState.travelled_m`). Returns the first ``k`` whose row names
    no robot (-1: none); nothing is written from there."""
    n = t0_s.shape[0]
    for k in range(rows.size):
        i = rows[k]
        if i < -n or i >= n:
            return k
        out[k] = travel(odometer_m, speed_mps, t0_s, i, t)
    return -1


@jit(nogil=True, inline="always")
def pair_total(travel_a_m, travel_b_m):
    """A pair's travel from its two robots' path lengths: their sum, the clock its
    shadowing runs on (``netsim.radio._kernels.pair_clock``)."""
    return travel_b_m + travel_a_m


@jit(nogil=True)
def pair_totals(travel_m, a, b, out):
    """:func:`pair_total` of each pair ``(a[m], b[m])`` of robots whose path lengths are
    ``travel_m``, into ``out``."""
    for m in range(a.shape[0]):
        out[m] = pair_total(travel_m[a[m]], travel_m[b[m]])


@jit(nogil=True, inline="always")
def pair_travel(odometer_m, speed_mps, t0_s, a, b, t):
    """A pair's travel at ``t``: :func:`pair_total` of its two robots' :func:`travel`."""
    return pair_total(travel(odometer_m, speed_mps, t0_s, a, t), travel(odometer_m, speed_mps, t0_s, b, t))


@jit(nogil=True)
def pair_travels(odometer_m, speed_mps, t0_s, a, b, t, out):
    """:func:`pair_travel` of each pair ``(a[m], b[m])`` at ``t`` into ``out``
    (:meth:`netsim.state.RobotState.pair_travelled_m`). Returns the first ``m`` whose pair
    names no robot (-1: none); nothing is written from there."""
    n = t0_s.shape[0]
    for m in range(a.shape[0]):
        if a[m] < -n or a[m] >= n or b[m] < -n or b[m] >= n:
            return m
        out[m] = pair_travel(odometer_m, speed_mps, t0_s, a[m], b[m], t)
    return -1


@jit(nogil=True)
def offset(origin_m, velocity_mps, t0_s, j, t, x, y, torus, side_m):
    """Robot ``j``'s position at ``t`` (:func:`position`, on its unfolded leg) minus ``(x,
    y)``, the nearest image on a torus: the range query's arithmetic."""
    xj, yj = position(origin_m, velocity_mps, t0_s, j, t, False, side_m)
    dx, dy = xj - x, yj - y
    if torus:
        return nearest_image(dx, dy, side_m)
    return dx, dy


@jit(nogil=True)
def nearest_image(dx, dy, box):
    """The offset ``(dx, dy)`` folded to its nearest image on a torus of side ``box > 0``
    (unchanged on the plane, ``box = 0``): the one torus wrap of the engine."""
    if box > 0.0:
        dx -= box * np.rint(dx / box)
        dy -= box * np.rint(dy / box)
    return dx, dy


@jit(nogil=True)
def nearest_images(d, box):
    """:func:`nearest_image` of every row of the offsets ``d`` (``(m, 2)``), as a new array
    (:func:`netsim.geometry.wrap`)."""
    out = np.empty((d.shape[0], 2))
    for k in range(d.shape[0]):
        out[k, 0], out[k, 1] = nearest_image(d[k, 0], d[k, 1], box)
    return out


@jit(nogil=True)
def within(cand, motion, i, t, r):
    """The candidates ``cand`` within ``r`` of robot ``i`` at ``t``, and their distances
    (:meth:`netsim.radio.spatial.RangeIndex.within` over a candidate list). ``motion``: the
    robots' :class:`Motion`."""
    mo = Motion(*motion)
    origin_m, velocity_mps, t0_s, torus, side_m = mo.origin_m, mo.velocity_mps, mo.t0_s, mo.torus, mo.side_m
    x, y = position(origin_m, velocity_mps, t0_s, i, t, torus, side_m)
    ids = np.empty(len(cand), dtype=np.int64)
    dist = np.empty(len(cand))
    k = 0
    for j in cand:
        dx, dy = offset(origin_m, velocity_mps, t0_s, j, t, x, y, torus, side_m)
        if reaches(dx, dy, r, 0.0):
            ids[k] = j
            dist[k] = length_m(dx, dy, 0.0)  # the offset is the nearest image already
            k += 1
    return ids[:k], dist[:k]


@jit(nogil=True)
def points_on_legs(origin_m, velocity_mps, t0_s, rows, times_s, out):
    """Where leg ``rows[k]`` (its origin, velocity and start) puts its robot at
    ``times_s[k]``, unfolded, into ``out``: :func:`position` with a time per row (a leg
    table's points, :func:`netsim.trajectory.points_on_legs`)."""
    for k in range(rows.size):
        x, y = position(origin_m, velocity_mps, t0_s, rows[k], times_s[k], False, 0.0)
        out[k, 0] = x
        out[k, 1] = y


@jit(nogil=True)
def legs_at(first, end, leg_t, robots, times, out):
    """For each query, the last leg of ``robots[k]`` (its legs ``first[r]`` to ``end[r]``, in
    time order) that starts at or before ``times[k]``; its first leg when none does."""
    for k in range(robots.shape[0]):
        r = robots[k]
        lo, hi = first[r], end[r]
        while lo < hi:
            mid = (lo + hi) // 2
            if leg_t[mid] <= times[k]:
                lo = mid + 1
            else:
                hi = mid
        out[k] = max(lo - 1, first[r])


@jit(nogil=True)
def pair_reach(motion, i, j, t, r):
    """Whether robot ``j`` is within ``r`` of robot ``i`` at ``t``, and their distance, as
    :func:`within` measures a candidate (a unicast's one receiver)."""
    mo = Motion(*motion)
    origin_m, velocity_mps, t0_s, torus, side_m = mo.origin_m, mo.velocity_mps, mo.t0_s, mo.torus, mo.side_m
    x, y = position(origin_m, velocity_mps, t0_s, i, t, torus, side_m)
    dx, dy = offset(origin_m, velocity_mps, t0_s, j, t, x, y, torus, side_m)
    return reaches(dx, dy, r, 0.0), length_m(dx, dy, 0.0)  # the offset is the nearest image already


@jit(nogil=True)
def within_alive(cand, lo, hi, motion, i, t, r, alive):
    """The candidates ``cand[lo:hi]`` within ``r`` of robot ``i`` at ``t`` (as
    :func:`within`, without the distances), and whether all of them are ``alive``
    (:meth:`netsim.radio.spatial.RangeIndex.within_alive`). The span is passed, not a slice:
    making the view would cost the caller more than the loop."""
    mo = Motion(*motion)
    origin_m, velocity_mps, t0_s, torus, side_m = mo.origin_m, mo.velocity_mps, mo.t0_s, mo.torus, mo.side_m
    x, y = position(origin_m, velocity_mps, t0_s, i, t, torus, side_m)
    ids = np.empty(hi - lo, dtype=np.int64)
    k = 0
    all_alive = True
    for j in cand[lo:hi]:
        dx, dy = offset(origin_m, velocity_mps, t0_s, j, t, x, y, torus, side_m)
        if reaches(dx, dy, r, 0.0):
            ids[k] = j
            k += 1
            if not alive[j]:
                all_alive = False
    return ids[:k], all_alive


@jit(nogil=True)
def restarted(deadline_s, armed_s, i, at_s):
    """Restart timer ``i`` to run out at ``at_s``: its deadline written; whether an event
    must be armed for it (the new deadline comes before the event armed at ``armed_s[i]``,
    or none is). The one rule of a restart (:class:`netsim.timers.DeadlineTimers`, and
    the clustering's rule 3 inside its compiled loop)."""
    deadline_s[i] = at_s
    return at_s < armed_s[i]


@jit(nogil=True)
def restarts(deadline_s, armed_s, ids, at_s, to_arm):
    """:func:`restarted` of timer ``ids[k]`` to ``at_s[k]``, for each ``k`` in order; the
    ``k`` whose events must be armed into ``to_arm``, their count returned."""
    m = 0
    for k in range(ids.shape[0]):
        if restarted(deadline_s, armed_s, ids[k], at_s[k]):
            to_arm[m] = k
            m += 1
    return m


@jit(nogil=True)
def count_each(counts, ids):
    """``counts[ids] += 1``, an id named twice counted twice (the channel's and the medium's
    per-robot reception and drop counts): for the tens of receivers of one delivery, a loop
    costs less than numpy's fancy index."""
    for j in ids:
        counts[j] += 1


@jit(nogil=True)
def all_set(mask, ids):
    """``mask[ids].all()`` (whether every receiver is alive), without the temporary array."""
    for j in ids:
        if not mask[j]:
            return False
    return True


@jit(nogil=True)
def _cell_of(v, lo, size, cells):
    # The map's clamped_cell in effect (below the grid is cell 0 either way), kept here: a
    # map kernel imported into this module would compile in every run that has no map.
    c = int((v - lo) / size)
    return min(max(c, 0), cells - 1)


@jit(nogil=True)
def _extent(pos):
    # The positions' smallest and largest x and y (zeros without positions): numpy's
    # min and max, without the machinery numba compiles for them.
    if pos.shape[0] == 0:
        return 0.0, 0.0, 0.0, 0.0
    lo_x = hi_x = pos[0, 0]
    lo_y = hi_y = pos[0, 1]
    for i in range(1, pos.shape[0]):
        x, y = pos[i, 0], pos[i, 1]
        if x < lo_x:
            lo_x = x
        if x > hi_x:
            hi_x = x
        if y < lo_y:
            lo_y = y
        if y > hi_y:
            hi_y = y
    return lo_x, lo_y, hi_x, hi_y


@jit(nogil=True)
def grid(pos, r, box):
    """The grid of :func:`near_pairs` over positions ``pos`` (in ``[0, box)`` on a torus of
    side ``box > 0``): cells no smaller than ``r``, ``cells_x`` by ``cells_y``; each
    position's cell (row-major), and the positions by cell, ascending within each:
    ``members[start[c]:start[c + 1]]`` are cell ``c``'s.

    Cells a little wider than ``r``, as long as there are at most ``16 n + 64`` of them;
    where that would take more (a few robots far from the others, a line of robots, a
    range of zero), cells twice as wide, and again, until it does not: every pair within
    ``r`` is still in the same or adjacent cells, and the grid's cost stays in proportion
    to the robots."""
    n = pos.shape[0]
    most = 16.0 * n + 64.0
    # Cells a little wider than r: two points within r are in the same or adjacent cells
    # whatever the rounding of their cell numbers.
    wide = r * (1.0 + 1e-6)
    if box > 0.0:
        lo_x = lo_y = 0.0
        across = box // wide if wide > 0.0 else most
        cells_x = cells_y = max(int(min(across, math.floor(math.sqrt(most)))), 1)
        size_x = size_y = box / cells_x
    else:
        lo_x, lo_y, hi_x, hi_y = _extent(pos)
        span_x, span_y = hi_x - lo_x, hi_y - lo_y
        if not wide > 0.0:
            wide = max(span_x, span_y, 1.0) / most
        while (span_x // wide + 1.0) * (span_y // wide + 1.0) > most:
            wide *= 2.0
        cells_x, cells_y = int(span_x // wide) + 1, int(span_y // wide) + 1
        size_x = size_y = wide
    # On a torus of fewer than three cells a side, neighbouring cells repeat: one cell.
    if box > 0.0 and (cells_x < 3 or cells_y < 3):
        cells_x = cells_y = 1
        size_x = size_y = box
    n_cells = cells_x * cells_y
    cell = np.empty(n, np.int64)
    for i in range(n):
        cell[i] = _cell_of(pos[i, 1], lo_y, size_y, cells_y) * cells_x + _cell_of(pos[i, 0], lo_x, size_x, cells_x)
    start = np.zeros(n_cells + 1, np.int64)
    for i in range(n):
        start[cell[i] + 1] += 1
    for c in range(n_cells):
        start[c + 1] += start[c]
    fill = start[:-1].copy()
    members = np.empty(n, np.int64)
    for i in range(n):
        members[fill[cell[i]]] = i
        fill[cell[i]] += 1
    return cells_x, cells_y, cell, start, members


@jit(nogil=True)
def near_pairs(pos, r, box):
    """Pairs ``(i, j)``, ``i < j``, of positions within ``r`` of each other (on a torus of
    side ``box`` when ``box > 0``), by a grid of cells no smaller than ``r`` (:func:`grid`): what
    ``cKDTree.query_pairs(r)`` finds, and possibly pairs further apart than ``r`` by a
    relative 1e-9 (a distance at the bound rounds either way; callers filter exactly and
    ask with a slack, so such pairs change nothing). Rows by robot ``i``, then its cells row by
    row, then the other robot's id in the cell: a fixed order (the link solvers emit in it)."""
    n = pos.shape[0]
    r2 = r * r * (1.0 + 1e-9)
    cells_x, cells_y, cell, start, members = grid(pos, r, box)
    n_cells = cells_x * cells_y
    wrap = box > 0.0 and n_cells > 1
    # The positions in cell order: a row of three cells' candidates contiguous in memory.
    px, py = np.empty(n), np.empty(n)
    for m in range(n):
        px[m], py[m] = pos[members[m], 0], pos[members[m], 1]
    out_i = np.empty(16 * n + 16, np.int64)
    out_j = np.empty(16 * n + 16, np.int64)
    spans = np.empty((6, 2), np.int64)
    k = 0
    for i in range(n):
        n_spans = _row_spans(cell[i] // cells_x, cell[i] % cells_x, cells_x, cells_y, wrap, spans)
        xi, yi = pos[i, 0], pos[i, 1]
        for sp in range(n_spans):
            lo, hi = start[spans[sp, 0]], start[spans[sp, 1]]
            if len(out_i) - k < hi - lo:
                out_i = grown(out_i, len(out_i) + hi - lo)
                out_j = grown(out_j, len(out_j) + hi - lo)
            for m in range(lo, hi):
                j = members[m]
                ddx, ddy = nearest_image(px[m] - xi, py[m] - yi, box)
                # No branch on the outcome (a coin toss for the processor): every candidate
                # is written, counted if it is a pair.
                out_i[k] = i
                out_j[k] = j
                k += (ddx * ddx + ddy * ddy <= r2) & (j > i)
    pairs = np.empty((k, 2), np.int64)
    for m in range(k):  # not a copy into a slice (docs/architecture.md, the compiled cache)
        pairs[m, 0] = out_i[m]
        pairs[m, 1] = out_j[m]
    return pairs


@jit(nogil=True)
def neighbour_lists(pairs, n):
    """Both directions of the ``pairs`` as lists per robot, ascending: ``(indptr,
    indices)`` with robot ``i``'s neighbours at ``indices[indptr[i]:indptr[i + 1]]``
    (what :meth:`netsim.radio.spatial.RangeIndex._build` makes with a lexsort)."""
    indptr = np.zeros(n + 1, np.int64)
    for k in range(pairs.shape[0]):
        indptr[pairs[k, 0] + 1] += 1
        indptr[pairs[k, 1] + 1] += 1
    for i in range(n):
        indptr[i + 1] += indptr[i]
    fill = indptr[:-1].copy()
    indices = np.empty(indptr[n], np.int64)
    for k in range(pairs.shape[0]):
        a, b = pairs[k, 0], pairs[k, 1]
        indices[fill[a]] = b
        fill[a] += 1
        indices[fill[b]] = a
        fill[b] += 1
    for i in range(n):
        sort_range(indices, indptr[i], indptr[i + 1])
    return indptr, indices


@jit(nogil=True)
def _row_spans(cy, cx, cells_x, cells_y, wrap, spans):
    """The cells next to cell ``(cy, cx)`` (itself included), as at most six spans
    ``[lo, hi)`` of consecutive (row-major) cell numbers in ``spans``; how many. In the
    order of ``dy, dx = -1, 0, 1`` (a row's wrapped cell first on its left edge)."""
    if cells_x * cells_y == 1:
        spans[0, 0], spans[0, 1] = 0, 1
        return 1
    k = 0
    for dy in range(-1, 2):
        ny = cy + dy
        if wrap:
            ny %= cells_y
        elif ny < 0 or ny >= cells_y:
            continue
        row = ny * cells_x
        if not wrap:
            spans[k, 0], spans[k, 1] = row + max(cx - 1, 0), row + min(cx + 1, cells_x - 1) + 1
            k += 1
        elif cx == 0:
            spans[k, 0], spans[k, 1] = row + cells_x - 1, row + cells_x
            spans[k + 1, 0], spans[k + 1, 1] = row, row + 2
            k += 2
        elif cx == cells_x - 1:
            spans[k, 0], spans[k, 1] = row + cx - 1, row + cx + 1
            spans[k + 1, 0], spans[k + 1, 1] = row, row + 1
            k += 2
        else:
            spans[k, 0], spans[k, 1] = row + cx - 1, row + cx + 2
            k += 1
    return k


@jit(nogil=True)
def sort_range(a, lo, hi):
    """Sort ``a[lo:hi]`` in place (numbers, no NaN): by insertion for the tens of ids of one
    robot, by a heap beyond. numba's own sort costs more to call than this costs to run on
    a robot's ids, and several times more to compile."""
    if hi - lo <= 32:
        for i in range(lo + 1, hi):
            v = a[i]
            j = i
            while j > lo and a[j - 1] > v:
                a[j] = a[j - 1]
                j -= 1
            a[j] = v
        return
    n = hi - lo
    for root in range(n // 2 - 1, -1, -1):
        _sift_down(a, lo, root, n)
    for end in range(n - 1, 0, -1):
        a[lo], a[lo + end] = a[lo + end], a[lo]
        # int(0), not 0: numba compiles a kernel once more for each literal argument.
        _sift_down(a, lo, int(0), end)


@jit(nogil=True)
def _sift_down(a, lo, root, n):
    # The heap of sort_range: a[lo + root]'s subtree among the first n, made a max-heap.
    while True:
        child = 2 * root + 1
        if child >= n:
            return
        if child + 1 < n and a[lo + child] < a[lo + child + 1]:
            child += 1
        if not a[lo + root] < a[lo + child]:
            return
        a[lo + root], a[lo + child] = a[lo + child], a[lo + root]
        root = child


@jit(nogil=True)
def grown(a, extra):
    """A copy of ``a`` with room for ``extra`` more items after it (left unset): what
    ``np.concatenate`` with an empty array gives, copied element by element
    (docs/architecture.md, the compiled cache)."""
    out = np.empty(len(a) + extra, a.dtype)
    for k in range(len(a)):
        out[k] = a[k]
    return out


@jit(nogil=True)
def _dot(x0, x1, y0, y1):
    # numpy's einsum over a row of two: a sum started at zero, term by term.
    s = 0.0
    s += x0 * y0
    s += x1 * y1
    return s


@jit(nogil=True)
def disk_crossing_times(origin, dx, dy, wx, wy, radius):
    """The instants the path ``(dx, dy) + (wx, wy) (t - origin)`` enters and leaves the disk
    of ``radius``: NaN when it does not cross it (at rest, or passing by). The link solvers'
    one rule of when a pair on straight legs comes into range and leaves it
    (:mod:`netsim.links._kernels`, :func:`netsim.world._sweep_kernels.link_chunks`)."""
    a = _dot(wx, wy, wx, wy)
    b = 2.0 * _dot(dx, dy, wx, wy)
    c = _dot(dx, dy, dx, dy) - radius * radius
    disc = b * b - 4.0 * a * c
    if not (a > 0 and disc > 0):
        return np.nan, np.nan
    # The numerically stable pair of roots: q / A and C / q.
    q = -0.5 * (b + math.copysign(math.sqrt(disc), b))
    r1 = q / a
    r2 = c / q if q != 0 else -r1
    return origin + min(r1, r2), origin + max(r1, r2)


@jit(nogil=True)
def disk_exits(offset, radius, move, safety, out):
    """Row by row, the largest ``s`` in [0, 1] with ``|offset + s move| <= radius``, times
    ``safety`` (a hair short of the circle, against rounding), into ``out``: when a straight
    step from inside a disk leaves it, by :func:`disk_crossing_times`. A row that does not
    move, or whose disk is unbounded, may take its whole step (times ``safety``, as every
    row); one whose path misses the circle or only touches it, none."""
    for k in range(out.shape[0]):
        wx, wy = move[k, 0], move[k, 1]
        if _dot(wx, wy, wx, wy) > 0 and radius[k] < np.inf:
            leave = disk_crossing_times(0.0, offset[k, 0], offset[k, 1], wx, wy, radius[k])[1]
            s = leave if leave == leave else 0.0
        else:
            s = 1.0
        out[k] = min(max(s * safety, 0.0), 1.0)


@jit(nogil=True)
def reaches(ddx, ddy, lim, box):
    """Whether a robot at ``(ddx, ddy)`` from another (the nearest image on a torus of side
    ``box > 0``) is within ``lim`` of it: ``hypot(ddx, ddy) <= lim``, the one rule of "in
    range" (the range query, the link solvers' state, the pairs in range, who reaches whom).
    The square decides all but a distance within a relative 1e-6 of the range, where
    ``np.hypot`` (correctly rounded or nearly) decides: the same answer, mostly without the
    root."""
    ddx, ddy, d2, sure, unsure = _reach_band(ddx, ddy, lim, box)
    hit = d2 <= sure
    if (d2 > sure) & (d2 <= unsure):
        hit = length_m(ddx, ddy, 0.0) <= lim  # _reach_band took the nearest image
    return hit


@jit(nogil=True, inline="always")
def length_m(dx, dy, box):
    """The length of the offset ``(dx, dy)``: ``np.hypot`` of its nearest image on a torus
    of side ``box > 0`` (:func:`nearest_image`), of itself on the plane (``box = 0``, also
    for an offset already folded). The engine's one rule of a length: a link's, a robot's
    distance to a disk's centre or a grid's cell, the clustering's nearest leader."""
    dx, dy = nearest_image(dx, dy, box)
    return np.hypot(dx, dy)


@jit(nogil=True)
def distances(p, q, box, out):
    """The length of each segment from ``p[k]`` to ``q[k]`` into ``out``: ``np.hypot`` of the
    nearest image on a torus of side ``box > 0`` (:func:`nearest_image`), the plane's
    straight line for ``box = 0``: a link's length as :func:`pairs_in_range` and
    :func:`within` measure the pairs they find, for pairs already known."""
    for k in range(out.shape[0]):
        out[k] = length_m(p[k, 0] - q[k, 0], p[k, 1] - q[k, 1], box)


@jit(nogil=True)
def beyond_disks(points, centres, radius, out):
    """Whether each point lies farther than ``radius`` from its centre (``hypot > r``), into
    ``out``: by :func:`reaches` for a radius of 0 or more; a negative radius has every point
    beyond it, and a NaN anywhere none, as the comparison has."""
    for k in range(out.shape[0]):
        dx = points[k, 0] - centres[k, 0]
        dy = points[k, 1] - centres[k, 1]
        r = radius[k]
        if r >= 0.0 and dx == dx and dy == dy:
            out[k] = not reaches(dx, dy, r, 0.0)
        else:
            out[k] = length_m(dx, dy, 0.0) > r


@jit(nogil=True, inline="always")
def _reach_band(ddx, ddy, lim, box):
    """:func:`reaches`'s arithmetic: the offset (folded to the nearest image on a torus),
    its square, and the squares up to which it surely reaches and beyond which it surely
    does not."""
    ddx, ddy = nearest_image(ddx, ddy, box)
    return ddx, ddy, ddx * ddx + ddy * ddy, lim * lim * (1.0 - 1e-6), lim * lim * (1.0 + 1e-6)


@jit(nogil=True)
def reaches_robot(pos, ranges, box, a, m):
    """Whether robot ``m``'s transmissions reach robot ``a`` (positions ``pos``, ranges
    ``ranges``): :func:`reach_keys_in_lists`'s test of one candidate."""
    return reaches(pos[a, 0] - pos[m, 0], pos[a, 1] - pos[m, 1], ranges[m], box)


@jit(nogil=True)
def in_range(pos, a, b, radius, box):
    """Whether robots ``a[k]`` and ``b[k]`` at positions ``pos`` are within ``radius[k]`` of
    each other (:func:`reaches`, the nearest image on a torus of side ``box > 0``): the
    state a link solver sets at the start and at a jump, a connected placement's links, a
    member within its leader's range, the local plan's force sources."""
    n = len(a)
    out = np.empty(n, np.bool_)
    for k in range(n):
        out[k] = reaches(pos[a[k], 0] - pos[b[k], 0], pos[a[k], 1] - pos[b[k], 1], radius[k], box)
    return out


@jit(nogil=True, inline="always")
def link_range(r_a, r_b):
    """A pair's range: the smaller of its robots' ranges (a link needs both to hear each
    other)."""
    return min(r_a, r_b)


@jit(nogil=True)
def link_ranges(ranges, a, b, out):
    """:func:`link_range` of each pair ``(a[m], b[m])`` into ``out``."""
    for m in range(a.shape[0]):
        out[m] = link_range(ranges[a[m]], ranges[b[m]])


@jit(nogil=True)
def pairs_in_range(pos, i, j, ranges, box, directed):
    """Of the candidate pairs ``(i[k], j[k])`` (:func:`near_pairs`), those in range
    (:func:`reaches`) at positions ``pos`` (the nearest image on a torus of side ``box >
    0``), as ``(a, b, distance)``, unsorted. Undirected: ``(i, j)`` within ``min(r_i, r_j)``
    (both hear each other). Directed: ``(i, j)`` within ``r_i`` (i reaches j) and ``(j, i)``
    within ``r_j``. The distance is ``np.hypot`` of the nearest image."""
    m = len(i)
    a = np.empty(2 * m, np.int64)
    b = np.empty(2 * m, np.int64)
    dist = np.empty(2 * m)
    k = 0
    for q in range(m):
        p, o = i[q], j[q]
        dx, dy = nearest_image(pos[p, 0] - pos[o, 0], pos[p, 1] - pos[o, 1], box)
        if directed:
            forward = reaches(dx, dy, ranges[p], 0.0)
            back = reaches(dx, dy, ranges[o], 0.0)
        else:
            forward = reaches(dx, dy, link_range(ranges[p], ranges[o]), 0.0)
            back = False
        if forward or back:
            d = length_m(dx, dy, 0.0)  # the offset is the nearest image already
            if forward:
                a[k], b[k], dist[k] = p, o, d
                k += 1
            if back:
                a[k], b[k], dist[k] = o, p, d
                k += 1
    return a[:k], b[:k], dist[:k]


@jit(nogil=True)
def senders_in_list(pos, ranges, box, indptr, indices, a, out):
    """The robots of ``a``'s neighbour list (``indices[indptr[a]:indptr[a + 1]]``,
    ascending) whose transmissions reach ``a`` (:func:`reaches_robot`), ascending, in
    ``out`` (room for the list); how many.

    By the square alone, without a branch on each outcome (a coin toss for the processor,
    and a branch keeps the compiler from vectorising): every candidate is written, counted
    if surely in reach. Only a list with a candidate within the band where the square does
    not decide is gone through again, each candidate by :func:`reaches_robot`."""
    ax, ay = pos[a, 0], pos[a, 1]
    h = 0
    unsure = False
    for t in range(indptr[a], indptr[a + 1]):
        m = indices[t]
        _, _, d2, below, above = _reach_band(ax - pos[m, 0], ay - pos[m, 1], ranges[m], box)
        out[h] = m
        h += d2 <= below
        unsure |= (d2 > below) & (d2 <= above)
    if unsure:
        h = 0
        for t in range(indptr[a], indptr[a + 1]):
            m = indices[t]
            if reaches_robot(pos, ranges, box, a, m):
                out[h] = m
                h += 1
    return h


@jit(nogil=True)
def reach_keys_in_lists(pos, ranges, box, indptr, indices):
    """``receiver * n + sender`` for every ordered pair where the sender reaches the
    receiver (:func:`senders_in_list`), ascending, each receiver's candidates from neighbour
    lists (ascending, holding every robot within reach: :func:`netsim.topology.reach_lists`)."""
    n = pos.shape[0]
    keys = np.empty(len(indices), np.int64)
    senders = np.empty(longest_list(indptr), np.int64)
    q = 0
    for a in range(n):
        base = a * n
        for u in range(senders_in_list(pos, ranges, box, indptr, indices, a, senders)):
            keys[q] = base + senders[u]
            q += 1
    return keys[:q]


@jit(nogil=True)
def longest_list(indptr):
    """The length of the longest of the lists ``indptr`` delimits."""
    longest = 0
    for a in range(len(indptr) - 1):
        longest = max(longest, indptr[a + 1] - indptr[a])
    return longest


@jit(nogil=True)
def hops_in_lists(pos, ranges, box, indptr, indices, source, towards, target):
    """Hops from ``source`` to every robot over the directed links where a sender reaches a
    receiver (``towards``: from every robot to ``source``), ``inf`` where there is no path: a
    breadth-first search over the neighbour lists of :meth:`netsim.radio.spatial.RangeIndex.lists`,
    each link decided as :func:`reach_keys_in_lists` decides it. ``target`` >= 0: the search
    ends once it has reached ``target``, whose hops are then final (of the others, only
    those fewer; the rest may be left ``inf``)."""
    n = pos.shape[0]
    hops = np.full(n, np.inf)
    hops[source] = 0.0
    frontier = np.empty(n, np.int64)
    reached = np.empty(n, np.int64)
    frontier[0] = source
    size, level = 1, 0.0
    while size:
        level += 1.0
        found = 0
        for q in range(size):
            u = frontier[q]
            for t in range(indptr[u], indptr[u + 1]):
                v = indices[t]
                if hops[v] != np.inf:
                    continue
                # The receiver's position minus the sender's, and the sender's range.
                if towards:
                    ddx, ddy, lim = pos[u, 0] - pos[v, 0], pos[u, 1] - pos[v, 1], ranges[v]
                else:
                    ddx, ddy, lim = pos[v, 0] - pos[u, 0], pos[v, 1] - pos[u, 1], ranges[u]
                if reaches(ddx, ddy, lim, box):
                    hops[v] = level
                    if v == target:
                        return hops
                    reached[found] = v
                    found += 1
        frontier, reached = reached, frontier
        size = found
    return hops


@jit(nogil=True, inline="always")
def shadow_correlation(travel_m, decorrelation_m):
    """Gudmundson's correlation of a pair's shadowing across a pair travel ``travel_m``
    (none counts as 0): ``exp(-travel / decorrelation)``. The radio's shadowing steps by it
    (``netsim.radio._kernels.moved_on``) and the plans' fade rule bounds its change by it
    (``netsim.mobility._fade_kernels``)."""
    return math.exp(-max(travel_m, 0.0) / decorrelation_m)


@jit(nogil=True, inline="always")
def innovation_scale(rho):
    """``sqrt(1 - rho^2)``: how much of the shadowing's standard deviation a step of
    correlation ``rho`` (:func:`shadow_correlation`, in [0, 1]) draws anew, the rest carried
    by ``rho``. The channel's step scales its innovation by it
    (``netsim.radio._kernels.moved_on``) and the fade rule bounds the change with it
    (``netsim.mobility._fade_kernels``)."""
    return math.sqrt(1.0 - rho * rho)


@jit(nogil=True, inline="always")
def shadow_renewal(travel_m, decorrelation_m):
    """``1 - shadow_correlation^2``, the share of the shadowing's variance that a pair travel
    ``travel_m`` renews, to full precision where the travel is short (where ``1 - rho^2``
    of a correlation rounded near 1 is not)."""
    return -math.expm1(-2.0 * max(travel_m, 0.0) / decorrelation_m)


@jit(nogil=True)
def shadow_steps(travel_m, decorrelation_m, correlation, renewal):
    """:func:`shadow_correlation` and :func:`shadow_renewal` of each travel, into
    ``correlation`` and ``renewal``: the steps of the shadowing's AR(1) for the channel's fit."""
    for k in range(correlation.shape[0]):
        correlation[k] = shadow_correlation(travel_m[k], decorrelation_m)
        renewal[k] = shadow_renewal(travel_m[k], decorrelation_m)


@jit(nogil=True)
def range_at_margin_m(margin_db, d0_m, exponent):
    """The log-distance law's inverse (:func:`netsim.radio._kernels.path_loss_db`), the one
    place it is computed: the distance at which the path loss exceeds ``PL(d0)`` by
    ``margin_db`` (``d0 10^(margin / 10 n)``); 0 where the margin is negative (not even
    ``d0`` is in reach) or not a number."""
    if not margin_db >= 0:
        return 0.0
    decades = margin_db / (10.0 * exponent)
    # Past every float: Python's power raises where the compiled one gives inf.
    if decades > 308.0:
        return math.inf
    return d0_m * 10.0**decades


@jit(nogil=True)
def range_at_loss_m(shadowing_db, walls_db, budget_db, d0_m, exponent):
    """The distance at which a pair whose shadowing costs ``shadowing_db`` and whose walls
    ``walls_db`` meets the sensitivity under log-distance (``budget_db = P_t - PL(d0) -
    sensitivity``): the range a link solver, a plan's kept link and a measured link all
    read; 0 when even ``d0`` is too far. The margin is ``(budget - X) - W``, in that order."""
    return range_at_margin_m(budget_db - shadowing_db - walls_db, d0_m, exponent)


@jit(nogil=True)
def ranges_at_loss_m(shadowing_db, walls_db, budget_db, d0_m, exponent, out):
    """:func:`range_at_loss_m` of every pair of ``shadowing_db`` and ``walls_db`` (1-d, of
    one length), written to ``out``."""
    for m in range(shadowing_db.shape[0]):
        out[m] = range_at_loss_m(shadowing_db[m], walls_db[m], budget_db, d0_m, exponent)


@jit(nogil=True)
def component_labels(n, a, b):
    """The component of each of ``n`` robots in the network whose links are the pairs
    ``(a[k], b[k])``, by union-find: numbered 0, 1, ... in the order of each component's
    lowest robot (a set's root is its lowest robot, labelled before the others)."""
    parent = np.arange(n)
    for k in range(a.shape[0]):
        i, j = a[k], b[k]
        while parent[i] != i:
            i = parent[i]
        while parent[j] != j:
            j = parent[j]
        if i != j:
            parent[max(i, j)] = min(i, j)
    labels = np.empty(n, np.int64)
    count = 0
    for i in range(n):
        r = i
        while parent[r] != r:
            r = parent[r]
        if r == i:
            labels[i] = count
            count += 1
        else:
            labels[i] = labels[r]
    return labels


@jit(nogil=True)
def component_count(n, a, b):
    """Connected components of the network of ``n`` robots whose links are the pairs
    ``(a[k], b[k])``: one more than the largest of :func:`component_labels` (none of no robot)."""
    if n == 0:
        return 0
    return component_labels(n, a, b).max() + 1


@jit(nogil=True, inline="always")
def cell_centre(k, h_m):
    """Where cell ``k`` of a row of cells of size ``h_m`` has its centre, from the row's
    start: the grid's one rule of where a cell is (:func:`grid_nearest_m`,
    :func:`cell_centres`)."""
    return (k + 0.5) * h_m


@jit(nogil=True)
def cell_centres(x0_m, h_m, k, out):
    """``x0_m`` plus :func:`cell_centre` of each cell index of ``k`` (1-d) into ``out``: the
    centres of cells ``k`` of a row of cells of size ``h_m`` starting at ``x0_m``."""
    for m in range(k.shape[0]):
        out[m] = x0_m + cell_centre(k[m], h_m)


@jit(nogil=True)
def grid_nearest_m(p, reach_m, x0_m, y0_m, width_m, height_m, cells, box, any_within):
    """The distance from each centre of the ``cells x cells`` grid of cells of the rectangle
    ``[x0, x0 + width] x [y0, y0 + height]`` (``[row, col]``: row along y) to the nearest of
    the points ``p`` within ``reach_m`` of it (``inf`` where none is): the one rule of "a
    cell is covered" (:func:`netsim.metrics.covered_fraction`, the environments' score).
    The distance is ``np.hypot`` of the offset, the nearest image on a torus of side
    ``box > 0`` (the rectangle is then the square ``[0, box]^2``). Each point visits, in
    each grid row its disk of radius ``reach_m`` reaches, the run of cells the disk can
    cover there, one more at each end.

    ``any_within``: only whether a cell is within ``reach_m`` of some point is wanted (a
    covered share, :func:`share_within` at ``reach_m``): a cell's entry is then ``reach_m``
    where some point is within it, decided by :func:`reaches` (the same answer as the
    hypot's, mostly without the root), and a cell that has one is not visited again."""
    out = np.full((cells, cells), np.inf)
    hx = width_m / cells
    hy = height_m / cells
    for k in range(p.shape[0]):
        x, y = p[k, 0] - x0_m, p[k, 1] - y0_m
        if box > 0.0:
            x, y = fold(x, box), fold(y, box)
        for iy in range(-1, 2):
            if iy != 0 and (box <= 0.0 or (iy < 0 and y - reach_m > 0.0) or (iy > 0 and y + reach_m < box)):
                continue
            sy = y - iy * box
            # one cell beyond the disk's rows and runs is tried too: the distance, not the
            # rounding of a bound, decides
            lo = max(int(math.floor((sy - reach_m) / hy - 0.5)), 0)
            hi = min(int(math.ceil((sy + reach_m) / hy - 0.5)), cells - 1)
            for ix in range(-1, 2):
                if ix != 0 and (box <= 0.0 or (ix < 0 and x - reach_m > 0.0) or (ix > 0 and x + reach_m < box)):
                    continue
                sx = x - ix * box
                for row in range(lo, hi + 1):
                    dy = cell_centre(row, hy) - sy
                    half = math.sqrt(max(reach_m * reach_m - dy * dy, 0.0))
                    first = max(int(math.floor((sx - half) / hx - 0.5)), 0)
                    last = min(int(math.ceil((sx + half) / hx - 0.5)), cells - 1)
                    for col in range(first, last + 1):
                        dx = cell_centre(col, hx) - sx
                        if any_within:
                            if out[row, col] > reach_m and reaches(dx, dy, reach_m, 0.0):
                                out[row, col] = reach_m
                            continue
                        d = length_m(dx, dy, 0.0)  # the image is chosen above
                        if d <= reach_m and d < out[row, col]:
                            out[row, col] = d
    return out


@jit(nogil=True)
def share_within(distance_m, radius_m):
    """The share of the distances (one dimension) at most ``radius_m``: of a grid's cells,
    by :func:`grid_nearest_m`, the covered fraction (the coverage table's and the
    environments' score); NaN of none."""
    n = distance_m.shape[0]
    if n == 0:
        return np.nan
    # One array expression: as fast in plain Python (a small team's path) as compiled.
    return np.count_nonzero(distance_m <= radius_m) / n
