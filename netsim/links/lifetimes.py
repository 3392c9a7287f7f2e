"""Exact link up/down times, solved from the robots' piecewise-linear trajectories.

Two robots on straight legs have relative position ``d + w t``; they are linked while
``|d + w t| <= R`` with ``R = min(r_a, r_b)`` (both hear each other), so the link comes up
and goes down at the roots of ``|w|^2 t^2 + 2 (d.w) t + |d|^2 - R^2 = 0``. Nothing is
sampled: the times are as exact as floating point allows, whatever the output interval.

The run is cut into windows: each as long as half a range at the speed of the fastest
leg current at its start, ended where a faster leg begins, and cut at every jump (a leg
that does not start where the previous one ended: a trace's ``set X_``, or any model that
places a robot). The candidate pairs of a window are those within ``R_max + 2 D`` at its
start, ``D`` the longest path a robot can travel in it (no other pair can meet during
it), found with :func:`netsim.geometry.near_pairs`. Pairs whose robots keep their legs
through the window are solved in one vectorised step; pairs where a robot changes course
are solved leg piece by leg piece.
At a jump the links of the robots that jumped are judged afresh on their new positions:
a link opens or closes at the jump instant exactly.

On a torus every image of the other robot counts, not only the nearest one at the start
of a piece: with a side below about ``4 R`` another image can come into range within a
piece. The images whose disks the relative path can reach are each solved; as the side
exceeds ``2 R`` their disks are disjoint, so the union of their intervals is the link's.

A link up at t = 0 or still up at the end is censored; ``censored`` is true for both,
``censored_start`` and ``censored_end`` say which.
"""

from __future__ import annotations

from collections.abc import Callable
from types import ModuleType

import numpy as np
import pandas as pd

from netsim.compiled import load
from netsim.geometry import link_ranges_m, near_pairs, speeds_mps
from netsim.links._kernels import PHASE_STATE
from netsim.trajectory import LegTable

COLUMNS = ["a", "b", "t_up_s", "t_down_s", "censored", "censored_start", "censored_end"]


def jump_times(L: LegTable, box: float | None = None) -> tuple[np.ndarray, np.ndarray]:
    """Legs that start with a jump (:meth:`~netsim.trajectory.LegTable.jumps`; on a torus of
    side ``box``), as ``(t, robot)``."""
    k = np.flatnonzero(L.jumps(box))
    return L.t[k], L.robot[k]


def link_events(
    legs: pd.DataFrame,
    range_m: float | np.ndarray,
    duration_s: float,
    side_m: float | None = None,
    torus: bool = False,
    window_s: float | None = None,
) -> tuple[np.ndarray, ...]:
    """Up (+1) and down (-1) events of every link, as arrays ``(t, a, b, kind, phase)``.

    ``phase`` orders events of a pair at the same instant (``netsim.links._kernels.PHASE_*``). ``window_s``
    overrides the solver's window (the results do not depend on it).
    """
    n = len(np.atleast_1d(range_m)) if np.ndim(range_m) else int(legs["robot"].max()) + 1
    ranges = np.broadcast_to(np.asarray(range_m, float), (n,))
    L = LegTable(legs, n)
    kernels = load("netsim.links._kernels", n)
    speed = speeds_mps(L.v) if len(L.v) else np.zeros(0)
    r_max, r_half = float(ranges.max()), 0.5 * float(ranges.min())
    # Each window is sized by the legs current at its start, and ends where a faster leg
    # begins: a fast leg (a metre between two near-equal stamps of a recorded trace, a
    # robot driven at any speed) shortens only the windows it is current in, instead of
    # cutting the whole run into microseconds.
    by_start = np.argsort(L.t, kind="stable")
    leg_start, leg_robot = L.t[by_start], L.robot[by_start]
    leg_speed, leg_stop = speed[by_start], L.end_times(duration_s)[by_start]
    box = float(side_m) if torus else None  # type: ignore[arg-type]  # side_m is given with torus
    jt, jr = jump_times(L, box)
    inside = (jt > 0) & (jt < duration_s)
    jt, jr = jt[inside], jr[inside]
    order = np.argsort(jt, kind="stable")
    jt, jr = jt[order], jr[order]
    cuts = np.unique(jt)

    out: list[tuple[np.ndarray, ...]] = []

    def emit(t: np.ndarray, a: np.ndarray, b: np.ndarray, k: int | np.ndarray, phase: int | np.ndarray) -> None:
        a = np.asarray(a, np.int64)
        out.append(
            (
                np.asarray(t, float),
                a,
                np.asarray(b, np.int64),
                np.broadcast_to(np.asarray(k, np.int8), a.shape),
                np.broadcast_to(np.asarray(phase, np.int8), a.shape),
            )
        )

    start = 0.0
    first = True
    while start < duration_s or first:
        L.advance(start)
        v_now = float(speed[L.cur].max(initial=0.0))
        if window_s is not None:
            stop = min(start + float(window_s), duration_s)
        else:
            stop = duration_s if v_now == 0 else min(start + max(r_half / v_now, 1e-6), duration_s)
            lo, hi = int(np.searchsorted(leg_start, start, "right")), int(np.searchsorted(leg_start, stop, "left"))
            faster = np.flatnonzero(leg_speed[lo:hi] > v_now)
            if len(faster):
                stop = float(leg_start[lo + faster[0]])
        nxt = int(np.searchsorted(cuts, start, "right"))
        if nxt < len(cuts):
            stop = min(stop, float(cuts[nxt]))
        pos = L.at(L.cur, start)
        if not first and nxt > 0 and cuts[nxt - 1] == start:
            _jump_state(L, jr[jt == start], start, pos, ranges, r_max, box, emit, kernels)
        # How far any robot can go in the window: its current leg at v_now at most, and
        # every leg it starts in the window, each for the part of it the window holds.
        lo, hi = int(np.searchsorted(leg_start, start, "right")), int(np.searchsorted(leg_start, stop, "left"))
        later = leg_speed[lo:hi] * (np.minimum(leg_stop[lo:hi], stop) - leg_start[lo:hi])
        path = v_now * (stop - start) + float(np.bincount(leg_robot[lo:hi], later, L.n).max(initial=0.0))
        reach = r_max + 2.0 * path
        pairs = near_pairs(pos, reach, box)
        if len(pairs):
            i, j = pairs[:, 0], pairs[:, 1]
            swap = i > j
            i, j = np.where(swap, j, i), np.where(swap, i, j)
            radius = link_ranges_m(ranges, i, j)
            if first:
                up = kernels.in_range(pos, i, j, radius, box or 0.0)
                emit(np.zeros(int(up.sum())), i[up], j[up], 1, PHASE_STATE)
            # Each robot's course changes in the window are its legs cur+1 .. cur+count: up
            # to the last that starts before stop.
            count = np.maximum(L.legs_at(np.arange(L.n), np.nextafter(stop, -np.inf)) - L.cur, 0)
            simple = (count[i] == 0) & (count[j] == 0)
            li, lj = L.cur[i[simple]], L.cur[j[simple]]
            _solve_legs(L, li, lj, radius[simple], start, stop - start, i[simple], j[simple], emit, box, kernels)
            if (~simple).any():
                _solve_changing(L, count, i[~simple], j[~simple], radius[~simple], start, stop, box, emit, kernels)
        first = False
        if stop >= duration_s:
            break
        start = stop
    if not out:
        empty = np.empty(0, np.int64)
        return np.empty(0), empty, empty, np.empty(0, np.int8), np.empty(0, np.int8)
    return tuple(np.concatenate(col) for col in zip(*out))


def _near(pos: np.ndarray, who: np.ndarray, r: float, box: float | None) -> tuple[np.ndarray, np.ndarray]:
    """Pairs ``(who[k], j)`` with ``j`` within ``r`` of ``who[k]`` (and maybe a little
    further: :func:`netsim.geometry.near_pairs`; callers judge the distance exactly)."""
    pairs = near_pairs(pos, r, box)
    mine = np.zeros(len(pos), bool)
    mine[who] = True
    a, b = pairs[:, 0], pairs[:, 1]
    return np.r_[a[mine[a]], b[mine[b]]], np.r_[b[mine[a]], a[mine[b]]]


def _jump_state(
    L: LegTable,
    jumpers: np.ndarray,
    t: float,
    pos: np.ndarray,
    ranges: np.ndarray,
    r_max: float,
    box: float | None,
    emit: Callable[..., None],
    kernels: ModuleType,
) -> None:
    """At a jump instant ``t``, set the state of every link of the robots that jumped: up if
    in range on the new positions ``pos``, down if it was in range on the old ones (events
    that change nothing are dropped later)."""
    jumpers = np.unique(jumpers)
    before = pos.copy()
    # The legs that were current just before t.
    before[jumpers] = L.at(L.legs_at(jumpers, np.nextafter(t, -np.inf)), t)
    a1, b1 = _near(before, jumpers, r_max, box)
    a2, b2 = _near(pos, jumpers, r_max, box)
    a, b = np.r_[a1, a2], np.r_[b1, b2]
    keep = a != b
    a, b = np.minimum(a[keep], b[keep]), np.maximum(a[keep], b[keep])
    up = kernels.in_range(pos, a, b, link_ranges_m(ranges, a, b), box or 0.0)
    emit(np.full(int(up.sum()), t), a[up], b[up], 1, PHASE_STATE)
    emit(np.full(int((~up).sum()), t), a[~up], b[~up], -1, PHASE_STATE)


def _solve_changing(
    L: LegTable,
    count: np.ndarray,
    a: np.ndarray,
    b: np.ndarray,
    radius: np.ndarray,
    start: float,
    stop: float,
    box: float | None,
    emit: Callable[..., None],
    kernels: ModuleType,
) -> None:
    """Pairs where a robot changes course within ``[start, stop)`` (``count``: each robot's
    changes there): cut each pair's window at both robots' course changes and solve every
    piece, all pairs in one pass."""
    n_pairs = len(a)
    pid = np.arange(n_pairs)
    parts_p, parts_t = [pid], [np.full(n_pairs, start)]
    for robot in (a, b):
        c = count[robot]
        p = np.repeat(pid, c)
        offset = np.arange(int(c.sum())) - np.repeat(np.cumsum(c) - c, c)
        parts_p.append(p)
        parts_t.append(L.t[L.cur[robot][p] + 1 + offset])
    p = np.concatenate(parts_p)
    t = np.concatenate(parts_t)
    order = np.lexsort((t, p))
    p, t = p[order], t[order]
    # Changes at the same instant make one cut.
    last = np.r_[(p[1:] != p[:-1]) | (t[1:] != t[:-1]), True]
    p, t = p[last], t[last]
    end = np.where(np.r_[p[1:] == p[:-1], False], np.r_[t[1:], stop], stop)
    la, lb = L.legs_at(a[p], t), L.legs_at(b[p], t)
    _solve_legs(L, la, lb, radius[p], t, end - t, a[p], b[p], emit, box, kernels)


def _solve_legs(
    L: LegTable,
    la: np.ndarray,
    lb: np.ndarray,
    radius: np.ndarray,
    t_start: float | np.ndarray,
    length: float | np.ndarray,
    a: np.ndarray,
    b: np.ndarray,
    emit: Callable[..., None],
    box: float | None,
    kernels: ModuleType,
) -> None:
    """Crossings of pairs on legs ``la``, ``lb`` within ``[t_start, t_start + length]``, solved
    from the later of the two legs' starts (:func:`netsim.links._kernels.crossings`; on a
    torus every image of the other robot counts)."""
    n = len(la)
    t_start, length = (np.full(n, x, float) if np.ndim(x) == 0 else np.array(x, float) for x in (t_start, length))
    pair, t, phase, kind = kernels.crossings(L.t, L.p, L.v, la, lb, radius, t_start, length, box or 0.0)
    emit(t, a[pair], b[pair], kind, phase)


def link_lifetimes(
    legs: pd.DataFrame,
    range_m: float | np.ndarray,
    duration_s: float,
    side_m: float | None = None,
    torus: bool = False,
    window_s: float | None = None,
) -> pd.DataFrame:
    """One row per link lifetime: ``a, b`` (a < b), ``t_up_s, t_down_s, censored, ...``."""
    t, a, b, k, phase = link_events(legs, range_m, duration_s, side_m, torus, window_s)
    # At one instant a pair's events run by phase (a piece's end, a jump, the next piece's
    # start), ups before downs within a phase: a link that comes up at a window's end and
    # is re-found at the next window's start stays one lifetime. (numpy's lexsort, not a
    # DataFrame's sort and merge: the same order, at a fraction of pandas' cost per call.)
    # Keys folded for a cheaper sort: a pair (a, b) as one number, ordered as (a, b) is;
    # a phase and a kind as one, ordered as (phase, ups first) is.
    pair = a * (int(b.max()) + 1 if len(b) else 1) + b
    order = np.lexsort((2 * phase.astype(np.int64) + (k < 0), t, pair))
    a, b, t, k, pair = a[order], b[order], t[order], k[order], pair[order]
    same_pair = pair[1:] == pair[:-1]
    prev_kind = np.r_[-1, np.where(same_pair, k[:-1], -1)]
    # Each pair starts down; keep only the events that change its state.
    keep = k != prev_kind
    a, b, t, k, pair = a[keep], b[keep], t[keep], k[keep], pair[keep]
    # After the filter a pair's events alternate up, down, up, ..., starting with an up:
    # an up is closed by the event right after it if that is the same pair's.
    up = np.flatnonzero(k == 1)
    closed = up + 1 < len(k)
    closed[closed] = pair[up[closed] + 1] == pair[up[closed]]
    t_up = t[up]
    t_down = np.full(len(up), float(duration_s))
    t_down[closed] = t[up[closed] + 1]
    censored_start = t_up == 0.0
    censored_end = ~closed
    rows = np.lexsort((pair[up], t_up))
    return pd.DataFrame(
        {
            "a": a[up][rows],
            "b": b[up][rows],
            "t_up_s": t_up[rows],
            "t_down_s": t_down[rows],
            "censored": (censored_start | censored_end)[rows],
            "censored_start": censored_start[rows],
            "censored_end": censored_end[rows],
        }
    )
