"""Plain callbacks run in the kernel's exact order, without a kernel event each.

A SimPy event costs an ``Event`` object, a push on the kernel's heap, a pop and a loop
over its callbacks. The busiest events of a run, the Ack beacons' ticks and the channel's
deliveries, need none of that: each is one function called at one instant. An
:class:`Agenda` keeps them in a heap of its own, keyed ``(t, priority, id)`` as the
kernel keys its events, with the id drawn from SimPy's own counter at the moment the
entry is scheduled: every entry gets the key the kernel would have given its event, so
ties between simultaneous events (same instant, same priority) are broken exactly as
before, whoever scheduled them.

One kernel event wakes the agenda, queued with the exact key of its head. The kernel runs
it when everything before that key has run; the agenda then runs its entries in order, moving
the clock to each, for as long as its head comes before the kernel's next event (the run's
stop event included), and arms a wake for its new head. The global order is that of one
kernel event per entry; the kernel sees one event per run of consecutive entries. (A
wake stays queued when an earlier entry arms another before it; by its turn its entry may
have run from that one, and it runs whatever is due then, or nothing.)
:func:`netsim.events.kernel_queue` and :func:`netsim.events.advance_clock` say why reading
the kernel's queue and setting its clock is sound (``netsim.kinetic`` does the same for
the runtime link events).

Entries that a caller schedules in key order (the channel's deliveries at its constant
latency: each at now + the same delay, at the same priority, with a later id) go to a
plain queue beside the heap (:meth:`Agenda.at_in_order`), which costs an append and a pop
instead of a heap's log n comparisons; the agenda runs whichever head comes first. An
entry that would not keep that queue in order goes to the heap instead, so the order never
rests on the caller.

One caller may keep its entries in a structure of its own and show the agenda only its
first (:meth:`Agenda.attach`; :class:`netsim.timers.DeadlineTimers`, whose events are
armed seconds ahead and taken thousands a second): the agenda runs that source's first
entry when it comes before the heap's and the queue's heads, so those entries never pass
through the heap, whose log n steps over cold memory cost more than the entry's own work.
Keys drawn with :meth:`Agenda.key` order them among all others.
"""

from __future__ import annotations

from collections import deque
from collections.abc import Callable
from heapq import heappop, heappush
from typing import Protocol

import simpy

from netsim.events import kernel_queue


class _Wake(simpy.Event):
    """The kernel event that wakes an agenda. It shares its key with the agenda entry it
    was armed for; ordered against that entry (the only key it can tie with) it comes after,
    so that the agenda runs the entry itself rather than wait for its own wake."""

    def __lt__(self, _other: object) -> bool:
        return False


class _Side(Protocol):
    head: tuple | None

    def run_head(self) -> None: ...


class _NoSide:
    head: tuple | None = None

    def run_head(self) -> None:  # pragma: no cover  # its head is always None
        raise AssertionError("no entries")


_NO_SIDE = _NoSide()


class Agenda:
    """Callbacks ``fn(*args)`` due at ``(t, priority)``, run in the kernel's order (module notes).

    An entry is the tuple ``(t, priority, id, fn, args)``: the arguments ride in it, so that
    a caller schedules a bound method and its arguments without making an object (a
    ``partial``, a closure) for each call; the unique id decides every comparison before
    ``fn``."""

    def __init__(self, env: simpy.Environment):
        self.env = env
        self._heap: list[tuple] = []
        # Entries scheduled in key order (at_in_order), first due first.
        self._queue: deque[tuple] = deque()
        # Keys (t, priority, id) of the wakes queued in the kernel and not yet run, a heap.
        self._wakes: list[tuple] = []
        self._kernel = kernel_queue(env)  # the same list for the whole run
        self._ids = env._eid  # type: ignore[attr-defined]  # SimPy's counter of event ids
        self._running = False
        self.wakes_run = 0
        # A source of entries of its own (attach): its ``head`` is its first entry or None.
        self._side: _Side = _NO_SIDE

    def __len__(self) -> int:
        return len(self._heap) + len(self._queue)

    def at(self, delay_s: float, priority: int, fn: Callable[..., object], *args: object) -> None:
        """Call ``fn(*args)`` ``delay_s`` from now at ``priority``: where an event scheduled
        now with ``env.schedule(event, priority, delay_s)`` would run."""
        entry = (self.env._now + delay_s, priority, next(self._ids), fn, args)  # type: ignore[attr-defined]
        heappush(self._heap, entry)
        wakes = self._wakes
        if (not wakes or entry < wakes[0]) and not self._running:
            self._arm(entry)

    def key(self, delay_s: float, priority: int) -> tuple[float, int, int]:
        """The key ``(t, priority, id)`` of an entry scheduled now ``delay_s`` ahead (its id
        drawn now), for an attached source's entries (:meth:`attach`)."""
        return (self.env._now + delay_s, priority, next(self._ids))  # type: ignore[attr-defined]

    def attach(self, side: _Side) -> bool:
        """Run the entries of ``side`` in order with the agenda's own (module notes):
        ``side.head`` is its first entry, a tuple starting with a key drawn by :meth:`key`
        (None: it has none), and ``side.run_head()`` takes that entry and runs it (with the
        clock at its time). ``side`` calls :meth:`side_armed` when its head becomes an
        earlier entry. One source per agenda: False if one is attached already."""
        if self._side is not _NO_SIDE:
            return False
        self._side = side
        return True

    def side_armed(self, entry: tuple) -> None:
        """The attached source's head is now ``entry``, earlier than before: a wake for it
        if it comes before every queued wake (none while the agenda runs: see _run)."""
        wakes = self._wakes
        if (not wakes or entry < wakes[0]) and not self._running:
            self._arm(entry)

    def at_in_order(self, delay_s: float, priority: int, fn: Callable[..., object], *args: object) -> None:
        """:meth:`at`, for a caller whose entries mostly come in key order (the same delay
        and priority each time): those are queued, not heaped (module notes)."""
        entry = (self.env._now + delay_s, priority, next(self._ids), fn, args)  # type: ignore[attr-defined]
        queue = self._queue
        if queue and entry < queue[-1]:
            heappush(self._heap, entry)
        else:
            queue.append(entry)
        wakes = self._wakes
        if (not wakes or entry < wakes[0]) and not self._running:
            self._arm(entry)

    def _head(self) -> tuple | None:
        heap, queue, first = self._heap, self._queue, self._side.head
        head: tuple | None
        if heap:
            head = queue[0] if queue and queue[0] < heap[0] else heap[0]
        else:
            head = queue[0] if queue else None
        if first is not None and (head is None or first < head):
            return first
        return head

    def _arm(self, entry: tuple) -> None:
        t, priority, eid = entry[0], entry[1], entry[2]
        wake = _Wake(self.env)
        wake._ok = True
        wake._value = None
        wake.callbacks.append(self._run)
        heappush(self._kernel, (t, priority, eid, wake))
        heappush(self._wakes, (t, priority, eid))

    def _run(self, _event: simpy.Event) -> None:
        # Wakes run in key order, and all of them are in _wakes: this one is its head. What
        # the entries schedule arms no wake: the one armed below, for the new head, is enough.
        wakes = self._wakes
        heappop(wakes)
        self.wakes_run += 1
        self._running = True
        heap, queue, kernel, env, side = self._heap, self._queue, self._kernel, self.env, self._side
        try:
            while True:
                if heap:
                    head = heap[0]
                    queued = queue and queue[0] < head
                    if queued:
                        head = queue[0]
                elif queue:
                    head, queued = queue[0], True
                else:
                    head = None
                first = side.head
                if first is not None and (head is None or first < head):
                    if kernel and kernel[0] < first:
                        break
                    env._now = first[0]  # type: ignore[attr-defined]
                    side.run_head()
                    continue
                if head is None:
                    break
                if kernel and kernel[0] < head:
                    break
                if queued:
                    queue.popleft()
                else:
                    heappop(heap)
                # As the kernel's step() sets it: the entry's own time, the same float.
                env._now = head[0]  # type: ignore[attr-defined]
                head[3](*head[4])
        finally:
            self._running = False
            first = self._head()
            if first is not None and (not wakes or first < wakes[0]):
                self._arm(first)
