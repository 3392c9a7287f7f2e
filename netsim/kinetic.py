"""Link up/down events solved during the run, at their exact instants (a kinetic scheduler).

The same geometry as the post-hoc solver (:mod:`netsim.lifetimes`, which stays the
reference): two robots on straight legs are linked while ``|d + w t| <= min(r_a, r_b)``,
and the link's next up and down instants are roots of a quadratic. What changes is when
they are solved: as the run goes, so that ``link_up`` and ``link_down`` are announced on the
run's event bus at the instant they happen, and ``links.parquet`` is their record.

The run is cut into windows no longer than half the smallest range over the highest speed
seen so far (``v_bound``); at a window's start the candidate pairs are those within
``R_max + 2 v_bound W`` (a KD-tree query; no other pair can meet during the window), and
every candidate's crossings within the window are solved in one vectorised step and queued.
When a robot changes course, only its candidate pairs are solved again from that instant
to the window's end; their earlier solutions are cancelled (a generation count per pair).
A new window starts early when a robot jumps (its links are then judged afresh on its new
position, as the post-hoc solver does) or moves faster than ``v_bound``. So only pairs that
can meet before the end of the window or their next course change are ever scheduled.

Queued events run at priority :data:`~netsim.events.FIRST` (before anything else due at
their instant), in the order ``(t, a, b)``; for one pair, in the order the post-hoc solver
uses, keeping only those that change the link's state. One kernel event wakes the solver
for the next instant that has events; it goes on to the following instants, moving the
kernel's clock itself, while the kernel holds nothing that would run before them: the
order of one kernel event per instant, without paying for one per instant.
docs/events.md says what is exact and the order of events.
"""

from __future__ import annotations

import heapq
import math
from collections.abc import Iterator
from typing import Any

import numpy as np
import pandas as pd
import simpy

from netsim.crossings import PHASE_STATE, solve_piece, tree, wrap
from netsim.events import FIRST, LAST, EventBus, LinkDown, LinkUp, advance_clock, runs_before, scheduled_event
from netsim.lifetimes import COLUMNS
from netsim.state import RobotState

# A window's restart comes before the link events of its instant, which it solves again.
_RESTART = FIRST - 1


class RuntimeLinks:
    """Exact link events of one run, solved while it goes (module notes).

    Parameters
    ----------
    env, state : the run's kernel and robots (told of every course change).
    events : the run's bus: ``link_up`` and ``link_down`` are emitted on it.
    """

    def __init__(self, env: simpy.Environment, state: RobotState, events: EventBus | None = None):
        self.env, self.state, self.events = env, state, events
        self.ranges = state.range_m
        self.r_min = float(self.ranges.min()) if state.n else 0.0
        self.r_max = float(self.ranges.max()) if state.n else 0.0
        self.box = float(state.side_m) if state.torus else None
        # Links up now: (a, b) -> since when; and every lifetime that ended.
        self.up: dict[tuple[int, int], float] = {}
        self.ended: list[tuple[int, int, float, float]] = []
        self.started = False
        self.v_bound = 0.0
        self.windows = 0
        self._heap: list[tuple] = []
        self._queue: list[tuple] = []
        self._qi = 0
        self._batch: list | None = None
        self._armed_s = math.inf
        self._dirty: set[int] = set()
        self._jumped: set[int] = set()
        self._flush_pending = False
        self._w_end = 0.0
        self._wid = 0
        self._ca = self._cb = self._ptr = self._idx = np.empty(0, np.int64)
        self._cr = np.empty(0)
        self._gen = np.empty(0, np.int64)
        # The generations again, as a list: read one at a time by the hot loop.
        self._gen_now: list[int] = []
        self._on_up = events.subscribers("link_up") if events is not None else []
        self._on_down = events.subscribers("link_down") if events is not None else []
        state.watchers.append(self._on_leg)

    # -- life cycle ----------------------------------------------------------------------
    def start(self) -> None:
        """Solve from t = 0, after everything else due at t = 0 (placements, first legs)."""
        scheduled_event(self.env, 0.0, LAST, self._begin)

    def _begin(self, _event: object = None) -> None:
        self.started = True
        self._dirty.clear()
        self._jumped.clear()
        self._new_window(self.env.now, first=True)

    def finish(self, t_end: float) -> None:
        """Apply the queued events due at or before ``t_end`` (the run's end, whose events
        the kernel does not process), without announcing them."""
        for t, a, b, _phase, negk, idx, g in self._take(t_end):
            if idx >= 0 and self._gen[idx] != g:
                continue
            key = (a, b)
            if negk < 0:
                self.up.setdefault(key, t)
            elif key in self.up:
                self.ended.append((a, b, self.up.pop(key), t))

    def frame(self, t_end: float) -> pd.DataFrame:
        """The lifetimes so far, as links.parquet (the links still up end at ``t_end``,
        censored)."""
        rows = list(self.ended)
        still = [(a, b, t_up, t_end) for (a, b), t_up in self.up.items()]
        a = np.array([r[0] for r in rows + still], np.int64)
        b = np.array([r[1] for r in rows + still], np.int64)
        out = pd.DataFrame(
            {
                "a": a,
                "b": b,
                "t_up_s": np.array([r[2] for r in rows + still], float),
                "t_down_s": np.array([r[3] for r in rows + still], float),
            }
        )
        out["censored_start"] = out["t_up_s"].to_numpy() == 0.0
        out["censored_end"] = np.r_[np.zeros(len(rows), bool), np.ones(len(still), bool)]
        out["censored"] = out["censored_start"] | out["censored_end"]
        return out[COLUMNS].sort_values(["t_up_s", "a", "b"], kind="stable").reset_index(drop=True)

    # -- course changes ------------------------------------------------------------------
    def _on_leg(self, i: int, t: float, jump: bool) -> None:
        if not self.started:
            return
        self._dirty.add(i)
        if jump:
            self._jumped.add(i)
        if not self._flush_pending:
            # Solved once the model has set every leg of this instant (a controller sets
            # many in one step), before anything else due now.
            self._flush_pending = True
            scheduled_event(self.env, 0.0, FIRST, self._flush)

    def _flush(self, _event: object = None) -> None:
        self._flush_pending = False
        if not self._dirty:
            return
        t = self.env.now
        dirty = np.fromiter(sorted(self._dirty), np.int64, len(self._dirty))
        jumped = np.fromiter(sorted(self._jumped), np.int64, len(self._jumped))
        self._dirty.clear()
        self._jumped.clear()
        v = self.state.velocity_mps[dirty]
        if len(jumped) or float(np.hypot(v[:, 0], v[:, 1]).max()) > self.v_bound or t >= self._w_end:
            self._new_window(t, jumpers=jumped)
            return
        ptr = self._ptr
        idx = np.unique(np.concatenate([self._idx[ptr[r] : ptr[r + 1]] for r in dirty.tolist()]))
        if len(idx):
            self._gen[idx] += 1
            gen_now = self._gen_now
            for k in idx.tolist():
                gen_now[k] += 1
            self._solve(idx, t)
            self._arm()

    # -- windows -------------------------------------------------------------------------
    def _positions(self, t: float, who: np.ndarray | None = None) -> np.ndarray:
        st = self.state
        if who is None:
            return st.origin_m + st.velocity_mps * (t - st.t0_s)[:, None]
        return st.origin_m[who] + st.velocity_mps[who] * (t - st.t0_s[who])[:, None]

    def _new_window(self, t: float, first: bool = False, jumpers: np.ndarray | None = None) -> None:
        st = self.state
        self.windows += 1
        self._wid += 1
        # Every queued event is solved again from t; the window's events go into one sorted
        # list (walked in order), later re-solves into a small heap beside it.
        self._heap = []
        self._batch = []
        speeds = np.hypot(st.velocity_mps[:, 0], st.velocity_mps[:, 1])
        self.v_bound = max(self.v_bound, float(speeds.max()) if st.n else 0.0)
        if self.v_bound > 0:
            self._w_end = t + max(0.5 * self.r_min / self.v_bound, 1e-6)
            reach = self.r_max + 2.0 * self.v_bound * (self._w_end - t)
        else:
            self._w_end = math.inf  # nobody moves: nothing to solve until someone does
            reach = self.r_max
        pos = self._positions(t)
        pairs = tree(pos, self.box).query_pairs(reach, output_type="ndarray") if st.n > 1 else np.empty((0, 2))
        pairs = pairs.astype(np.int64, copy=False)
        ca, cb = np.minimum(pairs[:, 0], pairs[:, 1]), np.maximum(pairs[:, 0], pairs[:, 1])
        self._ca, self._cb = ca, cb
        self._cr = np.minimum(self.ranges[ca], self.ranges[cb])
        m = len(ca)
        # Each robot's candidate pairs (both ends), as a CSR list.
        rows = np.concatenate([ca, cb])
        order = np.argsort(rows, kind="stable")
        self._idx = np.concatenate([np.arange(m), np.arange(m)])[order]
        self._ptr = np.zeros(st.n + 1, np.int64)
        np.cumsum(np.bincount(rows, minlength=st.n), out=self._ptr[1:])
        self._gen = np.zeros(m, np.int64)
        self._gen_now = [0] * m
        if first:
            d = wrap(pos[ca] - pos[cb], self.box)
            inside = np.einsum("ij,ij->i", d, d) <= self._cr * self._cr
            self._push(np.full(int(inside.sum()), t), ca[inside], cb[inside], 1, PHASE_STATE)
        if jumpers is not None and len(jumpers):
            self._judge_jumpers(t, pos, jumpers)
        if self.v_bound > 0 and m:
            self._solve(np.arange(m), t)
        self._sort_batch()
        if math.isfinite(self._w_end):
            wid = self._wid
            scheduled_event(self.env, self._w_end - t, _RESTART, lambda _e: self._restart(wid))
        self._arm()

    def _restart(self, wid: int) -> None:
        if wid == self._wid:
            self._new_window(self.env.now)

    def _judge_jumpers(self, t: float, pos: np.ndarray, jumpers: np.ndarray) -> None:
        """At a jump, each link of a robot that jumped is up if in range on the new
        positions, down otherwise (its old links and its new candidates)."""
        mine = np.isin(self._ca, jumpers) | np.isin(self._cb, jumpers)
        a, b = self._ca[mine], self._cb[mine]
        who = set(jumpers.tolist())
        old = [(x, y) for (x, y) in self.up if x in who or y in who]
        if old:
            a = np.r_[a, np.array([p[0] for p in old], np.int64)]
            b = np.r_[b, np.array([p[1] for p in old], np.int64)]
        d = wrap(pos[a] - pos[b], self.box)
        radius = np.minimum(self.ranges[a], self.ranges[b])
        inside = np.einsum("ij,ij->i", d, d) <= radius * radius
        self._push(np.full(int(inside.sum()), t), a[inside], b[inside], 1, PHASE_STATE)
        self._push(np.full(int((~inside).sum()), t), a[~inside], b[~inside], -1, PHASE_STATE)

    def _solve(self, idx: np.ndarray, t: float) -> None:
        """Queue the crossings of candidate pairs ``idx`` from ``t`` to the window's end."""
        st = self.state
        a, b = self._ca[idx], self._cb[idx]
        # Solved from the later of the two legs' starts, as the post-hoc solver does
        # (netsim.crossings.solve_piece): the same floats, whatever the windows.
        origin = np.maximum(st.t0_s[a], st.t0_s[b])
        pa = st.origin_m[a] + st.velocity_mps[a] * (origin - st.t0_s[a])[:, None]
        pb = st.origin_m[b] + st.velocity_mps[b] * (origin - st.t0_s[b])[:, None]
        d0 = wrap(pa - pb, self.box)
        w = st.velocity_mps[a] - st.velocity_mps[b]
        found: list[tuple] = []

        def emit(t_ev: Any, ia: Any, _ib: Any, kind: int, phase: Any) -> None:
            if len(ia):
                found.append((np.asarray(t_ev, float), np.asarray(ia, np.int64), kind, np.asarray(phase)))

        solve_piece(d0, w, self._cr[idx], origin, t, self._w_end - t, idx, idx, emit, self.box)
        for t_ev, ia, kind, phase in found:
            self._push(t_ev, self._ca[ia], self._cb[ia], kind, phase, ia)

    # -- the queue -----------------------------------------------------------------------
    # An event is the tuple (t, a, b, phase, -kind, idx, gen): tuples sort in the order the
    # events run (module notes); idx is the candidate pair (-1: a state set at a jump or at
    # the start, never cancelled), gen its generation when solved.
    def _push(self, t: Any, a: Any, b: Any, kind: int, phase: Any, idx: np.ndarray | None = None) -> None:
        n = len(a)
        if n == 0:
            return
        cols = (
            np.broadcast_to(np.asarray(t, float), (n,)),
            np.asarray(a, np.int64),
            np.asarray(b, np.int64),
            np.broadcast_to(np.asarray(phase, np.int64), (n,)),
            np.full(n, -kind, np.int64),
            np.full(n, -1, np.int64) if idx is None else idx,
            np.zeros(n, np.int64) if idx is None else self._gen[idx],
        )
        if self._batch is not None:
            self._batch.append(cols)
            return
        heap = self._heap
        for row in zip(*(c.tolist() for c in cols)):
            heapq.heappush(heap, row)

    def _sort_batch(self) -> None:
        batch, self._batch = self._batch, None
        if batch:
            cols = [np.concatenate(c) for c in zip(*batch)]
            order = np.lexsort((cols[4], cols[3], cols[2], cols[1], cols[0]))
            self._queue = list(zip(*(c[order].tolist() for c in cols)))
        else:
            self._queue = []
        self._qi = 0

    def _next_time(self) -> float:
        t = self._queue[self._qi][0] if self._qi < len(self._queue) else math.inf
        return min(t, self._heap[0][0]) if self._heap else t

    def _arm(self) -> None:
        t = self._next_time()
        if t < self._armed_s:
            self._armed_s = t
            scheduled_event(self.env, max(t - self.env.now, 0.0), FIRST, lambda _e: self._wake(t))

    def _take(self, until: float) -> Iterator[tuple]:
        """The queued events due at or before ``until``, in order (both sources merged)."""
        queue, heap = self._queue, self._heap
        qi, nq = self._qi, len(queue)
        pop = heapq.heappop
        while True:
            if heap and (qi >= nq or heap[0] < queue[qi]):
                if heap[0][0] > until:
                    break
                row = pop(heap)
            elif qi < nq:
                row = queue[qi]
                if row[0] > until:
                    break
                qi += 1
                self._qi = qi
            else:
                break
            yield row

    def _wake(self, armed_s: float) -> None:
        # ``armed_s`` is the instant this wake was armed for. The kernel's clock, now + (t -
        # now), can be a rounding step away from it (no delay lands on some instants), so
        # the events are taken by their own time, never by the clock's.
        if armed_s >= self._armed_s:
            self._armed_s = math.inf
        env = self.env
        until = armed_s
        while True:
            self._announce(until)
            # The next instant is taken in the same wake when the kernel has nothing that
            # would run before a wake armed for it: the clock is moved there, exactly, and
            # the order is that of one kernel event per instant, without its cost.
            until = self._next_time()
            if until == math.inf or runs_before(env, until, FIRST):
                break
            advance_clock(env, until)
        self._arm()

    def _announce(self, until: float) -> None:
        """Apply and announce the queued events due at or before ``until``, in order."""
        queue, heap = self._queue, self._heap
        qi, nq = self._qi, len(queue)
        gen, up, ended = self._gen_now, self.up, self.ended
        on_up, on_down = self._on_up, self._on_down
        pop = heapq.heappop
        new = tuple.__new__
        # The hot loop of the runtime links: the window's sorted list and the heap of
        # re-solves merged, inline (no generator, no call per event but the subscribers').
        while True:
            if heap and (qi >= nq or heap[0] < queue[qi]):
                if heap[0][0] > until:
                    break
                t, a, b, _phase, negk, idx, g = pop(heap)
            elif qi < nq:
                row = queue[qi]
                if row[0] > until:
                    break
                qi += 1
                t, a, b, _phase, negk, idx, g = row
            else:
                break
            if idx >= 0 and gen[idx] != g:
                continue  # solved again since (a course change)
            key = (a, b)
            if negk < 0:
                if key in up:
                    continue
                up[key] = t
                if on_up:
                    up_event = new(LinkUp, (t, a, b))
                    for fn in on_up:
                        fn(up_event)
            else:
                t_up = up.pop(key, None)
                if t_up is None:
                    continue
                ended.append((a, b, t_up, t))
                if on_down:
                    down_event = new(LinkDown, (t, a, b, t_up))
                    for fn in on_down:
                        fn(down_event)
        self._qi = qi
