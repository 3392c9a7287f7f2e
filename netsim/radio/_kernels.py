"""Compiled (numba) loops behind :mod:`netsim.radio.los` and :mod:`netsim.radio.shadowing`.

Each computes exactly what its numpy counterpart computes, with the same arithmetic, one item
at a time: for the few tens of pairs a transmission involves, numpy's cost per operation, not
the arithmetic, is what a call costs. The tests check that both agree exactly.
"""

from __future__ import annotations

import numpy as np

from netsim.compiled import jit


@jit(nogil=True)
def cell(flat, w, half, pc, sc, p_max, s_max):
    pc = min(max(pc, 0), p_max)
    sc = min(max(sc, 0), s_max)
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
    i0 = min(max(np.int64(np.floor(u0)), 0), w - 1)
    j0 = min(max(np.int64(np.floor(v0)), 0), h - 1)
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
    are put on it first (``netsim.radio.los._snap``), so that walls at a robot on a grid
    corner are the same both ways."""
    count, _ = trace_one(cells, _snap(u0, eps), _snap(v0, eps), _snap(u1, eps), _snap(v1, eps), eps, limit)
    return count


@jit(nogil=True)
def trace(cells, points, eps, out, limit, snap):
    """Every segment's walls (counting stops once past ``limit``) and first blocked point,
    ``out``: ``(walls, first_t)``, filled; the segments from ``g0`` to ``g1`` (``points``, grid
    units) on the grid ``cells``, ``(flat, h, w)``. With ``snap``, the ends snapped as
    :func:`walls_one` does."""
    g0, g1 = points
    walls, first_t = out
    for s in range(g0.shape[0]):
        u0, v0, u1, v1 = g0[s, 0], g0[s, 1], g1[s, 0], g1[s, 1]
        if snap:
            u0, v0, u1, v1 = _snap(u0, eps), _snap(v0, eps), _snap(u1, eps), _snap(v1, eps)
        walls[s], first_t[s] = trace_one(cells, u0, v0, u1, v1, eps, limit)


@jit(nogil=True)
def slot(table_keys, dense_n, key):
    """Where ``key`` is (or would go) in the table: computed when every pair of ``dense_n``
    robots has its slot (keys in ascending order, lower id major), else a binary search."""
    if dense_n > 0:
        i = key >> 32
        j = key & 0xFFFFFFFF
        return i * dense_n - (i * (i + 1)) // 2 + (j - i - 1)
    return np.searchsorted(table_keys, key)


@jit(nogil=True)
def shadow_step(shadow, law, pairs, out):
    """Move the stored pairs among ``keys`` on to travel ``s_new`` (in place): their values
    to ``x``; flag the others in ``new``. ``shadow``: the records and the normals, taken in
    order, ``(table_keys, table_x, table_s, z)``; ``law``: ``(sigma, decorrelation_m,
    dense_n)``; ``pairs``: ``(keys, s_new)``; ``out``: ``(x, new)``, filled."""
    table_keys, table_x, table_s, z = shadow
    sigma, decorrelation_m, dense_n = law
    keys, s_new = pairs
    x, new = out
    n = table_keys.shape[0]
    for m in range(keys.shape[0]):
        pos = slot(table_keys, dense_n, keys[m])
        # A slot holding NaN is a pair listed in advance but never seen yet; with every pair
        # listed (dense_n > 0) the slot is the pair's, and its key need not be read.
        if pos < n and (dense_n > 0 or table_keys[pos] == keys[m]) and not np.isnan(table_x[pos]):
            delta = max(s_new[m] - table_s[pos], 0.0)
            rho = np.exp(-delta / decorrelation_m)
            v = rho * table_x[pos] + sigma * np.sqrt(1.0 - rho * rho) * z[m]
            table_x[pos] = v
            table_s[pos] = max(s_new[m], table_s[pos])
            x[m] = v
            new[m] = False
        else:
            new[m] = True


@jit(nogil=True)
def path_loss_pass(frame, d, loss, alive):
    """Path loss of each pair, and whether the terms after it could still let it through
    (``frame``: the run's constants, :data:`netsim.radio.fast.FRAME`)."""
    c = frame[0]
    d0, pl0, n10, rest_db, budget_slack = c.d0_m, c.pl0_db, c.n10, -c.clip_db, c.budget_slack
    count = 0
    for m in range(d.shape[0]):
        loss[m] = 0.0 + (pl0 + n10 * np.log10(max(d[m], d0) / d0))
        ok = loss[m] + rest_db <= budget_slack
        alive[m] = ok
        if ok:
            count += 1
    return count


@jit(nogil=True)
def budget_pass(frame, sigma, path, shadow, flat, points, pairs):
    """Shadowing (when ``sigma`` > 0) and walls (when the run has a wall loss) for the pairs
    still alive, then the decision ``tx - loss >= sensitivity``: the loss chain in one pass.
    ``frame``: the run's constants; ``path``: :func:`path_loss_pass`'s ``(loss, alive)``;
    ``shadow``: the shadowing's records
    (:meth:`~netsim.radio.shadowing.PairShadowing.table`) and its normals, taken in order,
    ``(table_keys, table_x, table_s, z)``; ``flat``: the map's occupied cells; ``points``:
    the ends in grid units, ``(g0, g1)``; ``pairs``: ``(keys, s_new, x_new, new,
    receivable)``, the keys and travels read (shadowing), the rest filled."""
    c = frame[0]
    loss, alive = path
    table_keys, table_x, table_s, z = shadow
    g0, g1 = points
    keys, s_new, x_new, new, receivable = pairs
    decorrelation_m, clip_db, wall_db, dense_n = c.decorrelation_m, c.clip_db, c.wall_db, c.dense_n
    cells, eps, budget_slack = (flat, c.map_h, c.map_w), c.eps, c.budget_slack
    tx_dbm, sensitivity_dbm = c.tx_dbm, c.sensitivity_dbm
    n = table_keys.shape[0]
    j = 0
    for m in range(loss.shape[0]):
        receivable[m] = False
        new[m] = False
        if not alive[m]:
            continue
        total = loss[m]
        if sigma > 0.0:
            pos = slot(table_keys, dense_n, keys[m])
            if pos < n and (dense_n > 0 or table_keys[pos] == keys[m]) and not np.isnan(table_x[pos]):
                delta = max(s_new[m] - table_s[pos], 0.0)
                rho = np.exp(-delta / decorrelation_m)
                v = rho * table_x[pos] + sigma * np.sqrt(1.0 - rho * rho) * z[j]
                table_x[pos] = v
                table_s[pos] = max(s_new[m], table_s[pos])
            else:
                v = sigma * z[j]
                new[m] = True
                x_new[m] = v
            j += 1
            total = total + min(max(v, -clip_db), clip_db)
        if wall_db > 0.0:
            if total > budget_slack:
                continue
            # Counting stops two walls past what the margin affords: the pair is then out,
            # whatever rounding the division made.
            affordable = (budget_slack - total) / wall_db
            limit = np.int64(affordable) + 1 if affordable < 1e18 else np.iinfo(np.int64).max
            walls = walls_one(cells, g0[m, 0], g0[m, 1], g1[m, 0], g1[m, 1], eps, limit)
            total = total + wall_db * walls
        receivable[m] = tx_dbm - total >= sensitivity_dbm


@jit(nogil=True)
def disk_pass(frame, d, a, range_m, flat, points, receivable):
    """The unit disk (the sender's range: ``range_m[a]``, or ``range_m[0]`` for all), with
    line of sight on a map (``flat``, the ends in grid units ``points``: ``(g0, g1)``)."""
    c = frame[0]
    g0, g1 = points
    for m in range(d.shape[0]):
        r = range_m[a[m]] if c.per_robot else range_m[0]
        ok = d[m] <= r
        if ok and c.use_map:
            walls = walls_one((flat, c.map_h, c.map_w), g0[m, 0], g0[m, 1], g1[m, 0], g1[m, 1], c.eps, 0)
            ok = walls == 0
        receivable[m] = ok


@jit(nogil=True)
def pair_clock(sender, receivers, odometer, speed, t0, t, step_m, keys, s_new):
    """Each pair's key, and its shadowing clock: the pair's travel at ``t`` (the two robots'
    :meth:`~netsim.state.RobotState.travelled_m` summed, ``speed`` being ``|v|`` as numpy
    computes it), floored to a multiple of ``step_m`` when ``step_m`` > 0
    (:meth:`~netsim.radio.shadowing.PairShadowing.anchor`)."""
    own = odometer[sender] + speed[sender] * (t - t0[sender])
    for m in range(receivers.shape[0]):
        r = receivers[m]
        travel = (odometer[r] + speed[r] * (t - t0[r])) + own
        s_new[m] = np.floor(travel / step_m) * step_m if step_m > 0.0 else travel
        keys[m] = (min(sender, r) << 32) | max(sender, r)


@jit(nogil=True)
def link_changes(up, sender, receivers, linked, scratch, changed):
    """Robots whose link with ``sender`` differs from ``up[sender]`` once this decision is
    taken (heard: up; otherwise down), written to ``changed``; returns how many.
    ``scratch`` is all False on entry and on return."""
    for m in range(receivers.shape[0]):
        if linked[m]:
            scratch[receivers[m]] = True
    count = 0
    row = up[sender]
    for j in range(row.shape[0]):
        if row[j] != scratch[j]:
            changed[count] = j
            count += 1
    for m in range(receivers.shape[0]):
        scratch[receivers[m]] = False
    return count


@jit(nogil=True)
def link_touches(up, sender, receivers, linked, t0, last_t, every, touched):
    """Robots heard by ``sender`` whose link with it is already up and that may have left
    the reach since the pair's last decision: one of the two started a leg (or jumped) at or
    after it (``t0``; the last decision is the later of the two robots' last sends,
    ``last_t``), or ``every``. Written to ``touched``; returns how many."""
    count = 0
    own_t0 = t0[sender]
    own_last = last_t[sender]
    for m in range(receivers.shape[0]):
        if not linked[m]:
            continue
        r = receivers[m]
        if not up[sender, r]:
            continue
        p = max(own_last, last_t[r])
        if every or own_t0 >= p or t0[r] >= p:
            touched[count] = r
            count += 1
    return count


@jit(nogil=True)
def grid_points(frame, t, sender, receivers, motion, points):
    """Grid coordinates (the map grid of ``frame``) of the sender (every row of ``g0``) and
    of each receiver (``g1``) at ``t``, ``points``: ``(g0, g1)``, filled. The positions of
    :meth:`~netsim.state.RobotState.positions_at` (plane), the same arithmetic in the same
    order; ``motion``: the state's ``(origin_m, velocity_mps, t0_s)``."""
    c = frame[0]
    map_ox, map_oy, res = c.map_ox, c.map_oy, c.res_m
    origin_m, velocity_mps, t0 = motion
    g0, g1 = points
    dt = t - t0[sender]
    u0 = (origin_m[sender, 0] + velocity_mps[sender, 0] * dt - map_ox) / res
    v0 = (origin_m[sender, 1] + velocity_mps[sender, 1] * dt - map_oy) / res
    for m in range(receivers.shape[0]):
        r = receivers[m]
        dt = t - t0[r]
        g0[m, 0] = u0
        g0[m, 1] = v0
        g1[m, 0] = (origin_m[r, 0] + velocity_mps[r, 0] * dt - map_ox) / res
        g1[m, 1] = (origin_m[r, 1] + velocity_mps[r, 1] * dt - map_oy) / res


@jit(nogil=True)
def log_frame(frame, t, sender, receivers, distance_m, robots, shadow, flat, out):
    """One frame under log-distance path loss, with shadowing when the run's ``sigma_db`` >
    0 and walls when its ``wall_db`` > 0: :func:`pair_clock`, :func:`grid_points`,
    :func:`path_loss_pass` and :func:`budget_pass` in one call.

    ``frame``: the run's constants (:data:`netsim.radio.fast.FRAME`); ``robots``: the
    state's ``(odometer_m, speed_mps, t0_s, origin_m, velocity_mps)``; ``shadow``: the
    shadowing's ``(table_keys, table_x, table_s, normals)``, the normals taken in order;
    ``flat``: the map's occupied cells; ``out``: ``(keys, s_new, x_new, new, receivable)``,
    filled. Pairs met for the first time get their slot at once when every pair has one
    (``dense_n`` > 0); otherwise they are left flagged in ``new`` for the caller to insert.
    Returns the number of normals used."""
    c = frame[0]
    odometer, speed, t0, origin_m, velocity_mps = robots
    table_keys, table_x, table_s, _normals = shadow
    keys, s_new, x_new, new, _receivable = out
    sigma, dense_n = c.sigma_db, c.dense_n
    k = receivers.shape[0]
    if sigma > 0.0:
        pair_clock(sender, receivers, odometer, speed, t0, t, c.step_m, keys, s_new)
    if c.wall_db > 0.0:
        points = (np.empty((k, 2)), np.empty((k, 2)))
        grid_points(frame, t, sender, receivers, (origin_m, velocity_mps, t0), points)
    else:
        none = np.zeros((1, 2))
        points = (none, none)
    loss = np.empty(k)
    alive = np.empty(k, dtype=np.bool_)
    count = path_loss_pass(frame, distance_m, loss, alive)
    if count == 0:
        sigma = 0.0
    budget_pass(frame, sigma, (loss, alive), shadow, flat, points, out)
    if dense_n > 0 and sigma > 0.0:
        for m in range(k):
            if new[m]:
                pos = slot(table_keys, dense_n, keys[m])
                table_x[pos] = x_new[m]
                table_s[pos] = s_new[m]
                new[m] = False
    return count if sigma > 0.0 else 0


@jit(nogil=True)
def disk_frame(frame, t, sender, receivers, distance_m, range_m, robots, flat, receivable):
    """One frame under the unit disk (the sender's range), with line of sight on a map:
    :func:`grid_points` and :func:`disk_pass` in one call. ``robots``: the state's
    ``(origin_m, velocity_mps, t0_s)``."""
    c = frame[0]
    k = receivers.shape[0]
    if c.use_map:
        points = (np.empty((k, 2)), np.empty((k, 2)))
        grid_points(frame, t, sender, receivers, robots, points)
    else:
        none = np.zeros((1, 2))
        points = (none, none)
    senders = np.full(k, sender, dtype=np.int64)
    disk_pass(frame, distance_m, senders, range_m, flat, points, receivable)


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


@jit(nogil=True)
def free_destinations(cells, grid, draws, here, batch, eps, out):
    """One round of :func:`netsim.radio.free_space.draw_destinations` for robots at ``here``:
    robot ``k``'s ``batch`` candidates are drawn as ``sample_free`` draws them (a cell by
    area from ``draw_cell``, a point in it from ``draw_uv``; a point that rounding put outside
    a free cell moved to its cell's centre), and the first whose straight leg from ``here[k]``
    stays in free cells is kept (``got[k]``). Legs after the first free one are not traced.

    ``cells``: the free cells to draw from, ``(cdf, x0, x1, y0, y1)`` (cumulative area,
    bounds in metres); ``grid``: the map's ``(free_flat, not_free_flat, h, w, ox, oy,
    res)``; ``draws``: ``(draw_cell, draw_uv)``; ``out``: ``(picked, got)``, filled."""
    cdf, x0, x1, y0, y1 = cells
    free_flat, not_free_flat, h, w, ox, oy, res = grid
    draw_cell, draw_uv = draws
    picked, got = out
    last = cdf.shape[0] - 1
    total = cdf[last]
    for k in range(here.shape[0]):
        got[k] = False
        hu = (here[k, 0] - ox) / res
        hv = (here[k, 1] - oy) / res
        for b in range(batch):
            c = k * batch + b
            cell = min(first_above(cdf, draw_cell[c] * total), last)
            x = x0[cell] + draw_uv[c, 0] * (x1[cell] - x0[cell])
            y = y0[cell] + draw_uv[c, 1] * (y1[cell] - y0[cell])
            u = (x - ox) / res
            v = (y - oy) / res
            free = False
            if u >= 0 and u <= w and v >= 0 and v <= h:
                i = min(np.int64(np.floor(u)), w - 1)
                j = min(np.int64(np.floor(v)), h - 1)
                free = free_flat[j * w + i]
            if not free:
                x = 0.5 * (x0[cell] + x1[cell])
                y = 0.5 * (y0[cell] + y1[cell])
                u = (x - ox) / res
                v = (y - oy) / res
            walls, _ = trace_one((not_free_flat, h, w), hu, hv, u, v, eps, 0)
            if walls == 0:
                picked[k, 0] = x
                picked[k, 1] = y
                got[k] = True
                break


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
