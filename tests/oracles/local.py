"""Reference oracles of the local plan's kernels (:mod:`netsim.mobility._local_kernels`):
the same rules in numpy array operations, written independently of the loops, for the
tests to compare the kernels with (plain and compiled)."""

import numpy as np
from netsim.mobility.local import Heard, Memory, Walls


def link_rank(length_m: np.ndarray, pair: np.ndarray, band_m: float, n: int) -> np.ndarray:
    """A link's place in the order every robot uses: by band of length (``band_m`` wide),
    then by the pair of ids (``min n + max``); one number, exact in a float.

    >>> link_rank(np.array([5.0, 15.0, 5.0]), np.array([7, 1, 9]), 10.0, 4).tolist()
    [7.0, 17.0, 9.0]
    """
    return np.floor(length_m / band_m) * (n * n) + pair


def clear_of_walls(walls: Walls, a, b, ea, eb) -> np.ndarray:
    """:func:`netsim.mobility.local.clear_of_walls` by its definition: the hull of the two
    disks is the union of the disks of radius ``(1 - f) ea + f eb`` around ``a + f (b -
    a)``, so its distance to an occupied cell is the least over ``f`` of the distance from
    that centre to the cell less that radius, a convex function of ``f`` (minimised by
    ternary search); clear when every occupied cell of the map is farther than
    ``walls.clearance_m``."""
    res = walls.resolution_m
    rows, cols = np.nonzero(~walls.open)
    x0 = walls.origin_x_m + cols * res
    y0 = walls.origin_y_m + rows * res
    boxes = np.stack([x0, x0 + res, y0, y0 + res], axis=1)
    return boxes_near_hull(boxes, a, b, ea, eb, walls.clearance_m) == 0


def walls_met(walls: Walls, a, b, ea, eb) -> np.ndarray:
    """How many of the walls' boxes (:attr:`netsim.mobility.local.Walls.rects`) come within
    the clearance of the hull of the two disks (the kernels' ``boxes_met``), by the same
    definition as :func:`clear_of_walls`."""
    return boxes_near_hull(walls.rects, a, b, ea, eb, walls.clearance_m)


def boxes_near_hull(boxes: np.ndarray, a, b, ea, eb, tol: float) -> np.ndarray:
    """For each row, how many ``boxes`` (rows ``x0, x1, y0, y1``) lie within ``tol`` of the hull
    of ``D(a, ea)`` and ``D(b, eb)``: the least gap over the hull's disks of each (row, box)
    pair near enough to matter, found by golden-section search (one new point a round) on all
    the pairs at once, where neither a bound nor a witness decides it first."""
    a = np.asarray(a, float).reshape(-1, 2)
    b = np.asarray(b, float).reshape(-1, 2)
    ea = np.broadcast_to(np.asarray(ea, float), (len(a),))
    eb = np.broadcast_to(np.asarray(eb, float), (len(a),))
    reach = (np.maximum(ea, eb) + tol)[:, None]
    near = (
        (boxes[:, 0] <= np.maximum(a[:, 0], b[:, 0])[:, None] + reach)
        & (boxes[:, 1] >= np.minimum(a[:, 0], b[:, 0])[:, None] - reach)
        & (boxes[:, 2] <= np.maximum(a[:, 1], b[:, 1])[:, None] + reach)
        & (boxes[:, 3] >= np.minimum(a[:, 1], b[:, 1])[:, None] - reach)
    )
    row, col = np.nonzero(near)
    box = boxes[col]
    # No disk of the hull comes nearer the box than the line through a and b does, less
    # the larger radius: pairs farther than that are not near.
    centre_x, centre_y = (box[:, 0] + box[:, 1]) / 2, (box[:, 2] + box[:, 3]) / 2
    half = np.hypot(box[:, 1] - box[:, 0], box[:, 3] - box[:, 2]) / 2
    d = b[row] - a[row]
    length = np.hypot(d[:, 0], d[:, 1])
    span = np.where(length > 0, length, 1.0)
    line = np.abs((centre_x - a[row, 0]) * d[:, 1] - (centre_y - a[row, 1]) * d[:, 0]) / span
    keep = ~((length > 0) & (line - half - np.maximum(ea, eb)[row] > tol + 1e-9))
    row, box, d, span = row[keep], box[keep], d[keep], span[keep]
    centre_x, centre_y = centre_x[keep], centre_y[keep]
    ends = (a[row], b[row], ea[row], eb[row])
    # A disk of the hull within tol is a witness: the ends, and the one nearest the box's
    # centre; the least gap is searched for where none is.
    nearest = np.clip(((centre_x - ends[0][:, 0]) * d[:, 0] + (centre_y - ends[0][:, 1]) * d[:, 1]) / span**2, 0.0, 1.0)
    hit = (_gap(box, ends, 0.0) <= tol) | (_gap(box, ends, 1.0) <= tol) | (_gap(box, ends, nearest) <= tol)
    open_ = np.flatnonzero(~hit)
    box = box[open_]
    ends = tuple(e[open_] for e in ends)
    lo, hi = np.zeros(len(open_)), np.ones(len(open_))
    r = (np.sqrt(5.0) - 1.0) / 2.0
    m1, m2 = hi - r, lo + r
    g1, g2 = _gap(box, ends, m1), _gap(box, ends, m2)
    # 0.618^90 of the unit interval: below the last bit of any f in it.
    for _ in range(90):
        left = g1 <= g2
        hi = np.where(left, m2, hi)
        lo = np.where(left, lo, m1)
        m = np.where(left, hi - r * (hi - lo), lo + r * (hi - lo))
        g = _gap(box, ends, m)
        m1, m2 = np.where(left, m, m2), np.where(left, m1, m)
        g1, g2 = np.where(left, g, g2), np.where(left, g1, g)
    hit[open_] = _gap(box, ends, lo) <= tol
    return np.bincount(row[hit], minlength=len(a)).astype(np.int64)


def _gap(boxes, ends, f):
    """The distance from each box (rows ``x0, x1, y0, y1``) to the disk at ``f`` of its row's
    two disks' hull (``a, b, ea, eb``, one row per box), less its radius."""
    a, b, ea, eb = ends
    px = a[:, 0] + f * (b[:, 0] - a[:, 0])
    py = a[:, 1] + f * (b[:, 1] - a[:, 1])
    dx = np.maximum(np.maximum(boxes[:, 0] - px, 0.0), px - boxes[:, 1])
    dy = np.maximum(np.maximum(boxes[:, 2] - py, 0.0), py - boxes[:, 3])
    return np.hypot(dx, dy) - (ea + f * (eb - ea))


def reported(heard: Heard, i: int, u: int, t_s: float) -> tuple[np.ndarray, np.ndarray]:
    """Entries (indices into ``heard``) of the list ``i`` holds from ``u`` that still stand at
    ``t_s`` (``u`` remembers those robots then), and the robots they name."""
    k = heard.which[i, u]
    if k < 0:
        return np.empty(0, np.int64), np.empty(0, np.int64)
    entries = np.arange(heard.start[k, u], heard.start[k, u + 1])
    entries = entries[t_s - heard.sent_s[entries] < heard.release_s]
    return entries, heard.other[entries]


def sources_heard(memory: Memory, heard: Heard, t0_s: float, reach_m: float, pos: np.ndarray):
    """Pairs ``(robot, position it knows of another robot within reach_m)``: the forces'
    sources in the local plan. A robot knows the robots it remembers, at the position it
    heard (``memory``), and those named in the lists it holds from them (:class:`Lists`;
    still remembered at ``t0_s``), at the position of the freshest Ack any of those lists
    reports (the first of the robots it remembers, by id, on a tie). By sorting the entries
    of each robot's lists, where the kernel keeps the freshest in one pass."""
    n = len(pos)
    known = heard.known
    robots, xys = [], []
    for i in range(n):
        nb = np.flatnonzero(known[i])
        if len(nb) == 0:
            continue
        xy = np.zeros((n, 2))
        fresh = np.zeros(n, dtype=bool)
        entries = [reported(heard, i, u, t0_s)[0] for u in nb.tolist()]
        rows = np.concatenate(entries)
        if len(rows):
            other, sent = heard.other[rows], heard.sent_s[rows]
            # Entries are in the order of the robots i remembers (ids ascending); a stable
            # sort keeps the first on a tie.
            order = np.lexsort((-sent, other))
            first = order[np.r_[True, other[order][1:] != other[order][:-1]]]
            fresh[other[first]] = True
            xy[other[first]] = heard.xy[rows[first]]
        fresh[i] = False
        own = known[i]
        xy[own] = memory.xy[i, own]
        have = np.flatnonzero(own | fresh)
        robots.append(np.full(len(have), i))
        xys.append(xy[have])
    if not robots:
        return np.empty(0, np.int64), np.empty((0, 2))
    robot, xy = np.concatenate(robots), np.concatenate(xys)
    # Within reach: d <= r, as the engine's pairs in range.
    d = np.hypot(*(xy - np.asarray(pos, float)[robot]).T)
    near = d <= reach_m
    return robot[near], xy[near]


def let_go(
    pos,
    memory: Memory,
    heard: Heard,
    t0_s,
    speed_mps,
    band_m,
    range_m,
    walls: Walls,
    window_s: float = 0.0,
    silent_of: np.ndarray | None = None,
) -> np.ndarray:
    """:func:`netsim.mobility.local.let_go` without shadowing: per robot, the minimum
    spanning tree of its certified graph by scipy, and the bottleneck of its path to each
    remembered robot; the graph's nodes the robot, the robots it remembers and (when
    ``heard`` carries the lists their senders held) the robots two hops out that their lists
    name, each where the freshest list puts it; a link certified up over the window before
    ``t0_s`` (on each piece of the window each end where its known leg puts it, at the cap
    for a robot two hops out: :func:`up_over_window`); a silent robot's link (``silent_of``) no detour's
    link."""
    n = len(pos)
    out = np.zeros((n, n), dtype=bool)
    known = heard.known
    from scipy.sparse.csgraph import breadth_first_order, minimum_spanning_tree

    two_hops = heard.held is not None and len(heard.held) > 0 and len(heard.start) > 0

    def held_list(s, u, w):
        # The snapshot of w's list u held at its snapshot s, from the ring of holdings by step.
        step = int(heard.held[(heard.steps[0] + s) % len(heard.held), u, w])
        return step - int(heard.steps[0]) if step >= heard.steps[0] else -1

    for i in range(n):
        nb = np.flatnonzero(known[i] & (np.arange(n) != i))
        m = len(nb)
        if m < 2:
            continue
        # Two hops out: every robot a remembered robot's list names (still remembered by its
        # sender at t0), at the position of the freshest such entry.
        far: dict[int, tuple[float, np.ndarray]] = {}
        if two_hops:
            for u in nb.tolist():
                entries, named = reported(heard, i, u, t0_s)
                for p, w in zip(entries.tolist(), named.tolist()):
                    if w != i and not known[i, w] and (w not in far or heard.sent_s[p] > far[w][0]):
                        far[w] = (float(heard.sent_s[p]), heard.xy[p])
        beyond = np.array(sorted(far), dtype=int)
        node = np.r_[i, nb, beyond]
        k = len(node)
        at = {int(v): a for a, v in enumerate(node)}
        # certain[a, b]: i can tell that node a remembers node b at t0.
        certain = np.zeros((k, k), dtype=bool)
        certain[0, 1 : m + 1] = True if silent_of is None else ~silent_of[i, nb]
        for a in range(1, m + 1):
            u = int(node[a])
            for w in reported(heard, i, u, t0_s)[1].tolist():
                if w in at:
                    certain[a, at[w]] = True
            s = heard.which[i, u]
            if two_hops and s >= 0:
                # The lists u held of the robots two hops out that its list names (whether u
                # still remembers them or not, they tell whom those robots remember).
                for w in heard.other[heard.start[s, u] : heard.start[s, u + 1]].tolist():
                    if w in far and held_list(s, u, w) >= 0:
                        h = held_list(s, u, w)
                        entries = np.arange(heard.start[h, w], heard.start[h, w + 1])
                        still = t0_s - heard.sent_s[entries] < heard.release_s
                        for x in heard.other[entries[still]].tolist():
                            if x in at:
                                certain[at[w], at[x]] = True
        q = np.concatenate([pos[i : i + 1], memory.xy[i, nb], np.array([far[w][1] for w in beyond]).reshape(-1, 2)])
        sent = np.r_[t0_s, memory.sent_s[i, nb], [far[w][0] for w in beyond]]
        e = speed_mps * np.maximum(t0_s - sent, 0.0)
        centre = np.hypot(*(q[:, None, :] - q[None, :, :]).transpose(2, 0, 1))
        pair = np.minimum.outer(node, node) * n + np.maximum.outer(node, node)
        longest = centre + e[:, None] + e[None, :]
        rank = link_rank(longest, pair, band_m, n) + 1.0
        sweep = np.zeros(k)
        if window_s > 0:
            sweep = largest_travel_m(
                np.where(np.arange(k) > m, np.nan, memory.leg_speed_mps[i, node]),
                memory.leg_from_s[i, node],
                memory.leg_until_s[i, node],
                np.full(k, t0_s - window_s),
                t0_s,
                speed_mps,
            )
        usable = certain & certain.T
        np.fill_diagonal(usable, False)
        a, b = np.nonzero(np.triu(usable, 1))
        # Up with each end anywhere within its whole travel over the window, or followed
        # along its leg piece by piece where an end may have moved.
        swept = longest[a, b] + sweep[a] + sweep[b]
        ok = swept <= range_m
        if walls.on:
            ok &= up_by_walls(walls, q[a], q[b], e[a] + sweep[a], e[b] + sweep[b], swept)
        retry = ~ok & (sweep[a] + sweep[b] > 0)
        if retry.any():
            legs = window_legs(memory, i, node, m, t0_s, window_s)
            ok[retry] = up_over_window(q, e, legs, a[retry], b[retry], t0_s, window_s, speed_mps, range_m, walls)
        usable[a[~ok], b[~ok]] = usable[b[~ok], a[~ok]] = False
        tree = minimum_spanning_tree(np.where(usable, rank, 0.0))
        order, pred = breadth_first_order(tree + tree.T, 0, directed=False, return_predecessors=True)
        worst = np.full(len(node), np.inf)
        worst[0] = 0.0
        for v, u in zip(order[1:].tolist(), pred[order[1:]].tolist()):
            worst[v] = max(worst[u], rank[u, v])
        shortest = np.maximum(centre[0, 1 : m + 1] - e[1 : m + 1], 0.0)
        out[i, nb] = worst[1 : m + 1] < link_rank(shortest, pair[0, 1 : m + 1], band_m, n) + 1.0
    return out


def up_by_walls(walls: Walls, qa, qb, ea, eb, longest) -> np.ndarray:
    """A link between the disks ``D(qa, ea)`` and ``D(qb, eb)``, at most ``longest`` long, is
    surely clear of walls or within the range through the walls its hull meets."""
    ok = clear_of_walls(walls, qa, qb, ea, eb)
    if len(walls.through_m):
        met = walls_met(walls, qa, qb, ea, eb)
        through = np.r_[-np.inf, walls.through_m, -np.inf][np.minimum(met, len(walls.through_m) + 1)]
        ok |= (met > 0) & (longest <= through)
    return ok


# As the kernel cuts the window (netsim.mobility._local_kernels.WINDOW_PIECES).
WINDOW_PIECES = 8


def window_legs(memory: Memory, i: int, node: np.ndarray, m: int, t0_s: float, window_s: float):
    """Each node's known leg over the window as robot ``i`` knows it: when it starts (the
    window's opening at the earliest), its velocity and its speed; none (a robot two hops out, or a
    speed unknown): starting at ``t0_s`` with no velocity."""
    known = (np.arange(len(node)) <= m) & ~np.isnan(memory.leg_speed_mps[i, node])
    start = np.where(known, np.clip(memory.leg_from_s[i, node], t0_s - window_s, t0_s), t0_s)
    velocity = np.where(known[:, None], memory.leg_velocity_mps[i, node], 0.0)
    return start, velocity, np.where(known, memory.leg_speed_mps[i, node], 0.0)


def up_over_window(q, e, legs, a, b, t0_s, window_s, speed_mps, range_m, walls: Walls) -> np.ndarray:
    """The links ``(a, b)`` up at every instant of the window: on each of its
    :data:`WINDOW_PIECES` pieces, each end within the disk that holds it over the piece (on
    its known leg, about where the leg puts it at the piece's middle; before the leg, about
    where the leg starts, widened by the cap's travel), the disks within the range and
    clear of walls (or within the range through them)."""
    start, velocity, speed = legs
    opens = t0_s - window_s
    span = (t0_s - opens) / WINDOW_PIECES
    ok = np.ones(len(a), dtype=bool)
    for p in range(WINDOW_PIECES):
        s0 = opens + p * span
        s1 = t0_s if p == WINDOW_PIECES - 1 else opens + (p + 1) * span
        on_leg = s0 >= start
        back = np.where(on_leg, t0_s - 0.5 * (s0 + s1), t0_s - start)
        centre = q - velocity * back[:, None]
        before = np.maximum(speed_mps * (start - s0), speed * np.maximum(s1 - start, 0.0))
        radius = e + np.where(on_leg, speed * 0.5 * (s1 - s0), before)
        longest = np.hypot(*(centre[a] - centre[b]).T) + radius[a] + radius[b]
        ok &= longest <= range_m
        if walls.on:
            ok &= up_by_walls(walls, centre[a], centre[b], radius[a], radius[b], longest)
    return ok


def largest_travel_m(
    leg_speed_mps: np.ndarray,
    leg_from_s: np.ndarray,
    leg_until_s: np.ndarray,
    since_s: np.ndarray,
    t0_s: float,
    speed_mps: float,
) -> np.ndarray:
    """The farthest a robot can have travelled from ``since_s`` to ``t0_s``: at the speed its
    Ack carried (``leg_speed_mps``, its leg's, which holds from ``leg_from_s`` until its
    next step, ``leg_until_s``) where that is known, at the speed cap before and after it,
    and at the cap all along where no speed is known (NaN). numpy's reading of
    :func:`netsim.mobility._local_kernels.largest_travel_m`, element by element.

    >>> speed, leg_from = np.array([0.0, 0.5, np.nan, 0.0]), np.array([9.0, 9.5, np.inf, 8.5])
    >>> largest_travel_m(speed, leg_from, np.array([np.inf, np.inf, np.inf, 9.0]), np.full(4, 8.0), 10.0, 1.0).tolist()
    [1.0, 1.75, 2.0, 1.5]
    """
    since = np.asarray(since_s, float)
    with np.errstate(invalid="ignore"):
        known = ~np.isnan(leg_speed_mps)
        start = np.clip(np.maximum(leg_from_s, since), None, t0_s)
        end = np.clip(np.maximum(leg_until_s, start), None, t0_s)
        on_leg = np.nan_to_num(leg_speed_mps) * np.maximum(end - start, 0.0)
        out = np.where(
            known,
            speed_mps * np.maximum(start - since, 0.0) + on_leg + speed_mps * np.maximum(t0_s - end, 0.0),
            speed_mps * np.maximum(t0_s - since, 0.0),
        )
    return np.where(np.isfinite(since), out, np.inf)
