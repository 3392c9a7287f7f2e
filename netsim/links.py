"""Exact link up/down times, solved from the robots' piecewise-linear trajectories.

Two robots on straight legs have relative position ``d + w t``; they are linked while
``|d + w t| <= R`` with ``R = min(r_a, r_b)`` (both hear each other), so the link comes up
and goes down at the roots of ``|w|^2 t^2 + 2 (d.w) t + |d|^2 - R^2 = 0``. Nothing is
sampled: the times are as exact as floating point allows, whatever the output interval.

The run is cut into windows short enough that no robot moves more than half a range in
one; the candidate pairs of a window are those within ``R_max + 2 v_max W`` at its start
(no other pair can meet during it), found with a KD-tree. Pairs whose robots keep their
legs through the window are solved in one vectorised step; pairs where a robot changes
course are solved leg piece by leg piece.

A link up at t = 0 or still up at the end is censored; ``censored`` is true for both,
``censored_start`` and ``censored_end`` say which.
"""

from __future__ import annotations

import numpy as np
import pandas as pd
from scipy.spatial import cKDTree

from netsim.trajectory import LegTable

_EDGE_S = 1e-10

COLUMNS = ["a", "b", "t_up_s", "t_down_s", "censored", "censored_start", "censored_end"]


def _roots(d: np.ndarray, w: np.ndarray, radius: np.ndarray):
    """Entry and exit times (relative) of ``|d + w t| = radius``; NaN when none."""
    A = np.einsum("ij,ij->i", w, w)
    B = 2.0 * np.einsum("ij,ij->i", d, w)
    C = np.einsum("ij,ij->i", d, d) - radius * radius
    disc = B * B - 4.0 * A * C
    ok = (A > 0) & (disc > 0)
    sq = np.sqrt(np.where(ok, disc, 0.0))
    # The numerically stable pair of roots: q / A and C / q.
    q = -0.5 * (B + np.copysign(sq, B))
    with np.errstate(divide="ignore", invalid="ignore"):
        r1 = np.where(ok, q / np.where(A > 0, A, 1.0), np.nan)
        r2 = np.where(ok & (q != 0), C / np.where(q != 0, q, 1.0), np.nan)
    r2 = np.where(ok & (q == 0), -r1, r2)
    return np.fmin(r1, r2), np.fmax(r1, r2)


def link_events(legs: pd.DataFrame, range_m, duration_s: float, side_m=None, torus=False):
    """Up (+1) and down (-1) events of every link, as arrays ``(t, a, b, kind)``."""
    n = len(np.atleast_1d(range_m)) if np.ndim(range_m) else int(legs["robot"].max()) + 1
    ranges = np.broadcast_to(np.asarray(range_m, float), (n,))
    L = LegTable(legs, n)
    v_max = float(np.hypot(L.v[:, 0], L.v[:, 1]).max()) if len(L.v) else 0.0
    r_max = float(ranges.max())
    window = duration_s if v_max == 0 else max(0.5 * float(ranges.min()) / v_max, 1e-6)
    box = float(side_m) if torus else None

    out: list[tuple[np.ndarray, ...]] = []

    def emit(t, a, b, k):
        out.append(
            (np.asarray(t, float), np.asarray(a, np.int64), np.asarray(b, np.int64), np.full(len(a), k, np.int8))
        )

    def minimum_image(d):
        if torus:
            d = d - box * np.round(d / box)
        return d

    start = 0.0
    first = True
    while start < duration_s or first:
        stop = min(start + window, duration_s)
        L.advance(start)
        pos = L.at(L.cur, start)
        reach = r_max + 2.0 * v_max * (stop - start)
        if torus:
            tree = cKDTree(np.mod(pos, box) % box, boxsize=box)
        else:
            tree = cKDTree(pos)
        pairs = tree.query_pairs(reach, output_type="ndarray")
        if len(pairs):
            i, j = pairs[:, 0], pairs[:, 1]
            swap = i > j
            i, j = np.where(swap, j, i), np.where(swap, i, j)
            radius = np.minimum(ranges[i], ranges[j])
            d0 = minimum_image(pos[i] - pos[j])
            if first:
                up = np.einsum("ij,ij->i", d0, d0) <= radius * radius
                emit(np.zeros(int(up.sum())), i[up], j[up], 1)
            changing = L.changes_in(start, stop)
            simple = ~(changing[i] | changing[j])
            _solve_piece(
                d0[simple],
                L.v[L.cur[i[simple]]] - L.v[L.cur[j[simple]]],
                radius[simple],
                start,
                stop - start,
                i[simple],
                j[simple],
                emit,
            )
            if (~simple).any():
                _solve_changing(L, i[~simple], j[~simple], radius[~simple], start, stop, minimum_image, emit)
        first = False
        if stop >= duration_s:
            break
        start = stop
    if not out:
        return np.empty(0), np.empty(0, np.int64), np.empty(0, np.int64), np.empty(0, np.int8)
    t, a, b, k = (np.concatenate(col) for col in zip(*out))
    return t, a, b, k


def _solve_changing(L: LegTable, a, b, radius, start: float, stop: float, minimum_image, emit) -> None:
    """Pairs where a robot changes course within ``[start, stop)``: cut each pair's window
    at both robots' course changes and solve every piece, all pairs in one pass."""
    n_pairs = len(a)
    # Each robot's course changes in the window are its legs cur+1 .. cur+count.
    count = np.zeros(len(L.cur), dtype=np.int64)
    for r in np.unique(np.concatenate([a, b])).tolist():
        lo = L.cur[r] + 1
        count[r] = int(np.searchsorted(L.t[lo : L.end[r]], stop, "left"))
    pid = np.arange(n_pairs)
    parts_p, parts_leg, parts_from = [pid], [np.full(n_pairs, -1)], [np.zeros(n_pairs, np.int8)]
    for robot, tag in ((a, 1), (b, 2)):
        c = count[robot]
        p = np.repeat(pid, c)
        offset = np.arange(int(c.sum())) - np.repeat(np.cumsum(c) - c, c)
        parts_p.append(p)
        parts_leg.append(L.cur[robot][p] + 1 + offset)
        parts_from.append(np.full(len(p), tag, np.int8))
    p = np.concatenate(parts_p)
    leg = np.concatenate(parts_leg)
    frm = np.concatenate(parts_from)
    t = np.where(leg >= 0, L.t[np.maximum(leg, 0)], start)
    order = np.lexsort((t, p))
    p, t, frm = p[order], t[order], frm[order]
    group_start = np.searchsorted(p, pid)
    # Legs of a and b current on each piece: how many of their changes came so far.
    ca = np.cumsum(frm == 1)
    cb = np.cumsum(frm == 2)
    ca -= np.repeat(ca[group_start] - (frm[group_start] == 1), np.diff(np.r_[group_start, len(p)]))
    cb -= np.repeat(cb[group_start] - (frm[group_start] == 2), np.diff(np.r_[group_start, len(p)]))
    # Changes at the same instant make one cut: keep the last, which has seen them all.
    last = np.r_[(p[1:] != p[:-1]) | (t[1:] != t[:-1]), True]
    p, t, ca, cb = p[last], t[last], ca[last], cb[last]
    end = np.where(np.r_[p[1:] == p[:-1], False], np.r_[t[1:], stop], stop)
    la, lb = L.cur[a[p]] + ca, L.cur[b[p]] + cb
    pa = L.p[la] + L.v[la] * (t - L.t[la])[:, None]
    pb = L.p[lb] + L.v[lb] * (t - L.t[lb])[:, None]
    _solve_piece(minimum_image(pa - pb), L.v[la] - L.v[lb], radius[p], t, end - t, a[p], b[p], emit)


def _solve_piece(d, w, radius, t_start, length, a, b, emit):
    if len(d) == 0:
        return
    t_in, t_out = _roots(d, w, radius)
    # A crossing on a window's edge is looked for by both windows, with a little slack,
    # so that rounding cannot hide it from both; the duplicate is dropped later.
    length = np.broadcast_to(length, t_in.shape)
    t_start = np.broadcast_to(t_start, t_in.shape)
    enter = (t_in >= -_EDGE_S) & (t_in <= length + _EDGE_S)
    leave = (t_out >= -_EDGE_S) & (t_out <= length + _EDGE_S)
    emit(t_start[enter] + np.clip(t_in[enter], 0.0, length[enter]), a[enter], b[enter], 1)
    emit(t_start[leave] + np.clip(t_out[leave], 0.0, length[leave]), a[leave], b[leave], -1)


def link_lifetimes(legs: pd.DataFrame, range_m, duration_s: float, side_m=None, torus=False) -> pd.DataFrame:
    """One row per link lifetime: ``a, b`` (a < b), ``t_up_s, t_down_s, censored, ...``."""
    t, a, b, k = link_events(legs, range_m, duration_s, side_m, torus)
    ev = pd.DataFrame({"a": a, "b": b, "t": t, "k": k})
    # Up events sort before down events at the same instant: a link that comes up at a
    # window's end and is re-found at the next window's start stays one lifetime.
    ev = ev.sort_values(["a", "b", "t", "k"], ascending=[True, True, True, False], kind="stable")
    same_pair = (ev["a"].to_numpy()[1:] == ev["a"].to_numpy()[:-1]) & (
        ev["b"].to_numpy()[1:] == ev["b"].to_numpy()[:-1]
    )
    kinds = ev["k"].to_numpy()
    prev_kind = np.r_[-1, np.where(same_pair, kinds[:-1], -1)]
    # Each pair starts down; keep only the events that change its state.
    ev = ev[kinds != prev_kind]
    ups = ev[ev["k"] == 1].reset_index(drop=True)
    downs = ev[ev["k"] == -1].reset_index(drop=True)
    # After the filter events alternate up, down, up, ... per pair, so the n-th down of a
    # pair closes its n-th up.
    ups["n"] = ups.groupby(["a", "b"]).cumcount()
    downs["n"] = downs.groupby(["a", "b"]).cumcount()
    df = ups.merge(downs, on=["a", "b", "n"], how="left", suffixes=("_up", "_down"))
    censored_end = df["t_down"].isna().to_numpy()
    out = pd.DataFrame(
        {
            "a": df["a"].to_numpy(np.int64),
            "b": df["b"].to_numpy(np.int64),
            "t_up_s": df["t_up"].to_numpy(float),
            "t_down_s": np.where(censored_end, duration_s, df["t_down"].to_numpy(float)),
        }
    )
    out["censored_start"] = out["t_up_s"].to_numpy() == 0.0
    out["censored_end"] = censored_end
    out["censored"] = out["censored_start"] | out["censored_end"]
    return out[COLUMNS].sort_values(["t_up_s", "a", "b"], kind="stable").reset_index(drop=True)
