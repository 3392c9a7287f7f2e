"""``protocol.model = "olsr"``: Optimized Link State Routing, RFC 3626 (docs/routing.md, "olsr").

Every robot broadcasts a HELLO every HELLO_INTERVAL listing the neighbours it hears, which
of them are symmetric, and which it chose as multipoint relays (MPRs); from them each
robot knows its symmetric neighbours and its two-hop neighbours, and selects MPRs that
cover every two-hop neighbour (:func:`select_mprs`, section 8.3.1). A robot that some
neighbours chose as MPR (its MPR selectors) floods a topology control message (TC) every
TC_INTERVAL advertising them; a TC is considered for forwarding once, at its first copy,
and retransmitted only by the MPRs of the robot it came from (MPR flooding, section 3.4).
The routing table is the shortest paths over the symmetric links, the two-hop links and
the advertised links (section 10). No HNA or MID messages (one interface per robot),
every robot of WILL_DEFAULT willingness.

A packet carries one or more messages (section 3.4): every message a robot generates or
retransmits waits in its queue a jitter of up to MAXJITTER (section 18.3), and the
messages queued meanwhile leave together, packed into as few frames as
``channel.max_frame_bytes`` allows (:func:`pack`), so that a HELLO and a TC, or TCs
forwarded together, cost one frame and one medium access.
"""

from __future__ import annotations

from collections import deque
from dataclasses import dataclass
from typing import NamedTuple

import numpy as np
from netsim.protocols.routing import ROUTING_TABLES, Packet, Router, RoutingParams, check_pairs

from netsim.errors import ConfigError
from netsim.params import finite, non_negative, param, positive, ttl_field
from netsim.plugins import Parts, PluginSpec
from netsim.scheduling import URGENT

# Sizes (RFC 3626 section 3.3 and 6.1, 9.1), bytes: packet header, message header, the
# HELLO's and TC's own headers, a link code's header, an address (IPv4).
PACKET_HEADER_BYTES = 4
MESSAGE_HEADER_BYTES = 12
HELLO_HEADER_BYTES = 4
LINK_CODE_HEADER_BYTES = 4
TC_HEADER_BYTES = 4
ADDRESS_BYTES = 4


@dataclass(frozen=True)
class OlsrParams(RoutingParams):
    """OLSR's keys of ``[protocol]``, with RFC 3626's defaults (section 18)."""

    section = "protocol"
    hello_interval_s: float = param(2.0, finite(positive), "HELLO_INTERVAL, s", schedules="robot")
    tc_interval_s: float = param(5.0, finite(positive), "TC_INTERVAL, s", schedules="robot")
    neighb_hold_time_s: float = param(
        None, positive, "NEIGHB_HOLD_TIME, s", kind=float, derive=lambda p: 3.0 * p.hello_interval_s, rule="3 x hello"
    )
    top_hold_time_s: float = param(
        None, positive, "TOP_HOLD_TIME, s", kind=float, derive=lambda p: 3.0 * p.tc_interval_s, rule="3 x tc"
    )
    dup_hold_time_s: float = param(30.0, finite(positive), "DUP_HOLD_TIME: a message is remembered this long, s")
    ttl: int = param(255, ttl_field, "TTL of a TC and hops a data packet may take")
    start_spread_s: float = param(
        None,
        finite(non_negative),
        "each robot starts its HELLO and TC timers at U(0, spread) (0: all at t = 0, as ns-3's nodes), s",
        kind=float,
        derive=lambda p: p.hello_interval_s,
        rule="hello_interval_s",
    )

    def check(self) -> None:
        if not self.neighb_hold_time_s > self.hello_interval_s:
            raise ConfigError(
                "protocol.neighb_hold_time_s",
                self.neighb_hold_time_s,
                f"must be greater than protocol.hello_interval_s = {self.hello_interval_s}",
            )
        if not self.top_hold_time_s > self.tc_interval_s:
            raise ConfigError(
                "protocol.top_hold_time_s",
                self.top_hold_time_s,
                f"must be greater than protocol.tc_interval_s = {self.tc_interval_s}",
            )


def select_mprs(two_hop_via: dict[int, set[int]], two_hop: set[int]) -> set[int]:
    """The MPR heuristic of RFC 3626 section 8.3.1: ``two_hop_via[n]`` is the set of two-hop
    neighbours symmetric neighbour ``n`` reaches; ``two_hop`` the set to cover (N2). First
    every neighbour that alone reaches some two-hop neighbour, then, while some are not
    covered, the neighbour that covers most of them (ties: the one that reaches most of N2,
    then the lowest id). The MPRs cover every two-hop neighbour a neighbour reaches."""
    mprs: set[int] = set()
    reach = {n: s & two_hop for n, s in two_hop_via.items()}
    for t in two_hop:
        via = [n for n, s in reach.items() if t in s]
        if len(via) == 1:
            mprs.add(via[0])
    covered = set().union(*(reach[m] for m in mprs)) if mprs else set()
    uncovered = two_hop - covered
    while uncovered:
        best = min(reach, key=lambda n: (-len(reach[n] & uncovered), -len(reach[n]), n))
        if not reach[best] & uncovered:
            break  # the rest is reached by no neighbour
        mprs.add(best)
        uncovered -= reach[best]
    return mprs


class Hello(NamedTuple):
    sender: int
    heard: frozenset[int]  # every neighbour it hears (asymmetric or symmetric)
    symmetric: frozenset[int]
    mprs: frozenset[int]


class Tc(NamedTuple):
    orig: int
    ansn: int
    advertised: frozenset[int]  # the originator's MPR selectors
    ttl: int
    hops: int


def hello_bytes(hello: Hello) -> int:
    """A HELLO message's size: headers, then per link code (asymmetric, symmetric, MPR) its
    header and its addresses."""
    asym = hello.heard - hello.symmetric
    groups = [asym, hello.symmetric - hello.mprs, hello.mprs]
    body = sum(LINK_CODE_HEADER_BYTES + ADDRESS_BYTES * len(g) for g in groups if g)
    return MESSAGE_HEADER_BYTES + HELLO_HEADER_BYTES + body


def tc_bytes(count: int) -> int:
    """A TC message's size advertising ``count`` neighbours."""
    return MESSAGE_HEADER_BYTES + TC_HEADER_BYTES + ADDRESS_BYTES * count


def message_bytes(message: Hello | Tc) -> int:
    """A message's size, its headers included."""
    return hello_bytes(message) if isinstance(message, Hello) else tc_bytes(len(message.advertised))


def pack(messages: list, max_frame_bytes: int) -> list[tuple[tuple, int]]:
    """The packets ``messages`` leave in, in their order: ``(messages, bytes)``, each the
    packet header and as many messages as fit in ``max_frame_bytes``; a message too large
    to share a frame with another (a HELLO listing hundreds of neighbours) goes alone."""
    packets: list[tuple[tuple, int]] = []
    batch: list = []
    size = PACKET_HEADER_BYTES
    for m in messages:
        nbytes = message_bytes(m)
        if batch and size + nbytes > max_frame_bytes:
            packets.append((tuple(batch), size))
            batch, size = [], PACKET_HEADER_BYTES
        batch.append(m)
        size += nbytes
    if batch:
        packets.append((tuple(batch), size))
    return packets


class Olsr(Router):
    """OLSR at every robot (module notes)."""

    def __init__(self, params: OlsrParams, parts: Parts):
        super().__init__(parts, params.ttl, params)
        self.params = params
        n = self.state.n
        # Robot i's link set: neighbour -> (when last heard, until when symmetric).
        self.heard_until: list[dict[int, float]] = [{} for _ in range(n)]
        self.sym_until: list[dict[int, float]] = [{} for _ in range(n)]
        # Two-hop set: symmetric neighbour -> (its symmetric neighbours, until when).
        self.two_hop: list[dict[int, tuple[frozenset[int], float]]] = [{} for _ in range(n)]
        self.mprs: list[set[int]] = [set() for _ in range(n)]
        # MPR selectors: neighbour -> until when.
        self.selectors: list[dict[int, float]] = [{} for _ in range(n)]
        # Topology set: originator -> (ANSN, advertised, until when).
        self.topology: list[dict[int, tuple[int, frozenset[int], float]]] = [{} for _ in range(n)]
        # Messages seen: (originator, ANSN) -> (until when, whether retransmitted).
        self.duplicates: list[dict[tuple[int, int], tuple[float, bool]]] = [{} for _ in range(n)]
        self.ansn = [0] * n
        # Each robot's routing table, when it was computed (None: to compute again).
        self._routes: list[dict[int, int] | None] = [None] * n
        self._routes_at = [-1.0] * n
        self._rng = self.streams.get("olsr.jitter")
        # Each robot's messages waiting to leave, and whether their departure is scheduled.
        self.queued: list[list[Hello | Tc]] = [[] for _ in range(n)]
        self._leaving = [False] * n
        self.max_frame_bytes = int(parts.max_frame_bytes)

    def start(self) -> None:
        super().start()
        p, n = self.params, self.state.n
        agenda = self.channel.agenda
        # Each robot starts its HELLO and TC timers together, at a time of its own.
        phase = self.streams.get("olsr.phase").uniform(0.0, p.start_spread_s, n)
        for i in range(n):
            agenda.at(float(phase[i]), URGENT, self._hello_tick, i)
            agenda.at(float(phase[i]), URGENT, self._tc_tick, i)

    def _kind(self, label: str, nbytes: int) -> str:
        kind = f"{label}_{nbytes}B"
        if kind not in self.control_bytes:
            self.control_kind(kind, nbytes, label)
        return kind

    # -- packets (section 3.4) -----------------------------------------------------------------
    def queue(self, i: int, message: Hello | Tc) -> None:
        """Robot ``i`` sends ``message`` in its next packet: the first message queued sets
        when that packet leaves, after U(0, MAXJITTER = hello_interval_s / 4) (section 18.3)."""
        self.queued[i].append(message)
        if not self._leaving[i]:
            self._leaving[i] = True
            delay_s = float(self._rng.uniform(0.0, self.params.hello_interval_s / 4))
            self.channel.agenda.at(delay_s, URGENT, self._send_queued, i)

    def _send_queued(self, i: int) -> None:
        messages, self.queued[i] = self.queued[i], []
        self._leaving[i] = False
        if not self.state.alive[i]:
            return
        for batch, nbytes in pack(messages, self.max_frame_bytes):
            label = "+".join(k for k, t in (("hello", Hello), ("tc", Tc)) if any(isinstance(m, t) for m in batch))
            self.control(i, batch, self._on_packet, self._kind(label, nbytes), messages=len(batch))

    def _on_packet(self, sender: int, receivers: np.ndarray, batch: tuple) -> None:
        for message in batch:
            if isinstance(message, Hello):
                self._on_hello(sender, receivers, message)
            else:
                self._on_tc(sender, receivers, message)

    # -- neighbour sensing (section 7 and 8) ------------------------------------------------
    def symmetric(self, i: int, now: float) -> set[int]:
        """Robot ``i``'s symmetric neighbours now."""
        return {j for j, t in self.sym_until[i].items() if t >= now}

    def _hello_tick(self, i: int) -> None:
        now = self.env.now
        if self.state.alive[i]:
            self._select_mprs(i, now)
            heard = frozenset(j for j, t in self.heard_until[i].items() if t >= now)
            self.queue(i, Hello(i, heard, frozenset(self.symmetric(i, now)), frozenset(self.mprs[i])))
        self.channel.agenda.at(self.params.hello_interval_s, URGENT, self._hello_tick, i)

    def _on_hello(self, sender: int, receivers: np.ndarray, hello: Hello) -> None:
        now, p = self.env.now, self.params
        until = now + p.neighb_hold_time_s
        for r in receivers.tolist():
            self.heard_until[r][sender] = until
            if r in hello.heard:
                self.sym_until[r][sender] = until
            elif sender in self.sym_until[r] and self.sym_until[r][sender] >= now:
                # The sender no longer hears r: the link is asymmetric again (section 7.1.1).
                self.sym_until[r][sender] = now - 1e-9
            if sender in self.symmetric(r, now):
                self.two_hop[r][sender] = (hello.symmetric - {r}, until)
            else:
                self.two_hop[r].pop(sender, None)
            if r in hello.mprs:
                self.selectors[r][sender] = until
            else:
                self.selectors[r].pop(sender, None)
            self._routes[r] = None

    def _select_mprs(self, i: int, now: float) -> None:
        sym = self.symmetric(i, now)
        via = {n: s for n, (s, t) in self.two_hop[i].items() if n in sym and t >= now}
        n2 = set().union(*via.values()) - sym - {i} if via else set()
        self.mprs[i] = select_mprs(via, n2)

    # -- topology control (section 9) --------------------------------------------------------
    def _tc_tick(self, i: int) -> None:
        now = self.env.now
        if self.state.alive[i]:
            selectors = frozenset(j for j, t in self.selectors[i].items() if t >= now)
            if selectors:
                self.ansn[i] += 1
                tc = Tc(i, self.ansn[i], selectors, self.params.ttl, 0)
                self.duplicates[i][(i, tc.ansn)] = (now + self.params.dup_hold_time_s, True)
                self.queue(i, tc)
        self.channel.agenda.at(self.params.tc_interval_s, URGENT, self._tc_tick, i)

    def _on_tc(self, sender: int, receivers: np.ndarray, tc: Tc) -> None:
        now, p = self.env.now, self.params
        for r in receivers.tolist():
            if sender not in self.symmetric(r, now):
                continue  # section 3.4: only from symmetric neighbours
            key = (tc.orig, tc.ansn)
            if tc.orig == r:
                continue
            if self.duplicates[r].get(key, (-1.0, False))[0] >= now:
                # Processed and considered for forwarding once, at the first copy from a
                # symmetric neighbour (one interface: section 3.4, 3.4.1 step 2).
                continue
            known = self.topology[r].get(tc.orig)
            if known is None or tc.ansn >= known[0]:
                self.topology[r][tc.orig] = (tc.ansn, tc.advertised, now + p.top_hold_time_s)
                self._routes[r] = None
            # MPR flooding: retransmitted by the sender's MPRs alone, while TTL allows.
            forward = self.selectors[r].get(sender, -1.0) >= now and tc.ttl > 1
            self.duplicates[r][key] = (now + p.dup_hold_time_s, forward)
            if forward:
                self.queue(r, tc._replace(ttl=tc.ttl - 1, hops=tc.hops + 1))

    # -- routing table (section 10) -----------------------------------------------------------
    def routes(self, i: int) -> dict[int, int]:
        """Robot ``i``'s routing table now: destination -> next hop, by a breadth-first
        search over its symmetric links, two-hop links and advertised links."""
        now = self.env.now
        cached = self._routes[i]
        if cached is not None and self._routes_at[i] == now:
            return cached
        edges: dict[int, set[int]] = {}
        sym = self.symmetric(i, now)
        edges[i] = set(sym)
        for n, (s, t) in self.two_hop[i].items():
            if n in sym and t >= now:
                edges.setdefault(n, set()).update(s)
        for orig, (_, adv, t) in self.topology[i].items():
            if t >= now:
                edges.setdefault(orig, set()).update(adv)
        nxt: dict[int, int] = {j: j for j in sorted(sym)}
        queue = deque(sorted(sym))
        while queue:
            u = queue.popleft()
            for v in sorted(edges.get(u, ())):
                if v != i and v not in nxt:
                    nxt[v] = nxt[u]
                    queue.append(v)
        self._routes[i] = nxt
        self._routes_at[i] = now
        return nxt

    def next_hop(self, holder: int, pkt: Packet) -> tuple[int, str]:
        nxt = self.routes(holder).get(pkt.dst)
        return (nxt, "") if nxt is not None else (-1, "no_route")


def build(params: OlsrParams, parts: Parts) -> Olsr:
    router = Olsr(params, parts)
    router.start()
    return router


PLUGIN = PluginSpec(Params=OlsrParams, build=build, tables=dict(ROUTING_TABLES), carries_flows=True, check=check_pairs)
