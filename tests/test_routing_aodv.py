"""AODV (RFC 3561), rule by rule: destination sequence numbers, route errors, the expanding
ring; and a flow over a static line."""

import re

import numpy as np
import pytest
from netsim.protocols.aodv import AodvParams, Route, RouteTable, fresher, ring_ttls, seq_newer

from netsim.config import ConfigWarning
from netsim.errors import ConfigError
from netsim.run import build, collect
from tests.fixtures import flow_over_trace, make_config


def _run(tmp_path, xy, flows, duration_s=30.0, **protocol):
    path = tmp_path / "robots.csv"
    path.write_text("x_m,y_m\n" + "".join(f"{x},{y}\n" for x, y in xy))
    config = make_config(
        seed=5,
        duration_s=duration_s,
        world={"n_robots": len(xy), "side_m": 1000.0, "placement": str(path)},
        mobility={"model": "static"},
        channel={"range_m": 120.0},
        protocol={"model": "aodv", **protocol},
        traffic={"flows": flows},
        output={"position_interval_s": 0.0},
    )
    sim = build(config)
    sim.run()
    return sim, collect(sim)


def test_stale_sequence_number_never_replaces_fresher_route():
    """A route offered with an older destination sequence number never replaces a known
    one, however short; the same number replaces it only when shorter; a newer one always
    does (RFC 3561 6.2), across the 32-bit rollover. Over random offers the table's
    sequence number never goes back."""
    t = RouteTable()
    t.offer(9, next_hop=1, hops=4, seq=10, valid_seq=True, expires_s=100.0)
    assert not t.offer(9, 2, 1, 9, True, 100.0) and t.routes[9].next_hop == 1
    assert not t.offer(9, 2, 5, 10, True, 100.0) and t.routes[9].next_hop == 1
    assert not t.offer(9, 2, 1, 0, False, 100.0) and t.routes[9].next_hop == 1
    assert t.offer(9, 2, 3, 10, True, 100.0) and t.routes[9].next_hop == 2
    assert t.offer(9, 3, 8, 11, True, 100.0) and t.routes[9].next_hop == 3
    t.offer(7, 1, 2, 2**32 - 1, True, 100.0)
    assert seq_newer(0, 2**32 - 1) and t.offer(7, 2, 9, 0, True, 100.0)
    rng = np.random.default_rng(3)
    t, best = RouteTable(), None
    for _ in range(2000):
        seq = int(rng.integers(0, 20))
        t.offer(5, int(rng.integers(10)), int(rng.integers(1, 10)), seq, True, 100.0)
        best = seq if best is None or seq > best else best
        assert t.routes[5].seq == best


def test_same_sequence_number_replaces_a_route_only_if_strictly_shorter():
    """RFC 3561 6.2: an offer with the known route's own destination sequence number
    replaces a valid route only if its hop count is smaller; one as long does not, and
    the table keeps its next hop and lifetime (a tie taken, ``<=``, would let every equally
    long reply move the route to another next hop: routes flapping between equal paths)."""
    known = Route(next_hop=1, hops=4, seq=10, valid_seq=True, expires_s=100.0)
    assert not fresher(known, 10, True, 4)
    assert fresher(known, 10, True, 3)
    t = RouteTable()
    t.offer(9, next_hop=1, hops=4, seq=10, valid_seq=True, expires_s=100.0)
    assert not t.offer(9, 2, 4, 10, True, 200.0)
    assert (t.routes[9].next_hop, t.routes[9].hops, t.routes[9].expires_s) == (1, 4, 100.0)


def test_route_error_invalidates_routes_through_the_broken_link():
    """A broken link to a next hop invalidates every valid route through it (their
    sequence numbers increased) and no other, and names them for the RERR; a RERR from a
    neighbour invalidates the listed routes through that neighbour alone (6.11, 6.12)."""
    t = RouteTable()
    for dst, nh in ((3, 1), (4, 1), (5, 2), (6, 1)):
        t.offer(dst, nh, 2, 10, True, 100.0)
    t.routes[6].precursors.add(8)
    lost = t.break_link(1, now=50.0, delete_period_s=15.0)
    assert sorted(d for d, _, _ in lost) == [3, 4, 6]
    assert all(seq == 11 for _, seq, _ in lost) and [p for d, _, p in lost if d == 6] == [{8}]
    assert t.active(5, 50.0) is not None and all(t.active(d, 50.0) is None for d in (3, 4, 6))
    u = RouteTable()
    for dst, nh in ((3, 1), (4, 2), (5, 1)):
        u.offer(dst, nh, 2, 10, True, 100.0)
    got = u.on_rerr(1, [(3, 12), (4, 12)], now=50.0, delete_period_s=15.0)
    assert [(d, s) for d, s, _ in got] == [(3, 12)]
    assert u.active(3, 50.0) is None and u.active(4, 50.0) is not None and u.active(5, 50.0) is not None


def test_expanding_ring_ttls(tmp_path):
    """A route discovery's RREQs go out with TTL_START, + TTL_INCREMENT up to
    TTL_THRESHOLD, then NET_DIAMETER for 1 + RREQ_RETRIES tries (RFC 3561 6.4); a run finds a
    destination five hops away at the third ring, and gives up on an unreachable one after
    every ring, dropping its packets for want of a route."""
    assert ring_ttls(AodvParams()) == [1, 3, 5, 7, 35, 35, 35]
    assert ring_ttls(AodvParams(ttl_start=2, ttl_increment=3, ttl_threshold=9, rreq_retries=1)) == [2, 5, 8, 35, 35]
    # The first ring is tried past the threshold too (ns-3's SendRequest).
    assert ring_ttls(AodvParams(ttl_start=9)) == [9, 35, 35, 35]
    assert ring_ttls(AodvParams(), last_hops=6) == [8, 35, 35, 35]
    assert ring_ttls(AodvParams(), last_hops=40) == [35, 35, 35]
    flow = {"src": 0, "dst": 5, "start_s": 10.0, "stop_s": 10.5, "rate_bps": 8000.0, "packet_bytes": 1000}
    sim, frames = _run(tmp_path, [(50 + 100 * i, 500) for i in range(6)], [flow])
    assert [ttl for _, _, _, ttl in sim.models["protocol"].rreqs_originated] == [1, 3, 5]
    assert frames["packets"]["delivered"].all() and (frames["packets"]["hops"] == 5).all()
    sim, frames = _run(tmp_path, [(50, 500), (150, 500), (900, 900)], [{**flow, "dst": 2}], duration_s=40.0)
    assert [ttl for _, _, _, ttl in sim.models["protocol"].rreqs_originated] == [1, 3, 5, 7, 35, 35, 35]
    assert (frames["packets"]["drop_cause"] == "no_route").all()


def test_aodv_delivers_along_a_static_line_with_control_frames_of_the_rfc_sizes(tmp_path):
    """Every packet of a flow down a static line arrives over the line's hops; RREQ, RREP
    and hello frames are sent with RFC 3561's sizes (24, 20, 20 bytes)."""
    flow = {"src": 0, "dst": 4, "start_s": 10.0, "stop_s": 20.0, "rate_bps": 8000.0, "packet_bytes": 1000}
    sim, frames = _run(tmp_path, [(50 + 100 * i, 500) for i in range(5)], [flow])
    assert frames["packets"]["delivered"].all() and (frames["packets"]["hops"] == 4).all()
    control = frames["control"].set_index("kind")
    assert dict(control["bytes_sent"] / control["sent"]) == {"hello": 20, "rrep": 20, "rreq": 24}
    assert (control["sent"] > 0).all()


@pytest.mark.parametrize(
    "key, value",
    [
        ("ttl_threshold", 40),
        ("ttl_start", 40),
        ("net_diameter", 256),
        ("ttl_increment", 0),
        ("ttl_start", 256),
        ("jitter_s", float("inf")),  # accepted, it ended the run in a traceback at the first rebroadcast
        # PATH_DISCOVERY_TIME infinite: refused as rreq_retries, a key the user had not set.
        ("node_traversal_time_s", 1e307),
    ],
)
def test_aodv_parameter_out_of_range_is_refused(key, value):
    """A TTL beyond the network diameter, or beyond the one octet a RREQ's TTL field holds,
    is refused, naming the key at fault."""
    with pytest.raises(ConfigError, match=re.escape(f"protocol.{key} = {value}:")):
        make_config(protocol={"model": "aodv", key: value})


def test_a_rreq_forgotten_before_its_flood_ends_is_warned_of(recwarn):
    """NODE_TRAVERSAL_TIME so short that PATH_DISCOVERY_TIME (how long a robot remembers a
    RREQ) ends before a flood over NET_DIAMETER hops can, with the forwarding jitter a hop:
    one warning naming the key and both times (the run storms, and seemed to hang); none at
    RFC 3561's defaults, nor where PATH_DISCOVERY_TIME just covers the flood."""
    with pytest.warns(ConfigWarning, match=r"protocol.node_traversal_time_s = 1e-05: .* = 0.0014 s, .* \(0.35 s\)"):
        make_config(protocol={"model": "aodv", "node_traversal_time_s": 1e-5})
    recwarn.clear()
    make_config(protocol={"model": "aodv"})
    make_config(protocol={"model": "aodv", "node_traversal_time_s": 0.0025, "jitter_s": 0.01})  # 0.35 s: covered
    assert [str(w.message) for w in recwarn] == []


BREAK = """$node_(0) set X_ 50.0
$node_(0) set Y_ 500.0
$node_(1) set X_ 150.0
$node_(1) set Y_ 500.0
$node_(2) set X_ 250.0
$node_(2) set Y_ 500.0
$node_(3) set X_ 350.0
$node_(3) set Y_ 500.0
$ns_ at 15.0 "$node_(2) setdest 250.0 900.0 50.0"
"""


@pytest.mark.parametrize("channel, hello", [({}, {}), ({"mac": "csma"}, {"hello": False})])
def test_route_error_reaches_the_source_when_a_link_of_its_route_breaks(tmp_path, channel, hello):
    """Robot 2 of the line 0-1-2-3 walks away while 0 sends to 3: robot 1 finds the link
    broken when a packet does not get through (link-layer detection), drops that packet
    there, invalidates its routes through 2 and sends a RERR to its precursor 0, whose
    route to 3 becomes invalid too; later packets wait for a new route. On a shared medium
    without hellos the unicast that fails after its retries is what says so (it was lost to
    the router, which then lost every later packet on the dead route)."""
    flow = {"src": 0, "dst": 3, "start_s": 10.0, "stop_s": 25.0, "rate_bps": 8000.0, "packet_bytes": 1000}
    protocol = {"model": "aodv", **hello}
    sim, frames = flow_over_trace(tmp_path, BREAK, 4, flow, 30.0, 2, {"range_m": 120.0, **channel}, protocol)
    aodv = sim.models["protocol"]
    assert not aodv.tables[1].routes[3].valid and not aodv.tables[0].routes[3].valid
    control = frames["control"].set_index("kind")
    assert control.loc["rerr", "sent"] >= 1 and control.loc["rerr", "received"] >= 1
    packets = frames["packets"]
    lost = packets[packets["drop_cause"] == "lost"]
    assert len(lost) == 1 and lost["drop_robot"].iloc[0] == 1
    assert packets[packets["t_sent_s"] < 15.0]["delivered"].all()
    assert (packets[packets["t_sent_s"] > lost["t_sent_s"].iloc[0]]["drop_cause"] == "in_flight").all()


DIAMOND = """$node_(0) set X_ 100.0
$node_(0) set Y_ 500.0
$node_(1) set X_ 200.0
$node_(1) set Y_ 550.0
$node_(2) set X_ 200.0
$node_(2) set Y_ 900.0
$node_(3) set X_ 300.0
$node_(3) set Y_ 500.0
$ns_ at 2.5 "$node_(2) setdest 200.0 450.0 1000.0"
$ns_ at 4.6 "$node_(1) setdest 200.0 950.0 1000.0"
"""


def test_a_source_whose_next_hop_missed_its_hellos_breaks_the_link_before_it_rediscovers(tmp_path):
    """Source 0 reaches 3 through 1; 2 joins as another relay, then 1 walks away. Its
    hellos stop, so 0's next packet starts a route discovery: 0 must first break the link
    to 1 (section 6.11: its route becomes invalid, its sequence number increased), or the
    reply through 2, as fresh and as short, cannot replace the stale route, and the packet
    that waited for it follows that route into the void (it was dropped no_route at 0)."""
    flow = {"src": 0, "dst": 3, "start_s": 2.0, "stop_s": 13.0, "rate_bps": 1600, "packet_bytes": 500}
    sim, frames = flow_over_trace(tmp_path, DIAMOND, 4, flow, 14.0, 1, {"range_m": 150.0}, {"model": "aodv"})
    packets = frames["packets"]
    assert len(packets) == 5 and packets["delivered"].all(), packets[["t_sent_s", "delivered", "drop_cause"]]
    assert sim.models["protocol"].tables[0].routes[3].next_hop == 2


def test_a_robots_buffer_holds_queue_packets_whatever_their_destinations(tmp_path):
    """Robot 0 sends 10 packets to each of two robots no route reaches, with room for 4:
    4 wait in all (then no_route when discovery gives up) and the other 16 are queue_full
    (each destination had a buffer of its own: 8 waited). A full buffer drops its most aged
    packet, as ns-3's request queue does: the 4 sent last are the ones that waited."""
    xy = [(100, 500), (200, 500), (300, 500), (900, 100), (900, 900)]
    flows = [
        {"src": 0, "dst": dst, "start_s": 1.0, "stop_s": 2.0, "rate_bps": 40000.0, "packet_bytes": 500}
        for dst in (3, 4)
    ]
    _sim, frames = _run(tmp_path, xy, flows, duration_s=30.0, queue_packets=4)
    packets = frames["packets"]
    causes = packets["drop_cause"].value_counts().to_dict()
    assert causes == {"queue_full": 16, "no_route": 4}, causes
    waited = packets.sort_values(["t_sent_s", "flow"]).tail(4)
    assert (waited["drop_cause"] == "no_route").all(), packets[["flow", "t_sent_s", "drop_cause"]]


def test_a_hello_or_a_rreq_makes_the_route_to_its_sender_active_whatever_its_sequence_number():
    """A robot heard directly is a neighbour: its hello makes the route to it one hop and
    active (section 6.9), with the hello's sequence number, even where a broken link raised
    the table's number above it; a RREQ does the same for its previous hop (section 6.5),
    bringing no sequence number: a known one is kept, valid if it was. Neither shortens the
    route's life."""
    t = RouteTable()
    t.offer(1, 1, 1, 0, True, 10.0)
    t.break_link(1, now=5.0, delete_period_s=15.0)
    assert not t.routes[1].valid and t.routes[1].seq == 1
    t.neighbour(1, seq=0, expires_s=10.0)
    r = t.routes[1]
    assert r.valid and (r.next_hop, r.hops, r.seq, r.valid_seq) == (1, 1, 0, True) and r.expires_s == 20.0
    t.break_link(1, now=21.0, delete_period_s=15.0)
    t.neighbour(1, seq=None, expires_s=24.0)
    r = t.routes[1]
    assert r.valid and (r.hops, r.seq, r.valid_seq) == (1, 1, True) and r.expires_s == 36.0
    t.neighbour(2, seq=None, expires_s=24.0)
    assert (t.routes[2].hops, t.routes[2].valid, t.routes[2].valid_seq) == (1, True, False)


BACK_AGAIN = """$node_(0) set X_ 100.0
$node_(0) set Y_ 500.0
$node_(1) set X_ 200.0
$node_(1) set Y_ 500.0
$ns_ at 5.0 "$node_(1) setdest 200.0 900.0 400.0"
$ns_ at 7.0 "$node_(1) setdest 200.0 500.0 400.0"
"""


def test_a_neighbour_back_in_range_is_reached_once_its_hello_is_heard(tmp_path):
    """Robot 1 leaves robot 0's range and comes back: once 0 hears its hellos again, the
    packets 0 sends it go straight, though the broken link raised the route's sequence
    number above the hello's."""
    flow = {"src": 0, "dst": 1, "start_s": 1.0, "stop_s": 20.0, "rate_bps": 8000.0, "packet_bytes": 500}
    sim, frames = flow_over_trace(tmp_path, BACK_AGAIN, 2, flow, 20.0, 1, {"range_m": 150.0}, {"model": "aodv"})
    packets = frames["packets"]
    back = packets[packets["t_sent_s"] >= 9.5]
    assert len(back) > 10 and back["delivered"].all()
    assert back["latency_s"].max() < 0.1, back[["t_sent_s", "latency_s"]]


def test_an_intermediate_robot_answers_a_rreq_that_knows_no_destination_number(tmp_path, monkeypatch):
    """Section 6.6.2 with the RREQ's unknown-number flag: robot 1 holds a valid route to 3
    (its own flow found it); robot 0, which knows no number for 3, asks, and robot 1 answers
    from its route (two hops to go) instead of passing the RREQ on to 3, as ns-3 does."""
    from netsim.protocols.aodv import Aodv

    answers: list[tuple[int, int, int, int]] = []
    real = Aodv._send_rrep

    def recorded(self, r, rrep):
        answers.append((r, rrep.orig, rrep.dst, rrep.hops))
        return real(self, r, rrep)

    monkeypatch.setattr(Aodv, "_send_rrep", recorded)
    first = {"src": 1, "dst": 3, "start_s": 10.0, "stop_s": 10.5, "rate_bps": 8000.0, "packet_bytes": 1000}
    then = {**first, "src": 0, "start_s": 11.0, "stop_s": 11.5}
    sim, frames = _run(tmp_path, [(50 + 100 * i, 500) for i in range(4)], [first, then], duration_s=15.0)
    asked = [(r, hops) for r, orig, dst, hops in answers if orig == 0 and dst == 3]
    assert asked and asked[0] == (1, 2), answers
    assert frames["packets"]["delivered"].all()


def test_an_offer_without_a_valid_sequence_number_keeps_the_number_the_table_holds():
    """A route learnt without a valid sequence number (a RREP's sender, a RREQ's previous
    hop: RFC 3561 6.2, 6.5) replaces a route whose number is not valid either, but keeps the
    number the table held, raised by the broken link, for the RREQ and the RERR that name
    it: the offer's placeholder 0 would send a number older than the one already lost."""
    t = RouteTable()
    t.neighbour(2, seq=None, expires_s=10.0)
    t.break_link(2, now=5.0, delete_period_s=15.0)
    assert (t.routes[2].seq, t.routes[2].valid_seq, t.routes[2].valid) == (1, False, False)
    assert t.offer(2, next_hop=2, hops=1, seq=0, valid_seq=False, expires_s=30.0)
    r = t.routes[2]
    assert (r.next_hop, r.hops, r.seq, r.valid_seq, r.valid, r.expires_s) == (2, 1, 1, False, True, 30.0)


def test_the_same_route_offered_again_only_extends_its_lifetime():
    """An offer that is not fresher (RFC 3561 6.2) leaves the route as it is; when it is
    the very route the table holds (same next hop, same hop count) its lifetime is the
    longer of the two, never shortened; an offer through the same next hop but of another
    hop count is another route and extends nothing."""
    t = RouteTable()
    t.offer(9, next_hop=1, hops=4, seq=10, valid_seq=True, expires_s=100.0)
    assert not t.offer(9, 1, 4, 10, True, 200.0) and t.routes[9].expires_s == 200.0
    assert not t.offer(9, 1, 4, 10, True, 150.0) and t.routes[9].expires_s == 200.0
    assert not t.offer(9, 1, 5, 10, True, 300.0)
    assert (t.routes[9].hops, t.routes[9].expires_s) == (4, 200.0)


def test_a_rerr_gives_the_invalidated_route_its_sequence_number():
    """RFC 3561 6.11: a route a RERR invalidates takes the destination sequence number the
    RERR lists (not its own, older one), so that a later RREQ asks for a route at least that
    fresh, and it is kept for DELETE_PERIOD."""
    t = RouteTable()
    t.offer(3, next_hop=1, hops=2, seq=10, valid_seq=True, expires_s=100.0)
    t.on_rerr(1, [(3, 12)], now=50.0, delete_period_s=15.0)
    r = t.routes[3]
    assert (r.valid, r.seq, r.expires_s) == (False, 12, 65.0)


def test_a_hello_keeps_the_route_to_its_sender_for_allowed_hello_loss_intervals(tmp_path):
    """RFC 3561 6.9: a hello's lifetime is ALLOWED_HELLO_LOSS * HELLO_INTERVAL, and the
    route to its sender lives that long after the last hello heard (no flow renews it)."""
    sim, _frames = _run(tmp_path, [(100, 500), (200, 500)], [], duration_s=10.0, allowed_hello_loss=3)
    aodv = sim.models["protocol"]
    heard = aodv.hello_heard[0][1]
    assert heard > 7.0 and aodv.tables[0].routes[1].expires_s == pytest.approx(heard + 3 * 1.0)


def _aodv(n=4):
    """An AODV router of ``n`` robots, built and not run (its clock at 0)."""
    return build(make_config(world={"n_robots": n}, protocol={"model": "aodv"})).models["protocol"]


def _sent(router):
    """The control frames ``router`` sends from now on, ``(sender, payload, kind, dest)``
    each, kept instead of put on the channel."""
    sent = []

    def control(sender, payload, deliver, kind, dest=-1, messages=1):
        sent.append((sender, payload, kind, dest))

    router.control = control
    return sent


def test_a_relay_with_no_route_for_a_packet_broadcasts_a_rerr_for_its_destination():
    """RFC 3561 6.11 (ii): a robot that holds data for a destination it has no active route
    to, and is not the data's source, broadcasts a RERR naming that destination (the source
    seeks a route instead)."""
    from netsim.protocols.aodv import Rerr
    from netsim.protocols.routing import Packet

    aodv = _aodv()
    sent = _sent(aodv)
    pkt = Packet(0, src=0, dst=3, ttl=35, hops=1, kind="data", t_sent_s=0.0)
    assert aodv.next_hop(1, pkt) == (-1, "no_route")
    assert sent == [(1, Rerr(((3, 0),)), "rerr_1", -1)]
    sent.clear()
    assert aodv.next_hop(0, pkt) == (-1, "no_route") and sent == []


def test_forwarding_on_a_route_keeps_the_routes_to_its_next_hop_and_back_to_the_source():
    """RFC 3561 6.2: each time a route forwards data, the routes to the destination, to the
    next hop and back to the source live ACTIVE_ROUTE_TIMEOUT from now at least."""
    from netsim.protocols.routing import Packet

    aodv = _aodv()
    t = aodv.tables[1]
    for dst, nh in ((3, 2), (2, 2), (0, 0)):
        t.offer(dst, nh, 1 + (dst == 3), 1, True, 0.5)
    assert aodv.next_hop(1, Packet(0, src=0, dst=3, ttl=35, hops=1, kind="data", t_sent_s=0.0)) == (2, "")
    assert [t.routes[d].expires_s for d in (3, 2, 0)] == [3.0, 3.0, 3.0]


def test_a_route_discovery_raises_the_sources_number_and_starts_past_the_last_known_hops():
    """RFC 3561 6.1: a source increments its own sequence number before it starts a route
    discovery; 6.4: for a destination it had a route to, the first ring's TTL is the last
    known hop count plus TTL_INCREMENT (4 + 2), not TTL_START."""
    from netsim.protocols.aodv import Route
    from netsim.protocols.routing import Packet

    aodv = _aodv()
    aodv.tables[0].routes[3] = Route(next_hop=1, hops=4, seq=5, valid_seq=True, expires_s=-1.0, valid=False)
    # A neighbour heard in a RREQ: a route with no valid number, so the RREQ asks for none.
    aodv.tables[0].neighbour(2, seq=None, expires_s=-1.0)
    sent = _sent(aodv)
    for dst in (3, 2):
        aodv.originate(0, Packet(dst, src=0, dst=dst, ttl=35, hops=0, kind="data", t_sent_s=0.0))
    assert [(q.ttl, q.orig_seq, q.dst_seq, q.unknown_seq) for _, q, _, _ in sent] == [(6, 1, 5, False), (3, 2, 0, True)]
    assert aodv.own_seq[0] == 2 and aodv.rreqs_originated == [(0.0, 0, 3, 6), (0.0, 0, 2, 3)]


def test_rreqs_wait_a_ring_traversal_time_then_double_at_net_diameter(tmp_path):
    """RFC 3561 6.4: after a RREQ of TTL t the source waits RING_TRAVERSAL_TIME = 2
    NODE_TRAVERSAL_TIME (t + TIMEOUT_BUFFER); at NET_DIAMETER, NET_TRAVERSAL_TIME = 2
    NODE_TRAVERSAL_TIME NET_DIAMETER, doubled on every retry (6.3's binary exponential backoff)."""
    p = AodvParams()
    assert p.ring_traversal_time_s(5) == pytest.approx(2 * 0.04 * (5 + 2))
    assert (p.net_traversal_time_s, p.path_discovery_time_s) == pytest.approx((2.8, 5.6))
    assert (p.my_route_timeout_s, p.delete_period_s) == pytest.approx((6.0, 15.0))
    assert AodvParams(hello_interval_s=4.0).delete_period_s == pytest.approx(20.0)
    flow = {"src": 0, "dst": 2, "start_s": 10.0, "stop_s": 10.5, "rate_bps": 8000.0, "packet_bytes": 1000}
    sim, _frames = _run(tmp_path, [(50, 500), (150, 500), (900, 900)], [flow], duration_s=40.0)
    times = [t for t, _, _, _ in sim.models["protocol"].rreqs_originated]
    assert np.diff(times) == pytest.approx([0.24, 0.40, 0.56, 0.72, 2.8, 5.6])


def test_a_rreq_sets_the_reverse_route_for_its_minimal_lifetime():
    """RFC 3561 6.5: a RREQ heard from a neighbour makes the route back to its originator,
    one hop longer than the RREQ came, living at least MinimalLifetime = 2
    NET_TRAVERSAL_TIME - 2 HopCount NODE_TRAVERSAL_TIME, with the originator's number. A
    route back through the same neighbour that the RREQ does not replace (as fresh and
    shorter) lives that long too: max(ExistingLifetime, MinimalLifetime)."""
    from netsim.protocols.aodv import Rreq

    aodv = _aodv()
    rreq = Rreq(orig=0, rreq_id=1, dst=3, dst_seq=0, unknown_seq=True, orig_seq=4, hops=1, ttl=5)
    aodv.tables[3].offer(0, next_hop=1, hops=1, seq=4, valid_seq=True, expires_s=1.0)
    aodv._on_rreq(1, np.array([2, 3]), rreq)
    r = aodv.tables[2].routes[0]
    assert (r.next_hop, r.hops, r.seq, r.valid_seq) == (1, 2, 4, True)
    assert r.expires_s == pytest.approx(2 * 2.8 - 2 * 2 * 0.04)
    kept = aodv.tables[3].routes[0]
    assert (kept.hops, kept.expires_s) == (1, pytest.approx(2 * 2.8 - 2 * 2 * 0.04))


def test_an_intermediate_robot_answers_a_rreq_whose_number_its_route_matches():
    """RFC 3561 6.6: a robot with an active route to the destination answers a RREQ when
    its destination sequence number is at least the RREQ's, equal included; an older one
    (the RREQ asks for 8, the route has 7) does not answer and passes the RREQ on, nor does
    a route whose next hop is the RREQ's sender (the reply would point back the way it came)."""
    from netsim.protocols.aodv import Rrep, Rreq

    for asked, via, answers in ((7, 3, True), (6, 3, True), (8, 3, False), (7, 1, False)):
        aodv = _aodv()
        aodv.tables[2].offer(3, next_hop=via, hops=1, seq=7, valid_seq=True, expires_s=10.0)
        sent = _sent(aodv)
        aodv._on_rreq(1, np.array([2]), Rreq(0, 1, 3, asked, False, 1, 1, 5))
        assert sent == ([(2, Rrep(3, 7, 0, 1, 10.0), "rrep", 1)] if answers else []), (asked, via, sent)


def test_a_forwarded_rreq_asks_for_the_freshest_number_the_robot_knows():
    """RFC 3561 6.5: a robot passing a RREQ on sets its destination sequence number to the
    larger of the RREQ's and the one its own table holds for the destination (here an
    invalid route with 9 against the RREQ's 7), one hop more and one TTL less."""
    from netsim.protocols.aodv import Route, Rreq

    aodv = _aodv()
    aodv.tables[2].routes[3] = Route(next_hop=3, hops=1, seq=9, valid_seq=True, expires_s=10.0, valid=False)
    aodv._later = lambda _delay, fn, *args: fn(*args)
    sent = _sent(aodv)
    aodv._on_rreq(1, np.array([2]), Rreq(0, 1, 3, 7, False, 1, 1, 5))
    assert sent == [(2, Rreq(0, 1, 3, 9, False, 1, 2, 4), "rreq", -1)]


def test_a_rrep_sets_the_forward_route_for_its_lifetime_and_notes_the_precursors():
    """RFC 3561 6.7: a RREP makes the route to its destination through the robot it came
    from, one hop longer, with its number, expiring its Lifetime from now (6 s here, not
    ACTIVE_ROUTE_TIMEOUT); a robot passing it on toward the originator notes the next hop
    back as a precursor of the forward route, and the forward next hop of the route back."""
    from netsim.protocols.aodv import Rrep

    aodv = _aodv()
    aodv.tables[1].offer(0, next_hop=0, hops=1, seq=1, valid_seq=True, expires_s=1.0)
    sent = _sent(aodv)
    aodv._on_rrep(2, np.array([1]), Rrep(dst=3, dst_seq=5, orig=0, hops=1, lifetime_s=6.0))
    fwd, back = aodv.tables[1].routes[3], aodv.tables[1].routes[0]
    assert (fwd.next_hop, fwd.hops, fwd.seq, fwd.expires_s) == (2, 2, 5, 6.0)
    assert (fwd.precursors, back.precursors) == ({0}, {2})
    assert sent == [(1, Rrep(3, 5, 0, 2, 6.0), "rrep", 0)]


def test_a_rerr_to_a_single_precursor_is_a_unicast_and_its_size_grows_with_its_destinations():
    """RFC 3561 6.11: a RERR goes by unicast when the lost routes had one precursor, else by
    broadcast, and none goes when nobody used them; it lists every unreachable destination,
    its size RERR_BYTES_BASE + 8 bytes a destination (RFC 3561 section 5)."""
    from netsim.protocols.aodv import Rerr

    aodv = _aodv()
    sent = _sent(aodv)
    aodv._send_rerr(1, [(3, 11, {0}), (2, 4, {0})])
    aodv._send_rerr(1, [(3, 11, {0, 2})])
    aodv._send_rerr(1, [(3, 11, set())])
    assert sent == [(1, Rerr(((3, 11), (2, 4))), "rerr_2", 0), (1, Rerr(((3, 11),)), "rerr_1", -1)]
    assert (aodv.control_bytes["rerr_2"], aodv.control_bytes["rerr_1"]) == (20, 12)


def test_a_route_is_active_up_to_its_expiry_instant_included():
    """A route lives until its lifetime runs out, its expiry instant included (ns-3's
    routing table invalidates a route when its remaining lifetime is below zero); past it,
    the lookup makes it invalid."""
    t = RouteTable()
    t.offer(9, next_hop=1, hops=2, seq=1, valid_seq=True, expires_s=13.0)
    assert t.active(9, 13.0) is t.routes[9]
    assert t.active(9, 13.0 + 1e-9) is None and not t.routes[9].valid


def _ticks(aodv):
    """The hello ticks ``aodv`` schedules from now on, ``(delay_s, robot)`` each, kept
    instead of put on the agenda; a hello's jitter drawn at its middle (one interval), a
    passed-on RREQ's at none."""
    ticks = []
    aodv._later = lambda delay_s, fn, *args: ticks.append((delay_s, *args))
    aodv._rng = type("Middle", (), {"random": staticmethod(lambda: 0.5), "uniform": staticmethod(lambda a, b: a)})()
    return ticks


def test_a_rreq_broadcast_since_the_last_hello_stands_for_the_next_one():
    """RFC 3561 6.9 (as ns-3's HelloTimerExpire): a robot that broadcast a RREQ since its
    hello timer last ran sends no hello at this tick, and its next tick comes one interval
    after that RREQ; with no RREQ since, it sends the hello and waits an interval."""
    from types import SimpleNamespace

    from netsim.protocols.aodv import Rreq

    aodv = _aodv()
    sent, ticks = _sent(aodv), _ticks(aodv)
    aodv.env = SimpleNamespace(now=0.4)  # a clock of its own: no other robot's tick runs
    aodv._send_rreq(2, 3, type("D", (), {"ttls": [1], "retries_at_diameter": 0})())
    assert aodv.last_rreq_s[2] == pytest.approx(0.4)
    aodv.env.now = 1.0
    ticks.clear()
    aodv._hello_tick(2)
    assert [k for _, _, k, _ in sent] == ["rreq"]  # no hello
    assert ticks == [(pytest.approx(0.4), 2)]  # an interval after the RREQ at 0.4 s
    aodv._hello_tick(2)
    assert [k for _, _, k, _ in sent] == ["rreq", "hello"] and ticks[-1] == (pytest.approx(1.0), 2)
    # A RREQ passed on counts too, and a RREQ heard keeps the link to its sender up.
    aodv._later = lambda delay_s, fn, *args: None
    aodv._on_rreq(0, np.array([1]), Rreq(0, 1, 3, 0, True, 1, 0, 5))
    assert aodv.last_rreq_s[1] == pytest.approx(1.0) and aodv.hello_heard[1][0] == pytest.approx(1.0)


def test_hellos_go_out_whatever_the_rreqs_when_not_deferred():
    aodv = build(
        make_config(world={"n_robots": 4}, protocol={"model": "aodv", "hello_deferred_by_broadcast": False})
    ).models["protocol"]
    sent = _sent(aodv)
    _ticks(aodv)
    aodv._send_rreq(2, 3, type("D", (), {"ttls": [1], "retries_at_diameter": 0})())
    aodv._hello_tick(2)
    assert [k for _, _, k, _ in sent] == ["rreq", "hello"] and aodv.last_rreq_s[2] is None


def test_an_intermediate_robot_that_answers_sends_the_destination_a_gratuitous_rrep():
    """RFC 3561 6.6.3: when the RREQ has the G flag, the robot that answers it from its own
    route also unicasts the destination a RREP for the originator (the hops and lifetime of
    its route back, the originator's sequence number), along its route to the destination."""
    from netsim.protocols.aodv import Rrep, Rreq

    for flag in (True, False):
        aodv = _aodv()
        aodv.tables[2].offer(3, next_hop=3, hops=1, seq=7, valid_seq=True, expires_s=10.0)
        sent = _sent(aodv)
        aodv._on_rreq(1, np.array([2]), Rreq(0, 1, 3, 7, False, 4, 1, 5, flag))
        back = aodv.tables[2].routes[0]
        answer = (2, Rrep(3, 7, 0, 1, 10.0), "rrep", 1)
        gratuitous = (2, Rrep(0, 4, 3, 2, back.expires_s), "rrep", 3)
        assert sent == ([answer, gratuitous] if flag else [answer]), flag


def test_a_gratuitous_rrep_gives_the_destination_its_route_to_the_originator(tmp_path):
    """On a line 0-1-2-3, robot 1 first finds 3; then 0 asks for 3 and 1 answers from its
    route. With the G flag (ns-3's default) 3 learns the way back to 0 without asking;
    without it 3 never heard of 0."""
    line = [(100 * k, 500) for k in range(4)]
    flows = [
        {"src": 1, "dst": 3, "start_s": 1.0, "stop_s": 4.0, "rate_bps": 4096.0, "packet_bytes": 512},
        {"src": 0, "dst": 3, "start_s": 5.0, "stop_s": 8.0, "rate_bps": 4096.0, "packet_bytes": 512},
    ]
    routes = {}
    for flag in (True, False):
        sim, frames = _run(tmp_path, line, flows, duration_s=9.0, gratuitous_reply=flag)
        assert frames["packets"]["delivered"].all()
        routes[flag] = sim.models["protocol"].tables[3].routes.get(0)
    assert routes[True] is not None and (routes[True].next_hop, routes[True].hops) == (2, 3)
    assert routes[False] is None


def test_a_rreq_known_unknown_is_passed_on_with_the_number_the_robot_knows_and_u_cleared():
    """RFC 3561 6.5 and 6.6.1 (ns-3's RecvRequest): a RREQ whose U flag says its
    originator knows no number for the destination is passed on with the valid number the
    robot knows and the flag cleared, so that the destination raises its own to it; left
    set, a destination whose number a broken link made older than a relay's answered with
    that older number, and the relay refused the route."""
    from netsim.protocols.aodv import Route, Rreq

    aodv = _aodv()
    aodv.tables[2].routes[3] = Route(next_hop=3, hops=1, seq=9, valid_seq=True, expires_s=10.0, valid=False)
    aodv._later = lambda _delay, fn, *args: fn(*args)
    sent = _sent(aodv)
    aodv._on_rreq(1, np.array([2]), Rreq(0, 1, 3, 0, True, 1, 1, 5))
    ((_, out, _, _),) = sent
    assert (out.dst_seq, out.unknown_seq) == (9, False)
    aodv.own_seq[3] = 1
    aodv._on_rreq(2, np.array([3]), out)
    assert aodv.own_seq[3] == 9


def test_every_copy_of_a_rreq_counts_as_a_hello():
    """RFC 3561 6.9: a link is lost when no packet of the neighbour was heard for
    ALLOWED_HELLO_LOSS hello intervals, hellos or otherwise: a copy of a RREQ a neighbour passes on keeps its
    link up even when the robot had the RREQ already (a robot that broadcast it skips its
    hello)."""
    from types import SimpleNamespace

    from netsim.protocols.aodv import Rreq

    aodv = _aodv()
    aodv._later = lambda _delay, fn, *args: None
    rreq = Rreq(0, 1, 3, 0, True, 1, 0, 5)
    aodv.env = SimpleNamespace(now=1.0)
    aodv._on_rreq(0, np.array([1]), rreq)
    aodv.env.now = 1.5
    aodv._on_rreq(2, np.array([1]), rreq._replace(hops=1))
    assert aodv.hello_heard[1] == {0: 1.0, 2: 1.5}
    aodv.env.now = 3.2  # 1.7 s after 2's copy: within two intervals, not lost
    assert not aodv._neighbour_lost(1, 2, 3.2) and aodv._neighbour_lost(1, 0, 3.2)


def test_no_gratuitous_rrep_without_an_active_route_back():
    """An intermediate robot whose route back to the originator is not active (a fresher
    route through another neighbour, which the RREQ does not replace, has expired) sends
    neither its answer nor a gratuitous RREP (whose lifetime would be that route's, already
    past)."""
    from types import SimpleNamespace

    from netsim.protocols.aodv import Rreq

    aodv = _aodv(5)
    aodv.env = SimpleNamespace(now=5.0)
    aodv.tables[2].offer(3, next_hop=3, hops=1, seq=7, valid_seq=True, expires_s=10.0)
    aodv.tables[2].offer(0, next_hop=4, hops=2, seq=50, valid_seq=True, expires_s=1.0)
    sent = _sent(aodv)
    aodv._on_rreq(1, np.array([2]), Rreq(0, 1, 3, 7, False, 4, 1, 5, True))
    assert sent == []


def test_an_offer_without_a_valid_sequence_number_never_replaces_a_valid_one():
    """RFC 3561 6.2 (docs/routing.md): an offered route replaces a known one only if the known
    has no valid sequence number, or the offer's is newer, or the same and shorter. An offer
    with no valid number (a RREP's sender, a RREQ's previous hop) never replaces a route whose
    number is valid, even a route numbered 0 and longer than the offer."""
    t = RouteTable()
    t.offer(9, next_hop=1, hops=3, seq=0, valid_seq=True, expires_s=100.0)
    assert not fresher(t.routes[9], 0, False, 1)
    assert not t.offer(9, 2, 1, 0, False, 100.0)
    assert (t.routes[9].next_hop, t.routes[9].hops, t.routes[9].valid_seq) == (1, 3, True)


def test_a_fresher_route_keeps_the_precursors_of_the_route_it_replaces():
    """A route replaced by a fresher one (RFC 3561 6.2) keeps its precursor list: the robots
    that send through this one still do, and the RERR of a later break of the new next hop
    must reach them (6.11), as ns-3's entry, updated in place, keeps them."""
    t = RouteTable()
    t.offer(9, next_hop=1, hops=3, seq=10, valid_seq=True, expires_s=100.0)
    t.routes[9].precursors.add(8)
    assert t.offer(9, 2, 2, 11, True, 100.0)
    assert t.routes[9].precursors == {8}
    assert t.break_link(2, now=50.0, delete_period_s=15.0) == [(9, 12, {8})]


def test_a_stale_offer_leaves_an_invalid_route_as_it_is():
    """An offer older than the route the table holds changes nothing (RFC 3561 6.2): an
    invalid route, kept for DELETE_PERIOD with the number its broken link raised, keeps that
    number and that lifetime when the same path is offered again with its old number."""
    t = RouteTable()
    t.offer(9, next_hop=1, hops=2, seq=10, valid_seq=True, expires_s=100.0)
    t.break_link(1, now=50.0, delete_period_s=15.0)
    assert not t.offer(9, 1, 2, 10, True, 500.0)
    r = t.routes[9]
    assert (r.valid, r.seq, r.expires_s) == (False, 11, 65.0)


def test_a_broken_link_names_only_the_routes_still_valid_through_it():
    """RFC 3561 6.11 (i): a broken link's RERR lists the destinations of the *active* routes
    through it; a route through it that is already invalid is not listed again, and its
    sequence number is not raised a second time (nor its DELETE_PERIOD restarted)."""
    t = RouteTable()
    for dst in (3, 4):
        t.offer(dst, next_hop=1, hops=2, seq=10, valid_seq=True, expires_s=100.0)
    t.break_link(1, now=50.0, delete_period_s=15.0)
    assert t.offer(4, 1, 2, 11, True, 100.0) and t.routes[4].valid
    lost = t.break_link(1, now=60.0, delete_period_s=15.0)
    assert [(d, s) for d, s, _ in lost] == [(4, 12)]
    assert (t.routes[3].seq, t.routes[3].expires_s) == (11, 65.0)


def test_aodv_hellos_are_sent_every_interval_jittered_by_a_quarter(tmp_path):
    """docs/routing.md: hellos are broadcast every hello_interval_s, jittered by a quarter:
    each robot's successive hellos are 0.75 to 1.25 intervals apart (and spread over that
    range, so that neighbours do not lock step)."""
    path = tmp_path / "robots.csv"
    path.write_text("x_m,y_m\n" + "".join(f"{50 + 100 * i},500\n" for i in range(4)))
    config = make_config(
        seed=5,
        duration_s=40.0,
        world={"n_robots": 4, "side_m": 1000.0, "placement": str(path)},
        mobility={"model": "static"},
        channel={"range_m": 120.0},
        protocol={"model": "aodv"},
        output={"position_interval_s": 0.0},
    )
    sim = build(config)
    aodv = sim.models["protocol"]
    times: dict[int, list[float]] = {}
    real = aodv.control

    def control(sender, payload, deliver, kind, dest=-1, messages=1):
        if kind == "hello":
            times.setdefault(sender, []).append(aodv.env.now)
        return real(sender, payload, deliver, kind, dest, messages)

    aodv.control = control
    sim.run()
    gaps = np.concatenate([np.diff(t) for t in times.values()])
    assert len(times) == 4 and len(gaps) > 100
    assert gaps.min() >= 0.75 - 1e-9 and gaps.max() <= 1.25 + 1e-9, (gaps.min(), gaps.max())
    assert gaps.max() - gaps.min() > 0.4


def test_a_next_hop_is_lost_after_more_than_allowed_hello_loss_intervals_without_its_hello():
    """RFC 3561 6.9: a neighbour not heard for more than ALLOWED_HELLO_LOSS * HELLO_INTERVAL
    (2 s here) is a lost link: found when a packet would take a route through it, which it
    invalidates (6.11). Exactly 2 s after its last hello it is still a neighbour."""
    aodv = _aodv()
    t = aodv.tables[0]
    t.offer(1, next_hop=1, hops=1, seq=1, valid_seq=True, expires_s=100.0)
    t.offer(3, next_hop=1, hops=2, seq=5, valid_seq=True, expires_s=100.0)
    aodv.hello_heard[0][1] = 10.0
    _sent(aodv)
    assert aodv._route(0, 3, 12.0) is t.routes[3]
    assert aodv._route(0, 3, 12.01) is None
    assert not t.routes[3].valid and not t.routes[1].valid


def test_a_link_broken_for_missed_hellos_is_not_broken_again_before_a_new_hello():
    """A link found lost for missed hellos (RFC 3561 6.9, 6.11) is broken once: a fresher
    route through that neighbour learnt afterwards (its RREP) is used, not thrown away at
    once for the hellos already counted missed."""
    aodv = _aodv()
    t = aodv.tables[0]
    t.offer(3, next_hop=1, hops=2, seq=5, valid_seq=True, expires_s=100.0)
    aodv.hello_heard[0][1] = 10.0
    _sent(aodv)
    assert aodv._route(0, 3, 12.5) is None
    assert t.offer(3, 1, 2, 7, True, 100.0)
    assert aodv._route(0, 3, 12.6) is t.routes[3]


def test_an_intermediate_robot_that_answers_notes_the_precursors_of_both_routes():
    """RFC 3561 6.6.2: an intermediate robot answering a RREQ from its route puts the RREQ's
    last hop in the precursor list of its forward route, and its next hop toward the
    destination in the precursor list of the reverse route, so that a later break on either
    side sends a RERR to the robots that use it."""
    from netsim.protocols.aodv import Rreq

    aodv = _aodv()
    aodv.tables[2].offer(3, next_hop=3, hops=1, seq=7, valid_seq=True, expires_s=10.0)
    _sent(aodv)
    aodv._on_rreq(1, np.array([2]), Rreq(0, 1, 3, 7, False, 1, 1, 5))
    assert aodv.tables[2].routes[3].precursors == {1}
    assert aodv.tables[2].routes[0].precursors == {3}


def test_a_robot_that_died_does_not_rebroadcast_a_rreq():
    """A RREQ's rebroadcast waits a jitter; a robot that died meanwhile sends nothing (a dead
    robot neither sends nor relays), one alive does."""
    from netsim.protocols.aodv import Rreq

    aodv = _aodv()
    sent = _sent(aodv)
    aodv.state.alive[2] = False
    rreq = Rreq(0, 1, 3, 0, True, 1, 1, 5)
    aodv._rebroadcast_rreq(2, rreq)
    aodv._rebroadcast_rreq(1, rreq)
    assert [sender for sender, _, _, _ in sent] == [1]


def test_a_rrep_makes_the_route_to_its_previous_hop_and_renews_the_reverse_route():
    """RFC 3561 6.7: a robot receiving a RREP makes a route to the robot it came from (one
    hop, without a valid sequence number, ACTIVE_ROUTE_TIMEOUT long); passing it on, the
    reverse route it uses lives max(existing, now + ACTIVE_ROUTE_TIMEOUT)."""
    from netsim.protocols.aodv import Rrep

    aodv = _aodv()
    aodv.tables[1].offer(0, next_hop=0, hops=1, seq=1, valid_seq=True, expires_s=1.0)
    _sent(aodv)
    aodv._on_rrep(2, np.array([1]), Rrep(dst=3, dst_seq=5, orig=0, hops=1, lifetime_s=6.0))
    prev = aodv.tables[1].routes[2]
    assert (prev.next_hop, prev.hops, prev.valid, prev.valid_seq, prev.expires_s) == (2, 1, True, False, 3.0)
    assert aodv.tables[1].routes[0].expires_s == 3.0


def test_a_rerr_is_passed_on_to_the_precursors_of_the_routes_it_invalidates():
    """RFC 3561 6.11 (iii), 6.12: a robot that receives a RERR from the next hop of its
    routes invalidates them and sends a RERR of those destinations on to their precursors
    (a unicast to a single one); destinations it does not route through the sender are not
    passed on."""
    from netsim.protocols.aodv import Rerr

    aodv = _aodv()
    t = aodv.tables[1]
    t.offer(3, next_hop=2, hops=2, seq=10, valid_seq=True, expires_s=100.0)
    t.routes[3].precursors.add(0)
    sent = _sent(aodv)
    aodv._on_rerr(2, np.array([1]), Rerr(((3, 12), (5, 4))))
    assert sent == [(1, Rerr(((3, 12),)), "rerr_1", 0)]


def test_a_forwarded_rreq_waits_a_jitter_of_up_to_jitter_s():
    """docs/routing.md: a robot rebroadcasts a RREQ once, after U(0, jitter_s) (10 ms by
    default: RFC 5148), so that neighbours that heard it together do not send together."""
    from netsim.protocols.aodv import Rreq

    aodv = _aodv()
    delays: list[float] = []
    aodv._later = lambda delay_s, fn, *args: delays.append(delay_s)
    for k in range(40):
        aodv._on_rreq(1, np.array([2]), Rreq(0, k + 1, 3, 0, True, 1, 1, 5))
    assert len(delays) == 40 and all(0.0 <= d <= 0.01 for d in delays)
    assert len(set(delays)) == 40


def test_aodv_ttls_up_to_net_diameter_are_accepted():
    """The TTLs must not *exceed* NET_DIAMETER: a first ring or a threshold equal to it is
    accepted, and its discovery is NET_DIAMETER tried 1 + RREQ_RETRIES times."""
    config = make_config(protocol={"model": "aodv", "ttl_start": 35, "ttl_threshold": 35})
    assert (config.protocol.params.ttl_start, config.protocol.params.ttl_threshold) == (35, 35)
    assert ring_ttls(AodvParams(ttl_start=35, ttl_threshold=35)) == [35, 35, 35]


def test_aodv_sends_every_packet_buffered_during_discovery_once_the_route_is_found(tmp_path):
    """A source buffers the packets that wait for a route (docs/routing.md) and sends them
    all when the RREP arrives: ten packets 0.1 s apart toward a robot five hops away, seven
    of them sent during the discovery's three rings, all delivered over the five hops, one
    discovery for all."""
    flow = {"src": 0, "dst": 5, "start_s": 10.0, "stop_s": 11.0, "rate_bps": 80000.0, "packet_bytes": 1000}
    sim, frames = _run(tmp_path, [(50 + 100 * i, 500) for i in range(6)], [flow], duration_s=15.0)
    packets = frames["packets"]
    assert len(packets) == 10 and packets["delivered"].all(), packets[["t_sent_s", "drop_cause"]]
    assert (packets["hops"] == 5).all()
    assert [ttl for _, _, _, ttl in sim.models["protocol"].rreqs_originated] == [1, 3, 5]
