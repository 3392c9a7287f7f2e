"""Deadline timers with O(1) restart, for many robots at once.

SimPy timeouts cannot be cancelled. A timer here is a deadline in an array; restarting
it writes the array (vectorised over any set of robots) and schedules nothing, unless
the new deadline is earlier than the pending event. When the pending event fires it
compares with the current deadline: if the deadline moved later, it re-arms itself there;
if it was cancelled, it does nothing; otherwise the timer expires. So a timer restarted on
every Ack costs one array write per Ack and at most one event per ``tau`` (a kernel event
without an agenda; an entry of the timers' calendar with one, below).

Timer events run at NORMAL priority; message deliveries run at URGENT priority, so an
Ack that arrives at the same instant as a deadline is processed first and counts.

Given an :class:`netsim.agenda.Agenda` (the channel's), a timer's events are not kernel
events: each gets the key the agenda would give it, ``(t, priority, id)``, at the moment it
is armed, and goes to a calendar of the timers' own (:class:`Calendar`), attached to the
agenda (:meth:`netsim.agenda.Agenda.attach`): the agenda runs the calendar's first event
when it comes before its own entries. So every event runs exactly where it would have run
as an entry of the agenda (the same instants, in the same order, ties included), while the
agenda's heap, which every Ack tick goes through, never holds a timer event. A calendar
rather than a heap: timer events are armed a few seconds ahead and taken a few thousand a
second, so a heap of them is cold by each pop, which then walks its whole depth through
cache misses; a calendar appends each event to the list of its slice of time and sorts a
list once, when its slice comes.
"""

from __future__ import annotations

import math
from bisect import insort
from collections.abc import Callable
from functools import partial
from heapq import heappop, heappush

import numpy as np
import simpy

from netsim.agenda import Agenda
from netsim.events import NORMAL, scheduled_event


class Calendar:
    """Entries (tuples, ordered by their first items, the first a time) taken in order: the
    order of a heap of them. Each goes to the list of its slice of ``slice_s`` of time,
    sorted when its slice comes first (an entry for the slice being taken is inserted in
    place); a heap of slice numbers finds the next."""

    def __init__(self, slice_s: float = 0.05):
        self._per_s = 1.0 / slice_s
        self._slices: dict[int, list] = {}
        self._numbers: list[int] = []  # a heap of the numbers of the slices in _slices
        # The slice being taken, sorted, and the position of its first entry not yet taken.
        self._current: list | None = None
        self._number = 0
        self._at = 0

    def push(self, entry: tuple) -> None:
        # floor(t * per_s) never decreases as t grows (IEEE products are monotonic): the
        # slices keep the entries' order.
        k = math.floor(entry[0] * self._per_s)
        current = self._current
        if current is not None:
            if k == self._number:
                insort(current, entry, lo=self._at)
                return
            if k < self._number:
                # An earlier slice: the current one goes back with what it has left.
                self._slices[self._number] = current[self._at :]
                heappush(self._numbers, self._number)
                self._current = None
        entries = self._slices.get(k)
        if entries is None:
            self._slices[k] = [entry]
            heappush(self._numbers, k)
        else:
            entries.append(entry)

    def first(self) -> tuple | None:
        """The first entry (None: there is none)."""
        current = self._current
        if current is not None and self._at < len(current):
            return current[self._at]
        if not self._numbers:
            self._current = None
            return None
        k = heappop(self._numbers)
        current = self._slices.pop(k)
        current.sort()
        self._current, self._number, self._at = current, k, 0
        return current[0]

    def pop(self) -> tuple:
        """Take the first entry (there must be one)."""
        entry = self.first()
        assert entry is not None
        self._at += 1
        return entry


class DeadlineTimers:
    """``n`` one-shot timers; ``on_expire(i, now)`` is called when timer ``i`` expires."""

    def __init__(
        self, env: simpy.Environment, n: int, on_expire: Callable[[int, float], None], agenda: Agenda | None = None
    ):
        self.env = env
        self.agenda = agenda
        self.on_expire = on_expire
        self.deadline_s = np.full(n, np.inf)
        # Time of the event (kernel or agenda) armed for each timer (inf: none; compiled loops that
        # set deadlines read it, see arm), and a generation number so that superseded
        # events recognise themselves.
        self.armed_s = np.full(n, np.inf)
        self._generation = [0] * n  # read one at a time: a list is cheaper than an array
        self._fire_bound = self._fire  # one bound method, not one per arming
        # With an agenda that takes a source of its own (module notes): the events, (t,
        # priority, id, timer, generation), in a calendar, and its first (None: there is
        # none), which the agenda reads. Another agenda (the tests' reference, a kernel event
        # per entry) gets an entry per timer event instead.
        self._events = Calendar()
        self.head: tuple | None = None
        self._attached = agenda is not None and hasattr(agenda, "attach") and agenda.attach(self)

    def restart(self, idx: int | np.ndarray, deadline_s: float | np.ndarray) -> None:
        """Set the deadline of timers ``idx`` (an int or an array) to ``deadline_s``."""
        if isinstance(deadline_s, float | int):
            # One deadline for all (the common case, per Ack): no broadcast array.
            d = float(deadline_s)
            if isinstance(idx, int | np.integer):
                self.deadline_s[idx] = d
                if d < self.armed_s[idx]:
                    self._arm(int(idx), d)
                return
            idx = np.asarray(idx, dtype=np.int64)
            self.deadline_s[idx] = d
            for i in idx[d < self.armed_s[idx]].tolist():
                self._arm(i, d)
            return
        idx = np.atleast_1d(np.asarray(idx, dtype=np.int64))
        deadline = np.broadcast_to(np.asarray(deadline_s, dtype=float), idx.shape)
        self.deadline_s[idx] = deadline
        early = deadline < self.armed_s[idx]
        if early.any():
            for i, d in zip(idx[early].tolist(), deadline[early].tolist()):
                self._arm(i, d)

    def arm(self, idx: np.ndarray, deadline_s: float) -> None:
        """Schedule the events of timers ``idx`` whose deadlines were set to ``deadline_s``
        elsewhere (a compiled loop) and fall before their armed events: the second half of
        :meth:`restart`."""
        for i in idx.tolist():
            self._arm(i, deadline_s)

    def cancel(self, idx: int | np.ndarray) -> None:
        self.deadline_s[idx] = np.inf

    def _arm(self, i: int, at_s: float) -> None:
        gen = self._generation[i] + 1
        self._generation[i] = gen
        self.armed_s[i] = at_s
        delay = at_s - self.env._now  # type: ignore[attr-defined]  # the clock, without the property
        if not delay > 0.0:
            delay = 0.0  # as max(0.0, delay)
        if self._attached:
            agenda = self.agenda
            key = agenda.key(delay, NORMAL)  # type: ignore[union-attr]
            entry = (key[0], key[1], key[2], i, gen)
            self._events.push(entry)
            head = self.head
            if head is None or entry < head:
                self.head = entry
                agenda.side_armed(entry)  # type: ignore[union-attr]
        elif self.agenda is not None:
            self.agenda.at(delay, NORMAL, self._fire_bound, i, gen)
        else:
            scheduled_event(self.env, delay, NORMAL, partial(self._fire_bound, i, gen))

    def run_head(self) -> None:
        """Take the first event and run it (the agenda calls this at its key)."""
        events = self._events
        _, _, _, i, gen = events.pop()
        self.head = events.first()
        self._fire(i, gen)

    def _fire(self, i: int, gen: int, _event: object = None) -> None:
        if gen != self._generation[i]:
            return
        deadline = self.deadline_s.item(i)
        now = self.env._now  # type: ignore[attr-defined]
        if deadline <= now:
            self.armed_s[i] = math.inf
            self.deadline_s[i] = math.inf
            self.on_expire(i, now)
        elif deadline != math.inf:
            self._arm(i, deadline)  # moved later: armed there (its armed_s written there)
        else:
            self.armed_s[i] = math.inf
