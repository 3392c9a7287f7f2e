"""The bridge's pace against the wall clock (netsim.bridge.loop.Pacer) and its Ctrl-C."""

import signal

import pytest

from netsim.bridge.loop import Pacer
from netsim.tools.bridge import _stop_on_signals


class _Sim:
    """A run whose steps cost nothing: the pacer's waits are all wall clock."""

    now = 0.0
    duration_s = 100.0

    def run(self, until_s: float) -> None:
        self.now = until_s


def _ctrl_c_at_the_second_step():
    """A wall clock that stands still and sends Ctrl-C at its second reading: the second
    step's check, before its wait (the first reading is the schedule's start)."""
    calls = []

    def clock() -> float:
        calls.append(None)
        if len(calls) == 2:
            signal.raise_signal(signal.SIGINT)
        return 0.0

    return clock


def test_ctrl_c_ends_a_wait_for_the_wall_clock_at_once():
    """Each step is due half a wall second after the last (``--rate 2``, a clock that
    stands still); Ctrl-C, arriving as the second step is found early, ends the run there,
    that step published at once: the run has computed it, and its tables must end at the
    last instant the nodes were told. (The wait was a sleep that went on after the
    signal's handler; later the step was left unpublished, and the tables held an instant
    no node had seen.)"""
    sim = _Sim()
    pacer = Pacer(sim, 1.0, 2.0, clock=_ctrl_c_at_the_second_step())
    published: list[float] = []
    with _stop_on_signals(pacer):
        pacer.run(published.append, lambda t_s: None)
    assert pacer.stop
    assert published == [1.0, 2.0] and sim.now == 2.0


def test_ctrl_c_before_the_first_step_is_out_is_an_interrupt():
    """Ctrl-C while the first step computes (the start-up) ends the bridge as it ends
    ``netsim run``: an interrupt, nothing published (the step was published and every table
    written, with exit status 0)."""

    class Starting(_Sim):
        def run(self, until_s: float) -> None:
            signal.raise_signal(signal.SIGINT)
            self.now = until_s

    pacer = Pacer(Starting(), 1.0, 2.0, clock=lambda: 0.0)
    published: list[float] = []
    with _stop_on_signals(pacer), pytest.raises(KeyboardInterrupt):
        pacer.run(published.append, lambda t_s: None)
    assert published == []


def test_a_command_answering_a_step_is_applied_at_the_next_step():
    """A node that answers each step's odometry at once (here, within the publication
    itself: the fastest node there is) has its answer taken at the next step, every time:
    commands are taken before a step is published, so the control delay is one period,
    not one or none as the microseconds fall. (They were taken right after it: an answer
    quick enough was applied at the step it answered.)"""
    sim = _Sim()
    sim.duration_s = 5.0
    inbox: list[float] = []
    applied: list[tuple[float, float]] = []

    def publish(t_s: float) -> None:
        inbox.append(t_s)  # the node's answer to the odometry of t_s

    def take(t_s: float) -> None:
        applied.extend((answer, t_s) for answer in inbox)
        inbox.clear()

    Pacer(sim, 1.0, 1e9, clock=lambda: 0.0).run(publish, take)
    assert applied == [(1.0, 2.0), (2.0, 3.0), (3.0, 4.0)]  # the run ends at 5: no step after it


def test_the_first_step_is_published_a_period_after_the_start_up_and_every_step_is_counted():
    """The first step is published a control period (over the rate) after it is computed,
    and the schedule runs from when it is out: its one-time costs (its publication's, here
    0.3 s) are no lag. Each step after it is due a period after the one before, and
    ``bridge_steps`` counts every step published. (The first was published at once, so a
    session ran a period short of real time, and the steps counted were one fewer than
    those published.)"""
    sim = _Sim()
    sim.duration_s = 3.0
    now = [10.0]

    def wait(seconds: float) -> bool:
        now[0] += seconds
        return False

    pacer = Pacer(sim, 1.0, 2.0, clock=lambda: now[0])
    pacer._wait = wait  # type: ignore[method-assign]
    published: list[float] = []

    def publish(t_s: float) -> None:
        published.append(now[0])
        if t_s == 1.0:
            now[0] += 0.3  # the first messages' serializers

    pacer.run(publish, lambda t_s: None)
    assert published == [10.5, 11.3, 11.8]
    assert pacer.lag.summary()["steps"] == 3 and pacer.lag.summary()["lag_max_s"] == 0.0


# -- rules a mutation audit found no test for ------------------------------------------------
def test_lag_summary_keeps_the_first_latest_step_the_mean_and_the_last():
    """Steps 3 and 4 are done half a wall second late (step 2's and 3's publications cost
    1.5 and 1 s at --rate 1): the largest lag is that of the first of them, the mean is over
    every step, the last is step 4's."""
    sim = _Sim()
    sim.duration_s = 4.0
    now = [0.0]
    cost = {2.0: 1.5, 3.0: 1.0}

    def wait(seconds: float) -> bool:
        now[0] += seconds
        return False

    pacer = Pacer(sim, 1.0, 1.0, clock=lambda: now[0])
    pacer._wait = wait  # type: ignore[method-assign]

    def publish(t_s: float) -> None:
        now[0] += cost.get(t_s, 0.0)

    pacer.run(publish, lambda t_s: None)
    assert pacer.lag.summary() == {
        "lag_max_s": 0.5,
        "lag_max_at_s": 3.0,
        "lag_mean_s": 0.25,
        "lag_last_s": 0.5,
        "steps": 4,
    }


def test_a_run_that_keeps_up_has_its_largest_lag_at_the_first_step():
    sim = _Sim()
    sim.duration_s = 3.0
    pacer = Pacer(sim, 1.0, 1e9, clock=lambda: 0.0)
    pacer.run(lambda t_s: None, lambda t_s: None)
    assert pacer.lag.summary()["lag_max_s"] == 0.0 and pacer.lag.summary()["lag_max_at_s"] == 1.0


def test_the_last_step_ends_at_the_runs_end():
    """A run of 2.5 s in steps of 1 s: its last step is half a period, published at 2.5."""
    sim = _Sim()
    sim.duration_s = 2.5
    published: list[float] = []
    Pacer(sim, 1.0, 1e9, clock=lambda: 0.0).run(published.append, lambda t_s: None)
    assert published == [1.0, 2.0, 2.5] and sim.now == 2.5


def test_commands_are_taken_at_the_start_and_each_step_but_not_at_the_end_or_once_stopped():
    """Commands sent before the run are applied from its start; a step that ends the run,
    at its end or by Ctrl-C, takes none: nothing would apply them, yet they would count."""
    sim = _Sim()
    sim.duration_s = 3.0
    starts: list[float] = []
    Pacer(sim, 1.0, 1e9, clock=lambda: 0.0).run(lambda t_s: None, starts.append)
    assert starts == [0.0, 1.0, 2.0]

    sim = _Sim()
    pacer = Pacer(sim, 1.0, 2.0, clock=_ctrl_c_at_the_second_step())
    starts = []
    with _stop_on_signals(pacer):
        pacer.run(lambda t_s: None, starts.append)
    assert starts == [0.0, 1.0] and sim.now == 2.0


def test_sigterm_stops_the_session_as_ctrl_c_does_and_the_handlers_come_back_after():
    """SIGTERM (a service manager's stop) ends a session as Ctrl-C does, tables kept; once
    the session is saved, both signals are the command's own again."""
    before = {s: signal.getsignal(s) for s in (signal.SIGINT, signal.SIGTERM)}
    outside: list[int] = []
    pacer = Pacer(_Sim(), 1.0, 1.0)
    try:
        # A handler of the test's own, so that a SIGTERM the session misses ends no process.
        signal.signal(signal.SIGTERM, lambda signum, frame: outside.append(signum))
        with _stop_on_signals(pacer):
            signal.raise_signal(signal.SIGTERM)
        assert pacer.stop and outside == []
        signal.raise_signal(signal.SIGTERM)
        assert outside == [signal.SIGTERM]
    finally:
        pacer._close()
        for s, handler in before.items():
            signal.signal(s, handler)


def test_setting_stop_wakes_a_wait_for_the_wall_clock():
    """Setting ``stop`` (Ctrl-C's handler does) makes the pipe a wait for the wall clock
    watches readable, so that a wait already under way ends at once instead of sleeping out
    the step; a pacer not stopped leaves it unreadable."""
    import select

    pacer = Pacer(_Sim(), 1.0, 1.0, clock=lambda: 0.0)
    try:
        assert select.select([pacer._wake_r], [], [], 0)[0] == []
        pacer.stop = True
        assert select.select([pacer._wake_r], [], [], 0)[0] == [pacer._wake_r]
    finally:
        pacer._close()
