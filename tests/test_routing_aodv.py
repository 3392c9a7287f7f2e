"""AODV (RFC 3561), rule by rule: destination sequence numbers, route errors, the expanding
ring; and a flow over a static line."""

import numpy as np
import pytest
from netsim.protocols.aodv import AodvParams, Route, RouteTable, fresher, ring_ttls, seq_newer

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
    ],
)
def test_aodv_parameter_out_of_range_is_refused(key, value):
    """A TTL beyond the network diameter, or beyond the one octet a RREQ's TTL field holds,
    is refused, naming the key at fault."""
    with pytest.raises(ConfigError, match=f"protocol.{key} = {value}:"):
        make_config(protocol={"model": "aodv", key: value})


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
