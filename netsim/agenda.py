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
:mod:`netsim.simpy_internals` says why reading the kernel's queue and setting its clock is
sound (``netsim.links.kinetic`` does the same for the runtime link events), and holds every
access to SimPy's internals.

Entries that a caller schedules in key order (the channel's deliveries at its constant
latency: each at now + the same delay, at the same priority, with a later id) go to a
plain queue beside the heap (:meth:`Agenda.at_in_order`), which costs an append and a pop
instead of a heap's log n comparisons; the agenda runs whichever head comes first. An
entry that would not keep that queue in order goes to the heap instead, so the order never
rests on the caller.

Entries scheduled well ahead, thousands a second (deadline timers' events, seconds ahead,
most of them only to re-arm: :meth:`Agenda.ahead`), go to a calendar instead
(:class:`Calendar`): a list per slice of time, sorted once when its slice comes. A heap of
them is cold by each push and pop, which then walk its depth through cache misses; a
calendar appends to one list and takes from another. (The beacons' ticks stay on the heap:
in the calendar, a large run's slices would each hold thousands of ticks to sort.)
"""

from __future__ import annotations

import math
from bisect import insort
from collections import deque
from collections.abc import Callable
from heapq import heappop, heappush

import simpy

from netsim.simpy_internals import event_ids, give_outcome, kernel_queue, push, set_now
from netsim.simpy_internals import now as clock


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
        self._ids = event_ids(env)
        self._running = False
        self.wakes_run = 0
        # Entries scheduled with ahead(), and the first of them (None: there is none).
        self._calendar = Calendar()
        self._ahead: tuple | None = None

    def __len__(self) -> int:
        return len(self._heap) + len(self._queue) + len(self._calendar)

    def at(self, delay_s: float, priority: int, fn: Callable[..., object], *args: object) -> None:
        """Call ``fn(*args)`` ``delay_s`` from now at ``priority``: where an event scheduled
        now with ``env.schedule(event, priority, delay_s)`` would run."""
        entry = (clock(self.env) + delay_s, priority, next(self._ids), fn, args)
        heappush(self._heap, entry)
        wakes = self._wakes
        if (not wakes or entry < wakes[0]) and not self._running:
            self._arm(entry)

    def ahead(self, delay_s: float, priority: int, fn: Callable[..., object], *args: object) -> None:
        """:meth:`at`, for an entry due well ahead, of a kind scheduled many at a time (a
        timer's event): it goes to the calendar (module notes)."""
        entry = (clock(self.env) + delay_s, priority, next(self._ids), fn, args)
        self._calendar.push(entry)
        first = self._ahead
        if first is None or entry < first:
            self._ahead = entry
            wakes = self._wakes
            if (not wakes or entry < wakes[0]) and not self._running:
                self._arm(entry)

    def at_in_order(self, delay_s: float, priority: int, fn: Callable[..., object], *args: object) -> None:
        """:meth:`at`, for a caller whose entries mostly come in key order (the same delay
        and priority each time): those are queued, not heaped (module notes)."""
        entry = (clock(self.env) + delay_s, priority, next(self._ids), fn, args)
        queue = self._queue
        if queue and entry < queue[-1]:
            heappush(self._heap, entry)
        else:
            queue.append(entry)
        wakes = self._wakes
        if (not wakes or entry < wakes[0]) and not self._running:
            self._arm(entry)

    def _head(self) -> tuple | None:
        heap, queue, first = self._heap, self._queue, self._ahead
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
        wake = give_outcome(_Wake(self.env))
        wake.callbacks.append(self._run)
        push(self.env, t, priority, eid, wake)
        heappush(self._wakes, (t, priority, eid))

    def _run(self, _event: simpy.Event) -> None:
        # Wakes run in key order, and all of them are in _wakes: this one is its head. What
        # the entries schedule arms no wake: the one armed below, for the new head, is enough.
        wakes = self._wakes
        heappop(wakes)
        self.wakes_run += 1
        self._running = True
        heap, queue, kernel, env, calendar = self._heap, self._queue, self._kernel, self.env, self._calendar
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
                first = self._ahead
                if first is not None and (head is None or first < head):
                    if kernel and kernel[0] < first:
                        break
                    calendar.pop()
                    self._ahead = calendar.first()
                    set_now(env, first[0])
                    first[3](*first[4])
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
                set_now(env, head[0])
                head[3](*head[4])
        finally:
            self._running = False
            first = self._head()
            if first is not None and (not wakes or first < wakes[0]):
                self._arm(first)


# A slice number above that of every finite time (floor of the largest double, 2**1024).
_BEYOND = 2**1025


class Calendar:
    """Entries (tuples, ordered by their first items, the first a time) taken in order: the
    order of a heap of them. Each goes to the list of its slice of ``slice_s`` of time,
    sorted when its slice comes first (an entry for the slice being taken is inserted in
    place); a heap of slice numbers finds the next."""

    def __init__(self, slice_s: float = 0.05):
        self._per_s = 1.0 / slice_s
        self._size = 0
        self._slices: dict[int, list] = {}
        self._numbers: list[int] = []  # a heap of the numbers of the slices in _slices
        # The slice being taken, sorted, and the position of its first entry not yet taken.
        self._current: list | None = None
        self._number = 0
        self._at = 0

    def push(self, entry: tuple) -> None:
        # floor(t * per_s) never decreases as t grows (IEEE products are monotonic): the
        # slices keep the entries' order.
        self._size += 1
        try:
            k = math.floor(entry[0] * self._per_s)
        except OverflowError:
            k = _BEYOND  # a time so late that the product overflows: after every finite slice
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
        self._size -= 1
        return entry

    def __len__(self) -> int:
        return self._size
