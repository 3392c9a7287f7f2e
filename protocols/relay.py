"""Multi-hop messages between any two robots (docs/model.md section 4.3).

``backbone`` (default): the source broadcasts the message; every leader and gateway that
receives it for the first time rebroadcasts it once, with the TTL decreased; ordinary
members only listen. Leaders and gateways alone do not always connect: two groups may
touch only through two of their members, neither of which hears the other's leader. With
``protocol.distributed_gateways`` (the default) such members relay too, so that on a
connected, static, loss-free network every message arrives; set it to false for the
strict leaders-and-gateways backbone. ``oracle``: the message goes hop by hop along a shortest path of
the true topology, recomputed by each holder at the moment it forwards (a baseline no
real robot could run). Either way each message records whether it arrived, after how
many hops and how long, and how many transmissions it cost in all, and every reception
of every transmission is kept (:meth:`Relay.hops_frame`, the ``hops`` table).
"""

from __future__ import annotations

from collections.abc import Callable
from enum import StrEnum
from typing import NamedTuple

import numpy as np
import pandas as pd
import simpy
from netsim.protocols._kernels import RoleArrays

from netsim.compiled import load
from netsim.cosim import Arrival
from netsim.events import MessageDelivered, MessageDropped
from netsim.plugins import Parts
from netsim.radio.spatial import RangeIndex
from netsim.rng import Streams
from netsim.scheduling import LAST, scheduled_event
from netsim.topology import hop_distances


class Routing(StrEnum):
    """How relayed messages travel."""

    BACKBONE = "backbone"  # flooding over leaders and gateways
    ORACLE = "oracle"  # shortest paths on the true topology


class Message(NamedTuple):
    id: int
    src: int
    dst: int
    ttl: int
    hops: int  # transmissions on the path so far, including the one that carries it
    t_tx_s: float = 0.0  # when the transmission that carries it was sent


HOP_COLUMNS = ["msg_id", "hop", "sender", "receiver", "t_sent_s", "t_received_s"]
HOPS_SCHEMA = {c: ("float64" if c.startswith("t_") else "int64") for c in HOP_COLUMNS}
MESSAGES_SCHEMA = {
    "msg_id": "int64",
    "src": "int64",
    "dst": "int64",
    "routing": "object",
    "t_sent_s": "float64",
    "delivered": "bool",
    "t_delivered_s": "float64",
    "hops": "int64",
    "latency_s": "float64",
    "transmissions": "int64",
    "shortest_hops": "float64",
}


class Outcome(NamedTuple):
    msg_id: int
    src: int
    dst: int
    routing: str
    t_sent_s: float
    delivered: bool
    t_delivered_s: float
    hops: int
    latency_s: float
    transmissions: int
    shortest_hops: float  # on the true topology at send time (inf: no path)


def shortest_paths_index(channel, state) -> RangeIndex:
    """The range index a protocol's searches for shortest paths on the true topology use
    (:func:`netsim.topology.hop_distances`): the channel's, whose lists hold every robot a
    sender reaches, or, under a radio, one over the disks of its implied range, rebuilt only
    as the robots move (a list of the pairs in range built for each search costs a run
    more than the searches)."""
    return channel.reach_lists or RangeIndex(state)


class Relay:
    """Sends messages and keeps their outcomes. ``params`` holds ``routing``,
    ``message_ttl`` and ``distributed_gateways`` (the clustering protocol's parameters)."""

    def __init__(self, params, parts: Parts, clustering):
        self.env, self.state, self.channel = parts.env, parts.state, parts.channel
        self.clustering = clustering
        self.roles = clustering.roles
        self.routing = Routing(params.routing)
        self.ttl = params.message_ttl
        self.distributed_gateways = params.distributed_gateways
        self._outcomes: dict[int, dict] = {}
        # Per message whose flood is under way, which robots have had it (a flag each).
        self._seen: dict[int, np.ndarray] = {}
        self._next_id = 0
        # Per message: arrivals still to come (its copies in flight), and whether a copy was
        # stopped by the hop limit (for the cause of a drop).
        self._pending: dict[int, int] = {}
        self._ttl_cut: set[int] = set()
        self.events = parts.events
        # Under a shared medium a flood ends when its last frame ends, received or not.
        self.channel.notify_empty.add("data")
        # Per message, what the medium lost of its frames (receptions, or frames for
        # queue_full and retry_limit), by cause.
        self.medium_losses: dict[int, dict[str, int]] = {}
        if self.channel.deferred:
            self.channel.medium_losses["data"] = self._medium_loss
        # One entry per delivery event in each column: msg_id, hop, sender, t_sent_s,
        # t_received_s, and the receivers (an array). Columns, not a tuple per delivery: the
        # table is built from them at once, and a run's 10^5 deliveries leave no records
        # for the garbage collector to walk again and again.
        self._hops: tuple[list, list, list, list, list, list] = ([], [], [], [], [], [])
        # Who relays a flooded message (netsim.protocols._kernels.flood_step: leaders and
        # gateways), loaded for the run's size.
        self.kernels = load("netsim.protocols._kernels", parts.state.n)
        self._roles = tuple(RoleArrays(self.roles.role, self.roles.leader))
        # The range index whose neighbour lists the searches for shortest paths use: the
        # channel's on a unit disk, else one of the implied range's disks (a radio decides
        # its links otherwise).
        self._index = shortest_paths_index(self.channel, parts.state)
        # Under a radio the oracle routes on the links as the channel decides them, tracked
        # during the run (links.parquet's), and measures the shortest paths on them. The
        # other routings measure them on the implied range's disks: tracking a radio's links
        # during the run costs a walled run more than the run itself.
        oracle_on_a_radio = self.routing is Routing.ORACLE and self.channel.reach_lists is None
        self._live = parts.links() if oracle_on_a_radio and parts.links is not None else None
        # Messages sent from outside (sim.send): what each carries until it arrives, and
        # what has arrived at each robot.
        self._payloads: dict[int, object] = {}
        self._inboxes: dict[int, list[Arrival]] = {}
        # Messages sent as frames of another kind than "data" (a flow's, sized apart), and
        # those whose sender is told their fate: on_outcome(msg_id, delivered, now, hops,
        # robot, cause), robot and cause saying where and why a message was dropped.
        self._kinds: dict[int, str] = {}
        self._watched: dict[int, Callable[[int, bool, float, int, int, str], None]] = {}

    def inbox(self, robot: int) -> list[Arrival]:
        """The messages sent with a payload that have reached ``robot``, in order of arrival."""
        return list(self._inboxes.get(robot, ()))

    def send(
        self,
        src: int,
        dst: int,
        payload: object = None,
        carried: bool = False,
        kind: str = "data",
        on_outcome: Callable[[int, bool, float, int, int, str], None] | None = None,
    ) -> int:
        """Send a message from ``src`` to ``dst`` now; returns its id. A message from
        outside (``carried``, or any ``payload``) is kept in ``dst``'s inbox when it arrives.
        ``kind``: the frames' kind (its size: ``channel.frame_bytes``); ``on_outcome`` is
        called once, when the message is delivered or can no longer be."""
        st, now = self.state, self.env.now
        if not (0 <= src < st.n and 0 <= dst < st.n) or src == dst:
            raise ValueError(f"need two different robots in [0, {st.n}), got src={src}, dst={dst}")
        mid = self._next_id
        self._next_id += 1
        self._outcomes[mid] = {
            "msg_id": mid,
            "src": src,
            "dst": dst,
            "routing": str(self.routing),
            "t_sent_s": now,
            "delivered": False,
            "t_delivered_s": np.nan,
            "hops": 0,
            "latency_s": np.nan,
            "transmissions": 0,
            "shortest_hops": float(self._hops_from(src, target=dst)[dst]),
        }
        self._pending[mid] = 0
        if carried or payload is not None:
            self._payloads[mid] = payload
        if kind != "data":
            self._kinds[mid] = kind
            if kind not in self.channel.notify_empty:
                self.channel.notify_empty.add(kind)
                if self.channel.deferred:
                    self.channel.medium_losses[kind] = self._medium_loss
        if on_outcome is not None:
            self._watched[mid] = on_outcome
        msg = Message(mid, src, dst, self.ttl, 1, now)
        if self.routing is Routing.ORACLE and not self._links_solved():
            # Sent at t = 0, before the channel's links are first solved (after everything
            # else due then): routed, and its shortest path measured, once they are.
            scheduled_event(self.env, 0.0, LAST, lambda _event: self._first_oracle_hop(src, msg))
        elif self.routing is Routing.ORACLE:
            self._forward_oracle(src, msg)
        else:
            seen = self._seen[mid] = np.zeros(st.n, dtype=bool)
            seen[src] = True
            self._broadcast(src, msg)
            if self._pending[mid] == 0:
                # Nobody received the source's broadcast: a flood that ended, held by no one robot.
                self._dropped(msg, now, "died_out")
                del self._seen[mid]
        return mid

    # -- backbone flooding -------------------------------------------------------------
    def _broadcast(self, sender: int, msg: Message) -> None:
        self._outcomes[msg.id]["transmissions"] += 1
        got = self.channel.broadcast(sender, msg, self._on_flood, kind=self._kinds.get(msg.id, "data"))
        self._pending[msg.id] += self._arrivals(len(got))

    def _arrivals(self, receivers: int) -> int:
        """Delivery callbacks a transmission received by ``receivers`` robots makes: one, or
        one per receiver when the latency has jitter (channel.py)."""
        if self.channel.deferred:
            return 1  # a shared medium: one delivery per frame, at its end (maybe to nobody)
        if receivers == 0:
            return 0
        return receivers if self.channel.latency_jitter_s > 0 else 1

    def _on_flood(self, sender: int, receivers: np.ndarray, msg: Message) -> None:
        now = self.env.now
        mid = msg.id
        self._pending[mid] -= 1
        self._hop(msg, sender, now, receivers)
        seen = self._seen[mid]
        had_dst = seen[msg.dst]
        cl = self.clustering
        fresh, relaying = self.kernels.flood_step(
            seen, receivers, cl.table.view, now, cl.symmetric, self._roles, self.distributed_gateways
        )
        if not had_dst and seen[msg.dst]:
            self._delivered(msg, now)
        if msg.ttl <= 1:
            if len(fresh):
                self._ttl_cut.add(mid)
        elif len(fresh):
            # Relayed now, by every robot that relays it.
            nxt = Message(mid, msg.src, msg.dst, msg.ttl - 1, msg.hops + 1, now)
            for r in relaying.tolist():
                if r != msg.dst:
                    self._broadcast(r, nxt)
        if self._pending[mid] == 0:
            self._dropped(msg, now, "ttl" if mid in self._ttl_cut else "died_out")
            del self._seen[mid]  # the flood is over: no copy of it is in flight

    def _links_solved(self) -> bool:
        """Whether the links the oracle routes on are known now (always on a unit disk)."""
        return self._live is None or self._live.started

    def _first_oracle_hop(self, src: int, msg: Message) -> None:
        self._outcomes[msg.id]["shortest_hops"] = float(self._hops_from(src, target=msg.dst)[msg.dst])
        self._forward_oracle(src, msg)

    def shortest_hops(self, msg_id: int) -> float:
        """The message's ``shortest_hops`` (messages.parquet's)."""
        return self._outcomes[msg_id]["shortest_hops"]

    def _hops_from(self, node: int, towards: bool = False, links=None, target: int = -1) -> np.ndarray:
        """:func:`hop_distances` now, over the channel's links (``links``: the tracked links
        up now, if already read); ``target``: the one robot whose hops are wanted."""
        if links is None and self._live is not None:
            links = self._live.up_pairs()
        return hop_distances(self.state, self.env.now, node, towards, self._index, links, target)

    # -- oracle shortest path ----------------------------------------------------------
    def _forward_oracle(self, holder: int, msg: Message) -> None:
        now = self.env.now
        if self._live is None:
            to_dst = self._hops_from(msg.dst, towards=True)
            nbrs, _ = self.channel.in_range(holder)
        else:
            # The next hop from the very links the distances are measured on: asking the
            # channel would draw its shadowing afresh and offer links the table has down.
            a, b = links = self._live.up_pairs()
            to_dst = self._hops_from(msg.dst, towards=True, links=links)
            nbrs = np.unique(np.concatenate((b[a == holder], a[b == holder])))
        if len(nbrs) == 0 or not np.isfinite(to_dst[nbrs]).any():
            self._dropped(msg, now, "no_route", holder)  # no route now: the message is lost
            return
        # The next hop: the neighbour fewest hops from the destination (lowest id on ties).
        nxt = int(nbrs[int(np.argmin(to_dst[nbrs]))])
        self._outcomes[msg.id]["transmissions"] += 1
        kind = self._kinds.get(msg.id, "data")
        sent = self.channel.unicast(holder, nxt, msg._replace(t_tx_s=now), self._on_oracle, kind=kind)
        # A medium tells a frame it could not queue through _on_oracle, with no receiver.
        if not sent and not self.channel.deferred:
            self._dropped(msg, now, "lost", holder)

    def _on_oracle(self, sender: int, receivers: np.ndarray, msg: Message) -> None:
        if not len(receivers):
            self._dropped(msg, self.env.now, "lost", sender)  # a shared medium: the frame did not get through
            return
        self._hop(msg, sender, self.env.now, receivers)
        holder = int(receivers[0])
        if holder == msg.dst:
            self._delivered(msg, self.env.now)
        elif msg.ttl > 1:
            self._forward_oracle(holder, msg._replace(ttl=msg.ttl - 1, hops=msg.hops + 1))
        else:
            self._dropped(msg, self.env.now, "ttl", holder)

    def _hop(self, msg: Message, sender: int, now: float, receivers: np.ndarray) -> None:
        ids, hops, senders, sent, received, recv = self._hops
        ids.append(msg.id)
        hops.append(msg.hops)
        senders.append(sender)
        sent.append(msg.t_tx_s)
        received.append(now)
        recv.append(receivers)

    def _delivered(self, msg: Message, now: float) -> None:
        out = self._outcomes[msg.id]
        if not out["delivered"]:
            out.update(delivered=True, t_delivered_s=now, hops=msg.hops, latency_s=now - out["t_sent_s"])
            if msg.id in self._payloads:
                arrival = Arrival(now, msg.src, self._payloads.pop(msg.id), msg.id)
                self._inboxes.setdefault(msg.dst, []).append(arrival)
            told = self._watched.pop(msg.id, None)
            if told is not None:
                told(msg.id, True, now, msg.hops, -1, "")
            ev = self.events
            if ev is not None and ev.wants("message_delivered"):
                ev.emit(
                    "message_delivered", MessageDelivered(now, msg.id, msg.src, msg.dst, msg.hops, out["latency_s"])
                )

    def _dropped(self, msg: Message, now: float, cause: str, at: int = -1) -> None:
        """No copy of ``msg`` can reach its destination any more (never called once
        delivered); ``at``: the robot that held it last (-1: a flood, held by many)."""
        if self._outcomes[msg.id]["delivered"]:
            return
        self._payloads.pop(msg.id, None)
        told = self._watched.pop(msg.id, None)
        if told is not None:
            told(msg.id, False, now, msg.hops, at, cause)
        ev = self.events
        if ev is not None and ev.wants("message_dropped"):
            ev.emit("message_dropped", MessageDropped(now, msg.id, msg.src, msg.dst, msg.hops, cause))

    def _medium_loss(self, msg: object, cause: str, count: int) -> None:
        assert isinstance(msg, Message)
        losses = self.medium_losses.setdefault(msg.id, {})
        losses[cause] = losses.get(cause, 0) + count

    def outcomes(self) -> list[Outcome]:
        return [Outcome(**o) for o in self._outcomes.values()]

    def hops_frame(self) -> pd.DataFrame:
        """Every reception of every transmission of every message, in order of reception:
        ``msg_id, hop, sender, receiver, t_sent_s, t_received_s``; ``hop`` counts the
        transmissions on the path up to and including this one (1: from the source).
        Receptions the channel dropped are not there; repeats (a robot hearing a message it
        already has) are."""
        ids, hops, senders, sent, received, recv = self._hops
        if not ids:
            return pd.DataFrame({c: np.empty(0, np.float64 if c.startswith("t_") else np.int64) for c in HOP_COLUMNS})
        sizes = np.fromiter(map(len, recv), dtype=np.int64, count=len(recv))
        return pd.DataFrame(
            {
                "msg_id": np.repeat(np.array(ids, dtype=np.int64), sizes),
                "hop": np.repeat(np.array(hops, dtype=np.int64), sizes),
                "sender": np.repeat(np.array(senders, dtype=np.int64), sizes),
                "receiver": np.concatenate(recv).astype(np.int64),
                "t_sent_s": np.repeat(np.array(sent, dtype=float), sizes),
                "t_received_s": np.repeat(np.array(received, dtype=float), sizes),
            },
            copy=False,  # new arrays, the table's own
        )


def traffic(env: simpy.Environment, streams: Streams, n: int, relay: Relay, rate_hz: float):
    """Messages between uniformly random pairs of the ``n`` robots, as a Poisson process of
    ``rate_hz``.

    A team of one robot has no pair to send to: it sends nothing (and draws nothing)."""
    rng = streams.get("traffic")
    if n < 2:
        return
    while True:
        yield env.timeout(rng.exponential(1.0 / rate_hz))
        src = int(rng.integers(n))
        dst = int(rng.integers(n - 1))
        relay.send(src, dst + (dst >= src))
