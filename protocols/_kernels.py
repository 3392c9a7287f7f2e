"""Compiled (numba) loops of the Ack beacon's hot path: the neighbour tables.

Each computes exactly what its numpy counterpart in :mod:`protocols.neighbours` computes,
receiver by receiver instead of in array operations: for the ten or so receivers of one
Ack, numpy's cost per operation, not the arithmetic, is what a call costs. The tests check
that both agree exactly.
"""

from __future__ import annotations

import numba
import numpy as np

from netsim._kernels import position

# The packed record's columns and the empty id (protocols.neighbours; repeated here so
# that numba sees constants).
LAST_HEARD, LIVE_SINCE, HEARS_ME, BIDIR_SINCE, SEQ, ROLE, LEADER, X, Y, GROUP_SIZE, DEGREE, ROLE_SINCE = range(12)
EMPTY = -1


@numba.njit(cache=True, nogil=True)
def receive(ids, records, slots, now, sender, receivers, heard, record, tau_s, fresh, hears_me, start):
    """Record an Ack of ``sender`` (its packed ``record``, the sorted ids it ``heard``) in
    the rows of ``receivers[start:]`` (:meth:`protocols.neighbours.NeighbourTable.update`).

    ``ids`` and ``records`` are the table's flat ``(n * slots)`` ids and ``(n * slots,
    fields)`` records. Fills ``hears_me`` (the receiver is among ``heard``) and ``fresh``
    (the Ack was taken: not older than the entry's). Returns ``(-1, stale)`` when done,
    ``stale`` the number of Acks not taken, or ``(k, 0)`` where ``receivers[k]``'s row has
    no free slot (the table must grow first; the receivers before it are done).
    """
    n_heard = len(heard)
    stale = 0
    for k in range(start, len(receivers)):
        r = receivers[k]
        at = np.searchsorted(heard, r)
        hm = at < n_heard and heard[at] == r
        hears_me[k] = hm
        base = r * slots
        slot = -1
        for s in range(slots):
            if ids[base + s] == sender:
                slot = s
                break
        found = slot >= 0
        if not found:
            # Strictly after tau: an Ack at the instant of expiry may still continue the entry.
            for s in range(slots):
                if ids[base + s] == EMPTY or now - records[base + s, LAST_HEARD] > tau_s:
                    slot = s
                    break
            if slot < 0:
                return k, 0
            ids[base + slot] = sender
        f = base + slot
        old = records[f]
        if found and not old[SEQ] <= record[SEQ]:
            fresh[k] = False
            stale += 1
            continue
        fresh[k] = True
        was_live = found and now - old[LAST_HEARD] <= tau_s
        live_since = old[LIVE_SINCE] if was_live else now
        if hm:
            bidir_since = old[BIDIR_SINCE] if was_live and old[HEARS_ME] != 0 else now
        else:
            bidir_since = np.inf
        role_since = old[ROLE_SINCE] if was_live and old[ROLE] == record[ROLE] else now
        for c in range(len(record)):
            old[c] = record[c]
        old[LAST_HEARD] = now
        old[LIVE_SINCE] = live_since
        old[HEARS_ME] = 1.0 if hm else 0.0
        old[BIDIR_SINCE] = bidir_since
        old[ROLE_SINCE] = role_since
    return -1, stale


@numba.njit(cache=True, nogil=True)
def heard_and_degree(ids_row, records_row, now, tau_s):
    """The ids of a row's live entries, ascending, and how many of them hear the row's
    robot (``np.sort(id[live])`` and ``(live & hears_me).sum()``)."""
    heard = np.empty(len(ids_row), dtype=np.int64)
    k = 0
    degree = 0
    for s in range(len(ids_row)):
        if now - records_row[s, LAST_HEARD] < tau_s:
            heard[k] = ids_row[s]
            k += 1
            if records_row[s, HEARS_ME] != 0:
                degree += 1
    return np.sort(heard[:k]), degree


@numba.njit(cache=True, nogil=True)
def announce(ids_row, records_row, now, tau_s, empty_record, seq, role, leader, x_m, y_m, group_size):
    """What a robot's Ack carries, from its row of the table: the ids of the live entries,
    ascending, and the Ack's packed record (the fields, and the two-way degree: live
    entries that hear the robot), as :func:`heard_and_degree` and
    :func:`protocols.neighbours.ack_record`."""
    heard, degree = heard_and_degree(ids_row, records_row, now, tau_s)
    record = empty_record.copy()
    record[SEQ], record[ROLE], record[LEADER], record[X], record[Y] = seq, role, leader, x_m, y_m
    record[GROUP_SIZE], record[DEGREE] = group_size, degree
    return heard, record


@numba.njit(cache=True, nogil=True)
def make_ack(
    i, now, origin_m, velocity_mps, t0_s, torus, side_m, seq, resign_pending, role, leader, group_size,
    ids, records, tau_s, empty_record, role_sent, degree_sent,
):  # fmt: skip
    """Robot ``i``'s Ack at ``now``, once its hooks have run, as
    :meth:`protocols.ack.AckBeacon.make_ack` builds it: its position, its next sequence
    number, the resignation it owes, its role, leader and group size, and what its row of
    the table (``ids``, ``records``: the table's ``(n, slots)`` arrays) announces
    (:func:`announce`). Counts the sequence number, clears the resignation and records the
    role and degree sent, as the numpy code does. Returns the Ack's fields ``(x, y, seq,
    role, leader, group_size, resign, heard, record)``."""
    x, y = position(origin_m, velocity_mps, t0_s, i, now, torus, side_m)
    s = seq[i] + 1
    seq[i] = s
    resign = resign_pending[i]
    if resign:
        resign_pending[i] = False
    ro, le, size = np.int64(role[i]), leader[i], group_size[i]
    heard, record = announce(ids[i], records[i], now, tau_s, empty_record, s, ro, le, x, y, size)
    role_sent[i] = ro
    degree_sent[i] = np.int64(record[DEGREE])
    return x, y, s, ro, le, size, resign, heard, record


# Roles (protocols.roles).
UNDECIDED, MEMBER, LEADER_ROLE = 0, 1, 2


@numba.njit(cache=True, nogil=True)
def sort_receivers(role, leader, receivers, hears_me, symmetric, sender):
    """The receivers of an Ack of ``sender`` by what the clustering does with it, from the
    roles before it acts: positions (in ``receivers``) of the members of ``sender``'s group;
    those of them over a two-way link; undecided robots and leaders over a two-way link
    (:func:`protocols.clustering.sort_receivers`)."""
    n = len(receivers)
    mine = np.empty(n, dtype=np.int64)
    renew = np.empty(n, dtype=np.int64)
    undecided = np.empty(n, dtype=np.int64)
    leaders = np.empty(n, dtype=np.int64)
    a = b = c = d = 0
    for k in range(n):
        r = receivers[k]
        ro = role[r]
        two_way = symmetric or hears_me[k]
        if ro == MEMBER and leader[r] == sender:
            mine[a] = k
            a += 1
            if two_way:
                renew[b] = r
                b += 1
        elif two_way and ro == UNDECIDED:
            undecided[c] = r
            c += 1
        elif two_way and ro == LEADER_ROLE:
            leaders[d] = r
            d += 1
    return mine[:a], renew[:b], undecided[:c], leaders[:d]
