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
"""

from __future__ import annotations

from collections import deque
from collections.abc import Callable
from heapq import heappop, heappush

import simpy

from netsim.events import kernel_queue


class _Wake(simpy.Event):
    """The kernel event that wakes an agenda. It shares its key with the agenda entry it
    was armed for; ordered against that entry (the only key it can tie with) it comes after,
    so that the agenda runs the entry itself rather than wait for its own wake."""

    def __lt__(self, _other: object) -> bool:
        return False


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
        drawn now), for :meth:`at_key`."""
        return (self.env._now + delay_s, priority, next(self._ids))  # type: ignore[attr-defined]

    def at_key(self, key: tuple[float, int, int], fn: Callable[..., object], *args: object) -> None:
        """Call ``fn(*args)`` at ``key``, drawn earlier by :meth:`key`: it runs where an entry
        scheduled at that moment would have run. For a caller that keeps entries of its own
        and queues here only the first (:class:`netsim.timers.DeadlineTimers`); a key may be
        queued only once."""
        entry = (key[0], key[1], key[2], fn, args)
        heappush(self._heap, entry)
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
        heap, queue = self._heap, self._queue
        if heap:
            return queue[0] if queue and queue[0] < heap[0] else heap[0]
        return queue[0] if queue else None

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
        heap, queue, kernel, env = self._heap, self._queue, self._kernel, self.env
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
