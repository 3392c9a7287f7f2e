"""The bridge's pace against the wall clock (netsim.bridge.loop.Pacer) and its Ctrl-C."""

import signal

from netsim.bridge.loop import Pacer
from netsim.tools.bridge import _stop_on_signals


class _Sim:
    """A run whose steps cost nothing: the pacer's waits are all wall clock."""

    now = 0.0
    duration_s = 100.0

    def run(self, until_s: float) -> None:
        self.now = until_s


def test_ctrl_c_ends_a_wait_for_the_wall_clock_at_once():
    """Each step is due half a wall second after the last (``--rate 2``, a clock that
    stands still); Ctrl-C, arriving as the second step is found early, ends the run there,
    that step unpublished. (The wait was a sleep that went on after the signal's handler:
    Ctrl-C waited out the step, and the step was published.)"""
    sim = _Sim()
    calls = []

    def clock() -> float:
        calls.append(None)
        if len(calls) == 2:  # the second step's check of the wall clock, just before its wait
            signal.raise_signal(signal.SIGINT)
        return 0.0

    pacer = Pacer(sim, 1.0, 2.0, clock=clock)
    published: list[float] = []
    with _stop_on_signals(pacer):
        pacer.run(published.append, lambda t_s: None)
    assert pacer.stop
    assert published == [1.0] and sim.now == 2.0
