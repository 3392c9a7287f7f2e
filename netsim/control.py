"""The control loop: the paper's "reserved interface" for robots' own control algorithms.

Every ``coverage.control_period_s`` the loop asks a chain of *controllers* what velocity
each robot should have over the next period. A controller is a plain callable
``controller(step: ControlStep) -> None`` that reads the step and may change
``step.velocity_mps`` in place, or record its own rows with :meth:`ControlStep.record`
(a logging or analysis hook). Controllers run in ascending ``order``; the built-in
coverage controller proposes the leaders' velocities first (order 0) and makes the plan
safe for connectivity last (order 100); user controllers run in between (order 50).

Timing: step ``k`` is decided at ``t_k`` and takes effect at ``t_k + lead`` where ``lead``
is the channel's largest delay, so that a command broadcast at ``t_k`` reaches its
receivers before they are to act on it. Positions in the step are those at ``t_k + lead``
(known exactly: every robot is on a straight leg until then).

Only robots the loop controls may change velocity: with ``mobility.model = "static"``
every robot; with another mobility model the loop observes only (hooks), and a changed
velocity raises an error rather than silently fighting the mobility model.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Protocol

import numpy as np
import pandas as pd

from netsim.errors import NetsimInputError


class GroupView(Protocol):
    """What a protocol that forms groups tells the controllers (implemented by the
    clustering stack): the positions a leader has heard of in Acks, directly or relayed
    by its neighbours."""

    def heard_leaders(self, leader: int, now: float) -> tuple[np.ndarray, np.ndarray]:
        """Ids and last-heard positions ``(k, 2)`` of the other leaders ``leader`` knows."""
        ...

    def neighbourhood(self, now: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """What every robot knows of those around it (those it hears and those they
        hear): arrays ``(robot, other, last-heard position of other (k, 2))``."""
        ...


@dataclass
class ControlStep:
    """One control step: the state a controller sees and the velocities it may change.

    Attributes
    ----------
    t_s : when the velocities take effect.
    period_s : how long they hold (until the next step).
    positions_m : ``(N, 2)`` positions at ``t_s``.
    velocity_mps : ``(N, 2)`` velocities over ``[t_s, t_s + period_s]``; change in place.
    role, leader : each robot's role (0 gamma, 1 beta, 2 alpha) and leader id.
    range_m : ``(N,)`` communication ranges.
    side_m : side of the square area.
    options : the ``[control.options]`` table.
    """

    t_s: float
    period_s: float
    positions_m: np.ndarray
    velocity_mps: np.ndarray
    role: np.ndarray
    leader: np.ndarray
    range_m: np.ndarray
    side_m: float
    options: dict
    _records: dict[str, list[dict]] = field(default_factory=dict, repr=False)

    def record(self, table: str, **values) -> None:
        """Add a row ``{t_s, **values}`` to output table ``table`` (``<table>.parquet``)."""
        self._records.setdefault(table, []).append({"t_s": self.t_s, **values})


Controller = Callable[[ControlStep], None]


class ControlLoop:
    def __init__(self, sim, period_s: float, start_s: float, controls_motion: bool):
        self.sim = sim
        self.period_s = float(period_s)
        self.start_s = float(start_s)
        self.controls_motion = controls_motion
        ch = sim.config.channel
        self.lead_s = ch.latency_s + ch.latency_jitter_s
        self._controllers: list[tuple[int, int, Controller]] = []
        # Called as fn(step) at t_s, after commands have arrived, before velocities apply.
        self.before_apply: list[Controller] = []
        self.records: dict[str, list[dict]] = {}
        self._registered: set[str] = set()
        self.steps = 0
        self.stopped = False
        self._process = None

    def add(self, controller: Controller, order: int = 50) -> None:
        self._controllers.append((order, len(self._controllers), controller))
        self._controllers.sort(key=lambda c: c[:2])
        if self._process is None:
            self._process = self.sim.env.process(self._run())

    def stop(self) -> None:
        """End the loop after the current step (the robots stop where they are)."""
        self.stopped = True

    def _register(self, table: str) -> None:
        if table not in self._registered:
            self._registered.add(table)
            self.sim.trace.add_frame(table, lambda: pd.DataFrame(self.records.get(table, [])))

    def _run(self):
        env, st = self.sim.env, self.sim.state
        yield env.timeout(self.start_s)
        while True:
            t_s = env.now + self.lead_s
            current = st.velocity_mps.copy()
            step = ControlStep(
                t_s=t_s,
                period_s=self.period_s,
                positions_m=st.positions_at(t_s),
                velocity_mps=current.copy(),
                role=st.role.copy(),
                leader=st.leader.copy(),
                range_m=st.range_m,
                side_m=st.side_m,
                options=self.sim.config.control.options,
                _records=self.records,
            )
            if self.stopped:
                step.velocity_mps[:] = 0.0
            else:
                for _, _, controller in self._controllers:
                    controller(step)
                if self.stopped:
                    # Stopping everyone at once is always safe: no kept link can break.
                    step.velocity_mps[:] = 0.0
            for table in self.records:
                self._register(table)
            if self.lead_s > 0:
                yield env.timeout(self.lead_s)
            for fn in self.before_apply:
                fn(step)
            self._apply(step, current)
            self.steps += 1
            if self.stopped:
                return
            yield env.timeout(self.period_s - self.lead_s)

    def _apply(self, step: ControlStep, current: np.ndarray) -> None:
        changed = np.flatnonzero((step.velocity_mps != current).any(axis=1))
        if len(changed) == 0:
            return
        if not self.controls_motion:
            raise NetsimInputError(
                f"a controller changed the velocity of robot {int(changed[0])}, but robots move by "
                f"mobility.model = {self.sim.config.mobility.model!r}; controllers may move robots only "
                "with mobility.model = 'static'"
            )
        st, now = self.sim.state, self.sim.env.now
        for i, v in zip(changed.tolist(), step.velocity_mps[changed].tolist()):
            st.set_leg(i, now, v)


def control_loop(sim) -> ControlLoop:
    """The run's control loop (created on first use)."""
    loop = sim.models.get("control")
    if loop is None:
        cov = sim.config.coverage
        loop = ControlLoop(sim, cov.control_period_s, cov.start_s, sim.config.mobility.model == "static")
        sim.models["control"] = loop
    return loop
