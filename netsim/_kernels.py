"""Compiled (numba) loops of the engine core's hot path: the range query of a transmission.

Each computes exactly what its numpy counterpart computes, with the same arithmetic in the
same order, one item at a time: for the tens of candidates of one query, numpy's cost per
operation, not the arithmetic, is what a call costs. The tests check that both agree exactly.
"""

from __future__ import annotations

import numba
import numpy as np


@numba.njit(cache=True, nogil=True)
def position(origin_m, velocity_mps, t0_s, i, t, torus, side_m):
    """Robot ``i``'s position at ``t`` (:meth:`netsim.state.RobotState.position`)."""
    dt = t - t0_s[i]
    x = origin_m[i, 0] + velocity_mps[i, 0] * dt
    y = origin_m[i, 1] + velocity_mps[i, 1] * dt
    if torus:
        x, y = x % side_m, y % side_m
    return x, y


@numba.njit(cache=True, nogil=True)
def within(cand, origin_m, velocity_mps, t0_s, i, t, r, torus, side_m):
    """The candidates ``cand`` within ``r`` of robot ``i`` at ``t``, and their distances
    (:meth:`netsim.spatial.RangeIndex.within` over a candidate list)."""
    x, y = position(origin_m, velocity_mps, t0_s, i, t, torus, side_m)
    r2 = r * r
    ids = np.empty(len(cand), dtype=np.int64)
    dist = np.empty(len(cand))
    k = 0
    for j in cand:
        dtj = t - t0_s[j]
        # The numpy code adds complex numbers: the same products and sums, part by part.
        dx = origin_m[j, 0] + velocity_mps[j, 0] * dtj - x
        dy = origin_m[j, 1] + velocity_mps[j, 1] * dtj - y
        if torus:
            dx = dx - side_m * np.rint(dx / side_m)
            dy = dy - side_m * np.rint(dy / side_m)
        d2 = dx * dx + dy * dy
        if d2 <= r2:
            ids[k] = j
            dist[k] = np.sqrt(d2)
            k += 1
    return ids[:k], dist[:k]


@numba.njit(cache=True, nogil=True)
def count_each(counts, ids):
    """``counts[ids] += 1`` for distinct ``ids`` (the channel's per-robot reception count):
    for the tens of receivers of one delivery, a loop costs less than numpy's fancy index."""
    for j in ids:
        counts[j] += 1


@numba.njit(cache=True, nogil=True)
def all_set(mask, ids):
    """``mask[ids].all()`` (whether every receiver is alive), without the temporary array."""
    for j in ids:
        if not mask[j]:
            return False
    return True
