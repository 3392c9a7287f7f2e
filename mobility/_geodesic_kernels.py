"""Distances along free space on a grid, for coverage on a map (docs/model.md 5.3,
:mod:`netsim.mobility.geodesic`), compiled or plain (:func:`netsim.compiled.load`).

The grid's moves are the 16 of a knight's and a king's: the 8 neighbours and the 8 cells a
knight's move away, a knight's move allowed when the two cells it passes between are free
too. Its path lengths over-estimate the straight distance in open space by at most 2.7 %
(8.2 % with the 8 neighbours alone), and the direction of steepest ascent is within 13.3
degrees of the true one (in open space), and it leads to a free cell: a push along it
flows through doors and along corridors instead of into walls.
"""

from __future__ import annotations

import math

import numpy as np

from netsim.compiled import jit

# The 16 moves (dx, dy); a knight's move (|dx| + |dy| = 3) passes between two cells, both
# of which must be free.
MOVES_X = np.array([1, -1, 0, 0, 1, 1, -1, -1, 2, 2, -2, -2, 1, 1, -1, -1], np.int64)
MOVES_Y = np.array([0, 0, 1, -1, 1, -1, 1, -1, 1, -1, 1, -1, 2, -2, 2, -2], np.int64)


@jit(walks=True, nogil=True)
def move_ok(free, w, h, x, y, dx, dy):
    """Whether the move ``(dx, dy)`` from free cell ``(x, y)`` ends in a free cell of the
    grid and, if diagonal, passes only free cells (no cutting a wall's corner)."""
    nx, ny = x + dx, y + dy
    if nx < 0 or ny < 0 or nx >= w or ny >= h or not free[ny * w + nx]:
        return False
    if dx != 0 and dy != 0:
        # Both cells the move's segment touches besides its ends must be free.
        sx = 1 if dx > 0 else -1
        sy = 1 if dy > 0 else -1
        if abs(dx) == 2:
            return free[y * w + x + sx] and free[(y + sy) * w + x + sx]
        if abs(dy) == 2:
            return free[(y + sy) * w + x] and free[(y + sy) * w + x + sx]
        return free[y * w + x + sx] and free[(y + sy) * w + x]
    return True


@jit(walks=True, nogil=True)
def allowed_moves(free, w, h, moves_x, moves_y):
    """Per cell, the moves :func:`move_ok` allows from it, bit ``m`` for move ``m`` (0 for a
    cell not free): the rule read once per grid, not at every step of every search."""
    out = np.zeros(w * h, np.int32)
    for c in range(w * h):
        if not free[c]:
            continue
        x, y = c % w, c // w
        bits = 0
        for m in range(len(moves_x)):
            if move_ok(free, w, h, x, y, moves_x[m], moves_y[m]):
                bits |= 1 << m
        out[c] = bits
    return out


@jit(walks=True, nogil=True)
def search_work(n):
    """The arrays :func:`search` works in, as it wants them: the next cell in each queued
    cell's bucket, each cell's bucket (-1: not queued), whether it is settled, whether it is
    a target, the cells it gave a value (to put back), and the previous cell in each queued
    cell's bucket."""
    return (
        np.empty(n, np.int64),
        np.full(n, -1, np.int64),
        np.zeros(n, np.bool_),
        np.zeros(n, np.bool_),
        np.empty(n, np.int64),
        np.empty(n, np.int64),
    )


@jit(walks=True, nogil=True)
def search(
    free, allowed, w, h, sources, cell_m, moves_x, moves_y, within, targets, out, work, centre_x, centre_y, bound_m
):
    """Shortest path lengths (m) over free cells from the nearest of the cells ``sources``
    (row-major indices; those not free are left out) into ``out`` (inf on every cell, as
    given; inf where not reached); Dijkstra's algorithm with a bucket queue (Dial's), every
    source at 0: a cell's value is the least over the cells settled in earlier buckets,
    whatever the order within a bucket, so no value depends on that order. The
    moves from each cell are ``allowed``'s (:func:`allowed_moves` of
    ``free``). Paths leave the sources only through the cells ``within`` marks, each move's
    end cell (a move's geometry is still :func:`move_ok`'s, over ``free``: a knight's move
    may pass beside a cell left out). With ``targets`` (cells), the search stops once every
    free one of them is settled: their values are then final, and so is every value below
    the largest of theirs, the others upper bounds or inf.
    Without, every cell is settled. It works in ``work`` (:func:`search_work`, as it gives
    them) and returns how many cells it gave a value, listed first in ``work[4]``;
    :func:`forget` puts both back.

    With ``bound_m``, no path is followed beyond a settled cell from which every point
    ``(centre_x[k], centre_y[k])`` (in cells) lies farther in a straight line than
    ``bound_m[k]`` less the cell's distance: no path through it reaches one of them within
    its bound, so a cell's value within its bound is as without (a search toward points
    whose distances are known to lie within those bounds)."""
    after, where, done, wanted, touched, before = work
    n = w * h
    used = 0
    lengths = np.empty(len(moves_x))
    offsets = np.empty(len(moves_x), np.int64)  # in row-major cells
    for m in range(len(moves_x)):
        lengths[m] = cell_m * math.sqrt(moves_x[m] * moves_x[m] + moves_y[m] * moves_y[m])
        offsets[m] = moves_y[m] * w + moves_x[m]
    # A bucket queue: cell values in buckets of half a cell's side, each a linked list
    # (after, before); a move is at least a side long, so a cell's value comes from cells of
    # earlier buckets, settled before it in any order within a bucket.
    # The queued buckets lie within the longest move of the one being settled: a ring of
    # more slots than that (a power of two, for a cheap remainder) holds them apart.
    width_m = 0.5 * cell_m
    ring = 1
    while ring < (int(lengths.max() / width_m) + 3 if len(lengths) > 0 else 1):
        ring *= 2
    mask = ring - 1
    head = np.full(ring, -1, np.int64)
    queued = 0
    for k in range(len(sources)):
        c = sources[k]
        if 0 <= c < n and free[c] and where[c] < 0:
            after[c] = head[0]
            before[c] = -1
            if head[0] >= 0:
                before[head[0]] = c
            head[0] = c
            where[c] = 0
            out[c] = 0.0
            touched[used] = c
            used += 1
            queued += 1
    pending = -1  # no targets: never stop early
    if len(targets) > 0:
        pending = 0
        for k in range(len(targets)):
            c = targets[k]
            if 0 <= c < n and free[c] and not wanted[c]:
                wanted[c] = True
                pending += 1
    # No free target: nothing to search for (the sources stay at 0).
    searching = pending != 0
    current = 0
    while searching and queued > 0:
        while head[current & mask] < 0:
            current += 1
        slot = current & mask
        c = head[slot]
        head[slot] = after[c]
        if after[c] >= 0:
            before[after[c]] = -1
        where[c] = -1
        queued -= 1
        done[c] = True
        if wanted[c]:
            pending -= 1
            if pending == 0:
                break
        if len(bound_m) > 0 and not leads_within(c % w, c // w, out[c], cell_m, centre_x, centre_y, bound_m):
            continue
        bits = allowed[c]
        for m in range(len(moves_x)):
            if not (bits >> m) & 1:
                continue
            nb = c + offsets[m]
            if done[nb] or not within[nb]:
                continue
            d = out[c] + lengths[m]
            if d >= out[nb]:
                continue
            if out[nb] == math.inf:
                touched[used] = nb
                used += 1
            out[nb] = d
            b = where[nb]
            if b >= 0:
                # A shorter path: out of the later bucket it was queued in.
                if before[nb] >= 0:
                    after[before[nb]] = after[nb]
                else:
                    head[b & mask] = after[nb]
                if after[nb] >= 0:
                    before[after[nb]] = before[nb]
            else:
                queued += 1
            b = int(d / width_m)
            slot = b & mask
            after[nb] = head[slot]
            before[nb] = -1
            if head[slot] >= 0:
                before[head[slot]] = nb
            head[slot] = nb
            where[nb] = b
    # The buckets are put back now; the values, by forget, once they are read.
    for slot in range(ring):
        c = head[slot]
        while c >= 0:
            where[c] = -1
            c = after[c]
    for k in range(len(targets)):
        c = targets[k]
        if 0 <= c < n:
            wanted[c] = False
    return used


@jit(walks=True, nogil=True)
def leads_within(x, y, distance_m, cell_m, centre_x, centre_y, bound_m):
    """Whether a path that reaches cell ``(x, y)`` after ``distance_m`` can still reach some
    point ``(centre_x[k], centre_y[k])`` (in cells) within ``bound_m[k]``: no path is
    shorter than the straight line."""
    for k in range(len(bound_m)):
        dx, dy = x - centre_x[k], y - centre_y[k]
        if distance_m + cell_m * math.sqrt(dx * dx + dy * dy) <= bound_m[k]:
            return True
    return False


@jit(walks=True, nogil=True)
def forget(out, work, used):
    """Puts back what :func:`search` changed: ``out`` to inf and nothing settled."""
    touched, done = work[4], work[2]
    for k in range(used):
        c = touched[k]
        out[c] = math.inf
        done[c] = False


@jit(walks=True, nogil=True)
def ascent(free, w, h, field, cell_x, cell_y, cell_m, moves_x, moves_y, out_dir, out_d):
    """For each cell ``(cell_x[k], cell_y[k])`` (a free one), the unit direction of the
    steepest ascent of ``field`` over its free moves (zero where no move ascends: a dead
    end, or a cell not reached) into ``out_dir[k]``, and the field there into ``out_d[k]``."""
    for k in range(len(cell_x)):
        x, y = cell_x[k], cell_y[k]
        out_dir[k, 0] = 0.0
        out_dir[k, 1] = 0.0
        here = field[y * w + x]
        out_d[k] = here
        if not math.isfinite(here):
            continue
        best = 0.0
        for m in range(len(moves_x)):
            if not move_ok(free, w, h, x, y, moves_x[m], moves_y[m]):
                continue
            there = field[(y + moves_y[m]) * w + x + moves_x[m]]
            length = cell_m * math.sqrt(moves_x[m] * moves_x[m] + moves_y[m] * moves_y[m])
            slope = (there - here) / length
            if math.isfinite(there) and slope > best:
                best = slope
                out_dir[k, 0] = moves_x[m] * cell_m / length
                out_dir[k, 1] = moves_y[m] * cell_m / length


@jit(walks=True, nogil=True)
def descend(
    free, allowed, w, h, sources, cell_m, moves_x, moves_y, within, targets, cell_x, cell_y, bound_m,
    field, work, out_dir, out_d,
):  # fmt: skip
    """At each cell ``(cell_x[k], cell_y[k])``, the direction of steepest descent of the
    distance :func:`search` finds from ``sources`` toward ``targets`` and that distance
    (inf: not reached), into ``out_dir`` and ``out_d`` (:func:`ascent` of its negative),
    following no path that cannot reach some cell within its ``bound_m[k]``; ``field`` and
    ``work`` are left as they were given."""
    cx, cy = cell_x.astype(np.float64), cell_y.astype(np.float64)
    used = search(free, allowed, w, h, sources, cell_m, moves_x, moves_y, within, targets, field, work, cx, cy, bound_m)
    touched = work[4]
    for k in range(used):
        field[touched[k]] = -field[touched[k]]
    ascent(free, w, h, field, cell_x, cell_y, cell_m, moves_x, moves_y, out_dir, out_d)
    for k in range(len(out_d)):
        out_d[k] = -out_d[k] if math.isfinite(out_d[k]) else math.inf
    forget(field, work, used)


@jit(walks=True, nogil=True)
def frontier(free, w, h, covered, moves_x, moves_y, centre_x, centre_y, reach_cells):
    """The free cells not ``covered`` that a move (:func:`move_ok`) joins to a covered free
    cell, ascending: where the free space not yet covered begins, seen from the covered
    part (a path from a covered cell to any cell not covered passes one of them first).
    Only those within ``reach_cells[k]`` cells of some ``(centre_x[k], centre_y[k])`` (an
    infinite reach: every one)."""
    x0, y0, x1, y1 = w, h, -1, -1
    for k in range(len(centre_x)):
        r = reach_cells[k]
        if not r < math.inf:
            x0, y0, x1, y1 = 0, 0, w - 1, h - 1
            break
        x0 = min(x0, max(0, int(math.floor(centre_x[k] - r))))
        y0 = min(y0, max(0, int(math.floor(centre_y[k] - r))))
        x1 = max(x1, min(w - 1, int(math.ceil(centre_x[k] + r))))
        y1 = max(y1, min(h - 1, int(math.ceil(centre_y[k] + r))))
    out = np.empty(max(0, (x1 - x0 + 1) * (y1 - y0 + 1)), np.int64)
    k = 0
    for y in range(y0, y1 + 1):
        for x in range(x0, x1 + 1):
            c = y * w + x
            if not free[c] or covered[c]:
                continue
            near = False
            for j in range(len(centre_x)):
                dx, dy = x - centre_x[j], y - centre_y[j]
                if dx * dx + dy * dy <= reach_cells[j] * reach_cells[j]:
                    near = True
                    break
            if not near:
                continue
            for m in range(len(moves_x)):
                nx, ny = x + moves_x[m], y + moves_y[m]
                # The cheap test first: far from the covered part, no neighbour is covered.
                joined = 0 <= nx < w and 0 <= ny < h and covered[ny * w + nx]
                if joined and move_ok(free, w, h, x, y, moves_x[m], moves_y[m]):
                    out[k] = c
                    k += 1
                    break
    return out[:k]
