"""The control loop: the paper's "reserved interface" for robots' own control algorithms.

Every control period (``coverage.control_period_s``: the coverage controller's section sets
the loop's period and first step) the loop asks a chain of *controllers* what velocity
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

Only robots the loop controls may change velocity: with a mobility model that leaves the
robots where they are (``mobility.model = "static"``) every robot; with another mobility
model the loop observes only (hooks), and a changed velocity raises an error rather than
silently fighting the mobility model.

Roles come from the protocol's :class:`~netsim.groups.GroupView`, when it forms groups.
"""

from __future__ import annotations

import functools
from collections.abc import Callable, Generator
from dataclasses import dataclass, field
from typing import Any

import numpy as np
import pandas as pd
import simpy

from netsim.area import Bounds, OnTorus
from netsim.errors import NetsimInputError
from netsim.events import read_only
from netsim.groups import GroupView
from netsim.state import RobotState
from netsim.trace import Trace


@dataclass
class ControlStep(OnTorus):
    """One control step: the state a controller sees and the velocities it may change.

    Attributes
    ----------
    t_s : when the velocities take effect.
    period_s : how long they hold (until the next step).
    positions_m : ``(N, 2)`` positions at ``t_s``.
    velocity_mps : ``(N, 2)`` velocities over ``[t_s, t_s + period_s]``; change in place.
    role, leader : each robot's role code and leader (its own id for a leader, -1 for
        none), from the protocol (all 0 and -1 when it forms no groups).
    role_names : the label of each role code (``("gamma", "beta", "alpha")`` with the
        clustering protocol; empty when the protocol forms no groups).
    range_m : ``(N,)`` communication ranges (read only: the robots' own).
    side_m : side of the square area.
    torus : whether that square wraps (``world.torus``): distances between robots are
        then measured to the nearest image (:attr:`torus_side_m` is the ``side_m`` of
        :func:`netsim.topology.geometric_pairs`).
    options : the ``[control.options]`` table.
    bounds : the area robots move in (``world.bounds_m``; default ``[0, side_m]^2``).
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
    role_names: tuple[str, ...] = ()
    bounds: Bounds | None = None
    torus: bool = False
    _records: dict[str, list[dict]] = field(default_factory=dict, repr=False)

    def __post_init__(self) -> None:
        if self.bounds is None:
            self.bounds = Bounds.square(self.side_m)

    def record(self, table: str, **values: object) -> None:
        """Add a row ``{t_s, **values}`` to output table ``table`` (``<table>.parquet``)."""
        self._records.setdefault(table, []).append({"t_s": self.t_s, **values})


Controller = Callable[[ControlStep], None]


class ControlLoop:
    """The control loop of one run.

    Parameters
    ----------
    env, state, trace : the run's kernel, robots and record.
    period_s, start_s : time between steps, and the first step.
    lead_s : the channel's largest delay (a step takes effect that long after it is decided).
    moved_by : None when the loop moves the robots; otherwise what does (``"mobility.model
        = 'random_waypoint'"``), for the error when a controller changes a velocity.
    groups : the protocol's view of the groups, if it forms any.
    options : the ``[control.options]`` table.
    """

    def __init__(
        self,
        env: simpy.Environment,
        state: RobotState,
        trace: Trace,
        period_s: float,
        start_s: float,
        lead_s: float,
        moved_by: str | None = None,
        groups: GroupView | None = None,
        options: dict | None = None,
        occupancy: Any = None,
    ) -> None:
        self.env, self.state, self.trace = env, state, trace
        self.period_s = float(period_s)
        self.start_s = float(start_s)
        self.lead_s = float(lead_s)
        self.moved_by = moved_by
        self.groups = groups
        self.options = options if options is not None else {}
        # The world's map (netsim.world.maps.OccupancyMap) or None: robots stay in free cells.
        self.occupancy = occupancy
        self._controllers: list[tuple[int, int, str | None, Controller]] = []
        # Called as fn(step) at t_s, after commands have arrived, before velocities apply.
        self.before_apply: list[Controller] = []
        self.records: dict[str, list[dict]] = {}
        self._registered: set[str] = set()
        self.steps = 0
        self.stopped = False
        self._process: simpy.Process | None = None

    def add(self, controller: Controller, order: int = 50, owner: str | None = None) -> None:
        """Call ``controller`` at every step, in ``order``; the tables it records are
        ``owner``'s (a user's model: the key that chose it; see Trace.written_by)."""
        self._controllers.append((order, len(self._controllers), owner, controller))
        self._controllers.sort(key=lambda c: c[:2])
        if self._process is None:
            self._process = self.env.process(self._run())

    def stop(self) -> None:
        """End the loop after the current step (the robots stop where they are)."""
        self.stopped = True

    def _register(self, owner: str | None = None) -> None:
        """Register the tables recorded for the first time (the last controller's, if
        ``owner`` is given)."""
        if len(self.records) == len(self._registered):
            return
        trace = self.trace if owner is None else self.trace.written_by(owner)
        for table in self.records:
            if table not in self._registered:
                self._registered.add(table)
                trace.add_frame(table, functools.partial(self._frame, table))

    def _frame(self, table: str) -> pd.DataFrame:
        return pd.DataFrame(self.records.get(table, []))

    def _roles(self) -> tuple[np.ndarray, np.ndarray, tuple[str, ...]]:
        if self.groups is None:
            n = self.state.n
            return np.zeros(n, dtype=np.int8), np.full(n, -1, dtype=np.int64), ()
        return self.groups.role.copy(), self.groups.leader.copy(), tuple(self.groups.role_names)

    def _run(self) -> Generator[simpy.Event, object, None]:
        env, st = self.env, self.state
        yield env.timeout(self.start_s)
        while True:
            t_s = env.now + self.lead_s
            current = st.velocity_mps.copy()
            role, leader, role_names = self._roles()
            step = ControlStep(
                t_s=t_s,
                period_s=self.period_s,
                positions_m=st.positions_at(t_s),
                velocity_mps=current.copy(),
                role=role,
                leader=leader,
                range_m=read_only(st.range_m),
                side_m=st.side_m,
                options=self.options,
                role_names=role_names,
                bounds=st.bounds,
                torus=st.torus,
                _records=self.records,
            )
            if self.stopped:
                step.velocity_mps[:] = 0.0
            else:
                self._register()  # what the last step's before_apply recorded first
                for _, _, owner, controller in self._controllers:
                    controller(step)
                    self._register(owner)
                if self.stopped:
                    # Stopping everyone at once is always safe: no kept link can break.
                    step.velocity_mps[:] = 0.0
            self._register()
            if self.lead_s > 0:
                yield env.timeout(self.lead_s)
            for fn in self.before_apply:
                fn(step)
            self._apply(step, current)
            self.steps += 1
            if self.stopped:
                return
            yield env.timeout(self.period_s - self.lead_s)

    def _keep_off_walls(self, step: ControlStep) -> None:
        """On a map, shorten every robot's step so that it ends just short of the first cell
        that is not free (a controller cannot drive a robot into a wall)."""
        from netsim.world.free_space import short_of_walls

        if not (step.velocity_mps != 0).any():
            return
        here = self.state.positions_at(self.env.now)
        short_of_walls(self.occupancy, here, step.velocity_mps, self.period_s)

    def _apply(self, step: ControlStep, current: np.ndarray) -> None:
        # Only where the loop drives the robots: a mobility model keeps its own robots off
        # the walls, and a step the loop shortened would read as a controller's change.
        if self.occupancy is not None and self.moved_by is None:
            self._keep_off_walls(step)
        changed = np.flatnonzero((step.velocity_mps != current).any(axis=1))
        if len(changed) == 0:
            return
        if self.moved_by is not None:
            raise NetsimInputError(
                f"a controller changed the velocity of robot {int(changed[0])}, but robots move by "
                f"{self.moved_by}; controllers may move robots only with a mobility model that "
                "leaves them where they are (mobility.model = 'static')"
            )
        st, now = self.state, self.env.now
        for i, v in zip(changed.tolist(), step.velocity_mps[changed].tolist()):
            st.set_leg(i, now, v)
