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


@numba.njit(cache=True, nogil=True)
def _cell_of(v, lo, size, cells):
    c = int((v - lo) / size)
    return min(max(c, 0), cells - 1)


@numba.njit(cache=True, nogil=True)
def near_pairs(pos, r, box):
    """Pairs ``(i, j)``, ``i < j``, of positions within ``r`` of each other (on a torus of
    side ``box`` when ``box > 0``), by a grid of cells no smaller than ``r`` (as many as
    :func:`netsim.crossings.grid_cells` counts: the caller checks they are not too many): what
    ``cKDTree.query_pairs(r)`` finds, and possibly pairs further apart than ``r`` by a
    relative 1e-9 (a distance at the bound rounds either way; callers filter exactly and
    ask with a slack, so such pairs change nothing). Rows in no particular order."""
    n = pos.shape[0]
    r2 = r * r * (1.0 + 1e-9)
    # Cells a little wider than r: two points within r are in the same or adjacent cells
    # whatever the rounding of their cell numbers.
    wide = r * (1.0 + 1e-6)
    if box > 0.0:
        lo_x = lo_y = 0.0
        cells_x = cells_y = max(int(box // wide), 1)
        size_x = size_y = box / cells_x
    else:
        lo_x, lo_y = pos[:, 0].min(), pos[:, 1].min()
        span_x, span_y = pos[:, 0].max() - lo_x, pos[:, 1].max() - lo_y
        # The caller keeps the count of cells in proportion to the points (grid_cells).
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
    out_i = np.empty(16 * n + 16, np.int64)
    out_j = np.empty(16 * n + 16, np.int64)
    k = 0
    wrap = box > 0.0 and n_cells > 1
    for i in range(n):
        cy, cx = cell[i] // cells_x, cell[i] % cells_x
        for dy in range(-1, 2):
            ny = cy + dy
            if wrap:
                ny %= cells_y
            elif ny < 0 or ny >= cells_y:
                continue
            for dx in range(-1, 2):
                nx = cx + dx
                if wrap:
                    nx %= cells_x
                elif nx < 0 or nx >= cells_x:
                    continue
                c = ny * cells_x + nx
                if n_cells == 1 and (dx != 0 or dy != 0):
                    continue
                for m in range(start[c], start[c + 1]):
                    j = members[m]
                    if j <= i:
                        continue
                    ddx = pos[j, 0] - pos[i, 0]
                    ddy = pos[j, 1] - pos[i, 1]
                    if box > 0.0:
                        ddx -= box * np.rint(ddx / box)
                        ddy -= box * np.rint(ddy / box)
                    if ddx * ddx + ddy * ddy <= r2:
                        if k == len(out_i):
                            out_i = np.concatenate((out_i, np.empty(k, np.int64)))
                            out_j = np.concatenate((out_j, np.empty(k, np.int64)))
                        out_i[k] = i
                        out_j[k] = j
                        k += 1
    pairs = np.empty((k, 2), np.int64)
    pairs[:, 0] = out_i[:k]
    pairs[:, 1] = out_j[:k]
    return pairs


@numba.njit(cache=True, nogil=True)
def neighbour_lists(pairs, n):
    """Both directions of the ``pairs`` as lists per robot, ascending: ``(indptr,
    indices)`` with robot ``i``'s neighbours at ``indices[indptr[i]:indptr[i + 1]]``
    (what :meth:`netsim.spatial.RangeIndex._build` makes with a lexsort)."""
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
        indices[indptr[i] : indptr[i + 1]].sort()
    return indptr, indices
