"""The agenda (netsim/agenda.py): callbacks run in exactly the order, and at exactly the
instants, that one kernel event each would give them, ties included."""

from __future__ import annotations

import numpy as np
import pandas as pd
import pytest
import simpy
from netsim.protocols.ack import AckBeacon, AckParams

import netsim.radio.channel
from netsim.agenda import Agenda
from netsim.run import build, collect
from netsim.scheduling import FIRST, LAST, NORMAL, URGENT, scheduled_event
from tests.fixtures import clustering, make_config, static_core


class KernelAgenda:
    """The reference the agenda must equal: one kernel event per entry."""

    def __init__(self, env: simpy.Environment):
        self.env = env

    def at(self, delay_s, priority, fn, *args):
        scheduled_event(self.env, delay_s, priority, lambda _event: fn(*args))

    at_in_order = at
    ahead = at


def _scripted(agenda_class, seed: int, stops=(0.5, 1.0, 1.0 + 1e-9, 2.0, 4.0)):
    """A random tree of callbacks, some on the agenda and some kernel events, at a few
    instants and every priority (many ties), each scheduling children of either kind; run
    in steps (the run's stop events tie with them too). Returns what ran, when, in order."""
    env = simpy.Environment()
    agenda = agenda_class(env)
    rng = np.random.default_rng(seed)
    log: list[tuple] = []
    names = iter(range(10**6))

    def plant(depth: int) -> None:
        name = next(names)
        delay = float(rng.choice([0.0, 0.0, 0.5, 1.0]))
        priority = int(rng.choice([FIRST, URGENT, NORMAL]))
        children = int(rng.integers(0, 3)) if depth < 4 else 0

        def run(tag: str, payload: int) -> None:
            log.append((name, tag, payload, env.now))
            for _ in range(children):
                plant(depth + 1)

        draw = rng.random()
        if draw < 0.25:
            agenda.at(delay, priority, run, "at", name * 7)
        elif draw < 0.45:
            # Often out of order (random delays and priorities): the heap takes those.
            agenda.at_in_order(delay, priority, run, "at_in_order", name * 7)
        elif draw < 0.65:
            agenda.ahead(delay, priority, run, "ahead", name * 7)
        else:
            scheduled_event(env, delay, priority, lambda _event: run("kernel", name * 7))

    for _ in range(12):
        plant(0)
    for t in stops:
        env.run(until=t)
        log.append(("stop", env.now))
    return log


@pytest.mark.parametrize("seed", range(40))
def test_agenda_runs_its_entries_in_the_kernels_order(seed):
    """Entries (heaped, queued in order when they come in order, or in the calendar) and
    kernel events at
    the same instants and priorities, scheduled from each other's callbacks, with the run
    stopped and resumed at their instants: the agenda runs everything in the order, and at
    the instants, of one kernel event per entry, each entry with its own arguments."""
    reference = _scripted(KernelAgenda, seed)
    assert len(reference) > 12
    assert _scripted(Agenda, seed) == reference


def test_agenda_wakes_once_for_consecutive_entries():
    """Entries with nothing in the kernel between them run from one wake, those scheduled
    from inside an entry (a beacon's next tick) included."""
    env = simpy.Environment()
    agenda = Agenda(env)
    ran = []

    def tick(k: int) -> None:
        ran.append(k)
        if k < 99:
            agenda.at(0.01, URGENT, lambda: tick(k + 1))

    for k in range(0, 100, 10):
        agenda.at(0.5, URGENT, lambda k=k: ran.append(-k - 1))
    agenda.at(0.0, URGENT, lambda: tick(0))
    env.run()
    assert len(ran) == 110 and sorted(k for k in ran if k >= 0) == list(range(100))
    # Two: the one armed for 0.5 first stays queued after the one for 0 is armed.
    assert agenda.wakes_run == 2


def test_an_agendas_length_is_its_entries_not_yet_run():
    """``len(agenda)`` counts the entries still to run, wherever they wait (heap, queue or
    calendar), and falls as they run."""
    env = simpy.Environment()
    agenda = Agenda(env)
    ran: list[float] = []
    agenda.at(1.0, URGENT, lambda: ran.append(env.now))
    agenda.at_in_order(1.0, URGENT, lambda: ran.append(env.now))
    agenda.ahead(2.0, NORMAL, lambda: ran.append(env.now))
    agenda.ahead(3.0, NORMAL, lambda: ran.append(env.now))
    lengths = [len(agenda)]
    for until in (1.5, 2.5, 4.0):
        env.run(until=until)
        lengths.append(len(agenda))
    assert lengths == [4, 2, 1, 0] and ran == [1.0, 1.0, 2.0, 3.0]


def test_a_scheduled_event_is_normal_unless_told():
    """``scheduled_event`` without a priority runs as a timeout does (NORMAL: after the
    URGENT events of its instant, among the NORMAL ones in the order scheduled)."""
    env = simpy.Environment()
    log = []
    env.timeout(1.0).callbacks.append(lambda _e: log.append("timeout"))
    scheduled_event(env, 1.0, callback=lambda _e: log.append("default"))
    scheduled_event(env, 1.0, URGENT, lambda _e: log.append("urgent"))
    env.run()
    assert log == ["urgent", "timeout", "default"]


def test_an_event_at_last_runs_after_everything_else_of_its_instant():
    """LAST (the runtime links' start at t = 0) comes after the NORMAL events of its instant,
    those scheduled after it included; FIRST before the URGENT ones."""
    env = simpy.Environment()
    log = []
    scheduled_event(env, 0.0, LAST, lambda _e: log.append("last"))
    scheduled_event(env, 0.0, NORMAL, lambda _e: log.append("normal"))
    env.timeout(0.0).callbacks.append(lambda _e: log.append("timeout"))
    scheduled_event(env, 0.0, URGENT, lambda _e: log.append("urgent"))
    scheduled_event(env, 0.0, FIRST, lambda _e: log.append("first"))
    env.run()
    assert log == ["first", "urgent", "normal", "timeout", "last"]


def _deliveries(sim):
    log = []
    sim.events.on("delivery", lambda d: log.append((d.t_s, d.kind, d.sender, d.receivers.tolist())))
    return log


def _ack_only(monkeypatch, agenda_class, jitter_s: float):
    monkeypatch.setattr(netsim.radio.channel, "Agenda", agenda_class)
    positions = [[0.0, 0.0], [5.0, 0.0], [0.0, 5.0], [5.0, 5.0], [30.0, 0.0]]
    sim = static_core(positions, duration_s=20.0, latency_jitter_s=jitter_s)
    beacon = AckBeacon(AckParams(ack_jitter_s=0.0), sim.parts)
    sim.add_model("protocol", beacon)
    log = _deliveries(sim)
    beacon.start(np.zeros(len(positions)))  # equal phases: every Ack of an instant ties
    sim.run()
    return log, beacon.table.data.copy()


@pytest.mark.parametrize("jitter_s", [0.0, 0.002])
def test_acks_with_equal_phases_arrive_in_the_kernels_order(monkeypatch, jitter_s):
    """Acks without jitter from robots of equal phases (all sent at the same instants, all
    arriving together) and with latency jitter: deliveries in the same order at the same
    instants, and the same neighbour tables, as with one kernel event each."""
    log, table = _ack_only(monkeypatch, Agenda, jitter_s)
    ref_log, ref_table = _ack_only(monkeypatch, KernelAgenda, jitter_s)
    assert len(log) > 50
    assert log == ref_log
    assert np.array_equal(table, ref_table, equal_nan=True)


def _clustering_run(monkeypatch, agenda_class):
    monkeypatch.setattr(netsim.radio.channel, "Agenda", agenda_class)
    positions = [[10.0 * (i % 4), 8.0 * (i // 4)] for i in range(12)]
    sim, _ = clustering(positions, phases=np.zeros(12), message_rate_hz=1.0, core={"duration_s": 30.0})
    log = _deliveries(sim)
    sim.run()
    return log, collect(sim)


def test_a_clustering_run_is_the_same_with_the_agenda(monkeypatch):
    """The clustering protocol (its listeners schedule timers and messages from inside a
    delivery), on equal Ack phases: the same deliveries and the same tables as with one
    kernel event per entry."""
    log, frames = _clustering_run(monkeypatch, Agenda)
    ref_log, ref_frames = _clustering_run(monkeypatch, KernelAgenda)
    assert log == ref_log
    assert frames.keys() == ref_frames.keys()
    for name in frames:
        pd.testing.assert_frame_equal(frames[name], ref_frames[name])


@pytest.mark.slow
def test_a_moving_run_with_loss_and_jitter_is_the_same_with_the_agenda(monkeypatch):
    """Random waypoint, loss, latency jitter, runtime link events (at FIRST priority),
    messages: every table as with one kernel event per entry."""
    config = make_config(
        duration_s=20.0,
        world={"n_robots": 25, "side_m": 300.0},
        channel={"range_m": 90.0, "loss_probability": 0.1, "latency_jitter_s": 0.01},
        protocol={"message_rate_hz": 1.0},
        events={"runtime_links": "on"},
    )
    out = []
    for agenda_class in (Agenda, KernelAgenda):
        monkeypatch.setattr(netsim.radio.channel, "Agenda", agenda_class)
        sim = build(config)
        log = _deliveries(sim)
        sim.run()
        out.append((log, collect(sim)))
    (log, frames), (ref_log, ref_frames) = out
    assert log == ref_log
    for name in ref_frames:
        pd.testing.assert_frame_equal(frames[name], ref_frames[name])


def _timer_script(agenda_class, seed: int, sets: int = 1):
    """Deadline timers (``sets`` sets of them on one agenda) restarted, moved earlier and
    later, and cancelled from entries at a few instants (so that deadlines, and other
    entries at NORMAL priority, tie), with a log of what ran when."""
    from netsim.timers import DeadlineTimers

    env = simpy.Environment()
    agenda = agenda_class(env)
    rng = np.random.default_rng(seed)
    log: list[tuple] = []
    all_timers = [
        DeadlineTimers(env, 6, lambda i, now, s=s: log.append((now, "expire", s, i)), agenda) for s in range(sets)
    ]

    def act(k: int) -> None:
        log.append((env.now, "act", k))
        for _ in range(int(rng.integers(1, 4))):
            timers = all_timers[int(rng.integers(sets))]
            i = int(rng.integers(6))
            what = rng.random()
            if what < 0.15:
                timers.cancel(i)
            else:
                timers.restart(i, env.now + 0.25 * int(rng.integers(0, 8)))
        if k < 150:
            agenda.at(0.25 * int(rng.integers(0, 3)), int(rng.choice([URGENT, NORMAL])), lambda: act(k + 1))
            if rng.random() < 0.3:
                agenda.at(0.25 * int(rng.integers(0, 6)), NORMAL, lambda: log.append((env.now, "mark", k)))

    agenda.at(0.0, URGENT, lambda: act(0))
    env.run(until=100.0)
    return log


@pytest.mark.parametrize("seed", range(6))
def test_timers_on_the_agenda_expire_in_the_kernels_order(seed):
    """Timers whose events wait in the agenda's calendar: every expiry at
    its instant and in the order of one kernel event per timer event, ties with other
    entries of the same instant and priority included."""
    log = _timer_script(Agenda, seed)
    assert log == _timer_script(KernelAgenda, seed)
    expiries = [e for e in log if e[1] == "expire"]
    assert len(expiries) > 30
    # Ties happened: expiries at the instant of another expiry or mark.
    instants = [e[0] for e in log if e[1] != "act"]
    assert len(instants) - len(set(instants)) > 10


@pytest.mark.parametrize("seed", range(3))
def test_two_sets_of_timers_on_one_agenda_expire_in_the_kernels_order(seed):
    """Two sets of timers whose events share the agenda's calendar: both in the order of
    one kernel event per timer event."""
    log = _timer_script(Agenda, seed, sets=2)
    assert log == _timer_script(KernelAgenda, seed, sets=2)
    assert {e[2] for e in log if e[1] == "expire"} == {0, 1}


def _timers_beside_kernel_events(agenda_class, seed: int, sets: int):
    """Timers restarted (into the past too) and cancelled from agenda entries and kernel
    events at every priority, and from their own expiries, with the run stopped and resumed
    at tie instants: a log of what ran when."""
    from netsim.timers import DeadlineTimers

    env = simpy.Environment()
    agenda = agenda_class(env)
    rng = np.random.default_rng(seed)
    log: list[tuple] = []
    timers: list[DeadlineTimers] = []

    def expired(i: int, now: float, s: int) -> None:
        log.append((now, "expire", s, i))
        draw = rng.random()
        if draw < 0.3:
            timers[int(rng.integers(sets))].restart(int(rng.integers(5)), now + 0.25 * int(rng.integers(0, 3)))
        elif draw < 0.45:
            agenda.at(0.0, int(rng.choice([URGENT, NORMAL])), lambda: log.append((env.now, "entry", i)))
        elif draw < 0.6:
            scheduled_event(env, 0.0, NORMAL, lambda _e: log.append((env.now, "kernel", i)))

    timers.extend(DeadlineTimers(env, 5, lambda i, now, s=s: expired(i, now, s), agenda) for s in range(sets))
    names = iter(range(10**6))

    def act(depth: int) -> None:
        k = next(names)
        log.append((env.now, "act", k))
        for _ in range(int(rng.integers(0, 4))):
            t, i, draw = timers[int(rng.integers(sets))], int(rng.integers(5)), rng.random()
            if draw < 0.15:
                t.cancel(i)
            elif draw < 0.3:
                t.restart(i, env.now - 0.25)
            else:
                t.restart(i, env.now + 0.25 * int(rng.integers(0, 6)))
        if depth < 60 and k < 400:
            for _ in range(int(rng.integers(1, 3))):
                delay, priority = 0.25 * int(rng.integers(0, 3)), int(rng.choice([FIRST, URGENT, NORMAL]))
                if rng.random() < 0.5:
                    agenda.at(delay, priority, act, depth + 1)
                else:
                    scheduled_event(env, delay, priority, lambda _e, depth=depth: act(depth + 1))

    for _ in range(3):
        scheduled_event(env, 0.0, NORMAL, lambda _e: act(0))
        agenda.at(0.0, NORMAL, act, 0)
    for stop in (0.25, 0.5, 1.0, 1.25, 2.0, 3.0, 5.0, 8.0, 13.0, 40.0):
        env.run(until=stop)
        log.append(("stop", env.now))
    return log


@pytest.mark.parametrize("seed", range(8))
@pytest.mark.parametrize("sets", [1, 2])
def test_timers_beside_kernel_events_and_stops_run_in_the_kernels_order(seed, sets):
    """Timers restarted and cancelled from kernel events as well as agenda entries, and
    from their expiries, with the run stopped at tie instants: every event in the order of
    one kernel event per entry."""
    log = _timers_beside_kernel_events(Agenda, seed, sets)
    assert log == _timers_beside_kernel_events(KernelAgenda, seed, sets)
    assert sum(e[1] == "expire" for e in log if len(e) > 2) > 10
