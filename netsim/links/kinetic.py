"""Link up/down events solved during the run, at their exact instants (a kinetic scheduler).

The same geometry as the post-hoc solver (:mod:`netsim.links.lifetimes`, which stays the
reference): two robots on straight legs are linked while ``|d + w t| <= min(r_a, r_b)``,
and the link's next up and down instants are roots of a quadratic. What changes is when
they are solved: as the run goes, so that ``link_up`` and ``link_down`` are announced on the
run's event bus at the instant they happen: the live feed of the links whose table,
``links.parquet``, the post-hoc solver writes (the feed's events are its rows, bit for bit).

The run is cut into windows no longer than half the smallest range over the highest speed
at the window's start (``v_bound``); at a window's start the candidate pairs are those within
``R_max + 2 v_bound W`` (:func:`netsim.geometry.near_pairs`; no other pair can meet during the window), and
every candidate's crossings within the window are solved in one vectorised step and queued.
When a robot changes course, only its candidate pairs are solved again from that instant
to the window's end; their earlier solutions are cancelled (a generation count per pair).
A new window starts early when a robot jumps (its links are then judged afresh on its new
position, as the post-hoc solver does) or moves faster than ``v_bound``. So only pairs that
can meet before the end of the window or their next course change are ever scheduled.
In the plane a pair's crossing instants depend on its two legs alone (they are solved from
the later leg start), so a candidate pair whose robots keep their legs into the next
window keeps the instants already solved, and each window solves only the pairs that are
new to it or changed course.

Queued events run at priority :data:`~netsim.scheduling.FIRST` (before anything else due at
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
from collections.abc import Mapping
from typing import Any, cast

import numpy as np
import simpy

from netsim.compiled import load
from netsim.events import EventBus, LinkDown, LinkUp, notify
from netsim.geometry import link_ranges_m, near_pairs, row_starts
from netsim.links._kernels import PHASE_START, PHASE_STATE
from netsim.scheduling import FIRST, LAST, advance_clock, kernel_queue, scheduled_event
from netsim.state import RobotState

# A window's restart comes before the link events of its instant, which it solves again.
_RESTART = FIRST - 1


def up_pairs(up: Mapping[int, object], n: int) -> tuple[np.ndarray, np.ndarray]:
    """The links of a solver's ``up`` record (pair key ``a n + b``): arrays ``(a, b)``, ``a < b``,
    in key order."""
    keys = np.sort(np.fromiter(up.keys(), np.int64, len(up)))
    return keys // n, keys % n


class RuntimeLinks:
    """Exact link events of one run, solved while it goes (module notes).

    Parameters
    ----------
    env, state : the run's kernel and robots (told of every course change).
    events : the run's bus: ``link_up`` and ``link_down`` are emitted on it.
    range_m : each robot's range (default: the robots' ``range_m``).
    """

    def __init__(
        self,
        env: simpy.Environment,
        state: RobotState,
        events: EventBus | None = None,
        range_m: np.ndarray | None = None,
    ):
        self.env, self.state, self.events = env, state, events
        self.ranges = state.range_m if range_m is None else np.asarray(range_m, float)
        self.r_min = float(self.ranges.min()) if state.n else 0.0
        self.r_max = float(self.ranges.max()) if state.n else 0.0
        self.box = state.torus_side_m
        # Links up now: key a n + b -> since when.
        self.up: dict[int, float] = {}
        self.started = False
        self.v_bound = 0.0
        self.windows = 0
        self._heap: list[tuple] = []
        self._queue: tuple[list, ...] = ([], [], [], [], [], [], [])
        self._qi = 0
        self._batch: list | None = None
        self._armed_s = math.inf
        self._dirty: set[int] = set()
        self._jumped: set[int] = set()
        self._flush_pending = False
        self._w_end = 0.0
        self._wid = 0
        self._ca = self._cb = self._ptr_a = self._ptr_b = self._by_b = np.empty(0, np.int64)
        self._csr_ready = False
        self._cr = np.empty(0)
        # In the plane, each candidate pair's crossings on its current legs (absolute
        # instants, NaN: none), by pair key ``a n + b`` (sorted): a pair whose robots keep
        # their legs into the next window is not solved again.
        self._keys = np.empty(0, np.int64)
        self._at_in = self._at_out = np.empty(0)
        self._gen = np.empty(0, np.int64)
        # The generations again, as a list: read one at a time by the hot loop.
        self._gen_now: list[int] = []
        # Called with each LinkUp / LinkDown: the bus's subscribers, or (no bus) whoever
        # appends to these lists.
        self.on_up: list = events.subscribers("link_up") if events is not None else []
        self.on_down: list = events.subscribers("link_down") if events is not None else []
        self._kernel = kernel_queue(env)  # the same list for the whole run (read only)
        self._n = max(state.n, 1)
        self._solver = load("netsim.links._kernels", state.n)
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
        self._announce(t_end, quiet=True)

    def up_pairs(self) -> tuple[np.ndarray, np.ndarray]:
        """The links up now: arrays ``(a, b)``, ``a < b``."""
        return up_pairs(self.up, self._n)

    @property
    def now_s(self) -> float:
        """The instant the links of :meth:`up_pairs` are up at: the run's present."""
        return float(self.env.now)

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
        if len(jumped) or float(self.state.speed_mps[dirty].max()) > self.v_bound or t >= self._w_end:
            self._new_window(t, jumpers=jumped, moved=dirty)
            return
        if not self._csr_ready:
            self._csr()
        pa, pb, by_b = self._ptr_a, self._ptr_b, self._by_b
        idx = np.unique(np.concatenate([np.r_[pa[r] : pa[r + 1], by_b[pb[r] : pb[r + 1]]] for r in dirty.tolist()]))
        if len(idx):
            self._gen[idx] += 1
            gen_now = self._gen_now
            for k in idx.tolist():
                gen_now[k] += 1
            self._solve(idx, t)
            self._arm()

    # -- windows -------------------------------------------------------------------------
    def _new_window(
        self, t: float, first: bool = False, jumpers: np.ndarray | None = None, moved: np.ndarray | None = None
    ) -> None:
        """Start a window at ``t``: find its candidate pairs and queue their crossings;
        ``moved``: robots whose legs changed at ``t`` (their pairs are solved afresh)."""
        st = self.state
        n = st.n
        self.windows += 1
        self._wid += 1
        # Every queued event is solved again from t; the window's events go into one sorted
        # list (walked in order), later re-solves into a small heap beside it.
        self._heap = []
        self._batch = []
        # The fastest robot now: one that speeds up past it starts a new window (_flush), so
        # no robot goes faster within this one. (The fastest ever seen would let one fast
        # moment, a drive at any speed, cut the rest of the run into microseconds.)
        self.v_bound = float(st.speed_mps.max()) if n else 0.0
        if self.v_bound > 0:
            self._w_end = t + max(0.5 * self.r_min / self.v_bound, 1e-6)
            reach = self.r_max + 2.0 * self.v_bound * (self._w_end - t)
        else:
            self._w_end = math.inf  # nobody moves: nothing to solve until someone does
            reach = self.r_max
        pos = st.positions_at(t, fold=False)
        pairs = near_pairs(pos, reach, self.box)
        # Candidate pairs in key order (a n + b, a < b), hence in the order (a, b).
        keys = np.sort(np.minimum(pairs[:, 0], pairs[:, 1]) * n + np.maximum(pairs[:, 0], pairs[:, 1]))
        ca, cb = np.divmod(keys, n) if n else (keys, keys)
        self._ca, self._cb = ca, cb
        self._cr = link_ranges_m(self.ranges, ca, cb)
        m = len(ca)
        self._csr_ready = False
        self._gen = np.zeros(m, np.int64)
        self._gen_now = [0] * m
        if first:
            inside = self._solver.in_range(pos, ca, cb, self._cr, self.box or 0.0)
            self._push(np.full(int(inside.sum()), t), ca[inside], cb[inside], 1, PHASE_STATE)
        if jumpers is not None and len(jumpers):
            self._judge_jumpers(t, pos, jumpers)
        if self.v_bound > 0 and m:
            if self.box is None:
                self._solve_window(t, keys, moved)
            else:
                self._solve(np.arange(m), t)
        else:
            # Nothing solved: no pair's crossings are known for the next window. A pair at
            # rest whose legs begin now comes up now if in range, as its crossings would have
            # it (netsim.links._kernels: a robot stopped exactly at the range).
            self._keys = np.empty(0, np.int64)
            self._at_in, self._at_out = np.full(m, np.nan), np.full(m, np.nan)
            if moved is not None and len(moved) and m:
                began = np.zeros(n, bool)
                began[moved] = True
                mine = began[ca] | began[cb]
                a, b = ca[mine], cb[mine]
                inside = self._solver.in_range(pos, a, b, self._cr[mine], self.box or 0.0)
                self._push(np.full(int(inside.sum()), t), a[inside], b[inside], 1, PHASE_START)
        self._sort_batch()
        if math.isfinite(self._w_end):
            wid = self._wid
            scheduled_event(self.env, self._w_end - t, _RESTART, lambda _e: self._restart(wid))
        self._arm()

    def _solve_window(self, t: float, keys: np.ndarray, moved: np.ndarray | None) -> None:
        """In the plane: queue the window's crossings of every candidate pair, solving only
        the pairs whose crossings on their current legs are not known yet."""
        m = len(keys)
        old = self._keys
        known = np.zeros(m, bool)
        at = np.zeros(m, np.int64)
        if len(old):
            at = np.minimum(np.searchsorted(old, keys), len(old) - 1)
            known = old[at] == keys
            if moved is not None and len(moved):
                stale = np.zeros(self.state.n, bool)
                stale[moved] = True
                known &= ~(stale[self._ca] | stale[self._cb])
        at_in, at_out = np.empty(m), np.empty(m)
        at_in[known] = self._at_in[at[known]]
        at_out[known] = self._at_out[at[known]]
        fresh = np.flatnonzero(~known)
        at_in[fresh], at_out[fresh] = self._crossings(fresh)
        self._keys, self._at_in, self._at_out = keys, at_in, at_out
        self._queue_crossings(np.arange(m), t)

    def _csr(self) -> None:
        """Each robot's candidate pairs, by either end (built when a course change first
        needs them in a window): pairs are in key order, so those with ``a = r`` are the
        range ``ptr_a[r] : ptr_a[r + 1]``; those with ``b = r`` are listed by ``by_b``."""
        n, ca, cb = self.state.n, self._ca, self._cb
        self._ptr_a = row_starts(ca, n)
        # Any order within a robot will do; numpy sorts 16-bit integers by radix.
        self._by_b = np.argsort(cb.astype(np.uint16) if n <= 1 << 16 else cb, kind="stable")
        self._ptr_b = np.zeros(n + 1, np.int64)
        np.cumsum(np.bincount(cb, minlength=n), out=self._ptr_b[1:])
        self._csr_ready = True

    def _restart(self, wid: int) -> None:
        if wid == self._wid:
            self._new_window(self.env.now)

    def _judge_jumpers(self, t: float, pos: np.ndarray, jumpers: np.ndarray) -> None:
        """At a jump, each link of a robot that jumped is up if in range on the new
        positions, down otherwise (its old links and its new candidates)."""
        mine = np.isin(self._ca, jumpers) | np.isin(self._cb, jumpers)
        a, b = self._ca[mine], self._cb[mine]
        up = np.fromiter(self.up.keys(), np.int64, len(self.up))
        n = self.state.n
        old = up[np.isin(up // n, jumpers) | np.isin(up % n, jumpers)]
        if len(old):
            a = np.r_[a, old // n]
            b = np.r_[b, old % n]
        inside = self._solver.in_range(pos, a, b, link_ranges_m(self.ranges, a, b), self.box or 0.0)
        self._push(np.full(int(inside.sum()), t), a[inside], b[inside], 1, PHASE_STATE)
        self._push(np.full(int((~inside).sum()), t), a[~inside], b[~inside], -1, PHASE_STATE)

    def _solve(self, idx: np.ndarray, t: float) -> None:
        """Queue the crossings of candidate pairs ``idx`` from ``t`` to the window's end."""
        if self.box is None:
            self._at_in[idx], self._at_out[idx] = self._crossings(idx)
            self._queue_crossings(idx, t)
            return
        st, k = self.state, len(idx)
        found = self._solver.crossings(
            st.t0_s,
            st.origin_m,
            st.velocity_mps,
            self._ca[idx],
            self._cb[idx],
            self._cr[idx],
            np.full(k, float(t)),
            np.full(k, self._w_end - t),
            self.box,
        )
        self._push_found(idx, *found)

    def _crossings(self, idx: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """In the plane: the instants candidate pairs ``idx`` enter and leave range on
        their current legs (NaN: never), solved from the later of their two legs' starts
        as the post-hoc solver solves them: the same floats, whatever the windows."""
        st = self.state
        return self._solver.crossing_times(
            st.t0_s, st.origin_m, st.velocity_mps, self._ca[idx], self._cb[idx], self._cr[idx]
        )

    def _queue_crossings(self, idx: np.ndarray, t: float) -> None:
        """Queue the known crossings of pairs ``idx`` that fall from ``t`` to the window's
        end, as :func:`netsim.links._kernels.crossings` would find them."""
        k = len(idx)
        if k == 0:
            return
        found = self._solver.clip_crossings(
            self._at_in[idx], self._at_out[idx], np.full(k, float(t)), np.full(k, self._w_end - t)
        )
        self._push_found(idx, *found)

    def _push_found(
        self, idx: np.ndarray, pair: np.ndarray, t: np.ndarray, phase: np.ndarray, kind: np.ndarray
    ) -> None:
        """Queue crossings found for candidate pairs ``idx`` (``pair`` indexes ``idx``): the
        entries, then the exits, as the kernels list them."""
        ia = idx[pair]
        up = kind > 0
        self._push(t[up], self._ca[ia[up]], self._cb[ia[up]], 1, phase[up], ia[up])
        self._push(t[~up], self._ca[ia[~up]], self._cb[ia[~up]], -1, phase[~up], ia[~up])

    # -- the queue -----------------------------------------------------------------------
    # An event is (t, a, b, phase, -kind, idx, gen): in that order events run (module
    # notes); idx is the candidate pair (-1: a state set at a jump or at the start, never
    # cancelled), gen its generation when solved. A window's events are sorted columns
    # (plain lists; their gen is 0), later re-solves tuples in a heap beside them.
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
        )
        if self._batch is not None:
            self._batch.append(cols)
            return
        heap = self._heap
        gen = np.zeros(n, np.int64) if idx is None else self._gen[idx]
        for row in zip(*(c.tolist() for c in cols), gen.tolist()):
            heapq.heappush(heap, row)

    def _sort_batch(self) -> None:
        batch, self._batch = self._batch, None
        if batch:
            cols = [np.concatenate(c) for c in zip(*batch)]
            t, a, b, phase, negk = cols[:5]
            key = a * self._n + b
            # (t, a, b, phase, -kind) as two sort keys: (a, b, phase, -kind) packed in one.
            order = np.lexsort(((key * 3 + phase) * 2 + (negk > 0), t))
            self._queue = tuple(c[order].tolist() for c in (t, a, b, phase, negk, cols[5], key))
        else:
            self._queue = ([], [], [], [], [], [], [])
        self._qi = 0

    def _arm(self) -> None:
        # Once per wake, and more often than not per instant when other events interleave:
        # the next time inline, and the instant armed for as the kernel event's value.
        qt, qi, heap = self._queue[0], self._qi, self._heap
        t = qt[qi] if qi < len(qt) else math.inf
        if heap and heap[0][0] < t:
            t = heap[0][0]
        if t < self._armed_s:
            self._armed_s = t
            scheduled_event(self.env, max(t - self.env.now, 0.0), FIRST, self._wake, value=t)

    def _wake(self, event: simpy.Event) -> None:
        # The instant this wake was armed for. The kernel's clock, now + (t - now), can be a
        # rounding step away from it (no delay lands on some instants), so the events are
        # taken by their own time, never by the clock's.
        armed_s = cast(float, event.value)
        if armed_s >= self._armed_s:
            self._armed_s = math.inf
        self._announce(armed_s)
        self._arm()

    def _announce(self, until: float, quiet: bool = False) -> None:
        """Apply and announce the queued events due at or before ``until``, in order, and
        those of the following instants while the kernel has nothing that would run before
        a wake armed for them (:func:`~netsim.scheduling.kernel_queue`): the clock is moved to
        each, exactly, and the order is that of one kernel event per instant, without its
        cost. ``quiet``: the run's end; apply up to ``until`` only, announcing nothing."""
        qt, qa, qb, qphase, qnegk, qidx, qkey = self._queue
        heap = self._heap
        qi, nq = self._qi, len(qt)
        gen, up = self._gen_now, self.up
        on_up: list = [] if quiet else self.on_up
        on_down: list = [] if quiet else self.on_down
        env, kernel, n = self.env, self._kernel, self._n
        pop = heapq.heappop
        new = tuple.__new__
        # The hot loop of the runtime links: the window's sorted columns and the heap of
        # re-solves merged, inline (no call per event but the subscribers').
        while True:
            if heap and (
                qi >= nq
                or heap[0][0] < qt[qi]
                or (heap[0][0] == qt[qi] and heap[0] < (qt[qi], qa[qi], qb[qi], qphase[qi], qnegk[qi], qidx[qi], 0))
            ):
                t = heap[0][0]
                from_heap = True
            elif qi < nq:
                t = qt[qi]
                from_heap = False
            else:
                break
            if t > until:
                # The next instant, in this wake if nothing in the kernel runs before it.
                if quiet or (kernel and (kernel[0][0] < t or (kernel[0][0] == t and kernel[0][1] <= FIRST))):
                    break
                advance_clock(env, t)
                until = t
            if from_heap:
                t, a, b, _phase, negk, idx, g = pop(heap)
                if idx >= 0 and gen[idx] != g:
                    continue  # solved again since (a course change)
                key = a * n + b
            else:
                idx = qidx[qi]
                if idx >= 0 and gen[idx] != 0:
                    qi += 1
                    continue
                a, b, negk, key = qa[qi], qb[qi], qnegk[qi], qkey[qi]
                qi += 1
            if negk < 0:
                if key in up:
                    continue
                up[key] = t
                if on_up:
                    up_event = new(LinkUp, (t, a, b))
                    notify(on_up, up_event)
            else:
                t_up = up.pop(key, None)
                if t_up is None:
                    continue
                if on_down:
                    down_event = new(LinkDown, (t, a, b, t_up))
                    notify(on_down, down_event)
        self._qi = qi
