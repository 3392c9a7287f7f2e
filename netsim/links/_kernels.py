"""Crossings of a pair's relative path with a disk: the rule every link solver shares,
compiled or plain Python as :func:`netsim.compiled.load` decides.

Two robots on straight legs have relative position ``d + w t``; they are linked while
``|d + w t| <= R``, so a link comes up and goes down at the roots of
``|w|^2 t^2 + 2 (d.w) t + |d|^2 - R^2 = 0``. The roots are solved from the later of the two
legs' starts, so that a crossing's instant depends on the pair's legs alone, not on where a
solver's windows happen to fall: the post-hoc solver (:mod:`netsim.links.lifetimes`), the
runtime one (:mod:`netsim.links.kinetic`) and the walls' stretches
(:mod:`netsim.links.wall_sweeps`) all call these functions, so they find the very same floats.

Legs are given as rows of ``leg_t`` (start), ``leg_p`` (position then) and ``leg_v``
(velocity); pair ``k`` is legs ``la[k]`` and ``lb[k]``. On a torus (``box > 0``) every image
of the other robot that the path can reach within the window counts, not only the nearest
one. Whether a pair is linked at an instant (the state a solver sets at the start and at a
jump) is :func:`netsim._kernels.in_range`, the engine's one rule of in range, and the
nearest image its one wrap. The tests compare these, plain and compiled, with a numpy
oracle bit for bit.
"""

from __future__ import annotations

import math

import numpy as np

from netsim._kernels import disk_crossing_times, nearest_image, position, reaches
from netsim._kernels import in_range as in_range  # the solvers' state test, through this module
from netsim.compiled import jit

EDGE_S = 1e-10

# Order of events at the same instant for one pair: a crossing at the end of a piece, then
# the state set at a jump (or at t = 0), then a crossing at the start of the next piece.
PHASE_END, PHASE_STATE, PHASE_START = 0, 1, 2


@jit(nogil=True)
def _relative(leg_t, leg_p, leg_v, i, j, box):
    """The later of legs ``i`` and ``j``'s starts, and the relative position then (the
    nearest image on a torus of side ``box > 0``)."""
    origin = leg_t[i] if leg_t[i] >= leg_t[j] else leg_t[j]
    xi, yi = position(leg_p, leg_v, leg_t, i, origin, False, 0.0)
    xj, yj = position(leg_p, leg_v, leg_t, j, origin, False, 0.0)
    dx, dy = nearest_image(xi - xj, yi - yj, box)
    return origin, dx, dy


@jit(nogil=True)
def _keep(at, start, length, k, kind, pair, times, phase, kinds, m):
    """A crossing of pair ``k`` at ``at``, kept at row ``m`` if it falls in the window
    ``[start, start + length]`` (give or take the edge tolerance), clipped into it, with its
    phase; returns the next free row.

    A crossing on a window's edge is looked for by both windows, with a little slack, so
    that rounding cannot hide it from both; the duplicate is dropped later. One near a
    window's start sorts after one near the previous window's end at the same instant."""
    end = start + length
    if at >= start - EDGE_S and at <= end + EDGE_S:
        t = min(max(at, start), end)
        pair[m], times[m], kinds[m] = k, t, kind
        phase[m] = PHASE_START if t - start <= 0.5 * length else PHASE_END
        return m + 1
    return m


@jit(nogil=True)
def _pair_crossings(origin, dx, dy, wx, wy, radius):
    """The instants a pair enters and leaves range (:func:`netsim._kernels.disk_crossing_times`);
    a pair at rest relative to each other in range comes up at ``origin``, where its legs
    begin: one that came to rest exactly on the circle, its exit found at the end of the
    leg before, is up again there (in range by :func:`netsim._kernels.reaches`)."""
    if wx == 0.0 and wy == 0.0:
        return (origin if reaches(dx, dy, radius, 0.0) else np.nan), np.nan
    return disk_crossing_times(origin, dx, dy, wx, wy, radius)


@jit(nogil=True)
def crossing_times(leg_t, leg_p, leg_v, la, lb, radius):
    """On the plane: the instants pairs on legs ``la``, ``lb`` enter and leave the disk of
    ``radius`` (NaN: never), solved from the later of the two legs' starts."""
    n = len(la)
    at_in = np.empty(n)
    at_out = np.empty(n)
    for k in range(n):
        i, j = la[k], lb[k]
        origin, dx, dy = _relative(leg_t, leg_p, leg_v, i, j, 0.0)
        wx, wy = leg_v[i, 0] - leg_v[j, 0], leg_v[i, 1] - leg_v[j, 1]
        at_in[k], at_out[k] = _pair_crossings(origin, dx, dy, wx, wy, radius[k])
    return at_in, at_out


@jit(nogil=True)
def clip_crossings(at_in, at_out, t_start, length):
    """The crossings ``at_in`` (up, kind 1) and ``at_out`` (down, kind -1) of each pair that
    fall within ``[t_start, t_start + length]``: ``(pair, t, phase, kind)``, the entries then
    the exits, each in pair order."""
    n = len(at_in)
    pair = np.empty(2 * n, np.int64)
    times = np.empty(2 * n)
    phase = np.empty(2 * n, np.int8)
    kinds = np.empty(2 * n, np.int8)
    # int(): values, not literals (docs/architecture.md, the compiled cache).
    m = int(0)
    for k in range(n):
        m = _keep(at_in[k], t_start[k], length[k], k, int(1), pair, times, phase, kinds, m)
    for k in range(n):
        m = _keep(at_out[k], t_start[k], length[k], k, int(-1), pair, times, phase, kinds, m)
    return pair[:m], times[:m], phase[:m], kinds[:m]


@jit(nogil=True)
def crossings(leg_t, leg_p, leg_v, la, lb, radius, t_start, length, box):
    """The crossings of pairs on legs ``la``, ``lb`` with the disk of ``radius`` within
    ``[t_start, t_start + length]``, on the plane (``box = 0``) or a torus of side ``box``:
    ``(pair, t, phase, kind)``. On a torus, image by image (the entries, then the exits, of
    the pairs whose path can reach it); on the plane, :func:`clip_crossings` of
    :func:`crossing_times`."""
    if not box > 0:
        at_in, at_out = crossing_times(leg_t, leg_p, leg_v, la, lb, radius)
        return clip_crossings(at_in, at_out, t_start, length)
    n = len(la)
    origin = np.empty(n)
    dx = np.empty(n)
    dy = np.empty(n)
    reach = np.empty(n)
    top = 0.0
    for k in range(n):
        i, j = la[k], lb[k]
        origin[k], dx[k], dy[k] = _relative(leg_t, leg_p, leg_v, i, j, box)
        w = np.hypot(leg_v[i, 0] - leg_v[j, 0], leg_v[i, 1] - leg_v[j, 1])
        # Image k is reachable when |d - box k| <= R + |w| span (span: from origin to the
        # window's end); with d the nearest image, |k_x|, |k_y| <= 1/2 + reach / box.
        reach[k] = radius[k] + w * (t_start[k] + length[k] - origin[k])
        if k == 0 or reach[k] > top:
            top = reach[k]
    n_img = int(math.floor(0.5 + top / box)) if n else 0
    side = 2 * n_img + 1
    cap = 2 * n * side * side
    pair = np.empty(cap, np.int64)
    times = np.empty(cap)
    phase = np.empty(cap, np.int8)
    kinds = np.empty(cap, np.int8)
    in_t = np.empty(n)
    out_t = np.empty(n)
    sel = np.empty(n, np.bool_)
    m = int(0)  # not a literal (clip_crossings)
    for kx in range(-n_img, n_img + 1):
        for ky in range(-n_img, n_img + 1):
            for k in range(n):
                i, j = la[k], lb[k]
                ex, ey = dx[k] - box * kx, dy[k] - box * ky
                sel[k] = (kx == 0 and ky == 0) or np.hypot(ex, ey) <= reach[k] * (1 + 1e-9)
                if sel[k]:
                    wx, wy = leg_v[i, 0] - leg_v[j, 0], leg_v[i, 1] - leg_v[j, 1]
                    if kx == 0 and ky == 0:  # the nearest image: the one a pair at rest is judged by
                        in_t[k], out_t[k] = _pair_crossings(origin[k], ex, ey, wx, wy, radius[k])
                    else:
                        in_t[k], out_t[k] = disk_crossing_times(origin[k], ex, ey, wx, wy, radius[k])
            for k in range(n):
                if sel[k]:
                    m = _keep(in_t[k], t_start[k], length[k], k, int(1), pair, times, phase, kinds, m)
            for k in range(n):
                if sel[k]:
                    m = _keep(out_t[k], t_start[k], length[k], k, int(-1), pair, times, phase, kinds, m)
    return pair[:m], times[:m], phase[:m], kinds[:m]
