"""The Ack beacon (docs/model.md section 4): every robot broadcasts an Ack every ``t`` seconds.

Each robot starts at a random phase, uniform on ``[0, t)``, and each period is
``t + U(-jitter, +jitter)``. An Ack carries the sender's id, role, leader, a sequence
number, its position, its group size, its degree (live neighbours that list it in their
own Acks: two-way links only), and the ids it has heard within ``tau`` (so that a
receiver can tell a two-way link from a one-way one).

Receivers record the Ack in their neighbour table. Protocols built on the beacon (the
clustering) subscribe to :attr:`AckBeacon.listeners` and see every delivery, in bulk. With
latency jitter an Ack can be overtaken by the sender's next one: a receiver that already
holds a newer Ack from that sender ignores the older (the table keeps the newest, the
listeners are not told; :attr:`AckBeacon.stale_acks` counts them).

The beacon records ``acks`` (per robot, the whole run) and ``ack_delivery``: the Acks'
fate over time, per interval of send time (``output.position_interval_s``; the Ack
period when positions are not sampled). The Ack delivery ratio of an interval is
``received / (received + dropped_loss)``: of the receptions the loss model decided (a
robot alive and within the sender's range at send time could have received the Ack),
the share that arrived. Summed over the intervals, the counts are the ``acks`` table's.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping
from dataclasses import dataclass
from typing import NamedTuple

import numpy as np
import pandas as pd
from netsim.protocols._kernels import Beacon, RoleArrays
from netsim.protocols.neighbours import NeighbourTable, heard_in
from netsim.protocols.roles import LEADER, ROLES_SCHEMA, Roles, declare_roles

from netsim._kernels import Motion
from netsim.errors import ConfigError
from netsim.params import Params, finite, frame_size, names, non_negative, param, positive
from netsim.plugins import Parts, PluginSpec
from netsim.scheduling import URGENT


@dataclass(frozen=True)
class AckParams(Params):
    """The Ack beacon's keys of ``[protocol]``."""

    section = "protocol"
    ack_period_s: float = param(1.0, finite(positive), "Ack period t, s", schedules="robot")
    ack_jitter_s: float = param(0.05, non_negative, "each period is t + U(-jitter, +jitter), s")
    ack_bytes: int = param(64, frame_size, "size of an Ack frame on a shared medium (channel.mac), bytes")
    tau_s: float = param(
        None,
        positive,
        "liveness timeout tau, s",
        kind=float,
        derive=lambda p: 3.0 * p.ack_period_s,
        rule="3 x ack_period_s",
    )

    def check(self) -> None:
        if not self.tau_s > self.ack_period_s:
            raise ConfigError(
                "protocol.tau_s", self.tau_s, f"must be greater than protocol.ack_period_s = {self.ack_period_s}"
            )
        if not self.ack_jitter_s < self.ack_period_s / 2:
            raise ConfigError(
                "protocol.ack_jitter_s",
                self.ack_jitter_s,
                f"must be less than half of protocol.ack_period_s = {self.ack_period_s}",
            )


def check_tau(params: AckParams, config) -> None:
    """Without any loss two Acks of a neighbour can be up to period + jitter + latency
    jitter apart: a tau no longer than that times neighbours out for nothing."""
    gap = params.ack_period_s + params.ack_jitter_s + config.channel.latency_jitter_s
    if not params.tau_s > gap:
        raise ConfigError(
            "protocol.tau_s",
            params.tau_s,
            "must be greater than protocol.ack_period_s + protocol.ack_jitter_s + channel.latency_jitter_s"
            f" = {gap:g}, the longest gap between two Acks without loss",
        )
    ch = config.channel
    airtime = ch.airtime_s(params.ack_bytes)
    if airtime is not None and not airtime < params.ack_period_s:
        # Else a robot's own Acks fill its queue faster than the medium can carry them.
        shorter = f" an airtime of {airtime:g} s: must be shorter than protocol.ack_period_s = {params.ack_period_s:g}"
        if "data_rate_bps" not in names(type(ch.medium)):
            raise ConfigError(
                "protocol.ack_bytes", params.ack_bytes, f"gives an Ack on channel.mac = {ch.mac!r}" + shorter
            )
        raise ConfigError(
            "channel.data_rate_bps",
            ch.data_rate_bps,
            f"gives an Ack (protocol.ack_bytes = {params.ack_bytes}, channel.preamble_s = {ch.preamble_s:g})" + shorter,
        )


ACKS_SCHEMA = {
    "robot": "int64",
    "sent": "int64",
    "received": "int64",
    "dropped_loss": "int64",
    "dropped_not_alive": "int64",
    "dropped_out_of_range": "int64",
}


ACK_DELIVERY_SCHEMA = {
    "t_s": "float64",
    "sent": "int64",
    "in_range": "int64",
    "received": "int64",
    "dropped_loss": "int64",
    "dropped_not_alive": "int64",
    "delivery_ratio": "float64",
}


# Receptions a shared medium (channel.mac) loses on the way, beside the loss model's.
MAC_RECEPTION_DROPS = ("dropped_collision", "dropped_half_duplex")


def lost_on_the_way(df):
    """Receptions lost after the sender's range decided them: the loss model's, and a shared
    medium's collisions and half-duplex losses when there is one."""
    lost = df["dropped_loss"]
    for col in MAC_RECEPTION_DROPS:
        if col in df:
            lost = lost + df[col]
    return lost


def delivery_ratio(received, dropped_loss):
    """Acks received over Acks a robot within the sender's range could have received
    (received or lost on the way; NaN where there were none)."""
    received = np.asarray(received, dtype=float)
    decided = received + np.asarray(dropped_loss, dtype=float)
    with np.errstate(invalid="ignore", divide="ignore"):
        return np.where(decided > 0, received / decided, np.nan)


def ack_delivery_frame(bins, duration_s: float) -> pd.DataFrame:
    """The ``ack_delivery`` table of the channel's send-time bins of Acks."""
    full = bins.frame(duration_s)
    columns = [c for c in ACK_DELIVERY_SCHEMA if c != "delivery_ratio"]
    df = full[columns + [c for c in MAC_RECEPTION_DROPS if c in full]]
    df["delivery_ratio"] = delivery_ratio(df["received"], lost_on_the_way(df))
    return df


def ack_figures(frames: Mapping[str, pd.DataFrame]) -> dict:
    """Acks sent, received, lost, and the delivery ratio, from the ``acks`` table."""
    acks = frames["acks"]
    received, lost = int(acks["received"].sum()), int(lost_on_the_way(acks).sum())
    out = {
        "acks_sent": int(acks["sent"].sum()),
        "acks_received": received,
        "acks_dropped_loss": int(acks["dropped_loss"].sum()),
        "ack_delivery_ratio": received / (received + lost) if received + lost else math.nan,
    }
    for col in MAC_RECEPTION_DROPS:
        if col in acks:
            out[f"acks_{col}"] = int(acks[col].sum())
    return out


class Ack(NamedTuple):
    sender: int
    role: int
    leader: int
    seq: int
    x_m: float
    y_m: float
    group_size: int
    resign: bool
    # The fields packed for neighbour tables, then the ids the sender has heard within tau,
    # ascending (netsim.protocols.neighbours.NeighbourTable.announce): one array per Ack.
    record: np.ndarray

    @property
    def heard(self) -> np.ndarray:
        """The ids the sender has heard within tau, ascending."""
        return heard_in(self.record)


# listener(now, ack, receivers, hears_me)
AckListener = Callable[[float, Ack, np.ndarray, np.ndarray], None]


class Jitter:
    """The draws of ``U(-jitter_s, +jitter_s)`` from ``rng``, in the stream's order, drawn in
    blocks (one numpy call per 4,096 draws instead of one per Ack: the same numbers)."""

    BLOCK = 4096

    def __init__(self, rng: np.random.Generator, jitter_s: float):
        self.rng, self.jitter_s = rng, jitter_s
        self._draws: list[float] = []
        self._next = 0

    def draw(self) -> float:
        if self._next == len(self._draws):
            self._draws = self.rng.uniform(-self.jitter_s, self.jitter_s, self.BLOCK).tolist()
            self._next = 0
        self._next += 1
        return self._draws[self._next - 1]


class AckTiming:
    """The Ack timing a protocol declares (:class:`netsim.cosim.AckSchedule`), read from its
    :class:`AckParams` (``params``): for the Ack beacon and the stacks built on it."""

    params: AckParams

    @property
    def ack_period_s(self) -> float:
        """The Ack period (:class:`netsim.cosim.AckSchedule`)."""
        return self.params.ack_period_s

    @property
    def ack_jitter_s(self) -> float:
        """The most an Ack leaves after its period (:class:`netsim.cosim.AckSchedule`)."""
        return self.params.ack_jitter_s


class AckBeacon(AckTiming):
    """Ack beacons and neighbour tables of all robots; ``roles``: the roles and leaders the
    Acks announce (the clustering's; all undecided without it)."""

    def __init__(self, params: AckParams, parts: Parts, roles: Roles | None = None):
        n = parts.state.n
        self.params = params
        self.env, self.state, self.channel = parts.env, parts.state, parts.channel
        self.streams, self.trace = parts.streams, parts.trace
        self.duration_s = parts.duration_s
        # The interval of the ack_delivery table: the run's sampling interval.
        self.series_interval_s = parts.output.position_interval_s or params.ack_period_s
        self.roles = roles if roles is not None else Roles(n)
        self.period_s = params.ack_period_s
        self.table = NeighbourTable(n, params.tau_s)
        # What each robot sent in its last Ack: its sequence number, role and two-way degree
        # (columns of one array: the compiled Ack takes one argument for the three).
        self.sent = np.zeros((n, 3), dtype=np.int64)
        self.seq, self.role_sent, self.degree_sent = self.sent[:, 0], self.sent[:, 1], self.sent[:, 2]
        self.role_sent[:] = -1
        # Robots the protocol above counts as members of each robot's group (1: alone).
        self.group_size = np.ones(n, dtype=np.int64)
        # Leaders that announce they are giving up leadership set this for their next Ack.
        self.resign_pending = np.zeros(n, dtype=bool)
        self.listeners: list[AckListener] = []
        # Listeners told, before those, only of the Acks that announce a leader and of those
        # whose sender is marked (nonzero) in ``watched``: the clustering's (no other Ack
        # changes anything there; most Acks are neither, and cost no call).
        self.leader_listeners: list[AckListener] = []
        self.watched: list[int] = [0] * n
        # Set by a leader listener that can also take the Acks it is told of into the table
        # (the clustering): (that listener, taker), taker(now, ack, receivers, power_dbm) recording
        # such an Ack and acting on it in one compiled call, returning how many receivers
        # did not take it (stale). Used while that listener is the only one: then
        # table.receive and the listener's call are the same work, done in two calls.
        self.taker: tuple[AckListener, Callable[[float, Ack, np.ndarray, np.ndarray | None], int]] | None = None
        # Set by a protocol whose leaders announce their group's size (the clustering): whose
        # announced size is other than 1, and whether links are symmetric. The Ack sets the
        # size itself (netsim.protocols._kernels.make_sized_ack).
        self.sized: np.ndarray | None = None
        self.sized_symmetric = True
        self.phase_s = np.zeros(n)
        # What the compiled Ack reads of the robots' motion, of the beacon and of the roles
        # (netsim.protocols._kernels' Motion, Beacon and RoleArrays, as plain tuples): arrays
        # kept for the run, so put together once.
        st = parts.state
        self.motion = tuple(Motion(st.origin_m, st.velocity_mps, st.t0_s, st.torus, st.side_m))
        self._beacon = tuple(Beacon(self.sent, self.resign_pending, self.group_size))
        self._roles = tuple(RoleArrays(self.roles.role, self.roles.leader))
        # Receptions ignored because a newer Ack of the same sender had arrived first.
        self.stale_acks = 0

    def start(self, phase_s=None) -> None:
        """Start every robot's beacon; ``phase_s`` (one per robot) overrides the random phases."""
        p, n = self.params, self.state.n
        if phase_s is None:
            self.phase_s = self.streams.get("ack.phase").uniform(0.0, p.ack_period_s, n)
        else:
            self.phase_s = np.asarray(phase_s, dtype=float)
        self._jitter = Jitter(self.streams.get("ack.jitter"), p.ack_jitter_s) if p.ack_jitter_s > 0 else None
        # Robot i's beacon: first Ack at its phase, then one every period (plus jitter). A
        # chain of callbacks on the channel's agenda (netsim.agenda) rather than a process
        # per robot: the order of the same events, without a kernel event for each Ack.
        self._agenda = agenda = self.channel.agenda
        # As Python floats: the same instants, and the agenda's heap compares floats faster
        # than numpy scalars (every later tick and delivery time is a sum starting here).
        phases = self.phase_s.tolist()
        for i in range(n):
            agenda.at(phases[i], URGENT, self._tick, i)
        channel = self.channel
        channel.frame_bytes["ack"] = p.ack_bytes
        # Each receiver's power, for its table (none under the unit disk).
        channel.measure_power("ack")
        self.trace.add_frame("acks", lambda: channel.frame("ack"))
        bins = channel.bin_by_send_time("ack", self.series_interval_s)
        # Binned up to now: the tables end where the run is (netsim.run.collect).
        env = self.env
        self.trace.add_frame("ack_delivery", lambda: ack_delivery_frame(bins, env.now))

    def _tick(self, i: int) -> None:
        # Robot i's Ack, if it is on.
        if self.state.alive[i]:
            self.channel.broadcast(i, self.make_ack(i), self.deliver, "ack")
        jitter = self._jitter
        step = self.period_s + jitter.draw() if jitter is not None else self.period_s
        self._agenda.at(step, URGENT, self._tick, i)

    def make_ack(self, i: int) -> Ack:
        """Robot ``i``'s Ack now, in one compiled call (:func:`netsim.protocols._kernels.make_ack`,
        or :func:`~netsim.protocols._kernels.make_sized_ack` when leaders announce their
        group's size); the kernel returns the Ack's fields in order: made into an Ack with no
        unpacking."""
        now, table, sized = self.env.now, self.table, self.sized
        k = table.kernels
        if sized is None:
            return Ack._make(k.make_ack(i, now, self.motion, self._beacon, self._roles, table.view))
        return Ack._make(
            k.make_sized_ack(i, now, self.motion, self._beacon, self._roles, table.view, sized, self.sized_symmetric)
        )

    def deliver(self, sender: int, receivers: np.ndarray, ack: Ack, power_dbm: np.ndarray | None = None) -> None:
        """``ack`` arrives at ``receivers``, each at ``power_dbm`` (None: not measured)."""
        now = self.env.now
        tell_leader_listeners = self.leader_listeners and (ack.role == LEADER or self.watched[ack.sender])
        if not tell_leader_listeners and not self.listeners:
            # Nobody to tell (the Ack model alone; most Acks under the clustering): the table
            # is all there is to update.
            self.stale_acks += self.table.take(now, sender, receivers, ack.record, power_dbm)
            return
        taker = self.taker
        if tell_leader_listeners and taker is not None and self._taker_alone(taker[0]):
            self.stale_acks += taker[1](now, ack, receivers, power_dbm)
            return
        fresh, hears_me, stale = self.table.receive(now, sender, receivers, ack.record, power_dbm)
        if stale:
            self.stale_acks += stale
            receivers, hears_me = receivers[fresh], hears_me[fresh]
            if len(receivers) == 0:
                return
        if tell_leader_listeners:
            for listener in self.leader_listeners:
                listener(now, ack, receivers, hears_me)
        for listener in self.listeners:
            listener(now, ack, receivers, hears_me)

    def heard(self, now: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """What the neighbour tables hold now (:class:`netsim.cosim.NeighbourView`)."""
        return self.table.heard(now)

    def link_quality(self, now: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """The tables' live entries and their last power (:class:`netsim.cosim.LinkQualityView`)."""
        return self.table.link_quality(now)

    def _taker_alone(self, listener: AckListener) -> bool:
        """Whether ``listener`` (a taker's) is the only one."""
        leaders = self.leader_listeners
        return not self.listeners and len(leaders) == 1 and leaders[0] is listener

    def summary(self, frames: Mapping[str, pd.DataFrame], duration_s: float) -> dict:
        return {**ack_figures(frames), "acks_overtaken": int(self.stale_acks)}


def build(params: AckParams, parts: Parts) -> AckBeacon:
    """``protocol.model = "ack"``: beacons and neighbour tables alone (nobody takes a role)."""
    declare_roles(parts.trace)
    beacon = AckBeacon(params, parts)
    beacon.start()
    return beacon


PLUGIN = PluginSpec(
    Params=AckParams,
    build=build,
    check=check_tau,
    tables={"roles": ROLES_SCHEMA, "acks": ACKS_SCHEMA, "ack_delivery": ACK_DELIVERY_SCHEMA},
)
