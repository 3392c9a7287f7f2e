"""What the routing protocols share (docs/routing.md, "Routing protocols"): data packets
sent hop by hop as unicast frames, each holder asking the protocol for the next hop, every
reception kept (the ``hops`` table); the flows of ``traffic.flows`` carried that way;
control frames counted by kind.

A protocol subclasses :class:`Router` and implements :meth:`Router.next_hop` (and, if it
learns of broken links, :meth:`Router.link_failed`); it sends its control frames with
:meth:`Router.control`, which puts them on the channel as frames of their own kind and
size, so that they take airtime, collide and are lost like any other.
"""

from __future__ import annotations

from array import array
from collections.abc import Callable, Mapping
from dataclasses import dataclass
from typing import NamedTuple

import numpy as np
import pandas as pd
from netsim.protocols.ack import ACKS_SCHEMA
from netsim.protocols.flows import FLOWS_SCHEMA, PACKETS_SCHEMA, FlowTraffic, packet_delivery
from netsim.protocols.relay import HOPS_SCHEMA, shortest_paths_index
from netsim.protocols.roles import ROLES_SCHEMA, declare_roles

from netsim.events import MessageDelivered, MessageDropped
from netsim.params import Params, finite, non_negative, param, positive
from netsim.plugins import Parts
from netsim.topology import hop_distances
from netsim.traffic import Traffic, frame_count, refuse_frames

# The tables every routing protocol writes (the flows' when there are flows), and its
# control frames: per kind, the frames sent, their bytes, their receptions, and the
# protocol's messages they carried (one per frame but where a frame packs several: OLSR).
CONTROL_SCHEMA = {"kind": "object", "sent": "int64", "bytes_sent": "int64", "received": "int64", "messages": "int64"}
# The clustering's hops table, and the packet of packets.parquet each frame belongs to.
ROUTED_HOPS_SCHEMA = {**HOPS_SCHEMA, "flow": "int64", "packet": "int64"}
ROUTING_TABLES = {
    "roles": ROLES_SCHEMA,
    "acks": ACKS_SCHEMA,
    "flows": FLOWS_SCHEMA,
    "packets": PACKETS_SCHEMA,
    "hops": ROUTED_HOPS_SCHEMA,
    "control": CONTROL_SCHEMA,
}

Outcome = Callable[[int, bool, float, int, int, str], None]


@dataclass(frozen=True)
class RoutingParams(Params):
    """The keys of ``[protocol]`` every routing protocol has: the messages between random
    pairs, as the clustering's (its default rate is 0.2 /s; here none unless asked)."""

    section = "protocol"
    message_rate_hz: float = param(
        0.0, finite(non_negative), "messages sent per second, network-wide (random pairs)", schedules="run"
    )
    message_bytes: int = param(
        512, positive, "size of a random pair's message, bytes (over channel.max_frame_bytes: several frames)"
    )


def check_pairs(params: RoutingParams, config) -> None:
    """The random pairs' messages send at most :data:`MAX_FRAMES_PER_RUN` frames in the
    run, as the flows (:func:`netsim.traffic.check_flows`): a size mistyped by orders of
    magnitude is refused, not split into a list of frames no memory holds."""
    per_message = frame_count(params.message_bytes, config.channel.max_frame_bytes)
    # One message at least, however short the run: its frames are listed when it is sent.
    messages = max(params.message_rate_hz * config.duration_s, 1.0) if params.message_rate_hz > 0 else 0.0
    frames = messages * per_message
    refuse_frames(
        "protocol.message_bytes",
        params.message_bytes,
        frames,
        f"the random pairs' messages would send {frames:.3g} frames in the run ({per_message:,} a message, "
        f"channel.max_frame_bytes = {config.channel.max_frame_bytes})",
        ": lower it, or protocol.message_rate_hz",
    )


class Packet(NamedTuple):
    """A data packet (one frame of a flow's packet) on its way."""

    id: int
    src: int
    dst: int
    ttl: int  # hops it may still take
    hops: int  # hops taken so far
    kind: str  # the channel's kind of its frame (its size)
    t_sent_s: float
    dst_xy: tuple[float, float] | None = None  # where the destination was (geographic routing)
    to: int = -1  # the next hop it was last sent to
    t_tx_s: float = 0.0  # when it was last sent


class Router:
    """Data forwarding and bookkeeping of a routing protocol (module notes)."""

    def __init__(self, parts: Parts, ttl: int, pairs: RoutingParams | None = None):
        self.env, self.state, self.channel = parts.env, parts.state, parts.channel
        self.streams, self.trace = parts.streams, parts.trace
        self.events = parts.events
        self.ttl = ttl
        self._next_id = 0
        self._told: dict[int, Outcome] = {}
        # Per channel kind of control frame: its size and the kind it counts as (frames of
        # one kind whose size varies, an OLSR HELLO, are channel kinds of their own).
        self.control_bytes: dict[str, int] = {}
        self.control_label: dict[str, str] = {}
        self.control_sent: dict[str, int] = {}
        self.control_received: dict[str, int] = {}
        self.control_messages: dict[str, int] = {}
        self.data_transmissions = 0
        # Per reception of a data frame by its next hop: the frame's id, the hops it took
        # with this one, sender, receiver, when sent and when received (the hops table).
        self._hops: tuple[list, ...] = tuple([] for _ in HOPS_SCHEMA)
        # Per data frame sent (frame ids count from 0), the shortest path's hops from its source to its destination
        # when it was sent, on the true topology (a unit disk's, or the disks of a radio's
        # implied range, as the clustering's backbone measures them); the last search's
        # time, jumps (a robot set down elsewhere at that instant changes the paths) and
        # ends, and its hops, which a packet's other frames reuse.
        self._shortest = array("d")
        self._index = shortest_paths_index(self.channel, self.state)
        self._searched: tuple[float, int, int, int] = (np.nan, -1, -1, -1)
        self._searched_hops = np.inf
        self.flows = None
        self.pairs = pairs if pairs is not None and pairs.message_rate_hz > 0 else None
        traffic = parts.traffic
        if traffic is None and self.pairs is not None:
            traffic = Traffic((), parts.max_frame_bytes)
        if traffic is not None:
            self.flows = FlowTraffic(traffic, self.env, self.channel.frame_bytes, self.send, self._shortest.__getitem__)
        declare_roles(parts.trace)
        channel = self.channel
        self.trace.add_frame("acks", lambda: channel.frame("ack"))
        self.trace.add_frame("control", self.control_frame)
        self.duration_s = float(parts.duration_s)

    def start(self) -> None:
        """Start the flows and the random pairs' messages (the protocol starts its own
        control traffic)."""
        if self.flows is not None:
            self.flows.start(self.duration_s)
            if self.pairs is not None:
                pairs = self.pairs
                rng = self.streams.get("traffic")
                self.flows.start_pairs(self.state.n, pairs.message_rate_hz, pairs.message_bytes, rng)
            self.trace.add_frame("packets", self.flows.packets_frame)
            self.trace.add_frame("flows", self.flows.flows_frame)
            self.trace.add_frame("hops", self.hops_frame)

    # -- what a protocol implements ----------------------------------------------------
    def next_hop(self, holder: int, pkt: Packet) -> tuple[int, str]:
        """The neighbour ``holder`` sends ``pkt`` to, or ``(-1, cause)``: dropped here."""
        raise NotImplementedError

    def link_failed(self, holder: int, nxt: int, pkt: Packet) -> None:
        """The frame ``holder`` sent ``nxt`` did not get through (link-layer detection)."""

    # -- data ---------------------------------------------------------------------------
    def send(self, src: int, dst: int, kind: str, on_outcome: Outcome) -> int:
        """A data packet (frame of ``kind``) from ``src`` to ``dst`` now (FlowTraffic's send)."""
        mid = self._next_id
        self._next_id += 1
        self._told[mid] = on_outcome
        if kind not in self.channel.notify_empty:
            self.channel.notify_empty.add(kind)  # under a medium, a unicast nobody got is told
        now = self.env.now
        searched = (now, self.state.jumps, src, dst)
        if self._searched != searched:
            hops = hop_distances(self.state, now, src, index=self._index, target=dst)
            self._searched, self._searched_hops = searched, float(hops[dst])
        self._shortest.append(self._searched_hops)
        pkt = Packet(mid, src, dst, self.ttl, 0, kind, now, self.destination_xy(dst))
        self.originate(src, pkt)
        return mid

    def destination_xy(self, dst: int) -> tuple[float, float] | None:
        """What the source puts in a packet of where its destination is (None: nothing)."""
        return None

    def originate(self, src: int, pkt: Packet) -> None:
        """A packet leaves its source (a protocol that must first find a route overrides)."""
        self.forward(src, pkt)

    def forward(self, holder: int, pkt: Packet) -> None:
        """``holder`` has ``pkt`` (not its destination): send it on, or drop it here."""
        if pkt.ttl <= 0:
            self.dropped(pkt, holder, "ttl")
            return
        nxt, cause = self.next_hop(holder, pkt)
        if nxt < 0:
            self.dropped(pkt, holder, cause)
            return
        self.data_transmissions += 1
        pkt = pkt._replace(to=nxt, t_tx_s=self.env.now)
        if not self.channel.unicast(holder, nxt, pkt, self._on_data, kind=pkt.kind) and not self.channel.deferred:
            # Under a medium the frame's notice says it did not get through (_on_data), once.
            self.link_failed(holder, nxt, pkt)
            self.dropped(pkt, holder, "lost")

    def _on_data(self, sender: int, receivers: np.ndarray, pkt: Packet) -> None:
        if not len(receivers):
            # A shared medium: the frame did not get through to its next hop.
            self.link_failed(sender, pkt.to, pkt)
            self.dropped(pkt, sender, "lost")
            return
        holder = int(receivers[0])
        pkt = pkt._replace(ttl=pkt.ttl - 1, hops=pkt.hops + 1)
        for column, value in zip(self._hops, (pkt.id, pkt.hops, sender, holder, pkt.t_tx_s, self.env.now)):
            column.append(value)
        if holder == pkt.dst:
            told = self._told.pop(pkt.id, None)
            if told is not None:
                now = self.env.now
                told(pkt.id, True, now, pkt.hops, -1, "")
                if self.events is not None and self.events.wants("message_delivered"):
                    delivered = MessageDelivered(now, pkt.id, pkt.src, pkt.dst, pkt.hops, now - pkt.t_sent_s)
                    self.events.emit("message_delivered", delivered)
        else:
            self.forward(holder, pkt)

    def dropped(self, pkt: Packet, robot: int, cause: str) -> None:
        """``pkt`` is lost at ``robot`` for ``cause``."""
        told = self._told.pop(pkt.id, None)
        if told is not None:
            now = self.env.now
            told(pkt.id, False, now, pkt.hops, robot, cause)
            if self.events is not None and self.events.wants("message_dropped"):
                self.events.emit("message_dropped", MessageDropped(now, pkt.id, pkt.src, pkt.dst, pkt.hops, cause))

    def hops_frame(self) -> pd.DataFrame:
        """Every reception of a data frame by the next hop it was sent to, in order of
        reception (ROUTED_HOPS_SCHEMA): the clustering's hops table (``msg_id`` the frame's,
        as in the message events; ``hop`` the transmissions up to and including this one),
        with the ``flow`` and ``packet`` of packets.parquet it carries a frame of."""
        assert self.flows is not None  # the table is written with the packets' only
        flow, packet = self.flows.packet_of(np.array(self._hops[0], dtype=np.int64))
        columns = dict(zip(HOPS_SCHEMA, self._hops))
        return pd.DataFrame({**columns, "flow": flow, "packet": packet}).astype(ROUTED_HOPS_SCHEMA)

    # -- control ------------------------------------------------------------------------
    def control_kind(self, kind: str, nbytes: int, label: str = "") -> None:
        """Declare a kind of control frame, its size (bytes), and the kind it is counted as
        in the ``control`` table (``label``; default the kind itself)."""
        self.control_bytes[kind] = nbytes
        self.control_label[kind] = label or kind
        self.channel.frame_bytes[kind] = nbytes
        self.control_sent.setdefault(kind, 0)
        self.control_received.setdefault(kind, 0)
        self.control_messages.setdefault(kind, 0)

    def control(
        self, sender: int, payload: object, deliver: Callable, kind: str, dest: int = -1, messages: int = 1
    ) -> None:
        """Send a control frame of ``kind`` (a broadcast, or a unicast to ``dest``) carrying
        ``messages`` of the protocol's messages."""
        self.control_sent[kind] += 1
        self.control_messages[kind] += messages
        if dest < 0:
            self.channel.broadcast(sender, payload, self._counted(deliver, kind), kind=kind)
        else:
            self.channel.unicast(sender, dest, payload, self._counted(deliver, kind), kind=kind)

    def _counted(self, deliver: Callable, kind: str) -> Callable:
        received = self.control_received

        def counted(sender: int, receivers: np.ndarray, payload: object, *rest) -> None:
            received[kind] += len(receivers)
            if len(receivers):
                deliver(sender, receivers, payload)

        return counted

    def control_frame(self) -> pd.DataFrame:
        """Per kind of control frame: the frames sent, their bytes, their receptions and the
        messages they carried."""
        rows: dict[str, list[int]] = {}
        for k, label in self.control_label.items():
            row = rows.setdefault(label, [0, 0, 0, 0])
            row[0] += self.control_sent[k]
            row[1] += self.control_sent[k] * self.control_bytes[k]
            row[2] += self.control_received[k]
            row[3] += self.control_messages[k]
        labels = sorted(rows)
        return pd.DataFrame(
            {
                "kind": labels,
                "sent": [rows[k][0] for k in labels],
                "bytes_sent": [rows[k][1] for k in labels],
                "received": [rows[k][2] for k in labels],
                "messages": [rows[k][3] for k in labels],
            }
        ).astype(CONTROL_SCHEMA)

    def summary(self, frames: Mapping[str, pd.DataFrame], duration_s: float) -> dict:
        """Control overhead, and the flows' delivery."""
        sent = sum(self.control_sent.values())
        messages = sum(self.control_messages.values())
        out = {
            "control_frames": sent,
            "control_frames_per_s": sent / duration_s if duration_s else float("nan"),
            "control_messages": messages,
            "control_messages_per_s": messages / duration_s if duration_s else float("nan"),
            "data_transmissions": self.data_transmissions,
        }
        out.update(packet_delivery(frames))
        return out
