"""OLSR (RFC 3626): multipoint relays, topology control and the routing table."""

import networkx as nx
import numpy as np
import pytest
from netsim.protocols.olsr import PACKET_HEADER_BYTES, message_bytes, select_mprs

from netsim.errors import ConfigError
from netsim.run import build, collect
from tests.fixtures import make_config


def _two_hop(graph, i):
    """``(two_hop_via, N2)`` of node ``i`` of ``graph``, as OLSR's HELLOs give them."""
    n1 = set(graph[i])
    via = {n: set(graph[n]) - {i} for n in n1}
    n2 = set().union(*via.values()) - n1 - {i} if via else set()
    return via, n2


def test_mprs_cover_every_two_hop_neighbour():
    """The MPRs a robot selects reach every one of its two-hop neighbours (RFC 3626 8.3.1),
    and are symmetric neighbours: random geometric graphs, every node."""
    rng = np.random.default_rng(11)
    checked = 0
    for _ in range(40):
        n = int(rng.integers(5, 40))
        pos = rng.uniform(0, 1, (n, 2))
        graph = nx.random_geometric_graph(n, 0.3, pos=dict(enumerate(pos)))
        for i in graph:
            via, n2 = _two_hop(graph, i)
            mprs = select_mprs(via, n2)
            assert mprs <= set(via)
            covered = set().union(*(via[m] for m in mprs)) if mprs else set()
            assert n2 <= covered
            checked += len(n2)
    assert checked > 1000


def test_mprs_take_a_neighbour_that_alone_reaches_a_two_hop_neighbour():
    """A neighbour that alone reaches some two-hop neighbour is an MPR before any other is
    chosen (8.3.1, step 3): here those two cover everything, and the neighbour that covers
    most is not needed."""
    via = {1: {10, 11, 12, 13}, 2: {10, 11, 14}, 3: {12, 13, 15}}
    assert select_mprs(via, set(range(10, 16))) == {2, 3}


def test_mprs_tie_on_coverage_goes_to_the_neighbour_reaching_most_then_the_lowest_id():
    """RFC 3626 8.3.1 as docs/routing.md states it: of the neighbours covering most of the
    two-hop neighbours still uncovered, the one reaching most of them all is chosen, then
    the lowest id. Here 5 alone reaches 13; 1 and 3 then each cover both of 10 and 11, and
    3, which reaches three, is chosen over the lower id 1, which reaches two (going to the
    lowest id at once, the reach left out, took 1)."""
    assert select_mprs({1: {10, 11}, 3: {10, 11, 12}, 5: {12, 13}}, {10, 11, 12, 13}) == {3, 5}
    # Tied on the reach too: the lowest id.
    assert select_mprs({4: {10, 11}, 2: {10, 11}, 5: {12}}, {10, 11, 12}) == {2, 5}


def _run(tmp_path, xy, flows, duration_s=40.0, channel=None, watch=None, **protocol):
    path = tmp_path / "robots.csv"
    path.write_text("x_m,y_m\n" + "".join(f"{x},{y}\n" for x, y in xy))
    config = make_config(
        seed=6,
        duration_s=duration_s,
        world={"n_robots": len(xy), "side_m": 1000.0, "placement": str(path)},
        mobility={"model": "static"},
        channel={"range_m": 120.0, **(channel or {})},
        protocol={"model": "olsr", **protocol},
        traffic={"flows": flows},
        output={"position_interval_s": 0.0},
    )
    sim = build(config)
    if watch is not None:
        watch(sim.models["protocol"])
    sim.run()
    return sim, collect(sim)


GRID = [(50 + 100 * i, 50 + 100 * j) for i in range(4) for j in range(4)]


def _departures(tmp_path, max_frame_bytes):
    """A static grid's OLSR for 25 s: per robot, the messages it queued since its previous
    packet left and the frames (messages, bytes) that left then, in order."""
    log: list = []  # ("queued", robot, message) or ("frame", robot, messages, bytes)

    def watch(olsr):
        queue, control = olsr.queue, olsr.control

        def queued(i, message):
            log.append(("queued", i, message))
            queue(i, message)

        def sent(i, batch, deliver, kind, dest=-1, messages=1):
            log.append(("frame", i, batch, olsr.control_bytes[kind], olsr.env.now))
            control(i, batch, deliver, kind, dest, messages)

        olsr.queue, olsr.control = queued, sent

    _run(tmp_path, GRID, [], duration_s=25.0, channel={"max_frame_bytes": max_frame_bytes}, watch=watch)
    waiting: dict[int, list] = {}
    departures: list[tuple[list, list]] = []  # (messages queued, frames that left)
    last: dict[int, tuple[float, list]] = {}
    for entry in log:
        i = entry[1]
        if entry[0] == "queued":
            waiting.setdefault(i, []).append(entry[2])
            continue
        _, _, batch, nbytes, now = entry
        if i in last and last[i][0] == now:
            last[i][1].append((batch, nbytes))  # another frame of the same departure
            continue
        frames = [(batch, nbytes)]
        last[i] = (now, frames)
        departures.append((waiting.pop(i, []), frames))
    return departures


def test_olsr_messages_queued_together_leave_in_one_frame(tmp_path):
    """RFC 3626 3.4 (a packet carries one or more messages), as ns-3 does it: the messages a
    robot queues (its HELLO, its TC, the TCs it forwards) before its queued packet leaves
    all leave then, in one frame when they fit (here always), of the packet header and
    their sizes."""
    departures = _departures(tmp_path, 1500)
    assert departures
    for queued, frames in departures:
        assert len(frames) == 1
        batch, nbytes = frames[0]
        assert list(batch) == queued
        assert nbytes == PACKET_HEADER_BYTES + sum(message_bytes(m) for m in batch)
    assert sum(len(frames[0][0]) > 1 for _, frames in departures) >= 10


def test_olsr_frame_never_exceeds_channel_max_frame_bytes(tmp_path):
    """Messages queued together that do not fit in ``channel.max_frame_bytes`` leave in
    several frames at once, none over the limit, each as full as the next message allows,
    the messages in the order queued."""
    limit = 64
    departures = _departures(tmp_path, limit)
    split = 0
    for queued, frames in departures:
        assert [m for batch, _ in frames for m in batch] == queued
        for (batch, nbytes), after in zip(frames, frames[1:] + [None]):
            assert nbytes == PACKET_HEADER_BYTES + sum(message_bytes(m) for m in batch) <= limit
            if after is not None:
                assert nbytes + message_bytes(after[0][0]) > limit
        split += len(frames) > 1
    assert split >= 10


def test_olsr_routes_shortest_paths_on_a_static_grid(tmp_path):
    """Once HELLOs and TCs have spread, every robot of a static 4 x 4 grid has a route to
    every other, of the grid's hop distance, and a flow corner to corner is delivered in 6
    hops."""
    flow = {"src": 0, "dst": 15, "start_s": 30.0, "stop_s": 35.0, "rate_bps": 8000.0, "packet_bytes": 1000}
    sim, frames = _run(tmp_path, GRID, [flow])
    olsr = sim.models["protocol"]
    for i in range(16):
        routes = olsr.routes(i)
        assert set(routes) == set(range(16)) - {i}
    packets = frames["packets"]
    assert packets["delivered"].all() and (packets["hops"] == 6).all()
    assert set(frames["control"]["kind"]) <= {"hello", "tc", "hello+tc"}


@pytest.mark.parametrize("key, value", [("neighb_hold_time_s", 2.0), ("ttl", 256), ("ttl", 0)])
def test_olsr_parameter_out_of_range_is_refused(key, value):
    """A neighbour hold time not longer than the HELLO interval, or a TTL that one octet
    cannot hold, is refused, naming the key."""
    with pytest.raises(ConfigError, match=f"protocol.{key} = {value}:"):
        make_config(protocol={"model": "olsr", key: value})


def test_olsr_tc_is_considered_for_forwarding_once_at_its_first_copy(tmp_path):
    """RFC 3626 3.4.1 (one interface): a TC is processed and considered for forwarding at
    the first copy a robot gets from a symmetric neighbour, and retransmitted then only if
    that neighbour chose the robot as MPR (and the TTL allows); a later copy, even from a
    neighbour that chose it, is not retransmitted."""
    expected: dict[tuple, bool] = {}  # (robot, originator, ANSN) -> retransmit
    forwarded: list[tuple] = []

    def watch(olsr):
        on_tc, queue = olsr._on_tc, olsr.queue

        def received(sender, receivers, tc):
            now = olsr.env.now
            for r in receivers.tolist():
                key = (r, tc.orig, tc.ansn)
                if tc.orig != r and key not in expected and sender in olsr.symmetric(r, now):
                    expected[key] = olsr.selectors[r].get(sender, -1.0) >= now and tc.ttl > 1
            on_tc(sender, receivers, tc)

        def queued(i, message):
            if message.__class__.__name__ == "Tc" and message.orig != i:
                forwarded.append((i, message.orig, message.ansn))
            queue(i, message)

        olsr._on_tc, olsr.queue = received, queued

    _run(tmp_path, GRID, [], duration_s=40.0, watch=watch)
    assert len(forwarded) == len(set(forwarded))
    assert set(forwarded) == {k for k, go in expected.items() if go}
    assert sum(expected.values()) > 50 and not all(expected.values())


def test_olsr_tc_from_a_robot_that_is_not_a_symmetric_neighbour_is_discarded(tmp_path):
    """RFC 3626 3.4 (step 1): a TC that comes from a robot that is not a symmetric
    neighbour is discarded, neither processed nor forwarded. Robot 3 (range 50 m) hears
    robot 1, the MPR of the line 0 - 1 - 2, 100 m away, but 1 does not hear 3: 1's TCs reach
    3 over a one-way link, and 3's topology must hold nothing of them (without the check
    it took them, learning links over a robot it cannot reach), while 0, a symmetric
    neighbour of 1, does."""
    xy = [(100, 500), (200, 500), (300, 500), (200, 600)]
    forwarded: list[tuple] = []

    def watch(olsr):
        queue = olsr.queue

        def queued(i, message):
            if message.__class__.__name__ == "Tc" and message.orig != i:
                forwarded.append((i, message.orig, message.ansn))
            queue(i, message)

        olsr.queue = queued

    sim, _ = _run(tmp_path, xy, [], duration_s=20.0, channel={"range_m": [120.0, 120.0, 120.0, 50.0]}, watch=watch)
    olsr = sim.models["protocol"]
    now = sim.now
    assert 1 in olsr.heard_until[3] and 3 not in olsr.heard_until[1]  # 3 hears 1, one way
    assert 1 not in olsr.symmetric(3, now)
    assert olsr.ansn[1] >= 2 and 1 in olsr.topology[0]  # 1 sent TCs; its symmetric neighbours took them
    assert olsr.topology[3] == {} and not any(orig == 1 for orig, _ in olsr.duplicates[3])
    assert not any(r == 3 for r, _, _ in forwarded)


def _olsr(n=6):
    """An OLSR router of ``n`` robots, built and not run (its clock at 0)."""
    return build(make_config(world={"n_robots": n}, protocol={"model": "olsr"})).models["protocol"]


def test_a_hello_sets_the_link_its_two_hop_neighbours_and_its_mpr_selector():
    """RFC 3626 7.1.1, 8.2.1, 8.4.1: a HELLO that lists its receiver makes the link
    symmetric for NEIGHB_HOLD_TIME, and one that no longer lists it makes it asymmetric at
    once; the two-hop neighbours through its sender are the sender's symmetric neighbours
    alone (not those it only hears), the receiver excluded; its sender is the receiver's
    MPR selector when it lists the receiver as an MPR, and only then."""
    from netsim.protocols.olsr import Hello

    olsr = _olsr()
    hold = olsr.params.neighb_hold_time_s
    olsr._on_hello(1, np.array([0]), Hello(1, frozenset({0, 2, 5}), frozenset({0, 2}), frozenset({0})))
    assert olsr.symmetric(0, 0.0) == {1} and olsr.sym_until[0][1] == hold
    assert olsr.two_hop[0][1] == (frozenset({2}), hold) and olsr.selectors[0] == {1: hold}
    olsr._on_hello(1, np.array([0]), Hello(1, frozenset({0, 2}), frozenset({0, 2}), frozenset()))
    assert olsr.symmetric(0, 0.0) == {1} and 1 not in olsr.selectors[0]
    olsr._on_hello(1, np.array([0]), Hello(1, frozenset({2}), frozenset({2}), frozenset()))
    assert olsr.symmetric(0, 0.0) == set() and 1 not in olsr.two_hop[0]


def test_a_robots_mprs_cover_its_two_hop_neighbours_that_are_not_its_neighbours():
    """RFC 3626 8.3.1: N2 is the robots two hops away that are neither the robot itself nor
    one of its symmetric neighbours; robot 0's neighbours 1 and 2 hear each other, and only
    1 reaches 3: 1 alone is an MPR (covering the neighbour 2 as well took 2 too)."""
    olsr = _olsr()
    olsr.sym_until[0].update({1: 10.0, 2: 10.0})
    olsr.two_hop[0].update({1: (frozenset({2, 3}), 10.0), 2: (frozenset({1}), 10.0)})
    olsr._select_mprs(0, 0.0)
    assert olsr.mprs[0] == {1}


def test_a_tc_older_than_the_one_known_from_its_originator_is_discarded():
    """RFC 3626 9.5: a TC whose ANSN is older than the one the topology set holds for its
    originator (a copy that took a slower path) changes nothing; a newer one replaces it."""
    from netsim.protocols.olsr import Tc

    olsr = _olsr()
    olsr.sym_until[0][1] = 10.0
    olsr._on_tc(1, np.array([0]), Tc(4, 5, frozenset({2, 3}), 255, 1))
    olsr._on_tc(1, np.array([0]), Tc(4, 4, frozenset({5}), 255, 1))
    assert olsr.topology[0][4][:2] == (5, frozenset({2, 3}))
    olsr._on_tc(1, np.array([0]), Tc(4, 6, frozenset({5}), 255, 1))
    assert olsr.topology[0][4][:2] == (6, frozenset({5}))


def test_an_mpr_retransmits_a_tc_only_while_its_ttl_is_above_one():
    """RFC 3626 3.4.1: a robot its sender chose as MPR retransmits the TC with the TTL one
    less and the hop count one more, when the TTL it came with is greater than 1; one that
    arrives with TTL 1 goes no further."""
    from netsim.protocols.olsr import Tc

    olsr = _olsr()
    olsr.sym_until[0][1] = olsr.selectors[0][1] = 10.0
    queued = []
    olsr.queue = lambda i, message: queued.append((i, message))
    olsr._on_tc(1, np.array([0]), Tc(4, 5, frozenset({2}), 2, 1))
    olsr._on_tc(1, np.array([0]), Tc(3, 5, frozenset({2}), 1, 1))
    assert queued == [(0, Tc(4, 5, frozenset({2}), 1, 2))]


def test_the_routing_table_takes_the_two_hop_links_and_the_unexpired_topology():
    """RFC 3626 section 10: the routes run over the symmetric links, the two-hop links
    (through a symmetric neighbour) and the topology set's links, an expired tuple's left
    out; every destination goes by the first hop of its shortest path."""
    olsr = _olsr(8)
    olsr.sym_until[0][1] = 10.0
    olsr.two_hop[0][1] = (frozenset({2}), 10.0)
    olsr.topology[0][2] = (1, frozenset({3}), 10.0)
    olsr.topology[0][3] = (1, frozenset({4}), -1.0)
    assert olsr.routes(0) == {1: 1, 2: 1, 3: 1}


def test_a_hello_lists_each_neighbour_once_under_its_link_code():
    """RFC 3626 6.1: a HELLO groups its neighbours by link code, each listed once: the
    heard-only (asymmetric), the symmetric non-MPRs, the MPRs; each group a 4-byte link
    message header and 4 bytes an address, after the 12-byte message and 4-byte HELLO headers."""
    from netsim.protocols.olsr import Hello

    hello = Hello(0, frozenset({1, 2, 3}), frozenset({1, 2}), frozenset({1}))
    assert message_bytes(hello) == 12 + 4 + 3 * (4 + 4)


def test_mpr_ties_count_only_the_two_hop_neighbours_a_neighbour_reaches():
    """RFC 3626 8.3.1: of neighbours covering as many uncovered two-hop neighbours, the MPR
    is the one of greatest reachability D(y), its symmetric neighbours *excluding* the robot's
    one-hop neighbours (not in N2), then the lowest id. Neighbour 3 hears three robots outside
    N2 as well: they do not make it win the tie, so 1, then 2, are the MPRs."""
    via = {1: {5, 6}, 2: {6, 7}, 3: {5, 7, 10, 11, 12}}
    assert select_mprs(via, {5, 6, 7}) == {1, 2}


def test_hello_and_tc_message_sizes_follow_rfc_3626():
    """docs/routing.md (IPv4): a HELLO is its 12-byte message header, 4 bytes, and per link
    code *present* a 4-byte header and 4 bytes an address (a lone robot's HELLO lists none: 16
    bytes); a TC is 12 + 4 bytes and 4 per advertised neighbour."""
    from netsim.protocols.olsr import Hello, Tc, tc_bytes

    assert message_bytes(Hello(0, frozenset(), frozenset(), frozenset())) == 16
    assert message_bytes(Hello(0, frozenset({1}), frozenset({1}), frozenset())) == 16 + 8
    assert tc_bytes(0) == 16 and tc_bytes(3) == 28
    assert message_bytes(Tc(0, 1, frozenset({1, 2, 3}), 255, 0)) == 28


def test_a_packet_is_its_header_and_its_messages_an_oversized_message_alone():
    """RFC 3626 3.4: a packet is a 4-byte header and its messages; messages leave in order
    in as few packets as ``max_frame_bytes`` allows, and one larger than the limit goes alone
    in a packet of its size, with no empty packet before it."""
    from netsim.protocols.olsr import Hello, pack

    small = Hello(0, frozenset({1}), frozenset({1}), frozenset())  # 24 bytes
    big = Hello(0, frozenset(range(1, 40)), frozenset(), frozenset())  # 16 + 4 + 156 bytes
    assert pack([small, small], 100) == [((small, small), 4 + 24 + 24)]
    assert pack([big], 100) == [((big,), 4 + 176)]
    assert pack([small, big, small], 100) == [((small,), 28), ((big,), 180), ((small,), 28)]


class _Agenda:
    """An agenda that keeps what it is asked to do: (delay, what, robot)."""

    def __init__(self):
        self.calls: list = []

    def at(self, delay_s, _priority, fn, *args):
        self.calls.append((delay_s, fn.__name__, *args))


def test_the_first_message_queued_sets_the_packets_departure_within_maxjitter():
    """RFC 3626 3.4, 18.3 (as ns-3): the first message a robot queues sets its packet's
    departure after U(0, MAXJITTER = hello_interval_s / 4); the messages queued meanwhile wait
    for that departure (no other is scheduled)."""
    from types import SimpleNamespace

    from netsim.protocols.olsr import Hello

    olsr = _olsr()
    agenda = _Agenda()
    olsr.channel = SimpleNamespace(agenda=agenda)
    hello = Hello(0, frozenset(), frozenset(), frozenset())
    olsr.queue(0, hello)
    olsr.queue(0, hello)
    assert len(agenda.calls) == 1 and olsr.queued[0] == [hello, hello]
    for _ in range(60):
        olsr._leaving[1] = False
        olsr.queue(1, hello)
    delays = [d for d, *_ in agenda.calls]
    assert all(0.0 <= d <= 2.0 / 4 for d in delays) and max(delays) - min(delays) > 0.3


def test_a_robot_that_died_sends_none_of_its_queued_messages():
    """A robot that died while its messages waited for their jitter sends nothing; its queue
    is emptied."""
    from netsim.protocols.olsr import Hello

    olsr = _olsr()
    sent = []
    olsr.control = lambda i, batch, deliver, kind, dest=-1, messages=1: sent.append(i)
    hello = Hello(0, frozenset(), frozenset(), frozenset())
    olsr.queued[0], olsr.queued[1] = [hello], [hello]
    olsr.state.alive[0] = False
    olsr._send_queued(0)
    olsr._send_queued(1)
    assert sent == [1] and olsr.queued[0] == []


def test_a_link_is_symmetric_up_to_its_expiry_instant_included():
    """RFC 3626 8.1: a link is symmetric while L_SYM_time >= now: at its expiry instant still,
    a moment later no longer."""
    olsr = _olsr()
    olsr.sym_until[0][1] = 10.0
    assert olsr.symmetric(0, 10.0) == {1}
    assert olsr.symmetric(0, 10.0 + 1e-9) == set()


def test_a_hello_lists_only_the_neighbours_heard_within_the_hold_time():
    """A robot's HELLO lists the neighbours it hears (RFC 3626 6.2: links not expired): one
    last heard longer than NEIGHB_HOLD_TIME ago is not listed."""
    olsr = _olsr()
    queued = []
    olsr.queue = lambda i, message: queued.append(message)
    olsr.heard_until[0].update({1: 10.0, 2: -1.0})
    olsr._hello_tick(0)
    assert [m.heard for m in queued] == [frozenset({1})]


def test_the_routing_table_follows_a_hello_heard_at_the_instant_it_was_computed():
    """RFC 3626 section 10: the routing table is computed again when the link set changes;
    a HELLO heard at the very instant the table was last computed changes it then."""
    from netsim.protocols.olsr import Hello

    olsr = _olsr()
    olsr.sym_until[0][1] = 10.0
    assert olsr.routes(0) == {1: 1}
    olsr._on_hello(2, np.array([0]), Hello(2, frozenset({0}), frozenset({0}), frozenset()))
    assert olsr.routes(0) == {1: 1, 2: 2}


def test_the_routing_table_drops_the_links_that_expired_since_it_was_computed():
    """The routing table holds at every instant the links unexpired then: a route over a
    symmetric link is gone once the link's hold time has passed, with nothing heard since."""
    from types import SimpleNamespace

    olsr = _olsr()
    olsr.env = SimpleNamespace(now=0.0)
    olsr.sym_until[0][1] = 10.0
    olsr.two_hop[0][1] = (frozenset({2}), 20.0)
    assert olsr.routes(0) == {1: 1, 2: 1}
    olsr.env.now = 11.0
    assert olsr.routes(0) == {}


def test_mprs_leave_out_expired_two_hop_tuples():
    """RFC 3626 8.2: a two-hop tuple lives until its hold time; an expired one covers no
    two-hop neighbour in the MPR selection."""
    olsr = _olsr()
    olsr.sym_until[0].update({1: 10.0, 2: 10.0})
    olsr.two_hop[0].update({1: (frozenset({3}), -1.0), 2: (frozenset({4}), 10.0)})
    olsr._select_mprs(0, 0.0)
    assert olsr.mprs[0] == {2}


def test_a_robot_no_neighbour_chose_as_mpr_floods_no_tc():
    """docs/routing.md: a robot that some neighbours chose as MPR floods a TC every
    tc_interval_s advertising them, with a new ANSN; one with no MPR selector (or only
    expired ones) sends none."""
    from netsim.protocols.olsr import Tc

    olsr = _olsr()
    queued = []
    olsr.queue = lambda i, message: queued.append((i, message))
    olsr.selectors[0][1] = -1.0
    olsr._tc_tick(0)
    assert queued == []
    olsr.selectors[0][2] = 10.0
    olsr._tc_tick(0)
    assert queued == [(0, Tc(0, 1, frozenset({2}), 255, 0))]


def test_olsr_routes_ties_between_first_hops_go_to_the_lowest_id():
    """docs/routing.md: the routes are the shortest paths found breadth first, lowest ids
    first: a robot two hops away through either of two neighbours goes through the lower."""
    olsr = _olsr()
    olsr.sym_until[0].update({1: 10.0, 2: 10.0})
    olsr.two_hop[0].update({1: (frozenset({3}), 10.0), 2: (frozenset({3}), 10.0)})
    assert olsr.routes(0)[3] == 1


def _first_hellos(tmp_path, **protocol) -> list[float]:
    """When each robot of the first eight of GRID queues its first HELLO, in a 3 s run."""
    from netsim.protocols.olsr import Hello

    first: dict[int, float] = {}

    def watch(olsr):
        queue = olsr.queue

        def queued(i, message):
            if isinstance(message, Hello):
                first.setdefault(i, olsr.env.now)
            queue(i, message)

        olsr.queue = queued

    _run(tmp_path, GRID[:8], [], duration_s=3.0, watch=watch, **protocol)
    assert len(first) == 8, first
    return list(first.values())


def test_olsr_timers_start_at_a_time_of_each_robots_own(tmp_path):
    """docs/routing.md: each robot's HELLO and TC timers start together at U(0,
    start_spread_s) (default hello_interval_s, 2 s); with 0 every robot starts at t = 0."""
    spread = _first_hellos(tmp_path)
    assert len(set(spread)) == 8 and max(spread) <= 2.0 and max(spread) - min(spread) > 0.5, spread
    assert set(_first_hellos(tmp_path, start_spread_s=0.0)) == {0.0}


def test_olsr_hold_times_are_three_intervals():
    """RFC 3626 18.3 (docs/routing.md): NEIGHB_HOLD_TIME is 3 HELLO intervals and
    TOP_HOLD_TIME 3 TC intervals, derived from the intervals given."""
    from netsim.protocols.olsr import OlsrParams

    p = OlsrParams()
    assert (p.neighb_hold_time_s, p.top_hold_time_s) == (6.0, 15.0)
    q = OlsrParams(hello_interval_s=1.0, tc_interval_s=4.0)
    assert (q.neighb_hold_time_s, q.top_hold_time_s) == (3.0, 12.0)
