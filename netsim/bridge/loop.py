"""The run paced against the wall clock, and what it tells and hears at each step.

The run advances in control periods of ``1 / bridge.odom_hz`` simulated seconds. At each
step's end, once the wall clock has reached it (``--rate R``: the simulated instant ``t``
is due at ``t / R`` wall seconds after the start), the bridge first takes the commands and
messages ROS 2 nodes sent meanwhile and applies them at that instant (a Twist drives its
robot from then on, a message on a ``tx`` topic goes on the air then), then publishes
``/clock`` and each robot's odometry, neighbours and the links, and the relayed messages
that arrived during the step. Taken before the step is published, no command can answer
that step: a node's answer to the odometry of ``t`` is applied at the next step, whatever
the microseconds it took, so the same node gives the same run. The lag is how late the
wall clock is when a step is done computing (0 while the run keeps up): its largest value
(and when), its mean and its last are the summary's ``bridge_lag_*``, and ``bridge_steps``
the steps published. The first step carries the start-up's one-time costs, which are no
lag: it is published a control period (over the rate) after it is computed, and the
schedule starts when it is out, each step due a period after the one before.

The loop ends at ``duration_s`` or when :attr:`Pacer.stop` is set (Ctrl-C): at once, also
while it waits for the wall clock, the step computed then published at once, so that the
run's tables end at the last instant the nodes were told. Stopped before its first step is
out, it raises :class:`KeyboardInterrupt`: nothing was published.
"""

from __future__ import annotations

import contextlib
import math
import os
import select
import time
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any


@dataclass
class Lag:
    """How late the steps were done, s of wall time."""

    max_s: float = 0.0
    total_s: float = 0.0
    steps: int = 0
    last_s: float = 0.0
    max_at_s: float = math.nan  # the simulated instant of the step that was latest

    def add(self, lag_s: float, t_s: float) -> None:
        self.last_s = lag_s
        if lag_s > self.max_s or math.isnan(self.max_at_s):
            self.max_s, self.max_at_s = lag_s, t_s
        self.total_s += lag_s
        self.steps += 1

    def summary(self) -> dict:
        mean = self.total_s / self.steps if self.steps else math.nan
        return {
            "lag_max_s": self.max_s,
            "lag_max_at_s": self.max_at_s,
            "lag_mean_s": mean,
            "lag_last_s": self.last_s,
            "steps": self.steps,
        }


class Pacer:
    """Steps a simulation at ``rate`` simulated seconds per wall second."""

    def __init__(self, sim: Any, period_s: float, rate: float, clock: Callable[[], float] = time.monotonic):
        self.sim, self.period_s, self.rate, self.clock = sim, float(period_s), float(rate), clock
        self.lag = Lag()
        self._stop = False
        # A wait for the wall clock watches this pipe, which setting stop writes to: a
        # signal handler may write to a pipe, where taking a lock could deadlock.
        self._wake_r, self._wake_w = os.pipe()
        os.set_blocking(self._wake_w, False)

    @property
    def stop(self) -> bool:
        """Whether the run is to end; setting it ends a wait for the wall clock at once."""
        return self._stop

    @stop.setter
    def stop(self, value: bool) -> None:
        self._stop = bool(value)
        if value and self._wake_w >= 0:
            with contextlib.suppress(BlockingIOError):  # the pipe full: already woken
                os.write(self._wake_w, b"x")

    def _wait(self, seconds: float) -> bool:
        """Wait ``seconds`` of wall time, or less if stopped meanwhile; whether stopped."""
        if not self._stop:
            select.select([self._wake_r], [], [], seconds)
        return self._stop

    def _close(self) -> None:
        fds, self._wake_r, self._wake_w = (self._wake_r, self._wake_w), -1, -1
        for fd in fds:
            os.close(fd)

    def run(self, step_end: Callable[[float], None], step_start: Callable[[float], None]) -> None:
        """Advance to the run's end (or :attr:`stop`): ``step_start(t)`` at each step's start
        (commands), taken just before ``step_end`` of the step before (outputs), once that
        step's end is due on the wall clock."""
        try:
            self._run(step_end, step_start)
        finally:
            self._close()

    def _run(self, step_end: Callable[[float], None], step_start: Callable[[float], None]) -> None:
        sim, end = self.sim, self.sim.duration_s
        t0_sim = sim.now
        wall0 = math.nan
        k = 0
        step_start(sim.now)
        while sim.now < end:
            k += 1
            t = min(t0_sim + k * self.period_s, end)
            sim.run(until_s=t)
            if k == 1:
                if self.stop:
                    raise KeyboardInterrupt  # stopped while starting: nothing is out yet
                # The first step carries the start-up's one-time costs (the run's first
                # events, the first messages' serializers), which are no lag: it is out a
                # control period after it is computed, and the schedule runs from then.
                late = -(t - t0_sim) / self.rate
            else:
                late = self.clock() - (wall0 + (t - t0_sim) / self.rate)
            self.lag.add(max(late, 0.0), t)
            if late < 0:
                self._wait(-late)
            if t < end and not self.stop:
                step_start(t)
            step_end(t)
            if k == 1:
                wall0 = self.clock() - (t - t0_sim) / self.rate
            if self.stop:
                break
