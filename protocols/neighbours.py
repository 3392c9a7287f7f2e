"""Each robot's neighbour table, for all robots at once.

Row ``i`` holds what robot ``i`` learnt from the Acks it heard: for each neighbour, the
time of its last Ack, when the entry became live, whether the neighbour hears ``i``, and
the Ack's fields. An entry is live while its last Ack is younger than ``tau``
(``now < last + tau`` and the instants that round into it, the deadline its timer runs out
at: :func:`netsim.protocols._kernels.deadline_after`); at that deadline it has expired,
but an Ack that arrives at that very instant continues it (arrivals come before
deadlines: the entry keeps its ``live_since`` and two-way start). An Ack older (by sequence number) than the one an
entry holds, overtaken in flight by a newer one, is ignored.

The table is a fixed number of slots per robot, doubled when a robot hears more
neighbours than it has slots; an expired slot is reused. The fields of a slot are packed
in one float64 record (integers up to 2^53 are exact), a slot's fields in one row of
memory. An Ack's own record (:meth:`NeighbourTable.announce`) is the same fields followed
by the ids the sender heard, ascending: one array per Ack. A slot also keeps the power
(dBm) at which its robot got the Ack the entry holds (``rx_power_dbm``), measured by the
channel on the way (NaN when it measures none: under the unit disk, or any radio without a
log-distance law); an Ack's own record carries NaN there.

The table's rules are compiled loops (:mod:`netsim.protocols._kernels`, loaded for the
run's size by :func:`netsim.compiled.load`), which also define the record's columns.
"""

from __future__ import annotations

import numpy as np
from netsim.protocols._kernels import (
    BIDIR_SINCE,
    DEGREE,
    EMPTY,
    EMPTY_RECORD,
    FIELDS,
    GROUP_SIZE,
    HEARS_ME,
    LAST_HEARD,
    LEADER,
    LIVE_SINCE,
    MEMBER_OF,
    ROLE,
    ROLE_SINCE,
    RX_POWER,
    SEQ,
    Table,
    X,
    Y,
)

from netsim.compiled import load


class NeighbourTable:
    def __init__(self, n: int, tau_s: float, slots: int = 16):
        self.n = n
        self.tau_s = float(tau_s)
        self.id = np.full((n, slots), EMPTY, dtype=np.int64)
        self.data = np.broadcast_to(EMPTY_RECORD, (n, slots, FIELDS)).copy()
        # What the compiled loops take (netsim.protocols._kernels.Table, as a plain tuple),
        # made again on growth.
        self.view = tuple(Table(self.id, self.data, self.tau_s))
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
    rx_power_dbm = property(lambda self: self.data[:, :, RX_POWER])
    member_of = property(lambda self: self.data[:, :, MEMBER_OF].astype(np.int64))

    @property
    def slots(self) -> int:
        return self.id.shape[1]

    def _grow(self) -> None:
        k = self.slots
        ids = np.full((self.n, 2 * k), EMPTY, dtype=np.int64)
        ids[:, :k] = self.id
        data = np.broadcast_to(EMPTY_RECORD, (self.n, 2 * k, FIELDS)).copy()
        data[:, :k] = self.data
        self.id, self.data = ids, data
        self.view = tuple(Table(ids, data, self.tau_s))

    def receive(
        self,
        now: float,
        sender: int,
        receivers: np.ndarray,
        record: np.ndarray,
        power_dbm: np.ndarray | None = None,
    ) -> tuple[np.ndarray, np.ndarray, int]:
        """Record an Ack from ``sender`` (its packed ``record``, with the ids it heard),
        heard by every robot in ``receivers`` at ``now``, each at ``power_dbm`` (None: not
        measured) (:func:`netsim.protocols._kernels.receive`). Returns ``(fresh, hears_me, stale)``:
        per receiver whether the Ack was taken (False: an older Ack than the entry's
        newest) and whether it was among the ids the Ack carried, and how many receivers
        did not take the Ack (not fresh)."""
        fresh = np.empty(len(receivers), dtype=bool)
        hears_me = np.empty(len(receivers), dtype=bool)
        stale, _ = self.take_by(self.kernels.receive, now, sender, receivers, record, power_dbm, fresh, hears_me)
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

    def take(
        self, now: float, sender: int, receivers: np.ndarray, record: np.ndarray, power_dbm: np.ndarray | None = None
    ) -> int:
        """:meth:`receive`, for a caller that keeps no flag: returns only how many receivers
        did not take the Ack (not fresh)."""
        # take_by's loop, written out: the path of most Acks, with no arguments to gather.
        take = self.kernels.take
        start, stale = 0, 0
        while True:
            start, more = take(self.view, now, sender, receivers, record, power_dbm, start)
            stale += more
            if start < 0:
                return stale
            self._grow()

    def live_mask(self, now: float, i=None) -> np.ndarray:
        """Which slots hold live entries (all rows, or row ``i``)."""
        last = self.data[:, :, LAST_HEARD] if i is None else self.data[i, :, LAST_HEARD]
        return self.kernels.live_entries(last.ravel(), float(now), self.tau_s).reshape(last.shape)

    def heard(self, now: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Every row's live entries now (:class:`netsim.cosim.NeighbourView`): ids ``(n,
        slots)``, -1 where no live entry; positions told ``(n, slots, 2)``; arrival times of
        the Acks that told them ``(n, slots)``."""
        live = self.live_mask(now)
        return np.where(live, self.id, EMPTY), self.data[:, :, X : Y + 1].copy(), self.data[:, :, LAST_HEARD].copy()

    def link_quality(self, now: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Every row's live entries now (:class:`netsim.cosim.LinkQualityView`): ids ``(n,
        slots)``, -1 where no live entry; the power (dBm, NaN: not measured) at which the
        row's robot got the Ack each entry holds, and when it arrived ``(n, slots)``."""
        live = self.live_mask(now)
        return np.where(live, self.id, EMPTY), self.data[:, :, RX_POWER].copy(), self.data[:, :, LAST_HEARD].copy()

    def announce(
        self, now: float, i: int, seq: int, role: int, leader: int, x_m: float, y_m: float, group_size: int
    ) -> np.ndarray:
        """What ``i``'s Ack carries: its packed record (these fields, with ``i``'s two-way
        degree: the live neighbours that hear it), then the ids of its live neighbours,
        ascending (:func:`netsim.protocols._kernels.announce`)."""
        return self.kernels.announce(self.view, i, float(now), seq, role, leader, x_m, y_m, group_size)

    def live_ids(self, now: float, i: int) -> np.ndarray:
        """Ids of ``i``'s live neighbours, ascending."""
        return np.sort(self.id[i][self.live_mask(now, i)])

    def entry(self, i: int, j: int) -> int | None:
        """The slot of ``j`` in ``i``'s row, or None."""
        s = np.flatnonzero(self.id[i] == j)
        return int(s[0]) if len(s) else None


def heard_in(record: np.ndarray) -> np.ndarray:
    """The ids an Ack's packed ``record`` carries (those its sender heard), ascending."""
    return record[FIELDS:].astype(np.int64)
