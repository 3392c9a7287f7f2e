"""The local plan's loops (compiled or plain, :func:`netsim.compiled.load`): rule 1
(:func:`netsim.mobility.local.let_go`), per robot the bottleneck of its certified detours,
by a widest-path search over the robots it remembers, a link surely up within the plan's
range or, under shadowing, within the range its measured shadowing allows over the pair's
travel since, as far as the robot knows it (:func:`measured_range_m`,
:func:`largest_travel_m`); and the walls' test
(:func:`netsim.mobility.local.clear_of_walls`). The tests compare them with numpy oracles
(tests/oracles/local.py).
"""

from __future__ import annotations

import math

import numpy as np
from netsim.mobility._fade_kernels import plausible_change_db, range_at_m

from netsim.compiled import jit


@jit(nogil=True, walks=True)
def clear(walls, ax, ay, bx, by, ea, eb):
    """The convex hull of the disks of radius ``ea`` around ``(ax, ay)`` and ``eb`` around
    ``(bx, by)`` meets no wall (:func:`netsim.mobility.local.clear_of_walls`, one pair)."""
    field = walls.field
    h, w = field.shape
    res = walls.resolution_m
    length = math.hypot(bx - ax, by - ay)
    growth = abs(eb - ea) / length if length > 0 else 0.0
    t = 0.0
    while True:
        f = t / length if length > 0 else 0.0
        u = (ax + f * (bx - ax) - walls.origin_x_m) / res
        v = (ay + f * (by - ay) - walls.origin_y_m) / res
        ci = min(max(math.floor(u), 0), w - 1)
        cj = min(max(math.floor(v), 0), h - 1)
        radius = ea + f * (eb - ea) if length > 0 else max(ea, eb)
        gap = field[cj, ci] - math.hypot(u - ci - 0.5, v - cj - 0.5) * res - radius
        if gap <= walls.step_m:
            return False
        if t >= length:
            return True
        t = min(t + gap / (1.0 + growth), length)


@jit(nogil=True, walks=True)
def clear_many(walls, a, b, ea, eb, out):
    """:func:`clear` for every row."""
    for k in range(a.shape[0]):
        out[k] = clear(walls, a[k, 0], a[k, 1], b[k, 0], b[k, 1], ea[k], eb[k])


@jit(nogil=True)
def largest_travel_m(leg_speed_mps, leg_from_s, since_s, t0_s, speed_mps):
    """The farthest a robot can have travelled from ``since_s`` to ``t0_s``: at the speed its
    Ack carried from ``leg_from_s`` on (NaN: unknown), at the speed cap before
    (one pair)."""
    if not since_s > -math.inf:
        return math.inf
    if math.isnan(leg_speed_mps):
        return speed_mps * max(t0_s - since_s, 0.0)
    start = min(max(leg_from_s, since_s), t0_s)
    return speed_mps * max(start - since_s, 0.0) + leg_speed_mps * max(t0_s - start, 0.0)


@jit(nogil=True)
def largest_travels_m(leg_speed_mps, leg_from_s, since_s, t0_s, speed_mps):
    """:func:`largest_travel_m` of every ``(i, j)`` of the ``(n, m)`` arrays: robot ``j``'s
    leg as ``i`` knows it, since ``since_s[i, j]``."""
    out = np.empty(since_s.shape)
    for i in range(since_s.shape[0]):
        for j in range(since_s.shape[1]):
            out[i, j] = largest_travel_m(leg_speed_mps[i, j], leg_from_s[i, j], since_s[i, j], t0_s, speed_mps)
    return out


@jit(nogil=True)
def measured_range_m(x_db, measured_s, travel_m, fade):
    """How long a link whose shadowing was measured at ``x_db`` on a frame sent no earlier
    than ``measured_s`` can surely be now (0: no measurement): the length at which its
    margin meets the sensitivity after the plausible change of the shadowing over the
    pair's largest travel since, ``travel_m`` (each end's by :func:`largest_travel_m`).
    ``fade``: ``(on, sigma_db, decorrelation_m, budget_db, reference_distance_m, exponent)``."""
    on, sigma_db, decorrelation_m, budget_db, d0_m, exponent = fade
    if not on or math.isnan(x_db) or not measured_s > -math.inf:
        return 0.0
    change = plausible_change_db(travel_m, x_db, sigma_db, decorrelation_m)
    return range_at_m(x_db + change, budget_db, d0_m, exponent)


@jit(nogil=True)
def let_go(pos, memory, lists, rule, walls, out, fade, measured):
    """Fill ``out[i, j]`` (False on entry): robot ``i`` knows a certified detour to ``j``
    through robots it remembers (:func:`netsim.mobility.local.let_go`). ``memory``: what the
    robots remember, ``(xy, sent_s, known, silent)``, ``silent[i, j]``: ``i``'s link to ``j``
    was down in the window (:class:`netsim.mobility.local.Silence`), never a detour's link
    (``j`` still a node); ``lists``: the lists they hold from each other
    (:class:`netsim.mobility.local.Heard`), ``(which, start, other, sent_s)``; ``rule``: the
    step's ``(t0_s, speed_mps, band_m, range_m, release_s, window_s)``, a detour's link
    certified up over ``[t0_s - window_s, t0_s]`` (0: at ``t0_s``): each end farther from
    where it is at ``t0_s`` by its largest travel over the window, and a measured link's
    pair travel counted from the window's start where that is earlier than the measurement
    (:func:`largest_travel_m`); ``fade``: the shadowing's rule
    (:func:`measured_range_m`, ``on`` False: none); ``measured``: the shadowing each robot
    measured on each robot's latest Ack and when it can have been sent, ``(x_db (n, n),
    measured_s (n, n), listed_x_db (M,), leg_speed_mps (n, n), leg_from_s (n, n))``, the
    third for the lists' entries, the last two the speeds each robot knows (its own on the
    diagonal; :func:`largest_travel_m`)."""
    xy, sent_s, known, silent = memory
    which, start, other, listed_s = lists
    t0_s, speed_mps, band_m, range_m, release_s, window_s = rule
    opens_s = t0_s - window_s
    x_db, measured_s, listed_x, leg_speed, leg_from = measured
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
    # sweep[a]: node a's largest travel over the window, as i knows it.
    sweep = np.zeros(n)
    worst = np.empty(n)
    done = np.empty(n, np.bool_)
    for i in range(n):
        k = 1
        node[0] = i
        qx[0], qy[0], e[0] = pos[i, 0], pos[i, 1], 0.0
        for j in range(n):
            if known[i, j]:
                node[k] = j
                qx[k], qy[k] = xy[i, j, 0], xy[i, j, 1]
                e[k] = speed_mps * max(t0_s - sent_s[i, j], 0.0)
                k += 1
        m = k - 1
        if m < 2:
            continue
        if window_s > 0:
            for a in range(k):
                u = node[a]
                sweep[a] = largest_travel_m(leg_speed[i, u], leg_from[i, u], opens_s, t0_s, speed_mps)
        # certain[a, b]: i can tell that node a remembers node b at t0 (from a's list).
        for a in range(k):
            local[node[a]] = a
            for b in range(k):
                certain[a, b] = a == 0 and b > 0 and not silent[i, node[b]]
                sure[a, b] = range_m
        for b in range(1, k):
            # The pair's travel since the measurement: each end's, as far as i knows it; over
            # a window, from its start if earlier (an instant of the window before the
            # measurement is within the window's travel of it: the shadowing's change
            # depends on the pair's travel between the two instants, either way).
            j = node[b]
            s_ij = min(measured_s[i, j], opens_s) if window_s > 0 else measured_s[i, j]
            travel = largest_travel_m(leg_speed[i, i], leg_from[i, i], s_ij, t0_s, speed_mps)
            travel += largest_travel_m(leg_speed[i, j], leg_from[i, j], s_ij, t0_s, speed_mps)
            r = measured_range_m(x_db[i, j], s_ij, travel, fade)
            sure[0, b] = max(sure[0, b], r)
            sure[b, 0] = sure[0, b]
        for a in range(1, k):
            u = node[a]
            s = which[i, u]
            if s < 0:
                continue
            for p in range(start[s, u], start[s, u + 1]):
                b = local[other[p]]
                if b >= 0 and t0_s - listed_s[p] < release_s:
                    certain[a, b] = True
                    s_p = min(listed_s[p], opens_s) if window_s > 0 else listed_s[p]
                    listed = node[b]
                    travel = largest_travel_m(leg_speed[i, u], leg_from[i, u], s_p, t0_s, speed_mps)
                    travel += largest_travel_m(leg_speed[i, listed], leg_from[i, listed], s_p, t0_s, speed_mps)
                    r = measured_range_m(listed_x[p], s_p, travel, fade)
                    sure[a, b] = max(sure[a, b], r)
                    sure[b, a] = max(sure[b, a], r)
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
                longest = math.hypot(qx[u] - qx[v], qy[u] - qy[v]) + e[u] + e[v]
                if longest + sweep[u] + sweep[v] > sure[u, v]:
                    continue
                # From the node met first in the list (the order the oracle walks too).
                a, b = min(u, v), max(u, v)
                if walls.on and not clear(walls, qx[a], qy[a], qx[b], qy[b], e[a] + sweep[a], e[b] + sweep[b]):
                    continue
                rank = math.floor(longest / band_m) * nn + float(min(nu, nv) * n + max(nu, nv)) + 1.0
                w = max(worst[u], rank)
                if w < worst[v]:
                    worst[v] = w
        for a in range(1, m + 1):
            j = node[a]
            shortest = max(math.hypot(qx[a] - qx[0], qy[a] - qy[0]) - e[a], 0.0)
            rank = math.floor(shortest / band_m) * nn + float(min(i, j) * n + max(i, j)) + 1.0
            out[i, j] = worst[a] < rank
