"""Deadline timers with O(1) restart, for many robots at once.

SimPy timeouts cannot be cancelled. A timer here is a deadline in an array; restarting
it writes the array (vectorised over any set of robots) and schedules nothing, unless
the new deadline is earlier than the pending event. When the pending event fires it
compares with the current deadline: if the deadline moved later, it re-arms itself there;
if it was cancelled, it does nothing; otherwise the timer expires. So a timer restarted on
every Ack costs one array write per Ack and at most one event per ``tau`` (a kernel event
without an agenda; an entry of the agenda's calendar with one, below).

Timer events run at NORMAL priority; message deliveries run at URGENT priority, so an
Ack that arrives at the same instant as a deadline is processed first and counts.

Given an :class:`netsim.agenda.Agenda` (the channel's), a timer's events are not kernel
events but entries of its calendar (:meth:`netsim.agenda.Agenda.ahead`): armed a few
seconds ahead and taken a few thousand a second, each runs exactly where its kernel event
would have run (the same instants, in the same order, ties included).
"""

from __future__ import annotations

import math
from collections.abc import Callable
from functools import partial

import numpy as np
import simpy

from netsim.agenda import Agenda
from netsim.compiled import filled, load
from netsim.scheduling import NORMAL, scheduled_event
from netsim.simpy_internals import now as clock


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
        # An agenda with a calendar takes the events there (module notes); another (the
        # tests' reference, a kernel event per entry) one entry each.
        self._ahead = getattr(agenda, "ahead", None)
        self._kernels = load("netsim._kernels", n)

    def restart(self, idx: int | np.ndarray, deadline_s: float | np.ndarray) -> None:
        """Set the deadline of timers ``idx`` (an int or an array) to ``deadline_s`` (one
        for all, or one each), arming an event where it comes first
        (:func:`netsim._kernels.restarted`)."""
        if isinstance(idx, int | np.integer) and isinstance(deadline_s, float | int):
            # One timer (the common case, a role's change): no arrays.
            d = float(deadline_s)
            if self._kernels.restarted(self.deadline_s, self.armed_s, int(idx), d):
                self._arm(int(idx), d)
            return
        ids = np.atleast_1d(np.asarray(idx, dtype=np.int64))
        at = filled(deadline_s, ids.shape)
        to_arm = np.empty(len(ids), dtype=np.int64)
        m = self._kernels.restarts(self.deadline_s, self.armed_s, ids, at, to_arm)
        for k in to_arm[:m].tolist():
            self._arm(int(ids[k]), float(at[k]))

    def arm(self, idx: np.ndarray) -> None:
        """Schedule the events of timers ``idx`` whose deadlines were set elsewhere (a
        compiled loop) and fall before their armed events: the second half of
        :meth:`restart`."""
        for i, d in zip(idx.tolist(), self.deadline_s[idx].tolist()):
            self._arm(i, d)

    def cancel(self, idx: int | np.ndarray) -> None:
        self.deadline_s[idx] = np.inf

    def _arm(self, i: int, at_s: float) -> None:
        gen = self._generation[i] + 1
        self._generation[i] = gen
        self.armed_s[i] = at_s
        delay = at_s - clock(self.env)
        if not delay > 0.0:
            delay = 0.0  # as max(0.0, delay)
        if self._ahead is not None:
            self._ahead(delay, NORMAL, self._fire_bound, i, gen)
        elif self.agenda is not None:
            self.agenda.at(delay, NORMAL, self._fire_bound, i, gen)
        else:
            scheduled_event(self.env, delay, NORMAL, partial(self._fire_bound, i, gen))

    def _fire(self, i: int, gen: int, _event: object = None) -> None:
        if gen != self._generation[i]:
            return
        deadline = self.deadline_s.item(i)
        now = clock(self.env)
        if deadline <= now:
            self.armed_s[i] = math.inf
            self.deadline_s[i] = math.inf
            self.on_expire(i, now)
        elif deadline != math.inf:
            self._arm(i, deadline)  # moved later: armed there (its armed_s written there)
        else:
            self.armed_s[i] = math.inf
