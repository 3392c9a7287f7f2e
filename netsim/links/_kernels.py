"""The loop of the post-hoc link solver (:mod:`netsim.links.lifetimes`), compiled or plain
Python as :func:`netsim.compiled.load` decides: the crossings of pairs of robots on straight
legs, on the plane.

One pair at a time, the arithmetic of :func:`netsim.links.crossings.solve_piece` in the same
order: a 1,000-robot run hands the solver some 20,000 candidate pairs per window, and numpy's
temporary arrays for each of its forty-odd steps cost more than the arithmetic. The tests
compare it, plain and compiled, with that numpy solver bit for bit.
"""

from __future__ import annotations

import math

import numpy as np

from netsim.compiled import jit
from netsim.links.crossings import EDGE_S, PHASE_END, PHASE_START


@jit(nogil=True)
def _dot(x0, x1, y0, y1):
    # numpy's einsum over a row of two: a sum started at zero, term by term.
    s = 0.0
    s += x0 * y0
    s += x1 * y1
    return s


@jit(nogil=True)
def _keep(at, start, length, k, pair, times, phase, m):
    """A crossing of pair ``k`` at ``at``, kept at row ``m`` if it falls in the window
    ``[start, start + length]`` (give or take the edge tolerance), clipped into it, with its
    phase; returns the next free row."""
    end = start + length
    if at >= start - EDGE_S and at <= end + EDGE_S:
        t = min(max(at, start), end)
        pair[m], times[m] = k, t
        phase[m] = PHASE_START if t - start <= 0.5 * length else PHASE_END
        return m + 1
    return m


@jit(nogil=True)
def plane_crossings(leg_t, leg_p, leg_v, la, lb, radius, t_start, length):
    """Crossings of pairs on legs ``la``, ``lb`` (rows of ``leg_t``, ``leg_p``, ``leg_v``)
    with the disk of ``radius`` within ``[t_start, t_start + length]``, solved from the later
    of the two legs' starts: ``(pair, t, phase)`` of the entries, then of the exits, each in
    pair order (:func:`netsim.links.crossings.clip_crossings` hands ``emit`` the same)."""
    n = len(la)
    in_pair = np.empty(n, np.int64)
    in_t = np.empty(n)
    in_phase = np.empty(n, np.int8)
    out_pair = np.empty(n, np.int64)
    out_t = np.empty(n)
    out_phase = np.empty(n, np.int8)
    n_in = n_out = 0
    for k in range(n):
        i, j = la[k], lb[k]
        origin = leg_t[i] if leg_t[i] >= leg_t[j] else leg_t[j]
        dt_i, dt_j = origin - leg_t[i], origin - leg_t[j]
        dx = (leg_p[i, 0] + leg_v[i, 0] * dt_i) - (leg_p[j, 0] + leg_v[j, 0] * dt_j)
        dy = (leg_p[i, 1] + leg_v[i, 1] * dt_i) - (leg_p[j, 1] + leg_v[j, 1] * dt_j)
        wx, wy = leg_v[i, 0] - leg_v[j, 0], leg_v[i, 1] - leg_v[j, 1]
        # netsim.links.crossings.roots: the numerically stable pair q / A and C / q.
        a = _dot(wx, wy, wx, wy)
        b = 2.0 * _dot(dx, dy, wx, wy)
        c = _dot(dx, dy, dx, dy) - radius[k] * radius[k]
        disc = b * b - 4.0 * a * c
        if not (a > 0 and disc > 0):
            continue  # no crossing: numpy's NaN roots, which no window holds
        q = -0.5 * (b + math.copysign(math.sqrt(disc), b))
        r1 = q / a
        r2 = c / q if q != 0 else -r1
        lo, hi = min(r1, r2), max(r1, r2)
        start = t_start[k]
        n_in = _keep(origin + lo, start, length[k], k, in_pair, in_t, in_phase, n_in)
        n_out = _keep(origin + hi, start, length[k], k, out_pair, out_t, out_phase, n_out)
    return in_pair[:n_in], in_t[:n_in], in_phase[:n_in], out_pair[:n_out], out_t[:n_out], out_phase[:n_out]
