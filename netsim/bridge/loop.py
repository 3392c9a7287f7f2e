"""The run paced against the wall clock, and what it tells and hears at each step.

The run advances in control periods of ``1 / bridge.odom_hz`` simulated seconds. At each
step's end, once the wall clock has reached it (``--rate R``: the simulated instant ``t``
is due at ``t / R`` wall seconds after the start), the bridge publishes ``/clock`` and each
robot's odometry, neighbours and the links, then the relayed messages that arrived during
the step; then it takes the commands and messages ROS 2 nodes sent meanwhile and applies
them at that instant: a Twist drives its robot from then on, a message on a ``tx`` topic
goes on the air then. The lag is how late the wall clock is when a step is done computing
(0 while the run keeps up): its largest value and its mean are the run's ``lag_*``.

The loop ends at ``duration_s`` or when :attr:`Pacer.stop` is set (Ctrl-C).
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import numpy as np


@dataclass
class Lag:
    """How late the steps were done, s of wall time."""

    max_s: float = 0.0
    total_s: float = 0.0
    steps: int = 0
    last_s: float = 0.0

    def add(self, lag_s: float) -> None:
        self.last_s = lag_s
        self.max_s = max(self.max_s, lag_s)
        self.total_s += lag_s
        self.steps += 1

    def summary(self) -> dict:
        mean = self.total_s / self.steps if self.steps else math.nan
        return {"lag_max_s": self.max_s, "lag_mean_s": mean, "lag_last_s": self.last_s, "steps": self.steps}


class Pacer:
    """Steps a simulation at ``rate`` simulated seconds per wall second."""

    def __init__(self, sim: Any, period_s: float, rate: float, clock: Callable[[], float] = time.monotonic):
        self.sim, self.period_s, self.rate, self.clock = sim, float(period_s), float(rate), clock
        self.lag = Lag()
        self.stop = False

    def run(self, step_end: Callable[[float], None], step_start: Callable[[float], None]) -> None:
        """Advance to the run's end (or :attr:`stop`): ``step_start(t)`` at each step's start
        (commands), ``step_end(t)`` once its end is due on the wall clock (outputs)."""
        sim, end = self.sim, self.sim.duration_s
        t0_sim = sim.now
        wall0 = self.clock()
        k = 0
        step_start(sim.now)
        while not self.stop and sim.now < end:
            k += 1
            t = min(t0_sim + k * self.period_s, end)
            sim.run(until_s=t)
            due = wall0 + (t - t0_sim) / self.rate
            late = self.clock() - due
            self.lag.add(max(late, 0.0))
            if late < 0:
                time.sleep(-late)
            step_end(t)
            if t < end:
                step_start(t)


def odometry_rows(sim: Any) -> tuple[np.ndarray, np.ndarray]:
    """Positions ``(N, 2)`` and velocities ``(N, 2)`` of every robot now."""
    return sim.positions(), sim.state.velocity_mps.copy()
