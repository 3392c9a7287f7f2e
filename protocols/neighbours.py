"""Each robot's neighbour table, for all robots at once.

Row ``i`` holds what robot ``i`` learnt from the Acks it heard: for each neighbour, the
time of its last Ack, when the entry became live, whether the neighbour hears ``i``, and
the Ack's fields. An entry is live while its last Ack is younger than ``tau``
(``now - last < tau``); at exactly ``tau`` it has expired, but an Ack that arrives at that
very instant continues it (arrivals come before deadlines: the entry keeps its
``live_since`` and two-way start). An Ack older (by sequence number) than the one an
entry holds, overtaken in flight by a newer one, is ignored.

The table is a fixed number of slots per robot, doubled when a robot hears more
neighbours than it has slots; an expired slot is reused. The fields of a slot are packed
in one float64 record (integers up to 2^53 are exact), so that a delivery to ``k``
receivers is one gather and one scatter of ``k`` records, with no Python loop. An Ack's
own record (:func:`ack_record`) is the same fields followed by the ids the sender heard,
ascending: one array per Ack.

Past :data:`netsim.compiled.SMALL_RUN_ROBOTS` robots, :meth:`NeighbourTable.receive` and
:meth:`NeighbourTable.announce` run compiled loops (:mod:`netsim.protocols._kernels`) that
compute exactly what the numpy code here computes.
"""

from __future__ import annotations

import numpy as np

from netsim.compiled import load

EMPTY = -1

# Columns of the packed record. BIDIR_SINCE: since when the neighbour has continuously
# listed us in its Acks (the link is known two-way); inf while it does not. ROLE_SINCE:
# since when the live entry's Acks have continuously told the role they tell now.
LAST_HEARD, LIVE_SINCE, HEARS_ME, BIDIR_SINCE, SEQ, ROLE, LEADER, X, Y, GROUP_SIZE, DEGREE, ROLE_SINCE = range(12)
EMPTY_RECORD = np.array([-np.inf, np.inf, 0, np.inf, 0, 0, EMPTY, 0, 0, 0, 0, np.inf], dtype=float)
FIELDS = len(EMPTY_RECORD)


class NeighbourTable:
    def __init__(self, n: int, tau_s: float, slots: int = 16):
        self.n = n
        self.tau_s = float(tau_s)
        self.id = np.full((n, slots), EMPTY, dtype=np.int64)
        self.data = np.broadcast_to(EMPTY_RECORD, (n, slots, len(EMPTY_RECORD))).copy()
        self._records = self.data.reshape(-1, len(EMPTY_RECORD))
        self._ids = self.id.reshape(-1)
        # What the compiled loops take (netsim.protocols._kernels' ``table``), made again on growth.
        self.view = (self.id, self.data, self.tau_s)
        self.kernels = load("netsim.protocols._kernels", n)

    # Views of single columns, for reading.
    last_heard_s = property(lambda self: self.data[:, :, LAST_HEARD])
    live_since_s = property(lambda self: self.data[:, :, LIVE_SINCE])
    hears_me = property(lambda self: self.data[:, :, HEARS_ME] != 0)
    seq = property(lambda self: self.data[:, :, SEQ].astype(np.int64))
    role = property(lambda self: self.data[:, :, ROLE].astype(np.int8))
    leader = property(lambda self: self.data[:, :, LEADER].astype(np.int64))
    x_m = property(lambda self: self.data[:, :, X])
    y_m = property(lambda self: self.data[:, :, Y])
    group_size = property(lambda self: self.data[:, :, GROUP_SIZE].astype(np.int64))
    ack_degree = property(lambda self: self.data[:, :, DEGREE].astype(np.int64))
    bidir_since_s = property(lambda self: self.data[:, :, BIDIR_SINCE])
    role_since_s = property(lambda self: self.data[:, :, ROLE_SINCE])

    @property
    def slots(self) -> int:
        return self.id.shape[1]

    def _grow(self) -> None:
        k = self.slots
        ids = np.full((self.n, 2 * k), EMPTY, dtype=np.int64)
        ids[:, :k] = self.id
        data = np.broadcast_to(EMPTY_RECORD, (self.n, 2 * k, len(EMPTY_RECORD))).copy()
        data[:, :k] = self.data
        self.id, self.data = ids, data
        self._records = data.reshape(-1, len(EMPTY_RECORD))
        self._ids = ids.reshape(-1)
        self.view = (ids, data, self.tau_s)

    def _free_slots(self, now: float, rows: np.ndarray) -> np.ndarray:
        # Strictly after tau: an Ack at the instant of expiry may still continue the entry.
        return (self.id[rows] == EMPTY) | (now - self.data[rows, :, LAST_HEARD] > self.tau_s)

    def update(self, now: float, sender: int, receivers: np.ndarray, hears_me: np.ndarray, record: np.ndarray):
        """Record an Ack from ``sender`` heard by every robot in ``receivers`` at ``now``.

        ``hears_me[k]`` says whether ``receivers[k]`` was among the ids the Ack carried;
        ``record`` is the Ack's packed record (see :func:`ack_record`; the ids it heard, if
        it carries them, are not read here). Returns, per receiver, whether the Ack was
        taken (False: an older Ack than the entry's newest).
        """
        slots = self.id.shape[1]
        flat = receivers * slots + (self.id.take(receivers, axis=0) == sender).argmax(axis=1)
        found = self.id.ravel().take(flat) == sender
        if not found.all():
            flat = self._place(now, sender, receivers, flat, found)
        # Flat indices into the (n * slots, fields) records: cheaper than 2-D indexing.
        records = self._records
        old = records.take(flat, axis=0)
        fresh = ~found | (old[:, SEQ] <= record[SEQ])
        if not fresh.all():
            flat, old, found, hears_me = flat[fresh], old[fresh], found[fresh], hears_me[fresh]
        rec = np.empty_like(old)
        rec[:] = record[:FIELDS]
        rec[:, LAST_HEARD] = now
        was_live = found & (now - old[:, LAST_HEARD] <= self.tau_s)
        rec[:, LIVE_SINCE] = np.where(was_live, old[:, LIVE_SINCE], now)
        rec[:, HEARS_ME] = hears_me
        still_two_way = was_live & (old[:, HEARS_ME] != 0)
        rec[:, BIDIR_SINCE] = np.where(hears_me, np.where(still_two_way, old[:, BIDIR_SINCE], now), np.inf)
        same_role = was_live & (old[:, ROLE] == record[ROLE])
        rec[:, ROLE_SINCE] = np.where(same_role, old[:, ROLE_SINCE], now)
        records[flat] = rec
        return fresh

    def receive(
        self, now: float, sender: int, receivers: np.ndarray, record: np.ndarray
    ) -> tuple[np.ndarray, np.ndarray, int]:
        """Record an Ack from ``sender`` (its packed ``record``, with the ids it heard),
        heard by every robot in ``receivers`` at ``now``: :meth:`update`, with ``hears_me``
        worked out here. Returns ``(fresh, hears_me, stale)``: one flag each per receiver,
        and how many receivers did not take the Ack (not fresh)."""
        k = self.kernels
        if k is None:
            hears_me = hears(record[FIELDS:], receivers)
            fresh = self.update(now, sender, receivers, hears_me, record)
            return fresh, hears_me, len(fresh) - int(fresh.sum())
        fresh = np.empty(len(receivers), dtype=bool)
        hears_me = np.empty(len(receivers), dtype=bool)
        stale, _ = self.take_by(k.receive, now, sender, receivers, record, (fresh, hears_me))
        return fresh, hears_me, stale

    def take_by(self, kernel, *args) -> tuple:
        """Record an Ack as :meth:`receive` does, by a compiled ``kernel`` that takes the
        table as :func:`netsim.protocols._kernels.receive` does and may do more with it:
        ``kernel(view, *args, start)`` (:attr:`view`) returns ``(k, stale, *results)``, ``k
        >= 0`` when the row of the ``k``-th receiver must grow first (then it is called
        again from there). Returns the receivers that did not take the Ack (stale) and the
        last call's ``results``."""
        start, stale = 0, 0
        while True:
            start, more_stale, *results = kernel(self.view, *args, start)
            stale += more_stale
            if start < 0:
                return stale, results
            self._grow()

    def take(self, now: float, sender: int, receivers: np.ndarray, record: np.ndarray) -> int:
        """:meth:`receive`, for a caller that keeps no flag: returns only how many receivers
        did not take the Ack (not fresh)."""
        k = self.kernels
        if k is None:
            return self.receive(now, sender, receivers, record)[2]
        # take_by's loop, written out: the path of most Acks, with no arguments to gather.
        start, stale = 0, 0
        while True:
            start, more = k.take(self.view, now, sender, receivers, record, start)
            stale += more
            if start < 0:
                return stale
            self._grow()

    def _place(self, now, sender, receivers, flat, found):
        """Give ``sender`` a slot in the rows of the receivers that have none for it."""
        new = ~found
        r_new = receivers[new]
        free = self._free_slots(now, r_new)
        while not free.any(axis=1).all():
            self._grow()
            free = self._free_slots(now, r_new)
        slot = free.argmax(axis=1)
        self.id[r_new, slot] = sender
        flat = receivers * self.slots + (self.id.take(receivers, axis=0) == sender).argmax(axis=1)
        return flat

    def live_mask(self, now: float, i=None) -> np.ndarray:
        """Which slots hold live entries (all rows, or row ``i``)."""
        last = self.data[:, :, LAST_HEARD] if i is None else self.data[i, :, LAST_HEARD]
        return now - last < self.tau_s

    def heard(self, now: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Every row's live entries now (:class:`netsim.cosim.NeighbourView`): ids ``(n,
        slots)``, -1 where no live entry; positions told ``(n, slots, 2)``; arrival times of
        the Acks that told them ``(n, slots)``."""
        live = self.live_mask(now)
        return np.where(live, self.id, EMPTY), self.data[:, :, X : Y + 1].copy(), self.data[:, :, LAST_HEARD].copy()

    def announce(
        self, now: float, i: int, seq: int, role: int, leader: int, x_m: float, y_m: float, group_size: int
    ) -> np.ndarray:
        """What ``i``'s Ack carries: its packed record (:func:`ack_record`, with ``i``'s
        two-way degree: the live neighbours that hear it), then the ids of its live
        neighbours, ascending."""
        k = self.kernels
        if k is not None:
            return k.announce(self.view, i, float(now), (seq, role, leader, x_m, y_m, group_size))
        live = self.live_mask(now, i)
        degree = int((live & (self.data[i, :, HEARS_ME] != 0)).sum())
        return ack_record(seq, role, leader, x_m, y_m, group_size, degree, np.sort(self.id[i][live]))

    def live_ids(self, now: float, i: int) -> np.ndarray:
        """Ids of ``i``'s live neighbours, ascending."""
        return np.sort(self.id[i][self.live_mask(now, i)])

    def entry(self, i: int, j: int) -> int | None:
        """The slot of ``j`` in ``i``'s row, or None."""
        s = np.flatnonzero(self.id[i] == j)
        return int(s[0]) if len(s) else None


def two_way(records: np.ndarray, now: float, tau_s: float, symmetric: bool) -> np.ndarray:
    """Which of the table's ``records`` (any leading shape: a row, rows, the whole table)
    are live neighbours over a two-way link (with equal ranges, ``symmetric``: every live
    one)."""
    live = now - records[..., LAST_HEARD] < tau_s
    if not symmetric:
        live &= records[..., HEARS_ME] != 0
    return live


def hears(heard: np.ndarray, receivers: np.ndarray) -> np.ndarray:
    """Per receiver, whether it is among the ids ``heard`` (ascending; ints, or the floats
    of an Ack's record)."""
    if len(heard) == 0:
        return np.zeros(len(receivers), dtype=bool)
    at = np.minimum(heard.searchsorted(receivers), len(heard) - 1)
    return heard[at] == receivers


def ack_record(seq, role, leader, x_m, y_m, group_size, degree=0, heard=()) -> np.ndarray:
    """The packed record of an Ack's fields (time and link columns are filled on update),
    followed by the ids ``heard`` (ascending) it carries."""
    rec = np.empty(FIELDS + len(heard))
    rec[:FIELDS] = EMPTY_RECORD
    rec[SEQ], rec[ROLE], rec[LEADER], rec[X], rec[Y] = seq, role, leader, x_m, y_m
    rec[GROUP_SIZE], rec[DEGREE] = group_size, degree
    rec[FIELDS:] = heard
    return rec


def heard_in(record: np.ndarray) -> np.ndarray:
    """The ids an Ack's packed ``record`` carries (those its sender heard), ascending."""
    return record[FIELDS:].astype(np.int64)
