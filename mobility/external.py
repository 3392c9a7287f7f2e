"""Robots moved from outside (``mobility.model = "external"``, docs/cosim.md): they start
where ``world.placement`` puts them, at rest, and move only as ``sim.drive`` tells them.

A drive is a new straight leg from where the robot is, now (cause ``"command"``), so link
events stay exact. The area's border and the map's walls hold as for every model: a robot
driven toward the border stops on it, and on a map it stops just short of the first cell
that is not free (as random direction does, :func:`netsim.world.free_space.free_fraction`),
at the exact instant it gets there (a leg at rest, cause ``"border"``). It then stays there,
whatever it was told, until it is driven at another velocity; a robot on the border driven
outward (even partly: there is no sliding along the border) does not move. On a torus there
is no border: robots wrap around.
"""

from __future__ import annotations

import numpy as np
import simpy

from netsim.area import time_to_border
from netsim.params import NoParams
from netsim.placement import initial_positions
from netsim.plugins import Parts, PluginSpec
from netsim.scheduling import NORMAL, scheduled_event
from netsim.state import RobotState


class ExternalDriver:
    """Moves robots at the velocities they are given, stopping them at the border or a wall.

    Each driven robot's stop (its instant and place) is kept in arrays; one kernel event,
    at the earliest stop, stops every robot due then and waits for the next: a drive costs
    no event per robot, and a stop made void by a later drive is never acted on.
    """

    def __init__(self, env: simpy.Environment, state: RobotState, occupancy=None):
        self.env, self.state, self.occupancy = env, state, occupancy
        n = state.n
        # The velocity each robot was last told: telling it again changes nothing (a robot
        # stopped at the border stays stopped).
        self.wished_mps = np.zeros((n, 2))
        self.stop_s = np.full(n, np.inf)
        self.stop_m = np.zeros((n, 2))
        self._armed_s = np.inf  # when the pending wake-up is due (inf: none)
        self._token = 0  # the pending wake-up's number: an older one is void

    def drive(self, robots: np.ndarray, velocities_mps: np.ndarray, now: float) -> None:
        wished = self.wished_mps[robots]
        new = (velocities_mps[:, 0] != wished[:, 0]) | (velocities_mps[:, 1] != wished[:, 1])
        if not new.all():
            robots, velocities_mps = robots[new], velocities_mps[new]
        if len(robots) == 0:
            return
        st, v = self.state, velocities_mps
        self.wished_mps[robots] = v
        if st.torus:
            st.set_legs(robots, now, v)
            return
        here = st.positions_at(now, robots)
        t_stop = time_to_border(here, v, st.bounds)
        finite = np.isfinite(t_stop)
        ends = st.bounds.clip(here + v * np.where(finite, t_stop, 0.0)[:, None])
        if self.occupancy is not None and (t_stop > 0).any():
            from netsim.world.free_space import free_fraction

            ahead = np.flatnonzero(t_stop > 0)
            # A robot at rest that is told to move "to infinity" (a torus has no map) is
            # checked along its way to the border.
            f = free_fraction(self.occupancy, here[ahead], ends[ahead])
            short = f < 1.0
            blocked = ahead[short]
            t_stop[blocked] *= f[short]
            ends[blocked] = here[blocked] + v[blocked] * t_stop[blocked, None]
        # On the border (or against a wall) and heading out: it stays where it is.
        stuck = t_stop <= 0.0
        if stuck.any():
            v = np.where(stuck[:, None], 0.0, v)
            st.set_legs(robots, now, v, cause=np.where(stuck, "border", "command").tolist())
        else:
            st.set_legs(robots, now, v)
        self.stop_s[robots] = np.where(stuck, np.inf, now + t_stop)
        self.stop_m[robots] = ends
        self._arm(now)

    def _arm(self, now: float) -> None:
        first = float(self.stop_s.min())
        if first < self._armed_s:
            self._armed_s = first
            self._token += 1
            token = self._token
            scheduled_event(self.env, max(first - now, 0.0), NORMAL, lambda _event: self._wake(token))

    def _wake(self, token: int) -> None:
        if token != self._token:
            return  # superseded by an earlier wake-up, which armed the next one
        st, now = self.state, self.env.now
        # Due by the instant the wake-up was set for (the kernel's clock may differ from it
        # in the last bit: now + (first - now)).
        due = np.flatnonzero(self.stop_s <= self._armed_s)
        for i in due.tolist():
            st.arrive(i, now, self.stop_m[i].copy(), cause="border")
        self.stop_s[due] = np.inf
        self._armed_s = np.inf
        self._arm(now)


def build(params: NoParams, parts: Parts) -> ExternalDriver:
    parts.state.place(initial_positions(parts.world, parts.streams, parts.occupancy, parts.channel))
    return ExternalDriver(parts.env, parts.state, parts.occupancy)


PLUGIN = PluginSpec(Params=NoParams, build=build, moves_robots=True, respects_map=True)
