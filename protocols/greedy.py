"""``protocol.model = "greedy"``: greedy geographic forwarding (docs/routing.md, "greedy").

Every robot beacons its position every ``beacon_period_s`` (plus jitter); a robot keeps
the last position each neighbour beaconed, for ``neighbour_timeout_s``. A packet carries
where its destination was when it was sent (a location service, as GPSR assumes: the
source is told its destination's true position). Each holder sends it to the neighbour
whose beaconed position is closest to that point, and only to one strictly closer than
itself: a holder with no such neighbour is a *local maximum*, and the packet is dropped
there (``drop_cause = "local_maximum"``; no perimeter recovery). A frame to a neighbour
that no longer hears it is lost (``lost``), and that neighbour is forgotten.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from netsim.protocols.routing import ROUTING_TABLES, Packet, Router, RoutingParams, check_pairs

from netsim.compiled import load
from netsim.errors import ConfigError
from netsim.geometry import distances_m
from netsim.params import finite, frame_size, non_negative, param, positive
from netsim.plugins import Parts, PluginSpec
from netsim.scheduling import URGENT


@dataclass(frozen=True)
class GreedyParams(RoutingParams):
    """Greedy geographic forwarding's keys of ``[protocol]``."""

    section = "protocol"
    beacon_period_s: float = param(1.0, finite(positive), "period of the position beacons, s", schedules="robot")
    beacon_jitter_s: float = param(0.1, non_negative, "each period is the period + U(-jitter, +jitter), s")
    beacon_bytes: int = param(24, frame_size, "size of a position beacon frame (id, x, y, time), bytes")
    neighbour_timeout_s: float = param(
        None,
        positive,
        "a neighbour not heard for this long is forgotten, s",
        kind=float,
        derive=lambda p: 3.0 * p.beacon_period_s,
        rule="3 x beacon_period_s",
    )
    hop_limit: int = param(64, positive, "hops a data packet may take")

    def check(self) -> None:
        if not self.beacon_jitter_s < self.beacon_period_s / 2:
            raise ConfigError(
                "protocol.beacon_jitter_s",
                self.beacon_jitter_s,
                f"must be less than half of protocol.beacon_period_s = {self.beacon_period_s}",
            )
        if not self.neighbour_timeout_s > self.beacon_period_s + self.beacon_jitter_s:
            raise ConfigError(
                "protocol.neighbour_timeout_s",
                self.neighbour_timeout_s,
                "must be greater than protocol.beacon_period_s + protocol.beacon_jitter_s"
                f" = {self.beacon_period_s + self.beacon_jitter_s:g}",
            )


def greedy_next_hop(
    own_xy: np.ndarray,
    dst_xy: np.ndarray,
    nbr_ids: np.ndarray,
    nbr_xy: np.ndarray,
    side_m: float | None = None,
    n_robots: int | None = None,
) -> int:
    """The greedy rule: the neighbour (of ``nbr_ids`` at ``nbr_xy``) closest to ``dst_xy``,
    if strictly closer than ``own_xy``; -1 if none is (a local maximum). Ties go to the
    lowest id. Lengths are :func:`netsim.geometry.distances_m`'s: to the nearest image on a
    torus of side ``side_m`` (None: the plane), as a team of ``n_robots`` (None: as many as
    the neighbours) measures them.

    >>> greedy_next_hop(np.array([0.0, 0]), np.array([10.0, 0]), np.array([3, 5]), np.array([[4.0, 0], [-4, 0]]))
    3
    >>> greedy_next_hop(np.array([0.0, 0]), np.array([10.0, 0]), np.array([5]), np.array([[-4.0, 0]]))
    -1
    """
    if len(nbr_ids) == 0:
        return -1
    ends = np.empty((len(nbr_ids) + 1, 2))
    ends[0], ends[1:] = own_xy, nbr_xy
    lengths = distances_m(ends, dst_xy, side_m, n_robots)
    own, d = float(lengths[0]), lengths[1:]
    order = np.lexsort((nbr_ids, d))
    best = int(order[0])
    return int(nbr_ids[best]) if d[best] < own else -1


class Beacon:
    __slots__ = ("sender", "x_m", "y_m")

    def __init__(self, sender: int, x_m: float, y_m: float):
        self.sender, self.x_m, self.y_m = sender, x_m, y_m


class Greedy(Router):
    """Position beacons, neighbour tables and greedy forwarding (module notes)."""

    def __init__(self, params: GreedyParams, parts: Parts):
        super().__init__(parts, params.hop_limit, params)
        self.params = params
        n = self.state.n
        # What robot i last heard of neighbour j: its position and when (-inf: never).
        self.heard_xy = np.zeros((n, n, 2))
        self.heard_t = np.full((n, n), -np.inf)
        self.kernels = load("netsim.protocols._kernels", n)
        self.control_kind("beacon", params.beacon_bytes)

    def start(self) -> None:
        super().start()
        p, n = self.params, self.state.n
        self._phase = self.streams.get("greedy.phase").uniform(0.0, p.beacon_period_s, n)
        self._jitter = self.streams.get("greedy.jitter")
        agenda = self.channel.agenda
        for i in range(n):
            agenda.at(float(self._phase[i]), URGENT, self._tick, i)

    def _tick(self, i: int) -> None:
        p = self.params
        if self.state.alive[i]:
            x, y = self.state.positions_at(self.env.now, [i])[0]
            self.control(i, Beacon(i, float(x), float(y)), self._on_beacon, "beacon")
        jitter = self._jitter.uniform(-p.beacon_jitter_s, p.beacon_jitter_s) if p.beacon_jitter_s > 0 else 0.0
        self.channel.agenda.at(p.beacon_period_s + jitter, URGENT, self._tick, i)

    def _on_beacon(self, sender: int, receivers: np.ndarray, beacon: Beacon) -> None:
        self.heard_xy[receivers, sender] = (beacon.x_m, beacon.y_m)
        self.heard_t[receivers, sender] = self.env.now

    def neighbours(self, i: int) -> np.ndarray:
        """The robots ``i`` has heard within the timeout, ids ascending: live as a clustering
        neighbour entry is (``is_live``: heard less than the timeout ago)."""
        return np.flatnonzero(
            self.kernels.live_entries(self.heard_t[i], float(self.env.now), float(self.params.neighbour_timeout_s))
        )

    def destination_xy(self, dst: int) -> tuple[float, float]:
        x, y = self.state.positions_at(self.env.now, [dst])[0]
        return float(x), float(y)

    def next_hop(self, holder: int, pkt: Packet) -> tuple[int, str]:
        nbrs = self.neighbours(holder)
        if pkt.dst in nbrs.tolist():
            return pkt.dst, ""
        st = self.state
        own = st.positions_at(self.env.now, [holder])[0]
        assert pkt.dst_xy is not None
        side = st.torus_side_m
        nxt = greedy_next_hop(own, np.asarray(pkt.dst_xy), nbrs, self.heard_xy[holder, nbrs], side, st.n)
        return (nxt, "") if nxt >= 0 else (-1, "local_maximum")

    def link_failed(self, holder: int, nxt: int, pkt: Packet) -> None:
        self.heard_t[holder, nxt] = -np.inf


def build(params: GreedyParams, parts: Parts) -> Greedy:
    router = Greedy(params, parts)
    router.start()
    return router


PLUGIN = PluginSpec(
    Params=GreedyParams, build=build, tables=dict(ROUTING_TABLES), carries_flows=True, check=check_pairs
)
