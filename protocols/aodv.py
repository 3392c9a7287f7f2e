"""``protocol.model = "aodv"``: Ad hoc On-Demand Distance Vector routing, RFC 3561
(docs/routing.md, "aodv").

A source without a route buffers its packets and floods a route request (RREQ) with an
expanding ring (TTL_START, + TTL_INCREMENT up to TTL_THRESHOLD, then NET_DIAMETER, retried
RREQ_RETRIES times, each wait a ring traversal time, doubled on every retry at
NET_DIAMETER). Each robot the RREQ reaches learns the reverse route to its originator; the
destination, or a robot with a fresh enough route, unicasts a route reply (RREP) back,
which sets up the forward route. Routes carry destination sequence numbers (a route is
replaced only by a fresher one, section 6.2) and lifetimes (ACTIVE_ROUTE_TIMEOUT, renewed
by use). Neighbours are known from hello messages (RREPs with TTL 1, every
HELLO_INTERVAL, skipped after a RREQ the robot broadcast) and from the link layer (a
unicast that does not get through); a broken link invalidates every route through it and a
route error (RERR) goes to the robots that used them (precursors). An intermediate robot
that answers a RREQ also sends the destination a gratuitous RREP. No local repair, no
RREP-ACK.

The RFC's rules are plain functions (:func:`fresher`, :func:`ring_ttls`) and the routing
table a small class (:class:`RouteTable`), each tested by name in tests/test_routing_aodv.py.
"""

from __future__ import annotations

import math
import sys
import warnings
from dataclasses import dataclass, field
from typing import NamedTuple

import numpy as np
from netsim.protocols.routing import ROUTING_TABLES, Packet, Router, RoutingParams, check_pairs

from netsim.config import ConfigWarning
from netsim.errors import ConfigError
from netsim.params import finite, non_negative, param, positive, ttl_field
from netsim.plugins import Parts, PluginSpec
from netsim.scheduling import URGENT

# Message sizes (RFC 3561 section 5), bytes.
RREQ_BYTES = 24
RREP_BYTES = 20
RERR_BYTES_BASE = 4
RERR_BYTES_PER_DEST = 8


@dataclass(frozen=True)
class AodvParams(RoutingParams):
    """AODV's keys of ``[protocol]``, with RFC 3561's defaults (section 10)."""

    section = "protocol"
    active_route_timeout_s: float = param(3.0, finite(positive), "ACTIVE_ROUTE_TIMEOUT: a route unused this long, s")
    hello: bool = param(True, None, "send hello messages (false: neighbours from the link layer alone)")
    hello_interval_s: float = param(1.0, finite(positive), "HELLO_INTERVAL, s", schedules="robot")
    hello_deferred_by_broadcast: bool = param(
        True,
        None,
        "a RREQ the robot broadcast since its last hello stands for it: the next hello comes an interval "
        "after that RREQ (RFC 3561 6.9, as ns-3 does)",
    )
    gratuitous_reply: bool = param(
        True,
        None,
        "RREQs ask an intermediate robot that answers to send the destination a gratuitous RREP too "
        "(RFC 3561 6.6.3's G flag; ns-3's GratuitousReply)",
    )
    allowed_hello_loss: int = param(2, positive, "ALLOWED_HELLO_LOSS: hellos missed before a link is broken")
    net_diameter: int = param(35, ttl_field, "NET_DIAMETER: the largest TTL of a RREQ, hops")
    node_traversal_time_s: float = param(0.04, finite(positive), "NODE_TRAVERSAL_TIME, s")
    rreq_retries: int = param(2, non_negative, "RREQ_RETRIES: RREQs at NET_DIAMETER after the first")
    ttl_start: int = param(1, ttl_field, "TTL_START: the TTL of the first RREQ")
    ttl_increment: int = param(2, ttl_field, "TTL_INCREMENT: added to the TTL of each new ring")
    ttl_threshold: int = param(7, ttl_field, "TTL_THRESHOLD: past it, the RREQ's TTL is NET_DIAMETER")
    timeout_buffer: int = param(2, non_negative, "TIMEOUT_BUFFER of RING_TRAVERSAL_TIME, hops")
    queue_packets: int = param(
        64,
        positive,
        "packets buffered per robot while a route is sought (each frame of a flow's packet one); "
        "full, the oldest is dropped",
    )
    jitter_s: float = param(0.01, finite(non_negative), "forwarded broadcasts wait U(0, jitter), s (RFC 5148)")

    def check(self) -> None:
        for key in ("ttl_start", "ttl_threshold"):
            if getattr(self, key) > self.net_diameter:
                raise ConfigError(
                    f"protocol.{key}",
                    getattr(self, key),
                    f"must not exceed protocol.net_diameter = {self.net_diameter}",
                )
        if not math.isfinite(self.path_discovery_time_s):
            raise ConfigError(
                "protocol.node_traversal_time_s",
                self.node_traversal_time_s,
                f"must be at most {sys.float_info.max / (4.0 * self.net_diameter):.6g}: PATH_DISCOVERY_TIME = 4 x it "
                "x NET_DIAMETER, how long a robot remembers a RREQ, must be a finite number of seconds",
            )
        most = most_rreq_retries(self.net_traversal_time_s)
        if self.rreq_retries > most:
            # A discovery lists its RREQs' TTLs when it starts (ring_ttls), and the last waits
            # NET_TRAVERSAL_TIME x 2^RREQ_RETRIES: past this, that wait is no number (and the
            # list no memory holds), a traceback at the run's first route discovery.
            raise ConfigError(
                "protocol.rreq_retries",
                self.rreq_retries,
                f"must be at most {most} with protocol.node_traversal_time_s = {self.node_traversal_time_s:g}: "
                "each retry waits twice as long as the one before, and the last "
                f"one's wait, NET_TRAVERSAL_TIME = {self.net_traversal_time_s:g} s x 2^rreq_retries, must be "
                "a finite number of seconds",
            )
        flood_s = self.net_diameter * self.jitter_s
        if self.path_discovery_time_s < flood_s:
            # A copy of a RREQ that reaches a robot after it forgot the RREQ is forwarded
            # again, and so are that copy's copies: the flood need not end.
            warnings.warn(
                f"protocol.node_traversal_time_s = {self.node_traversal_time_s:g}: a robot remembers a RREQ for "
                f"PATH_DISCOVERY_TIME = 4 x it x NET_DIAMETER = {self.path_discovery_time_s:g} s, less than a "
                f"flood over NET_DIAMETER hops may take with protocol.jitter_s a hop ({flood_s:g} s): copies "
                "arriving later are forwarded again, a broadcast storm that can slow the run to a crawl",
                ConfigWarning,
                stacklevel=2,
            )

    @property
    def net_traversal_time_s(self) -> float:
        """NET_TRAVERSAL_TIME = 2 NODE_TRAVERSAL_TIME NET_DIAMETER."""
        return 2.0 * self.node_traversal_time_s * self.net_diameter

    @property
    def path_discovery_time_s(self) -> float:
        """PATH_DISCOVERY_TIME = 2 NET_TRAVERSAL_TIME: how long a RREQ is remembered."""
        return 2.0 * self.net_traversal_time_s

    @property
    def my_route_timeout_s(self) -> float:
        """MY_ROUTE_TIMEOUT = 2 ACTIVE_ROUTE_TIMEOUT: the lifetime a destination's RREP gives."""
        return 2.0 * self.active_route_timeout_s

    @property
    def delete_period_s(self) -> float:
        """DELETE_PERIOD = K max(ACTIVE_ROUTE_TIMEOUT, HELLO_INTERVAL), K = 5."""
        return 5.0 * max(self.active_route_timeout_s, self.hello_interval_s)

    def ring_traversal_time_s(self, ttl: int) -> float:
        """RING_TRAVERSAL_TIME = 2 NODE_TRAVERSAL_TIME (TTL_VALUE + TIMEOUT_BUFFER)."""
        return 2.0 * self.node_traversal_time_s * (ttl + self.timeout_buffer)


def most_rreq_retries(net_traversal_time_s: float) -> int:
    """The most RREQ_RETRIES whose last wait, ``net_traversal_time_s x 2^retries``, is a
    finite float (the largest float is below 2^1024)."""
    most = 1023
    while most > 0 and not _finite_product(net_traversal_time_s, most):
        most -= 1
    return most


def _finite_product(seconds: float, exponent: int) -> bool:
    try:
        return math.isfinite(seconds * 2**exponent)
    except OverflowError:
        return False


def seq_newer(a: int, b: int) -> bool:
    """Whether sequence number ``a`` is newer than ``b``: signed 32-bit rollover (section 6.1)."""
    return ((a - b + 2**31) % 2**32) - 2**31 > 0


def fresher(known: Route | None, seq: int, valid_seq: bool, hops: int) -> bool:
    """Whether an offered route (``seq``, ``valid_seq``, ``hops``) replaces the ``known`` one
    (section 6.2): when none is known, or the known has no valid sequence number, or the
    offer's sequence number is newer, or the same with the known route invalid or longer.
    An offer without a valid sequence number never replaces a known valid one."""
    if known is None or not known.valid_seq:
        return True
    if not valid_seq:
        return False
    if seq_newer(seq, known.seq):
        return True
    return seq == known.seq and (not known.valid or hops < known.hops)


def ring_ttls(p: AodvParams, last_hops: int | None = None) -> list[int]:
    """The TTLs of a route discovery's RREQs, in order (section 6.4): TTL_START (or the last
    known hop count + TTL_INCREMENT), tried whatever TTL_THRESHOLD is, as ns-3 does; then +
    TTL_INCREMENT while not past TTL_THRESHOLD; then NET_DIAMETER, tried 1 + RREQ_RETRIES
    times."""
    first = p.ttl_start if last_hops is None else min(last_hops + p.ttl_increment, p.net_diameter)
    out = []
    ttl = first
    while ttl < p.net_diameter and (ttl <= p.ttl_threshold or ttl == first):
        out.append(ttl)
        ttl += p.ttl_increment
    return out + [p.net_diameter] * (1 + p.rreq_retries)


@dataclass
class Route:
    """One entry of a robot's routing table (section 6.1)."""

    next_hop: int
    hops: int
    seq: int
    valid_seq: bool
    expires_s: float
    valid: bool = True
    precursors: set[int] = field(default_factory=set)


class RouteTable:
    """A robot's routes, by destination."""

    def __init__(self) -> None:
        self.routes: dict[int, Route] = {}

    def active(self, dst: int, now: float) -> Route | None:
        """The valid, unexpired route to ``dst``, if any (an expired one becomes invalid)."""
        r = self.routes.get(dst)
        if r is None or not r.valid:
            return None
        if r.expires_s < now:
            r.valid = False
            return None
        return r

    def offer(self, dst: int, next_hop: int, hops: int, seq: int, valid_seq: bool, expires_s: float) -> bool:
        """Take an offered route if :func:`fresher` (else only extend the lifetime of the
        same route); returns whether it was taken."""
        known = self.routes.get(dst)
        if fresher(known, seq, valid_seq, hops):
            precursors = known.precursors if known is not None else set()
            keep_seq = known.seq if (known is not None and not valid_seq) else seq
            self.routes[dst] = Route(next_hop, hops, keep_seq, valid_seq, expires_s, True, precursors)
            return True
        if known is not None and known.valid and known.next_hop == next_hop and known.hops == hops:
            known.expires_s = max(known.expires_s, expires_s)
        return False

    def neighbour(self, nbr: int, seq: int | None, expires_s: float) -> None:
        """``nbr`` was heard directly: its route is made one hop through itself and active,
        whatever sequence number the table held, living until ``expires_s`` at least. A hello
        (section 6.9: "SHOULD make sure that it has an active route to the neighbor") brings
        its sender's sequence number, ``seq``; a RREQ's previous hop (section 6.5: "without a
        valid sequence number") brings none (None), and a number already known is kept."""
        known = self.routes.get(nbr)
        if known is None:
            self.routes[nbr] = Route(nbr, 1, 0 if seq is None else seq, seq is not None, expires_s)
            return
        known.next_hop, known.hops, known.valid = nbr, 1, True
        if seq is not None:
            known.seq, known.valid_seq = seq, True
        known.expires_s = max(known.expires_s, expires_s)

    def break_link(self, next_hop: int, now: float, delete_period_s: float) -> list[tuple[int, int, set[int]]]:
        """The link to ``next_hop`` is broken: every valid route through it becomes invalid,
        its sequence number increased (section 6.11); returns ``(dst, seq, precursors)`` of
        each, the unreachable destinations of the RERR."""
        out = []
        for dst, r in self.routes.items():
            if r.valid and r.next_hop == next_hop:
                r.valid = False
                r.seq = (r.seq + 1) % 2**32
                r.expires_s = now + delete_period_s
                out.append((dst, r.seq, set(r.precursors)))
        return out

    def on_rerr(self, sender: int, unreachable: list[tuple[int, int]], now: float, delete_period_s: float):
        """A RERR from ``sender``: the valid routes to its unreachable destinations through
        ``sender`` become invalid, with the RERR's sequence numbers; returns them as
        :meth:`break_link` does (to be sent on to their precursors)."""
        out = []
        for dst, seq in unreachable:
            r = self.routes.get(dst)
            if r is not None and r.valid and r.next_hop == sender:
                r.valid = False
                r.seq = seq
                r.expires_s = now + delete_period_s
                out.append((dst, seq, set(r.precursors)))
        return out


class Rreq(NamedTuple):
    orig: int
    rreq_id: int
    dst: int
    dst_seq: int
    unknown_seq: bool
    orig_seq: int
    hops: int
    ttl: int
    gratuitous: bool = False  # the G flag: an intermediate robot that answers tells the destination


class Rrep(NamedTuple):
    dst: int
    dst_seq: int
    orig: int
    hops: int
    lifetime_s: float
    hello: bool = False


class Rerr(NamedTuple):
    unreachable: tuple[tuple[int, int], ...]


class Discovery:
    """A route discovery under way at a source: its TTLs still to try and its packets."""

    __slots__ = ("ttls", "waiting", "retries_at_diameter")

    def __init__(self, ttls: list[int]):
        self.ttls = ttls
        self.waiting: list[Packet] = []
        self.retries_at_diameter = 0


class Aodv(Router):
    """AODV at every robot (module notes)."""

    def __init__(self, params: AodvParams, parts: Parts):
        super().__init__(parts, params.net_diameter, params)
        self.params = p = params
        n = self.state.n
        self.tables = [RouteTable() for _ in range(n)]
        self.own_seq = [0] * n
        self.rreq_id = [0] * n
        # (orig, rreq_id) each robot has seen, until when it remembers it.
        self.seen: list[dict[tuple[int, int], float]] = [{} for _ in range(n)]
        self.discoveries: list[dict[int, Discovery]] = [{} for _ in range(n)]
        # When each robot last heard each neighbour's hello or RREQ (links from hellos).
        self.hello_heard: list[dict[int, float]] = [{} for _ in range(n)]
        # When each robot last broadcast a RREQ since its hello timer last ran (None: not
        # since): that RREQ stands for the next hello.
        self.last_rreq_s: list[float | None] = [None] * n
        # Every RREQ a source originated: (t_s, source, destination, ttl): the expanding ring.
        self.rreqs_originated: list[tuple[float, int, int, int]] = []
        self.control_kind("rreq", RREQ_BYTES)
        self.control_kind("rrep", RREP_BYTES)
        self.control_kind("hello", RREP_BYTES)
        self._rerr_kinds: set[int] = set()
        self._rng = self.streams.get("aodv.jitter")
        self._hello_phase = self.streams.get("aodv.hello").uniform(0.0, p.hello_interval_s, n) if p.hello else None

    def start(self) -> None:
        super().start()
        if self._hello_phase is not None:
            agenda = self.channel.agenda
            for i in range(self.state.n):
                agenda.at(float(self._hello_phase[i]), URGENT, self._hello_tick, i)

    def _later(self, delay_s: float, fn, *args) -> None:
        self.channel.agenda.at(delay_s, URGENT, fn, *args)

    def _jitter(self) -> float:
        j = self.params.jitter_s
        return float(self._rng.uniform(0.0, j)) if j > 0 else 0.0

    # -- hellos (section 6.9) -------------------------------------------------------------
    def _hello_tick(self, i: int) -> None:
        p = self.params
        since = self.last_rreq_s[i]
        self.last_rreq_s[i] = None
        if since is None and self.state.alive[i]:
            lifetime = p.allowed_hello_loss * p.hello_interval_s
            self.control(i, Rrep(i, self.own_seq[i], i, 0, lifetime, True), self._on_hello, "hello")
        # Jittered by a quarter of the interval, so that neighbours do not lock step; a RREQ
        # broadcast since the last tick stood for this hello, and the interval runs from it.
        wait = p.hello_interval_s * (0.75 + 0.5 * float(self._rng.random()))
        self._later(max(0.0, wait - (self.env.now - since if since is not None else 0.0)), self._hello_tick, i)

    def _broadcast_rreq(self, i: int) -> None:
        """``i`` broadcasts a RREQ now (originated or passed on): it stands for a hello."""
        if self.params.hello_deferred_by_broadcast:
            self.last_rreq_s[i] = self.env.now

    def _on_hello(self, sender: int, receivers: np.ndarray, hello: Rrep) -> None:
        now = self.env.now
        for r in receivers.tolist():
            self.hello_heard[r][sender] = now
            self.tables[r].neighbour(sender, hello.dst_seq, now + hello.lifetime_s)

    def _neighbour_lost(self, i: int, nbr: int, now: float) -> bool:
        """Whether ``i`` has missed ALLOWED_HELLO_LOSS hellos of ``nbr`` it used to hear."""
        p = self.params
        heard = self.hello_heard[i].get(nbr)
        return p.hello and heard is not None and now - heard > p.allowed_hello_loss * p.hello_interval_s

    # -- data -------------------------------------------------------------------------
    def _route(self, i: int, dst: int, now: float) -> Route | None:
        """``i``'s active route to ``dst``, None where there is none or where its next hop
        was lost by missed hellos (the link is then broken: section 6.11)."""
        r = self.tables[i].active(dst, now)
        if r is not None and self._neighbour_lost(i, r.next_hop, now):
            self._link_broken(i, r.next_hop)
            return None
        return r

    def next_hop(self, holder: int, pkt: Packet) -> tuple[int, str]:
        now, p = self.env.now, self.params
        table = self.tables[holder]
        r = self._route(holder, pkt.dst, now)
        if r is None:
            if holder != pkt.src:
                # Section 6.11 (ii): data for a destination with no active route.
                self._send_rerr(holder, [(pkt.dst, self._seq_of(table, pkt.dst), set())], broadcast=True)
            return -1, "no_route"
        # Using a route keeps it, and the routes to its next hop and back to the source (6.2).
        r.expires_s = max(r.expires_s, now + p.active_route_timeout_s)
        for other in (r.next_hop, pkt.src):
            back = table.active(other, now)
            if back is not None:
                back.expires_s = max(back.expires_s, now + p.active_route_timeout_s)
        return r.next_hop, ""

    @staticmethod
    def _seq_of(table: RouteTable, dst: int) -> int:
        r = table.routes.get(dst)
        return r.seq if r is not None else 0

    def originate(self, src: int, pkt: Packet) -> None:
        if self._route(src, pkt.dst, self.env.now) is not None:
            self.forward(src, pkt)
            return
        # One buffer a robot, whatever the destinations its packets wait for. Full, its most
        # aged packet makes room, as in ns-3's request queue: the newest is the likelier to
        # be still worth delivering once the route comes.
        discoveries = self.discoveries[src]
        if sum(len(d.waiting) for d in discoveries.values()) >= self.params.queue_packets:
            oldest = min((d for d in discoveries.values() if d.waiting), key=lambda d: d.waiting[0].id)
            self.dropped(oldest.waiting.pop(0), src, "queue_full")
        d = discoveries.get(pkt.dst)
        if d is None:
            known = self.tables[src].routes.get(pkt.dst)
            d = discoveries[pkt.dst] = Discovery(ring_ttls(self.params, known.hops if known else None))
            d.waiting.append(pkt)
            self._send_rreq(src, pkt.dst, d)
        else:
            d.waiting.append(pkt)

    def link_failed(self, holder: int, nxt: int, pkt: Packet) -> None:
        self._link_broken(holder, nxt)

    # -- route discovery (sections 6.3 to 6.7) -------------------------------------------
    def _send_rreq(self, src: int, dst: int, d: Discovery) -> None:
        p, now = self.params, self.env.now
        ttl = d.ttls.pop(0)
        self.own_seq[src] += 1  # section 6.1: before a route discovery
        self.rreq_id[src] += 1
        known = self.tables[src].routes.get(dst)
        rreq = Rreq(
            src,
            self.rreq_id[src],
            dst,
            known.seq if known is not None else 0,
            known is None or not known.valid_seq,
            self.own_seq[src],
            0,
            ttl,
            p.gratuitous_reply,
        )
        self.seen[src][(src, rreq.rreq_id)] = now + p.path_discovery_time_s
        self._broadcast_rreq(src)
        self.rreqs_originated.append((now, src, dst, ttl))
        self.control(src, rreq, self._on_rreq, "rreq")
        if ttl < p.net_diameter:
            wait = p.ring_traversal_time_s(ttl)
        else:
            wait = p.net_traversal_time_s * 2**d.retries_at_diameter  # binary exponential backoff
            d.retries_at_diameter += 1
        self._later(wait, self._rreq_timeout, src, dst, d)

    def _rreq_timeout(self, src: int, dst: int, d: Discovery) -> None:
        if self.discoveries[src].get(dst) is not d:
            return  # the route was found
        if d.ttls:
            self._send_rreq(src, dst, d)
            return
        del self.discoveries[src][dst]
        for pkt in d.waiting:
            self.dropped(pkt, src, "no_route")

    def _on_rreq(self, sender: int, receivers: np.ndarray, rreq: Rreq) -> None:
        now, p = self.env.now, self.params
        # Most receptions of a flood are copies a robot already had: what each needs is
        # looked up once, not per receiver.
        tables, seen, key = self.tables, self.seen, (rreq.orig, rreq.rreq_id)
        neighbour_until = now + p.active_route_timeout_s
        # A RREQ heard says the link is up as a hello does, every copy of it (section 6.9: any
        # packet of the neighbour), so a RREQ may stand for a hello. ns-3 counts first copies
        # alone, and the data a robot forwards besides.
        heard = self.hello_heard if p.hello else None
        for r in receivers.tolist():
            table = tables[r]
            table.neighbour(sender, None, neighbour_until)
            if heard is not None:
                heard[r][sender] = now
            if seen[r].get(key, -1.0) >= now:
                continue
            seen[r][key] = now + p.path_discovery_time_s
            hops = rreq.hops + 1
            lifetime = now + 2 * p.net_traversal_time_s - 2 * hops * p.node_traversal_time_s
            table.offer(rreq.orig, sender, hops, rreq.orig_seq, True, lifetime)
            back = table.routes[rreq.orig]
            if back.next_hop == sender:
                back.expires_s = max(back.expires_s, lifetime)
            if r == rreq.dst:
                # Section 6.6.1: the destination's sequence number, at least the RREQ's.
                if not rreq.unknown_seq and seq_newer(rreq.dst_seq, self.own_seq[r]):
                    self.own_seq[r] = rreq.dst_seq
                self._send_rrep(r, Rrep(r, self.own_seq[r], rreq.orig, 0, p.my_route_timeout_s))
                continue
            fwd = table.active(rreq.dst, now)
            if (
                fwd is not None
                and fwd.valid_seq
                # A RREQ that knows no number for the destination asks for none: any valid one
                # is fresh enough (ns-3's RecvRequest).
                and (rreq.unknown_seq or not seq_newer(rreq.dst_seq, fwd.seq))
                and fwd.next_hop != sender
            ):
                # Section 6.6.2: an intermediate robot with a fresh enough route answers.
                fwd.precursors.add(sender)
                back.precursors.add(fwd.next_hop)
                self._send_rrep(r, Rrep(rreq.dst, fwd.seq, rreq.orig, fwd.hops, fwd.expires_s - now))
                if rreq.gratuitous and table.active(rreq.orig, now) is not None:
                    # Section 6.6.3: the destination learns the route to the originator, as if
                    # it had asked for it and this robot had answered.
                    grat = Rrep(rreq.orig, back.seq, rreq.dst, back.hops, back.expires_s - now)
                    self.control(r, grat, self._on_rrep, "rrep", dest=fwd.next_hop)
                continue
            if rreq.ttl > 1:
                dst_seq, unknown = rreq.dst_seq, rreq.unknown_seq
                known = table.routes.get(rreq.dst)
                if known is not None and known.valid_seq and (unknown or seq_newer(known.seq, dst_seq)):
                    # The number it knows, and the U flag cleared, so that the destination
                    # takes it (section 6.6.1; ns-3's RecvRequest clears it too).
                    dst_seq, unknown = known.seq, False
                out = rreq._replace(hops=hops, ttl=rreq.ttl - 1, dst_seq=dst_seq, unknown_seq=unknown)
                self._broadcast_rreq(r)  # when it is decided, as ns-3 notes it, not after the jitter
                self._later(self._jitter(), self._rebroadcast_rreq, r, out)

    def _rebroadcast_rreq(self, r: int, rreq: Rreq) -> None:
        if self.state.alive[r]:
            self.control(r, rreq, self._on_rreq, "rreq")

    def _send_rrep(self, r: int, rrep: Rrep) -> None:
        """Unicast ``rrep`` from ``r`` one hop back toward its originator."""
        back = self.tables[r].active(rrep.orig, self.env.now)
        if back is None:
            return
        self.control(r, rrep, self._on_rrep, "rrep", dest=back.next_hop)

    def _on_rrep(self, sender: int, receivers: np.ndarray, rrep: Rrep) -> None:
        now, p = self.env.now, self.params
        for r in receivers.tolist():
            table = self.tables[r]
            table.offer(sender, sender, 1, 0, False, now + p.active_route_timeout_s)
            hops = rrep.hops + 1
            table.offer(rrep.dst, sender, hops, rrep.dst_seq, True, now + rrep.lifetime_s)
            if r == rrep.orig:
                d = self.discoveries[r].pop(rrep.dst, None)
                if d is not None:
                    for pkt in d.waiting:
                        self.forward(r, pkt)
                continue
            back = table.active(rrep.orig, now)
            fwd = table.routes.get(rrep.dst)
            if back is None or fwd is None:
                continue
            fwd.precursors.add(back.next_hop)
            back.precursors.add(fwd.next_hop)
            back.expires_s = max(back.expires_s, now + p.active_route_timeout_s)
            self.control(r, rrep._replace(hops=hops), self._on_rrep, "rrep", dest=back.next_hop)

    # -- route errors (section 6.11) -----------------------------------------------------
    def _link_broken(self, i: int, nbr: int) -> None:
        now, p = self.env.now, self.params
        self.hello_heard[i].pop(nbr, None)
        lost = self.tables[i].break_link(nbr, now, p.delete_period_s)
        if lost:
            self._send_rerr(i, lost)

    def _send_rerr(self, i: int, lost: list[tuple[int, int, set[int]]], broadcast: bool = False) -> None:
        """A RERR of the destinations ``lost`` to their precursors (a unicast to a single
        one, else a broadcast); none if nobody used those routes."""
        precursors = set().union(*(pre for _, _, pre in lost))
        if not precursors and not broadcast:
            return
        unreachable = tuple((dst, seq) for dst, seq, _ in lost)
        kind = self._rerr_kind(len(unreachable))
        dest = next(iter(precursors)) if len(precursors) == 1 else -1
        self.control(i, Rerr(unreachable), self._on_rerr, kind, dest=dest)

    def _rerr_kind(self, count: int) -> str:
        """The channel kind of a RERR of ``count`` destinations (its size grows with them),
        counted as ``rerr``."""
        kind = f"rerr_{count}"
        if count not in self._rerr_kinds:
            self._rerr_kinds.add(count)
            self.control_kind(kind, RERR_BYTES_BASE + RERR_BYTES_PER_DEST * count, "rerr")
        return kind

    def _on_rerr(self, sender: int, receivers: np.ndarray, rerr: Rerr) -> None:
        now, p = self.env.now, self.params
        for r in receivers.tolist():
            lost = self.tables[r].on_rerr(sender, list(rerr.unreachable), now, p.delete_period_s)
            if lost:
                self._send_rerr(r, lost)


def build(params: AodvParams, parts: Parts) -> Aodv:
    router = Aodv(params, parts)
    router.start()
    return router


PLUGIN = PluginSpec(Params=AodvParams, build=build, tables=dict(ROUTING_TABLES), carries_flows=True, check=check_pairs)
