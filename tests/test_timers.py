"""Deadline timers: exact expiry, O(1) restart, and the tie rule."""

import math

import numpy as np
import pytest
import simpy

from netsim.scheduling import URGENT, scheduled_event
from netsim.simpy_internals import kernel_queue
from netsim.timers import DeadlineTimers


def test_timer_expires_exactly_at_its_deadline():
    env = simpy.Environment()
    fired = []
    timers = DeadlineTimers(env, 2, lambda i, now: fired.append((i, now)))
    timers.restart(0, 3.25)
    env.run(until=10)
    assert fired == [(0, 3.25)]


def test_restart_moves_the_deadline_and_costs_no_kernel_event():
    env = simpy.Environment()
    fired = []
    timers = DeadlineTimers(env, 1, lambda i, now: fired.append(now))
    timers.restart(0, 3.0)
    for k in range(1000):
        timers.restart(0, 3.0 + k * 0.001)
    assert len(kernel_queue(env)) == 1  # still the one event armed at 3.0
    env.run(until=10)
    assert fired == [3.999]


def test_restart_to_an_earlier_deadline_fires_early_and_once():
    env = simpy.Environment()
    fired = []
    timers = DeadlineTimers(env, 1, lambda i, now: fired.append(now))
    timers.restart(0, 5.0)
    timers.restart(0, 2.0)
    env.run(until=10)
    assert fired == [2.0]


def test_cancelled_timer_does_not_fire():
    env = simpy.Environment()
    fired = []
    timers = DeadlineTimers(env, 1, lambda i, now: fired.append(now))
    timers.restart(0, 1.0)
    timers.cancel(0)
    env.run(until=10)
    assert fired == []


def test_vectorised_restart_of_many_timers():
    env = simpy.Environment()
    fired = []
    timers = DeadlineTimers(env, 100, lambda i, now: fired.append((i, now)))
    timers.restart(np.arange(100), np.arange(100) * 0.5 + 1.0)
    env.run(until=100)
    assert fired == [(i, i * 0.5 + 1.0) for i in range(100)]


def test_message_at_the_deadline_instant_counts():
    """docs/model.md 4.2: an Ack that arrives at the same instant as a deadline is processed
    first, even when it was scheduled after the timer's event."""
    env = simpy.Environment()
    fired = []
    timers = DeadlineTimers(env, 1, lambda i, now: fired.append(now))
    timers.restart(0, 3.0)
    scheduled_event(env, 3.0, URGENT, lambda _e: timers.restart(0, env.now + 3.0))
    env.run(until=10)
    assert fired == [6.0]


def test_one_deadline_for_many_timers_is_the_same_as_one_each():
    """Restarting a set of timers to one shared deadline (int or array ids, earlier or later
    than what is armed) fires as giving each its own copy of that deadline."""
    runs = []
    for shared in (True, False):
        env = simpy.Environment()
        fired = []
        timers = DeadlineTimers(env, 6, lambda i, now, fired=fired: fired.append((i, now)))
        timers.restart(np.arange(6), 4.0 if shared else np.full(6, 4.0))
        ids = np.array([1, 3, 5])
        timers.restart(ids, 2.0 if shared else np.full(3, 2.0))
        timers.restart(2, 6.5 if shared else np.array([6.5]))
        timers.restart(np.int64(4), 1.0)
        env.run(until=10)
        runs.append(fired)
    assert runs[0] == runs[1] == [(4, 1.0), (1, 2.0), (3, 2.0), (5, 2.0), (0, 4.0), (2, 6.5)]


def _timer_script(on_agenda: bool) -> list:
    """Restarts, a cancel and kernel events around the deadlines; what happened, in order."""
    from netsim.agenda import Agenda

    env = simpy.Environment()
    log: list = []
    timers = DeadlineTimers(env, 5, lambda i, now: log.append(("expire", i, now)), Agenda(env) if on_agenda else None)

    def at(delay, name):
        env.timeout(delay).callbacks.append(lambda _e: log.append((name, env.now)))

    at(2.0, "before")
    timers.restart(np.arange(5), 2.0)
    at(2.0, "after")
    timers.restart(np.array([1, 3]), 3.0)  # later: re-armed at 2.0
    timers.restart(4, 1.0)  # earlier: a new event
    timers.cancel(0)
    at(3.0, "between")
    env.timeout(1.5).callbacks.append(lambda _e: timers.restart(2, 3.0))
    env.run(until=10)
    return log


def test_timers_on_an_agenda_fire_as_kernel_events():
    """Timers whose events sit on an agenda fire at the same instants, in the same order
    against kernel events of the same instant and priority (scheduled before and after
    them), as timers with a kernel event each."""
    kernel, agenda = _timer_script(False), _timer_script(True)
    assert kernel == agenda
    assert [e[0] for e in kernel].count("expire") == 4


def test_calendar_takes_entries_too_late_for_a_slice_number_after_every_other():
    """A time whose slice number overflows (a timer of protocol.tau_s = 1e308, or infinite)
    goes after every finite slice, and such entries among themselves in time order; it
    raised OverflowError."""
    from netsim.agenda import Calendar

    entries = [(1e308, 0, 1), (2.0, 0, 2), (math.inf, 0, 3), (1.7e308, 0, 4), (1e306, 0, 5), (0.01, 0, 6)]
    calendar = Calendar(0.05)
    for e in entries:
        calendar.push(e)
    assert [calendar.pop() for _ in entries] == sorted(entries)
    assert calendar.first() is None


def test_calendar_takes_entries_in_the_order_of_a_heap():
    """The timers' calendar gives its entries in the order heapq gives them, pushes and
    takes interleaved: ties of time (broken by the next items), entries for the slice being
    taken, for earlier slices, far ahead, and after it ran empty."""
    import heapq

    from netsim.agenda import Calendar

    rng = np.random.default_rng(3)
    for slice_s in (0.05, 1.0):
        calendar, heap, taken, expected = Calendar(slice_s), [], [], []
        now, ids = 0.0, 0
        for _ in range(3000):
            if rng.random() < 0.55 or not heap:
                ids += 1
                t = now + float(rng.choice([0.0, 0.01, 0.02, 0.5, 3.0, rng.uniform(0, 4)]))
                entry = (t, int(rng.integers(0, 2)), ids)
                calendar.push(entry)
                heapq.heappush(heap, entry)
            else:
                assert calendar.first() == heap[0]
                taken.append(calendar.pop())
                expected.append(heapq.heappop(heap))
                now = taken[-1][0]
        while heap:
            taken.append(calendar.pop())
            expected.append(heapq.heappop(heap))
        assert taken == expected and calendar.first() is None
        assert len({e[0] for e in taken}) < len(taken) - 100  # ties happened


def test_a_restart_of_one_timer_twice_in_one_call_keeps_the_last_deadline():
    """Restarting timers by arrays with a deadline each, one timer named twice: its last
    deadline holds, and it runs out there, whether that comes before or after the other."""
    for deadlines, expected in (([5.0, 2.0, 3.0], [(0, 2.0), (1, 3.0)]), ([2.0, 5.0, 3.0], [(1, 3.0), (0, 5.0)])):
        env = simpy.Environment()
        fired = []
        timers = DeadlineTimers(env, 2, lambda i, now, fired=fired: fired.append((i, now)))
        timers.restart(np.array([0, 0, 1]), np.array(deadlines))
        env.run(until=10)
        assert fired == expected


@pytest.mark.parametrize("on_agenda", [False, True])
def test_a_deadline_already_past_expires_at_once_at_the_present(on_agenda):
    """A timer restarted to a deadline already gone runs out at once: at the instant of the
    restart, the clock never set back to the deadline."""
    from netsim.agenda import Agenda

    env = simpy.Environment()
    fired = []
    timers = DeadlineTimers(env, 1, lambda i, now: fired.append((i, now, env.now)), Agenda(env) if on_agenda else None)
    env.timeout(5.0).callbacks.append(lambda _e: timers.restart(0, 3.0))
    env.run(until=10)
    assert fired == [(0, 5.0, 5.0)]


@pytest.mark.parametrize("on_agenda", [False, True])
def test_an_event_a_restart_superseded_never_runs_its_timer_out(on_agenda):
    """Timer 0 is armed at 5 s, restarted to 1 s (armed again) and runs out there, then is
    restarted to 5 s at 2 s; timer 1 was armed at 5 s in between. At 5 s timer 0's first
    event, superseded, does nothing: timer 1 runs out first, then timer 0 by the event of
    its last restart, as one kernel event per restart would order them."""
    from netsim.agenda import Agenda

    env = simpy.Environment()
    fired = []
    timers = DeadlineTimers(env, 2, lambda i, now: fired.append((i, now)), Agenda(env) if on_agenda else None)
    timers.restart(0, 5.0)
    timers.restart(0, 1.0)
    timers.restart(1, 5.0)
    env.timeout(2.0).callbacks.append(lambda _e: timers.restart(0, 5.0))
    env.run(until=10)
    assert fired == [(0, 1.0), (1, 5.0), (0, 5.0)]


def test_the_calendar_takes_an_entry_earlier_than_those_it_took_next():
    """An entry pushed for a slice before the one being taken, after some of that one were
    taken, comes next, then the rest of that slice, never again the entries already taken
    (the order of a heap, whatever is pushed)."""
    from netsim.agenda import Calendar

    calendar = Calendar(0.05)
    calendar.push((1.0, 0, 1))
    calendar.push((1.01, 0, 2))
    assert calendar.pop() == (1.0, 0, 1)
    calendar.push((0.5, 0, 3))
    assert [calendar.pop(), calendar.pop()] == [(0.5, 0, 3), (1.01, 0, 2)]
    assert calendar.first() is None and len(calendar) == 0


def test_timers_whose_deadlines_a_compiled_loop_wrote_run_out_once_armed():
    """Deadlines written into ``deadline_s`` elsewhere (the clustering's compiled loop
    renews members' timers there) run out at those instants once ``arm`` schedules them."""
    env = simpy.Environment()
    fired = []
    timers = DeadlineTimers(env, 3, lambda i, now: fired.append((i, now)))
    timers.deadline_s[[0, 2]] = [2.0, 1.0]
    timers.arm(np.array([0, 2]))
    env.run(until=10)
    assert fired == [(2, 1.0), (0, 2.0)]
