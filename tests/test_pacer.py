"""The bridge's pace against the wall clock (netsim.bridge.loop.Pacer) and its Ctrl-C."""

import os
import signal
import threading

from netsim.bridge.loop import Pacer
from netsim.tools.bridge import _stop_on_signals


class _Sim:
    """A run whose steps cost nothing: the pacer's waits are all wall clock."""

    now = 0.0
    duration_s = 100.0

    def run(self, until_s: float) -> None:
        self.now = until_s


def test_ctrl_c_ends_a_wait_for_the_wall_clock_at_once():
    """Each step is due 30 wall seconds after the last (``--rate`` 1/30); Ctrl-C during the
    wait for the second ends the run there, that step unpublished. (The wait was a sleep
    that went on after the signal's handler: Ctrl-C waited out the step, and the step was
    published.)"""
    sim = _Sim()
    pacer = Pacer(sim, 1.0, 1.0 / 30.0)
    published: list[float] = []

    def step_start(t_s: float) -> None:
        if t_s == 1.0:  # the first step is out: the second now waits for the wall clock
            threading.Timer(0.05, os.kill, (os.getpid(), signal.SIGINT)).start()

    with _stop_on_signals(pacer):
        pacer.run(published.append, step_start)
    assert pacer.stop
    assert published == [1.0] and sim.now == 2.0
