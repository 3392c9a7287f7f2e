"""Link events during the run on a map (walls, no shadowing).

A link on a map is up while the radio says so (range or received power, and the walls
crossed). The post-hoc solver (``links.parquet``) solves it exactly within the exact envelope (the intervals in
which the pair is within the radio's largest range) along *stretches*, a chunk at a time,
chunks that depend only on what is known at the stretch's start (:mod:`netsim.links.wall_sweeps`,
the arithmetic shared with the post-hoc solver :func:`netsim.links.radio_links.walled_lifetimes`,
which stays the reference). So the same chunks can be solved as the run goes:

- the envelope is a :class:`~netsim.links.kinetic.RuntimeLinks` of its own (announced to nobody
  but this class), solved with the same arithmetic as after the run;
- where a pair enters it, and at every course change of either robot while it is in it, a
  stretch starts: its first chunk is solved at once, a change from the link's current
  state announced at that instant and the changes inside the chunk queued;
- the stretches' later chunks are solved ahead of time, a window at a time (all the pairs
  in the envelope in one call), on the legs as they stand, and their changes queued at
  their instants; a course change cancels the queued changes of its pairs' stretch that
  fall after it (a generation count per pair);
- where the pair leaves the envelope the link goes down, exactly.

The table of these events equals the post-hoc one, bit for bit (tests/test_events.py):
the chunks are the same floats whatever the windows, and a change found before a course
change is kept by both, one after it dropped by both.

Order at one instant: a change inside a stretch, and an envelope's edge, is a runtime link
event (before anything else due then, docs/events.md); a change at a stretch's start that
a course change causes is announced right after the course change.
"""

from __future__ import annotations

import heapq
import math
from typing import cast

import numpy as np
import simpy

from netsim.events import EventBus, LinkDown, LinkUp, notify
from netsim.geometry import link_ranges_m
from netsim.links.kinetic import RuntimeLinks, up_pairs
from netsim.links.wall_sweeps import CHUNK_M, Stretches, count_below, envelope_radii, map_radio
from netsim.radio.reception import Reception
from netsim.scheduling import FIRST, scheduled_event
from netsim.state import RobotState

# A window's start comes before the link events of its instant (it only queues later ones).
_RESTART = FIRST - 1
# A window takes this many chunks of the fastest robot's pairs (the results do not depend
# on it; longer windows waste more work when robots change course).
WINDOW_CHUNKS = 8


class WalledLinks:
    """Link events of one run on a map, announced as they happen (module notes). The same
    interface as :class:`~netsim.links.kinetic.RuntimeLinks`.

    Parameters
    ----------
    env, state : the run's kernel and robots.
    events : the run's bus (``link_up``, ``link_down``).
    reception : the channel's :class:`~netsim.radio.reception.Reception` (its map and radio).
    window_s : the length of a window (default: :data:`WINDOW_CHUNKS` chunks at the highest
        speed when it starts); the results do not depend on it.
    """

    def __init__(
        self,
        env: simpy.Environment,
        state: RobotState,
        events: EventBus | None,
        reception: Reception,
        window_s: float | None = None,
    ):
        self.env, self.state, self.reception = env, state, reception
        self.radii, self.equal = envelope_radii(reception, state.range_m)
        self.radio = map_radio(reception)
        self.n = max(state.n, 1)
        self.window_s = window_s
        self.envelope = RuntimeLinks(env, state, None, range_m=self.radii)
        self.envelope.on_up.append(self._entered)
        self.envelope.on_down.append(self._left)
        state.watchers.append(self._on_leg)
        self.on_up: list = events.subscribers("link_up") if events is not None else []
        self.on_down: list = events.subscribers("link_down") if events is not None else []
        # Links up now: key a n + b -> since when.
        self.up: dict[int, float] = {}
        # One slot per pair in the envelope: its stretch, the next chunk to solve (k_next)
        # and the state at the end of the last one solved, and a generation that cancels the
        # changes queued for an earlier stretch.
        self._slot: dict[int, int] = {}
        self._by_robot: dict[int, set[int]] = {}
        self._free: list[int] = []
        self._size = 0
        self._stretch = Stretches.blank(0)
        self._k_next = np.zeros(0)
        self._s_next = np.zeros(0, bool)
        self._gen: list[int] = []
        # Queued changes: (t, a, b, seq, up, slot, gen).
        self._heap: list[tuple] = []
        self._seq = 0
        self._armed_s = math.inf
        self._w_end = -math.inf
        self._restart_pending = False
        # Stretches whose chunks after the first are still to solve, and when the first of
        # them is due.
        self._pending: set[int] = set()
        self._pending_at = math.inf
        self._dirty: set[int] = set()
        self._flush_pending = False
        self._quiet = False
        self.chunks = 0

    @property
    def windows(self) -> int:
        return self.envelope.windows

    @property
    def started(self) -> bool:
        return self.envelope.started

    def start(self) -> None:
        self.envelope.start()

    def finish(self, t_end: float) -> None:
        """The run's end: the changes due by then are applied, not announced."""
        self.envelope.finish(t_end)
        self._quiet = True
        self._announce(t_end)

    # -- the link's state --------------------------------------------------------------
    def _set(self, key: int, t: float, now_up: bool) -> None:
        if now_up:
            if key in self.up:
                return
            self.up[key] = t
            if self.on_up and not self._quiet:
                event = LinkUp(t, *divmod(key, self.n))
                notify(self.on_up, event)
            return
        t_up = self.up.pop(key, None)
        if t_up is None:
            return
        if self.on_down and not self._quiet:
            down = LinkDown(t, *divmod(key, self.n), t_up)
            notify(self.on_down, down)

    # -- the envelope ------------------------------------------------------------------
    def _entered(self, event: LinkUp) -> None:
        key = event.a * self.n + event.b
        if key in self._slot:
            return
        if not self._free:
            self._grow()
        slot = self._free.pop()
        self._slot[key] = slot
        self._by_robot.setdefault(event.a, set()).add(slot)
        self._by_robot.setdefault(event.b, set()).add(slot)
        self._stretch.a[slot], self._stretch.b[slot] = event.a, event.b
        self._start(np.array([slot], np.int64), np.array([event.t_s]))

    def _left(self, event: LinkDown) -> None:
        key = event.a * self.n + event.b
        slot = self._slot.pop(key, None)
        if slot is None:
            return
        self._gen[slot] += 1
        # No more chunks for it (a stretch left waiting for its later chunks included).
        self._k_next[slot] = self._stretch.nc[slot]
        self._pending.discard(slot)
        self._by_robot[event.a].discard(slot)
        self._by_robot[event.b].discard(slot)
        self._free.append(slot)
        self._set(key, event.t_s, False)

    def _grow(self) -> None:
        old = self._size
        size = max(64, 2 * old)
        self._stretch = self._stretch.grown(size)
        self._k_next = np.r_[self._k_next, np.zeros(size - old)]
        self._s_next = np.r_[self._s_next, np.zeros(size - old, bool)]
        self._gen += [0] * (size - old)
        self._free.extend(range(size - 1, old - 1, -1))
        self._size = size

    # -- course changes ----------------------------------------------------------------
    def _on_leg(self, i: int, t: float, jump: bool) -> None:
        if not self._by_robot.get(i):
            return
        self._dirty.add(i)
        if not self._flush_pending:
            # Once the model has set every leg of this instant.
            self._flush_pending = True
            scheduled_event(self.env, 0.0, FIRST, self._flush)

    def _flush(self, _event: object = None) -> None:
        self._flush_pending = False
        slots: set[int] = set()
        for r in self._dirty:
            slots |= self._by_robot.get(r, set())
        self._dirty.clear()
        if slots:
            idx = np.fromiter(sorted(slots), np.int64, len(slots))
            st, s = self.state, self._stretch
            self._start(idx, np.maximum(st.t0_s[s.a[idx]], st.t0_s[s.b[idx]]))

    # -- stretches ---------------------------------------------------------------------
    def _start(self, slots: np.ndarray, u: np.ndarray) -> None:
        """New stretches of pairs ``slots`` from ``u`` on the robots' current legs: their
        first chunk decides the link's state now; later ones are solved a window at a time."""
        st = self.state
        a, b = self._stretch.a[slots], self._stretch.b[slots]
        o, v, t0 = st.origin_m, st.velocity_mps, st.t0_s
        new = Stretches(a, b, u, o[a], v[a], t0[a], o[b], v[b], t0[b], link_ranges_m(self.radii, a, b), self.n)
        self._stretch.put(slots, new)
        for s in slots.tolist():
            self._gen[s] += 1
        # The first chunk decides the link now and is solved at once (a change in it may be
        # due at once). The later chunks can wait until the second's start: they are solved
        # then, with every other stretch's due by then, in one call.
        k = len(new)
        rows = np.arange(k)
        row, t, now_up, first, last = new.take(self.radio, rows, np.zeros(k), np.ones(k), None)
        self.chunks += k
        n = self.n
        for ai, bi, ui, up in zip(a.tolist(), b.tolist(), u.tolist(), first.tolist()):
            self._set(ai * n + bi, ui, up)
        self._k_next[slots] = 1.0
        self._s_next[slots] = last
        if len(row):
            self._queue(slots[row], t, now_up)
        more = new.nc > 1
        later = slots[more]
        if len(later):
            self._pending.update(later.tolist())
            due = float(new.chunk_start(np.flatnonzero(more), np.ones(len(later))).min())
            if due < self._pending_at:
                self._pending_at = due
                scheduled_event(self.env, max(due - self.env.now, 0.0), _RESTART, self._take_pending, value=due)

    def _take_pending(self, event: simpy.Event) -> None:
        # Armed for an instant (the clock may be a rounding step off it); a later one armed
        # before an earlier took the stretches has nothing to do.
        if event.value != self._pending_at:
            return
        pending = np.fromiter(self._pending, np.int64, len(self._pending))
        self._pending.clear()
        self._pending_at = math.inf
        self._solve(np.sort(pending))

    def _queue(self, slots: np.ndarray, t: np.ndarray, now_up: np.ndarray) -> None:
        heap, gen, s = self._heap, self._gen, self._stretch
        for r, ti, up in zip(slots.tolist(), t.tolist(), now_up.tolist()):
            self._seq += 1
            heapq.heappush(heap, (ti, int(s.a[r]), int(s.b[r]), self._seq, up, r, gen[r]))
        self._arm()

    def _window(self) -> float:
        if self.window_s is not None:
            return float(self.window_s)
        top = float(self.state.speed_mps.max()) if self.state.n else 0.0
        return WINDOW_CHUNKS * CHUNK_M / top if top > 0 else 1.0

    def _solve(self, slots: np.ndarray) -> None:
        """Solve the chunks of stretches ``slots`` that start before the window's end; queue
        the changes."""
        now = self.env.now
        if not self._restart_pending and self._w_end <= now:
            self._w_end = now + self._window()
        s = self._stretch
        k1 = np.minimum(count_below(s.u[slots], s.h[slots], self._w_end), s.nc[slots])
        k0 = self._k_next[slots]
        todo = k0 < k1
        rows, k0, k1 = slots[todo], k0[todo], k1[todo]
        if len(rows):
            row, t, now_up, _, last = s.take(self.radio, rows, k0, k1, self._s_next[rows])
            self.chunks += int((k1 - k0).sum())
            self._k_next[rows] = k1
            self._s_next[rows] = last
            self._queue(row, t, now_up)
        if not self._restart_pending and bool((self._k_next[slots] < s.nc[slots]).any()):
            self._restart_pending = True
            scheduled_event(self.env, max(self._w_end - now, 0.0), _RESTART, self._restart)

    def _restart(self, _event: object = None) -> None:
        self._restart_pending = False
        self._w_end = self.env.now + self._window()
        live = np.fromiter(self._slot.values(), np.int64, len(self._slot))
        if len(live):
            self._solve(live[self._k_next[live] < self._stretch.nc[live]])

    # -- the queue ---------------------------------------------------------------------
    def _arm(self) -> None:
        heap = self._heap
        if heap and heap[0][0] < self._armed_s:
            t = heap[0][0]
            self._armed_s = t
            scheduled_event(self.env, max(t - self.env.now, 0.0), FIRST, self._wake, value=t)

    def _wake(self, event: simpy.Event) -> None:
        # Taken by the instant armed for, not the clock (which may be a rounding step off).
        armed_s = cast(float, event.value)
        if armed_s >= self._armed_s:
            self._armed_s = math.inf
        self._announce(armed_s)
        self._arm()

    def _announce(self, until: float) -> None:
        heap, gen, n = self._heap, self._gen, self.n
        while heap and heap[0][0] <= until:
            t, a, b, _seq, up, slot, g = heapq.heappop(heap)
            if gen[slot] == g:
                self._set(a * n + b, t, up)

    def up_pairs(self) -> tuple[np.ndarray, np.ndarray]:
        """The links up now: arrays ``(a, b)``, ``a < b``."""
        return up_pairs(self.up, self.n)

    @property
    def now_s(self) -> float:
        """The instant the links of :meth:`up_pairs` are up at: the run's present."""
        return float(self.env.now)
