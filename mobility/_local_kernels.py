"""The local plan's loops (compiled or plain, :func:`netsim.compiled.load`): rule 1
(:func:`netsim.mobility.local.let_go`), per robot the bottleneck of its certified detours,
by a widest-path search over the robots it remembers and those two hops out, a link surely
up within the plan's
range or, under shadowing, within the range its measured shadowing allows over the pair's
travel since, as far as the robot knows it (:func:`measured_range_m`,
:func:`largest_travel_m`); and the walls' test
(:func:`netsim.mobility.local.clear_of_walls`). The tests compare them with numpy oracles
(tests/oracles/local.py).
"""

from __future__ import annotations

import math

import numpy as np
from netsim.mobility._fade_kernels import plausible_change_within_db

from netsim._kernels import range_at_loss_m
from netsim.compiled import jit
from netsim.world._kernels import clamped_cell, on_grid


@jit(nogil=True)
def apart_along(dx, dy, disks, k, x0, x1, y0, y1, tol):
    """Whether, along the unit direction ``(dx, dy)``, the convex hull of the ``k`` disks
    ``disks[:k]`` (rows ``x, y, radius``) and the box ``[x0, x1] x [y0, y1]`` lie more than
    ``tol`` apart (their shadows on the line, which are never farther apart than the sets)."""
    lo = np.inf
    hi = -np.inf
    for m in range(k):
        c = dx * disks[m, 0] + dy * disks[m, 1]
        lo = min(lo, c - disks[m, 2])
        hi = max(hi, c + disks[m, 2])
    box_lo = min(dx * x0, dx * x1) + min(dy * y0, dy * y1)
    box_hi = max(dx * x0, dx * x1) + max(dy * y0, dy * y1)
    return box_lo - hi > tol or lo - box_hi > tol


@jit(nogil=True)
def hull_near_box(disks, k, x0, x1, y0, y1, tol):
    """Whether the convex hull of the ``k`` disks ``disks[:k]`` (rows ``x, y, radius``) comes
    within ``tol`` of the box ``[x0, x1] x [y0, y1]`` (a closed cell), exactly: the two are
    farther apart iff their shadows are on the line through their closest points, whose
    direction is one of the box's sides' normals, a normal of one of the hull's straight
    sides (each an outer tangent of two of the disks), or the direction from a disk's centre
    to a corner of the box."""
    for dx, dy in ((1.0, 0.0), (0.0, 1.0)):
        if apart_along(dx, dy, disks, k, x0, x1, y0, y1, tol):
            return False
    for m in range(k):
        ax, ay, ea = disks[m, 0], disks[m, 1], disks[m, 2]
        for n in range(m + 1, k):
            bx, by, eb = disks[n, 0], disks[n, 1], disks[n, 2]
            length = np.hypot(bx - ax, by - ay)
            if not length > abs(ea - eb):
                continue
            ux, uy = (bx - ax) / length, (by - ay) / length
            s = (ea - eb) / length
            c = math.sqrt(max(1.0 - s * s, 0.0))
            for side in (-1.0, 1.0):
                if apart_along(s * ux - side * c * uy, s * uy + side * c * ux, disks, k, x0, x1, y0, y1, tol):
                    return False
        for kx, ky in ((x0, y0), (x1, y0), (x0, y1), (x1, y1)):
            d = np.hypot(kx - ax, ky - ay)
            if d > 0 and apart_along((kx - ax) / d, (ky - ay) / d, disks, k, x0, x1, y0, y1, tol):
                return False
    return True


@jit(nogil=True)
def bounding_box(disks, k):
    """``x_lo, x_hi, y_lo, y_hi``: the bounding box of the ``k`` disks ``disks[:k]``."""
    x_lo, x_hi, y_lo, y_hi = np.inf, -np.inf, np.inf, -np.inf
    for m in range(k):
        x_lo = min(x_lo, disks[m, 0] - disks[m, 2])
        x_hi = max(x_hi, disks[m, 0] + disks[m, 2])
        y_lo = min(y_lo, disks[m, 1] - disks[m, 2])
        y_hi = max(y_hi, disks[m, 1] + disks[m, 2])
    return x_lo, x_hi, y_lo, y_hi


@jit(nogil=True, walks=True)
def near_walls(walls, disks, k):
    """Whether some occupied cell comes within ``walls.clearance_m`` of the convex hull of the
    ``k`` disks ``disks[:k]``: each occupied cell of the map under the hull's bounding box,
    tested exactly (:func:`hull_near_box`)."""
    res, ox, oy, tol = walls.resolution_m, walls.origin_x_m, walls.origin_y_m, walls.clearance_m
    h, w = walls.open.shape
    x_lo, x_hi, y_lo, y_hi = bounding_box(disks, k)
    i0 = max(math.floor(on_grid(x_lo - tol, ox, res)), 0)
    i1 = min(math.floor(on_grid(x_hi + tol, ox, res)), w - 1)
    j0 = max(math.floor(on_grid(y_lo - tol, oy, res)), 0)
    j1 = min(math.floor(on_grid(y_hi + tol, oy, res)), h - 1)
    for j in range(j0, j1 + 1):
        for i in range(i0, i1 + 1):
            if walls.open[j, i]:
                continue
            x0, y0 = ox + i * res, oy + j * res
            if hull_near_box(disks, k, x0, x0 + res, y0, y0 + res, tol):
                return True
    return False


# Where the clearance field leaves less than this many cells between the walls and the
# swept set, the walls' test looks at the cells themselves, this many cells of motion at a
# time.
EXACT_WITHIN_CELLS = 1.0
EXACT_SPAN_CELLS = 2.0


# The shape of a family whose members are disks (:func:`swept_clear`).
_POINT = np.zeros((1, 2))


@jit(nogil=True)
def _member(disks, row, ax, ay, ea, bx, by, eb, shape, k, f):
    """The disks whose hull is the family's member at ``f`` (:func:`swept_clear`), into
    ``disks[row:row + k]``."""
    cx, cy, r = ax + f * (bx - ax), ay + f * (by - ay), ea + f * (eb - ea)
    for m in range(k):
        disks[row + m, 0] = cx + f * shape[m, 0]
        disks[row + m, 1] = cy + f * shape[m, 1]
        disks[row + m, 2] = r


@jit(nogil=True, walks=True)
def swept_clear(walls, ax, ay, ea, bx, by, eb, shape, k):
    """Whether the union over ``f`` in [0, 1] of the sets ``C_f`` keeps more than
    ``walls.clearance_m`` from every wall: ``C_f`` is the convex polygon of vertices ``c_f + f
    shape[m]`` (``m < k``), ``c_f = a + f (b - a)``, grown by the radius ``(1 - f) ea + f
    eb``. With one vertex at 0 the union is the convex hull of the disks ``D(a, ea)`` and
    ``D(b, eb)``; with ``eb = 0`` and ``b + shape`` the ends of a segment, the convex hull
    of that segment and ``D(a, ea)``. ``C_f = (1 -
    f) C_0 + f C_1`` (Minkowski), so the members between two values of ``f`` fill the convex
    hull of theirs, a hull of disks. The test walks ``f`` by the clearance at ``c_f``
    (:attr:`netsim.mobility.local.Walls.field`, less the distance to the cell's centre, a
    lower bound) less the member's reach from ``c_f``, and where that leaves less than a
    cell it tests the hull of the next span's two members against the occupied cells near
    it (:func:`near_walls`): exact, up to rounding."""
    field = walls.field
    h, w = field.shape
    res = walls.resolution_m
    half_m = 0.0
    for m in range(k):
        half_m = max(half_m, np.hypot(shape[m, 0], shape[m, 1]))
    if not (math.isfinite(ea) and math.isfinite(eb)):
        return False  # a reach not known: no proof (and inf - inf, plain, would warn)
    per_f_m = np.hypot(bx - ax, by - ay) + half_m + abs(eb - ea)  # how fast a member's reach moves with f
    if not math.isfinite(per_f_m + ax + ay):
        return False  # nowhere known: no proof (and the walk would not end)
    if per_f_m == 0.0:
        disks = np.empty((k, 3))
        _member(disks, 0, ax, ay, ea, bx, by, eb, shape, k, 0.0)
        return not near_walls(walls, disks, k)
    f = 0.0
    while True:
        px, py = ax + f * (bx - ax), ay + f * (by - ay)
        u = on_grid(px, walls.origin_x_m, res)
        v = on_grid(py, walls.origin_y_m, res)
        ci = clamped_cell(u, w)
        cj = clamped_cell(v, h)
        reach_m = ea + f * (eb - ea) + f * half_m
        gap_m = field[cj, ci] - np.hypot(u - ci - 0.5, v - cj - 0.5) * res - reach_m
        if gap_m > EXACT_WITHIN_CELLS * res:
            if f >= 1.0:
                return True
            f = min(f + (gap_m - walls.clearance_m) / per_f_m, 1.0)
            continue
        f2 = min(f + EXACT_SPAN_CELLS * res / per_f_m, 1.0)
        disks = np.empty((2 * k, 3))  # only near a wall: most tests never get here
        _member(disks, 0, ax, ay, ea, bx, by, eb, shape, k, f)
        _member(disks, k, ax, ay, ea, bx, by, eb, shape, k, f2)
        if near_walls(walls, disks, 2 * k):
            return False
        if f2 >= 1.0:
            return True
        f = f2


@jit(nogil=True, walks=True)
def clear(walls, ax, ay, bx, by, ea, eb):
    """The convex hull of the disks of radius ``ea`` around ``(ax, ay)`` and ``eb`` around
    ``(bx, by)`` keeps more than ``walls.clearance_m`` from every wall
    (:func:`netsim.mobility.local.clear_of_walls`, one pair; :func:`swept_clear`)."""
    return swept_clear(walls, ax, ay, ea, bx, by, eb, _POINT, 1)


@jit(nogil=True, walks=True)
def clear_many(walls, a, b, ea, eb, out):
    """:func:`clear` for every row."""
    for k in range(a.shape[0]):
        out[k] = clear(walls, a[k, 0], a[k, 1], b[k, 0], b[k, 1], ea[k], eb[k])


@jit(nogil=True, walks=True)
def steps_clear(walls, p, move, q, e, out):
    """For every row, whether the convex hull of the step from ``p`` to ``p + move`` and the
    disk ``D(q, e)`` keeps off the walls (:func:`swept_clear`)."""
    ends = np.empty((2, 2))
    for k in range(p.shape[0]):
        hx, hy = 0.5 * move[k, 0], 0.5 * move[k, 1]
        ends[0, 0], ends[0, 1], ends[1, 0], ends[1, 1] = -hx, -hy, hx, hy
        out[k] = swept_clear(walls, q[k, 0], q[k, 1], e[k], p[k, 0] + hx, p[k, 1] + hy, 0.0, ends, 2)


@jit(nogil=True, walks=True)
def boxes_met(rects, disks, k, tol):
    """How many of the boxes ``rects`` (rows ``x0, x1, y0, y1``) come within ``tol`` of the
    convex hull of the ``k`` disks ``disks[:k]`` (:func:`hull_near_box`)."""
    x_lo, x_hi, y_lo, y_hi = bounding_box(disks, k)
    met = 0
    for b in range(rects.shape[0]):
        x0, x1, y0, y1 = rects[b, 0], rects[b, 1], rects[b, 2], rects[b, 3]
        if x0 - x_hi > tol or x_lo - x1 > tol or y0 - y_hi > tol or y_lo - y1 > tol:
            continue
        if hull_near_box(disks, k, x0, x1, y0, y1, tol):
            met += 1
    return met


@jit(nogil=True, walks=True)
def through(walls, ax, ay, ea, bx, by, eb, longest_m):
    """Whether a link between a point of ``D(a, ea)`` and one of ``D(b, eb)``, at most
    ``longest_m`` long, is surely up though walls stand between (rule 1's detour link on a
    map whose walls let power through): ``longest_m`` is within :func:`hull_range_through_m`
    of the two disks."""
    if walls.through_m.shape[0] == 0:
        return False
    disks = np.empty((2, 3))
    disks[0, 0], disks[0, 1], disks[0, 2] = ax, ay, ea
    disks[1, 0], disks[1, 1], disks[1, 2] = bx, by, eb
    return longest_m <= hull_range_through_m(walls, disks, 2)


@jit(nogil=True, walks=True)
def hull_range_through_m(walls, disks, k):
    """The plan's range for a link between two points of the convex hull of the ``k`` disks
    ``disks[:k]`` (rows ``x, y, radius``) where walls let power through: the hull meets ``c``
    of the walls' boxes (:func:`boxes_met`), so no such segment crosses more than ``c``
    walls, and the range through ``c`` walls holds it (:func:`range_through_m`: ``-inf`` for
    ``c = 0``, a link clear of walls, which rules 1 and 5 test on their own)."""
    return range_through_m(walls, boxes_met(walls.rects, disks, k, walls.clearance_m))


@jit(nogil=True)
def range_through_m(walls, k):
    """The plan's range for a link that crosses at most ``k`` walls where walls let power
    through (:attr:`netsim.mobility.local.Walls.through_m`); ``-inf`` for none (``k = 0`` is
    a link clear of walls, rule 5's and rule 1's own test) and beyond the table."""
    if 0 < k <= walls.through_m.shape[0]:
        return walls.through_m[k - 1]
    return -np.inf


@jit(nogil=True, walks=True)
def steps_through(walls, p, move, q, e, fall, margin_m, out):
    """Rule 5 through walls, for every row: whether a link is surely up over the step from
    ``p`` to ``p + move`` against the other end standing in ``D(q, e)`` (``fall`` by the
    step's end), though walls stand between (:func:`netsim.mobility.local.through_walls`):
    both ``|p - q| + e`` and ``|p + move - q| + fall`` within :func:`hull_range_through_m`
    of the step and the disk, less ``margin_m``."""
    disks = np.zeros((3, 3))
    for k in range(p.shape[0]):
        bx, by = p[k, 0] + move[k, 0], p[k, 1] + move[k, 1]
        disks[0, 0], disks[0, 1] = p[k, 0], p[k, 1]
        disks[1, 0], disks[1, 1] = bx, by
        disks[2, 0], disks[2, 1], disks[2, 2] = q[k, 0], q[k, 1], e[k]
        r = hull_range_through_m(walls, disks, 3) - margin_m
        start = np.hypot(p[k, 0] - q[k, 0], p[k, 1] - q[k, 1]) + e[k]
        end = np.hypot(bx - q[k, 0], by - q[k, 1]) + fall[k]
        out[k] = start <= r and end <= r


@jit(nogil=True)
def largest_travel_m(leg_speed_mps, leg_from_s, leg_until_s, since_s, t0_s, speed_mps):
    """The farthest a robot can have travelled from ``since_s`` to ``t0_s``: at the speed its
    Ack carried from ``leg_from_s`` until ``leg_until_s`` (NaN: unknown), at the speed cap
    before and after (after its leg it may have taken another, unheard of) (one pair)."""
    if not since_s > -math.inf:
        return math.inf
    if math.isnan(leg_speed_mps):
        return speed_mps * max(t0_s - since_s, 0.0)
    start = min(max(leg_from_s, since_s), t0_s)
    end = min(max(leg_until_s, start), t0_s)
    before = speed_mps * max(start - since_s, 0.0)
    return before + leg_speed_mps * max(end - start, 0.0) + speed_mps * max(t0_s - end, 0.0)


@jit(nogil=True)
def largest_travels_m(leg_speed_mps, leg_from_s, leg_until_s, since_s, t0_s, speed_mps):
    """:func:`largest_travel_m` of every ``(i, j)`` of the ``(n, m)`` arrays: robot ``j``'s
    leg as ``i`` knows it, since ``since_s[i, j]``."""
    out = np.empty(since_s.shape)
    for i in range(since_s.shape[0]):
        for j in range(since_s.shape[1]):
            leg = (leg_speed_mps[i, j], leg_from_s[i, j], leg_until_s[i, j])
            out[i, j] = largest_travel_m(*leg, since_s[i, j], t0_s, speed_mps)
    return out


@jit(nogil=True)
def remembers(sent_s, now_s, release_s):
    """A robot still remembers another at ``now_s`` when the latest Ack of it it heard was
    sent less than ``release_s`` before (docs/model.md 5.1): the one rule of memory, for
    one sending time or an array of them."""
    return now_s - sent_s < release_s


@jit(nogil=True)
def heard_sources(heard, t0_s, out):
    """Where each robot ``i`` knows each robot ``j`` from, into ``out[i, j]`` (the forces'
    sources in the local plan, :func:`netsim.mobility.local.sources_heard`): -1, its own
    memory (it remembers ``j``, ``heard.known``); else the entry of ``heard`` of the freshest
    Ack of ``j`` that the lists it holds from the robots it remembers still report at
    ``t0_s`` (the first, by the id of the robot whose list it is, on a tie); -2, nowhere."""
    known, which, start, other, sent_s = heard.known, heard.which, heard.start, heard.other, heard.sent_s
    release_s = heard.release_s
    n = known.shape[0]
    for i in range(n):
        for j in range(n):
            out[i, j] = -1 if known[i, j] else -2
        for u in range(n):
            k = which[i, u]
            if not known[i, u] or k < 0:
                continue
            for p in range(start[k, u], start[k, u + 1]):
                j = other[p]
                if j == i or known[i, j] or not remembers(sent_s[p], t0_s, release_s):
                    continue
                if out[i, j] == -2 or sent_s[p] > sent_s[out[i, j]]:
                    out[i, j] = p


@jit(nogil=True)
def measured_range_m(x_db, measured_s, travel_m, fade):
    """How long a link whose shadowing was measured at ``x_db`` on a frame sent no earlier
    than ``measured_s`` can surely be now (0: no measurement): the length at which its
    margin meets the sensitivity after the plausible change of the shadowing over the
    pair's largest travel since, ``travel_m`` (each end's by :func:`largest_travel_m`).
    ``fade``: the shadowing's rule, read by name (:class:`netsim.mobility.local.FadeRule`)."""
    if not fade.on or math.isnan(x_db) or not measured_s > -math.inf:
        return 0.0
    change = plausible_change_within_db(travel_m, x_db, fade.sigma_db, fade.decorrelation_m, fade.detour_sigmas)
    return range_at_loss_m(x_db + change, 0.0, fade.budget_db, fade.reference_distance_m, fade.exponent)


# The last band of rule 1's order under shadowing: links without a record, and links too long
# at zero shadowing for any earlier band (ordered among themselves by their ids).
LAST_BAND = 1048576.0


@jit(nogil=True)
def link_band(length_m, record_db, band_m, fade, nominal_m):
    """A link's band in rule 1's order: ``floor(length / band_m)``; under shadowing
    (``fade.on``) of its length at zero shadowing under its record, ``length R(0) / R(X)``
    (the length at which, with no shadowing, the link would have the margin its record ``X``
    gives it at ``length``; ``nominal_m``: ``R(0)``), a link without a record (NaN) or
    beyond every range in the last band, :data:`LAST_BAND`."""
    if not fade.on:
        return float(math.floor(length_m / band_m))
    if math.isnan(record_db):
        return LAST_BAND
    reach_m = range_at_loss_m(record_db, 0.0, fade.budget_db, fade.reference_distance_m, fade.exponent)
    if not reach_m > 0:
        return LAST_BAND
    at_zero_m = length_m * (nominal_m / reach_m)
    return float(math.floor(at_zero_m / band_m)) if at_zero_m / band_m < LAST_BAND else LAST_BAND


@jit(nogil=True)
def held_list(heard, s, u, w):
    """The snapshot (an index of ``heard``'s, -1: none) of ``w``'s list that ``u`` held when
    it made its list of snapshot ``s``: ``heard.held`` keeps each list's holdings by step in
    a ring (:class:`netsim.mobility.local.Heard`)."""
    first = heard.steps[0]
    step = heard.held[(first + s) % heard.held.shape[0], u, w]
    return step - first if step >= first else -1


@jit(nogil=True)
def in_epoch(heard, version):
    """Whether a list of snapshot ``version`` (an index of ``heard``'s snapshots, -1: none)
    carries the records rule 1 orders by at this step (:class:`netsim.mobility.local.Lists`)."""
    return version >= 0 and heard.records_from <= heard.steps[version] < heard.records_to


@jit(nogil=True)
def let_go(pos, memory, heard, rule, walls, out, fade):
    """Fill ``out[i, j]`` (False on entry): robot ``i`` knows a certified detour to ``j``
    through robots it remembers and the robots their lists name
    (:func:`netsim.mobility.local.let_go`). Read by field name: ``memory``, what the
    robots remember and measured (:class:`netsim.mobility.local.Remembered`; ``silent[i,
    j]``: ``i``'s link to ``j`` was down in the window, :class:`netsim.mobility.local.Silence`,
    never a detour's link, ``j`` still a node); ``heard``, the lists they hold from each
    other and the lists those lists' senders held (:class:`netsim.mobility.local.Heard`, its
    ``x_db``, ``held`` and ``records_db`` given); ``rule``, the step's
    (:class:`netsim.mobility.local.DetourRule`), a detour's link certified up over
    ``[t0_s - window_s, t0_s]`` (0: at ``t0_s``): on each piece of it each end where its
    known leg puts it (:func:`up_over_window`), and a measured link's pair travel
    counted from the window's start where that is earlier than the measurement
    (:func:`largest_travel_m`); ``fade``: the shadowing's rule (:func:`measured_range_m`,
    :func:`link_band`; ``on`` False: none)."""
    xy, sent_s, known, silent = memory.xy, memory.sent_s, memory.known, memory.silent
    x_db, measured_s = memory.x_db, memory.measured_s
    leg_speed, leg_from, leg_velocity = memory.leg_speed_mps, memory.leg_from_s, memory.leg_velocity_mps
    leg_until = memory.leg_until_s
    which, start, other, listed_s = heard.which, heard.start, heard.other, heard.sent_s
    held, records_db = heard.held, heard.records_db
    # Without the lists' senders' lists (``held`` empty) the graph ends at the robots i remembers.
    two_hops = held.shape[0] > 0 and start.shape[0] > 0
    t0_s, speed_mps, band_m, range_m = rule.t0_s, rule.speed_mps, rule.band_m, rule.range_m
    release_s, window_s = heard.release_s, rule.window_s
    opens_s = t0_s - window_s
    n = pos.shape[0]
    nn = float(n * n)
    node = np.empty(n, np.int64)
    local = np.full(n, -1, np.int64)
    certain = np.zeros((n, n), np.bool_)
    # sure[a, b]: the longest the link of nodes a, b can surely be at t0 (the plan's range,
    # or what a shadowing measured on it allows).
    sure = np.zeros((n, n))
    qx = np.empty(n)
    qy = np.empty(n)
    e = np.empty(n)
    # beyond[a]: node a is two hops out (named by lists, not remembered), known since heard_s[a].
    beyond = np.zeros(n, np.bool_)
    heard_s = np.empty(n)
    # record_db[a, b]: the link's record in the epoch ordered by (readable[a, b]: i holds it).
    record_db = np.full((n, n), np.nan)
    nominal_m = range_at_loss_m(0.0, 0.0, fade.budget_db, fade.reference_distance_m, fade.exponent)
    readable = np.zeros((n, n), np.bool_)
    # sweep[a]: node a's largest travel over the window, as i knows it (0: it cannot have
    # moved in it, and a detour's link is certified as at t0).
    sweep = np.zeros(n)
    # Node a's known leg over the window: its velocity from leg_s[a] to t0 (up_over_window).
    leg_s = np.empty(n)
    vx = np.zeros(n)
    vy = np.zeros(n)
    vs = np.zeros(n)
    worst = np.empty(n)
    done = np.empty(n, np.bool_)
    for i in range(n):
        k = 1
        node[0] = i
        qx[0], qy[0], e[0] = pos[i, 0], pos[i, 1], 0.0
        for j in range(n):
            if known[i, j] and j != i:
                node[k] = j
                qx[k], qy[k] = xy[i, j, 0], xy[i, j, 1]
                e[k] = largest_travel_m(np.nan, np.nan, np.nan, sent_s[i, j], t0_s, speed_mps)
                k += 1
        m = k - 1
        if m < 2:
            continue
        for a in range(k):
            local[node[a]] = a
            beyond[a] = False
        if two_hops:
            # Two hops out: the robots the lists i holds name (their senders still remember
            # them at t0), where the freshest of those lists puts them.
            for a in range(1, m + 1):
                u = node[a]
                s = which[i, u]
                if s < 0:
                    continue
                for p in range(start[s, u], start[s, u + 1]):
                    w = other[p]
                    if not remembers(listed_s[p], t0_s, release_s):
                        continue
                    b = local[w]
                    if b < 0:
                        b = k
                        node[k] = w
                        local[w] = k
                        beyond[k] = True
                        heard_s[k] = -np.inf
                        k += 1
                    if beyond[b] and listed_s[p] > heard_s[b]:
                        heard_s[b] = listed_s[p]
                        qx[b], qy[b] = heard.xy[p, 0], heard.xy[p, 1]
                        e[b] = largest_travel_m(np.nan, np.nan, np.nan, listed_s[p], t0_s, speed_mps)
        if window_s > 0:
            for a in range(k):
                u = node[a]
                # Of a robot two hops out i knows no leg: the cap all along.
                speed_u = np.nan if beyond[a] else leg_speed[i, u]
                sweep[a] = largest_travel_m(speed_u, leg_from[i, u], leg_until[i, u], opens_s, t0_s, speed_mps)
                # Its known leg, from leg_s[a] on; none: the leg "starts" at t0.
                if math.isnan(speed_u):
                    leg_s[a], vx[a], vy[a], vs[a] = t0_s, 0.0, 0.0, 0.0
                else:
                    leg_s[a] = min(max(leg_from[i, u], opens_s), t0_s)
                    vx[a], vy[a], vs[a] = leg_velocity[i, u, 0], leg_velocity[i, u, 1], speed_u
        # certain[a, b]: i can tell that node a remembers node b at t0 (from a's list).
        for a in range(k):
            for b in range(k):
                certain[a, b] = a == 0 and 0 < b <= m and not silent[i, node[b]]
                sure[a, b] = range_m
        for b in range(1, m + 1):
            # The pair's travel since the measurement: each end's, as far as i knows it; over
            # a window, from its start if earlier (an instant of the window before the
            # measurement is within the window's travel of it: the shadowing's change
            # depends on the pair's travel between the two instants, either way).
            j = node[b]
            s_ij = min(measured_s[i, j], opens_s) if window_s > 0 else measured_s[i, j]
            travel = largest_travel_m(leg_speed[i, i], leg_from[i, i], leg_until[i, i], s_ij, t0_s, speed_mps)
            travel += largest_travel_m(leg_speed[i, j], leg_from[i, j], leg_until[i, j], s_ij, t0_s, speed_mps)
            r = measured_range_m(x_db[i, j], s_ij, travel, fade)
            sure[0, b] = max(sure[0, b], r)
            sure[b, 0] = sure[0, b]
        for a in range(1, m + 1):
            u = node[a]
            s = which[i, u]
            if s < 0:
                continue
            args = (node, local, beyond, heard, leg_speed, leg_from, leg_until, rule, fade, certain, sure)
            listed_lists(i, a, s, u, *args)
            if two_hops:
                # The lists of the robots u's list names, as u held them at its snapshot s.
                for p in range(start[s, u], start[s, u + 1]):
                    b = local[other[p]]
                    if b < 0 or not beyond[b]:
                        continue
                    w = node[b]
                    h = held_list(heard, s, u, w)
                    if h >= 0:
                        listed_lists(i, b, h, w, *args)
        if fade.on:
            # The records rule 1 orders by: the smaller id's, as a list i holds of it carries
            # them (its own list always).
            for a in range(k):
                for b in range(k):
                    record_db[a, b] = np.nan
                    readable[a, b] = False
            for a in range(k):
                u = node[a]
                ok = a == 0 or (a <= m and in_epoch(heard, which[i, u]))
                if not ok and two_hops:
                    for c in range(1, m + 1):
                        s = which[i, node[c]]
                        if s >= 0 and in_epoch(heard, held_list(heard, s, node[c], u)):
                            ok = True
                            break
                if not ok:
                    continue
                for b in range(k):
                    if node[b] > u:
                        readable[a, b] = True
                        readable[b, a] = True
                        record_db[a, b] = records_db[u, node[b]]
                        record_db[b, a] = record_db[a, b]
        for a in range(k):
            local[node[a]] = -1
        for a in range(k):
            worst[a] = np.inf
            done[a] = False
        worst[0] = 0.0
        for _ in range(k):
            u = -1
            for a in range(k):
                if not done[a] and (u < 0 or worst[a] < worst[u]):
                    u = a
            if u < 0 or worst[u] == np.inf:
                break
            done[u] = True
            nu = node[u]
            for v in range(k):
                nv = node[v]
                if done[v] or not (certain[u, v] and certain[v, u]):
                    continue
                if fade.on and not readable[u, v]:
                    continue
                longest = np.hypot(qx[u] - qx[v], qy[u] - qy[v]) + e[u] + e[v]
                # From the node met first in the list (the order the oracle walks too).
                a, b = min(u, v), max(u, v)
                # Each end anywhere within its whole travel over the window of where it is at t0.
                swept = longest + sweep[u] + sweep[v]
                up = swept <= sure[u, v]
                if up and walls.on:
                    ea, eb = e[a] + sweep[a], e[b] + sweep[b]
                    if not clear(walls, qx[a], qy[a], qx[b], qy[b], ea, eb):
                        up = through(walls, qx[a], qy[a], ea, qx[b], qy[b], eb, swept)
                if not up and sweep[a] + sweep[b] > 0:
                    # That disk takes a robot that moved along a corridor to have swept across
                    # it: follow each end along its leg.
                    ends = (qx, qy, e, vx, vy, vs, leg_s)
                    up = up_over_window(walls, a, b, ends, sure[u, v], opens_s, t0_s, speed_mps)
                if not up:
                    continue
                band = link_band(longest, record_db[u, v], band_m, fade, nominal_m)
                rank = band * nn + float(min(nu, nv) * n + max(nu, nv)) + 1.0
                w = max(worst[u], rank)
                if w < worst[v]:
                    worst[v] = w
        for a in range(1, m + 1):
            j = node[a]
            if fade.on and not readable[0, a]:
                continue
            shortest = max(np.hypot(qx[a] - qx[0], qy[a] - qy[0]) - e[a], 0.0)
            band = link_band(shortest, record_db[0, a], band_m, fade, nominal_m)
            rank = band * nn + float(min(i, j) * n + max(i, j)) + 1.0
            out[i, j] = worst[a] < rank


# How many equal pieces rule 1 cuts the window into where an end of a detour's link moved in
# it: each piece certified with both ends where their known legs put them over the piece,
# so that a robot that moved along a corridor is not taken to have swept across it.
WINDOW_PIECES = 8


@jit(nogil=True)
def at_over(qx, qy, e, vx, vy, speed, leg_s, s0, s1, t0_s, speed_mps):
    """Where one end is over ``[s0, s1]`` of the window, as a disk ``(x, y, radius)``: at an
    instant ``t`` of its known leg (from ``leg_s`` on) within ``e`` of ``q - v (t0 - t)``,
    before the leg within the cap's travel of where the leg started (``speed``: the leg's)."""
    if s0 >= leg_s:
        back = t0_s - 0.5 * (s0 + s1)
        return qx - vx * back, qy - vy * back, e + speed * 0.5 * (s1 - s0)
    back = t0_s - leg_s
    return qx - vx * back, qy - vy * back, e + max(speed_mps * (leg_s - s0), speed * max(s1 - leg_s, 0.0))


@jit(nogil=True)
def up_over_window(walls, a, b, ends, sure_m, opens_s, t0_s, speed_mps):
    """Rule 1's detour link between nodes ``a`` and ``b`` (``ends``: the nodes' positions
    ``qx, qy`` at ``t0``, uncertainties ``e``, known legs' velocities ``vx, vy`` and speeds
    ``vs`` from ``leg_s``) surely up at every instant of ``[opens_s, t0_s]``: over each of
    :data:`WINDOW_PIECES` pieces, each end within a disk about where its leg puts it
    (:func:`at_over`), the two disks at most ``sure_m`` apart at their farthest and their
    hull clear of walls (or within the range through the walls it meets)."""
    qx, qy, e, vx, vy, vs, leg_s = ends
    span = (t0_s - opens_s) / WINDOW_PIECES
    for p in range(WINDOW_PIECES):
        s0 = opens_s + p * span
        s1 = t0_s if p == WINDOW_PIECES - 1 else opens_s + (p + 1) * span
        ax, ay, ra = at_over(qx[a], qy[a], e[a], vx[a], vy[a], vs[a], leg_s[a], s0, s1, t0_s, speed_mps)
        bx, by, rb = at_over(qx[b], qy[b], e[b], vx[b], vy[b], vs[b], leg_s[b], s0, s1, t0_s, speed_mps)
        longest = np.hypot(ax - bx, ay - by) + ra + rb
        if longest > sure_m:
            return False
        if walls.on and not clear(walls, ax, ay, bx, by, ra, rb):
            if not through(walls, ax, ay, ra, bx, by, rb, longest):
                return False
    return True


@jit(nogil=True)
def listed_lists(i, a, s, u, node, local, beyond, heard, leg_speed, leg_from, leg_until, rule, fade, certain, sure):
    """What ``u`` (node ``a`` of robot ``i``'s graph) remembers at ``t0`` by its list of
    snapshot ``s``: ``certain[a, b]`` for each node ``b`` it names (still remembered then),
    and the range the shadowing it measured on ``b`` allows, ``sure[a, b]``, over the pair's
    largest travel since as ``i`` knows it (a robot two hops out at the cap all along)."""
    start, other, listed_s, listed_x = heard.start, heard.other, heard.sent_s, heard.x_db
    t0_s, speed_mps, window_s = rule.t0_s, rule.speed_mps, rule.window_s
    opens_s = t0_s - window_s
    for p in range(start[s, u], start[s, u + 1]):
        b = local[other[p]]
        if b < 0 or not remembers(listed_s[p], t0_s, heard.release_s):
            continue
        certain[a, b] = True
        s_p = min(listed_s[p], opens_s) if window_s > 0 else listed_s[p]
        listed = node[b]
        travel = 0.0
        for c, robot in ((a, u), (b, listed)):
            speed_c = np.nan if beyond[c] else leg_speed[i, robot]
            travel += largest_travel_m(speed_c, leg_from[i, robot], leg_until[i, robot], s_p, t0_s, speed_mps)
        r = measured_range_m(listed_x[p], s_p, travel, fade)
        sure[a, b] = max(sure[a, b], r)
        sure[b, a] = max(sure[b, a], r)
