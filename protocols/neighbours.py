"""Each robot's neighbour table, for all robots at once.

Row ``i`` holds what robot ``i`` learnt from the Acks it heard: for each neighbour, the
time of its last Ack, when the entry became live, and the Ack's fields. An entry is live
while its last Ack is younger than ``tau`` (``now - last < tau``); at exactly ``tau`` it has
expired.

The table is a fixed number of slots per robot (numpy arrays of shape ``(n, slots)``),
doubled when a robot hears more neighbours than it has slots; an expired slot is reused.
A delivery to ``k`` receivers updates their rows in a handful of array operations,
without a Python loop over receivers.
"""

from __future__ import annotations

import numpy as np

EMPTY = -1


class NeighbourTable:
    FIELDS = ("seq", "role", "leader", "x_m", "y_m", "group_size")

    def __init__(self, n: int, tau_s: float, slots: int = 16):
        self.n = n
        self.tau_s = float(tau_s)
        self.id = np.full((n, slots), EMPTY, dtype=np.int64)
        self.last_heard_s = np.full((n, slots), -np.inf)
        self.live_since_s = np.full((n, slots), np.inf)
        self.hears_me = np.zeros((n, slots), dtype=bool)
        self.seq = np.zeros((n, slots), dtype=np.int64)
        self.role = np.zeros((n, slots), dtype=np.int8)
        self.leader = np.full((n, slots), EMPTY, dtype=np.int64)
        self.x_m = np.zeros((n, slots))
        self.y_m = np.zeros((n, slots))
        self.group_size = np.zeros((n, slots), dtype=np.int64)

    @property
    def slots(self) -> int:
        return self.id.shape[1]

    def _grow(self) -> None:
        k = self.slots
        for name, fill in (
            ("id", EMPTY), ("last_heard_s", -np.inf), ("live_since_s", np.inf), ("hears_me", False),
            ("seq", 0), ("role", 0), ("leader", EMPTY), ("x_m", 0.0), ("y_m", 0.0), ("group_size", 0),
        ):
            old = getattr(self, name)
            new = np.full((self.n, 2 * k), fill, dtype=old.dtype)
            new[:, :k] = old
            setattr(self, name, new)

    def update(self, now: float, sender: int, receivers: np.ndarray, hears_me: np.ndarray, fields: dict) -> None:
        """Record an Ack from ``sender`` heard by every robot in ``receivers`` at ``now``.

        ``hears_me[k]`` says whether ``receivers[k]`` was among the ids the Ack carried.
        """
        rows = self.id[receivers]
        hit = rows == sender
        found = hit.any(axis=1)
        slot = hit.argmax(axis=1)
        if not found.all():
            new = ~found
            r_new = receivers[new]
            free = (self.id[r_new] == EMPTY) | (now - self.last_heard_s[r_new] >= self.tau_s)
            while not free.any(axis=1).all():
                self._grow()
                free = (self.id[r_new] == EMPTY) | (now - self.last_heard_s[r_new] >= self.tau_s)
            slot[new] = free.argmax(axis=1)
        was_live = now - self.last_heard_s[receivers, slot] < self.tau_s
        was_live &= self.id[receivers, slot] == sender
        self.id[receivers, slot] = sender
        self.live_since_s[receivers, slot] = np.where(was_live, self.live_since_s[receivers, slot], now)
        self.last_heard_s[receivers, slot] = now
        self.hears_me[receivers, slot] = hears_me
        for name in self.FIELDS:
            getattr(self, name)[receivers, slot] = fields[name]

    def live_mask(self, now: float, i=None) -> np.ndarray:
        """Which slots hold live entries (all rows, or row ``i``)."""
        last = self.last_heard_s if i is None else self.last_heard_s[i]
        return now - last < self.tau_s

    def live_ids(self, now: float, i: int) -> np.ndarray:
        """Ids of ``i``'s live neighbours, ascending."""
        return np.sort(self.id[i][self.live_mask(now, i)])

    def entry(self, i: int, j: int) -> int | None:
        """The slot of ``j`` in ``i``'s row, or None."""
        s = np.flatnonzero(self.id[i] == j)
        return int(s[0]) if len(s) else None

    def degree(self, now: float) -> np.ndarray:
        """Number of live neighbours of every robot."""
        return self.live_mask(now).sum(axis=1)
