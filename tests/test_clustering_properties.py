"""Clustering under loss and on random deployments (docs/validation.md items 9 and 13), relaying,
leader commands, and the ground-truth view."""

import math

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from netsim.protocols.roles import LEADER, MEMBER, UNDECIDED

from netsim.config import from_dict
from netsim.metrics import components
from netsim.run import build, collect
from netsim.topology import geometric_edges
from tests.fixtures import clustering


def static_run(positions, duration=40.0, seed=1, range_m=10.0, run=True, phase_s=None, **protocol):
    core = {"duration_s": duration, "seed": seed, "range_m": range_m}
    sim, stack = clustering(positions, phase_s, core=core, **protocol)
    if run:
        sim.run()
    return sim, stack


def check_independent_dominating(sim, range_m):
    st = sim.groups
    edges = geometric_edges(sim.state.positions_at(sim.now), range_m)
    nbr = {(a, b) for a, b, _ in edges} | {(b, a) for a, b, _ in edges}
    leaders = set(np.flatnonzero(st.role == LEADER).tolist())
    assert not any(a in leaders and b in leaders for a, b, _ in edges), "two leaders in range"
    assert (st.role != UNDECIDED).all(), "a robot stayed undecided"
    for i in np.flatnonzero(st.role == MEMBER).tolist():
        assert st.leader[i] in leaders and (i, int(st.leader[i])) in nbr, f"member {i} not next to a leader"


@pytest.mark.parametrize("n", [20, 80, 250])
@pytest.mark.parametrize("seed", [1, 2, 3])
@pytest.mark.slow
def test_static_deployment_converges_to_independent_dominating_leaders(n, seed):
    """Item 13: no loss, static: leaders form an independent dominating set, nobody undecided."""
    side = 10.0 * math.sqrt(n * math.pi / 6)  # mean degree about 6
    pos = np.random.default_rng(seed).uniform(0, side, (n, 2))
    sim, _ = static_run(pos, seed=seed)
    check_independent_dominating(sim, 10.0)


def settled_run(seed, n=60, latency_s=1.3, latency_jitter_s=0.0, unequal=True, duration=100.0, **protocol):
    """A static loss-free run; returns the role changes after its first 60 s, and the pairs
    of robots that are each a member of the other at the end."""
    rng = np.random.default_rng(seed + 1000)
    side = 10.0 * math.sqrt(n * math.pi / 6)
    cfg = from_dict(
        {
            "seed": seed,
            "duration_s": duration,
            "world": {"n_robots": n, "side_m": side},
            "mobility": {"model": "static"},
            "channel": {
                "range_m": rng.uniform(8.0, 16.0, n).tolist() if unequal else 10.0,
                "latency_s": latency_s,
                "latency_jitter_s": latency_jitter_s,
            },
            "protocol": {"model": "clustering", "message_rate_hz": 0.0, **protocol},
            "output": {"position_interval_s": 0.0},
        }
    )
    sim = build(cfg)
    sim.run()
    roles = sim.trace.frame("roles")
    st = sim.groups
    mutual = [
        (i, int(st.leader[i]))
        for i in np.flatnonzero(st.role == MEMBER).tolist()
        if st.role[st.leader[i]] == MEMBER and st.leader[st.leader[i]] == i
    ]
    return roles[roles.t_s > 60.0], mutual


@pytest.mark.parametrize("seed", [4, 8])
def test_merging_settles_with_latency_above_the_ack_period(seed):
    """Latency 1.3 s (above the 1 s Ack period), unequal ranges, static, no loss: leaders
    may yield to each other on stale group sizes, but after a transient nothing changes
    any more, and no two robots end as members of each other."""
    late, mutual = settled_run(seed)
    assert late.empty, late.to_string()
    assert mutual == []


@pytest.mark.slow
@pytest.mark.parametrize(
    "latency_s, latency_jitter_s, unequal, policy",
    [
        (0.0, 0.0, False, "smaller_group_yields"),
        (0.4, 0.0, True, "smaller_group_yields"),
        (1.3, 0.0, True, "highest_degree_wins"),
        (2.7, 0.0, True, "smaller_group_yields"),
        (0.3, 1.5, True, "smaller_group_yields"),
        (1.3, 1.5, False, "highest_degree_wins"),
        (2.0, 0.8, True, "lowest_id_wins"),
    ],
)
@pytest.mark.parametrize("seed", [1, 2, 3])
def test_merging_settles_for_every_latency_jitter_and_range_mix(seed, latency_s, latency_jitter_s, unequal, policy):
    late, mutual = settled_run(
        seed, latency_s=latency_s, latency_jitter_s=latency_jitter_s, unequal=unequal, merge_policy=policy
    )
    assert late.empty, late.to_string()
    assert mutual == []


@settings(max_examples=25, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(st.integers(min_value=2, max_value=40), st.floats(min_value=5.0, max_value=40.0), st.integers(0, 2**31 - 1))
@pytest.mark.slow
def test_property_random_static_topologies(n, side, seed):
    """Hypothesis: on any static topology the invariants of item 13 hold at the end, and at
    every sampled instant no member's leader is missing from its live neighbours."""
    pos = np.random.default_rng(seed).uniform(0, side, (n, 2))
    sim, stack = static_run(pos, duration=30.0, seed=seed % 1000, run=False)
    violations = []

    def watch():
        rng = np.random.default_rng(seed)
        while True:
            yield sim.env.timeout(rng.uniform(0.05, 0.5))
            st = stack
            for i in np.flatnonzero(st.role == MEMBER).tolist():
                if st.leader[i] not in stack.table.live_ids(sim.now, i):
                    violations.append((sim.now, i))

    sim.env.process(watch())
    sim.run()
    assert violations == []
    check_independent_dominating(sim, 10.0)


@pytest.mark.slow
@pytest.mark.parametrize("p, tau_s, k", [(0.3, 2.5, 2), (0.5, 3.5, 3)])
def test_spurious_timeouts_under_loss(p, tau_s, k):
    """Item 9: a member falsely loses its (static, in range) leader after (1 - p^k) /
    ((1 - p) p^k) of the leader's Acks on average, k = Ack instants inside the tau window.

    Pairs far apart from each other; for each, the leader's Acks are counted from the one
    that made the robot a member to its first rule-3 timeout."""
    pairs = 400
    pos = np.zeros((2 * pairs, 2))
    pos[0::2, 0] = pos[1::2, 0] = np.arange(pairs) * 100.0
    pos[1::2, 1] = 5.0
    core = {"seed": 9, "duration_s": 200.0, "loss_probability": p}
    protocol = {"ack_jitter_s": 0.0, "tau_s": tau_s, "election_policy": "none", "message_rate_hz": 0.2}
    sim, stack = clustering(pos, core=core, **protocol)
    sim.run()
    roles = sim.trace.frame("roles")
    phase = stack.beacon.phase_s
    counts = []
    for robot in range(2 * pairs):
        rec = roles[roles.robot == robot]
        joins = rec[rec.role == "beta"]
        if joins.empty:
            continue
        t_join, leader = joins.t_s.iloc[0], int(joins.leader.iloc[0])
        lost = rec[(rec.cause == "rule3_leader_lost") & (rec.t_s > t_join)]
        if lost.empty:
            continue
        # The leader's sends are at phase + j (no jitter); the joining Ack was sent at
        # t_join - latency; the timeout comes tau after the last Ack heard.
        latency = sim.channel.latency_s
        first = math.floor(t_join - latency - phase[leader] + 1e-9) + 1
        last = math.floor(lost.t_s.iloc[0] - latency - phase[leader] + 1e-9)
        counts.append(last - first + 1)
    theory = (1 - p**k) / ((1 - p) * p**k)
    counts = np.array(counts)
    assert len(counts) > 300
    assert counts.min() >= k
    se = counts.std() / math.sqrt(len(counts))
    assert abs(counts.mean() - theory) < 4 * se


def connected_positions(n, seed, side):
    rng = np.random.default_rng(seed)
    while True:
        pos = rng.uniform(0, side, (n, 2))
        if len(set(components(pos, 10.0))) == 1:
            return pos


@pytest.mark.parametrize("routing", ["backbone", "oracle"])
def test_every_message_arrives_on_a_static_connected_lossless_network(routing):
    pos = connected_positions(60, 4, 45.0)
    sim, stack = static_run(pos, duration=60.0, run=False, routing=routing)
    sim.run(until_s=20.0)
    ids = []

    def sender():
        rng = np.random.default_rng(0)
        for _ in range(40):
            src, dst = rng.choice(60, 2, replace=False)
            ids.append(stack.relay.send(int(src), int(dst)))
            yield sim.env.timeout(0.5)

    sim.env.process(sender())
    sim.run()
    msgs = stack.messages_frame()
    assert len(msgs) == 40 and msgs.delivered.all()
    assert (msgs.hops >= msgs.shortest_hops).all()
    if routing == "oracle":
        assert (msgs.hops == msgs.shortest_hops).all()
        assert (msgs.transmissions == msgs.hops).all()
    assert (msgs.latency_s > 0).all()


def _hops_on_links_table(links, n: int, t: float, src: int, dst: int) -> float:
    """Hops from ``src`` to ``dst`` over the links of links.parquet up at ``t``."""
    import networkx as nx

    up = links[(links.t_up_s <= t) & (links.t_down_s > t)]
    g = nx.Graph()
    g.add_nodes_from(range(n))
    g.add_edges_from(zip(up.a.tolist(), up.b.tolist()))
    try:
        return float(nx.shortest_path_length(g, src, dst))
    except nx.NetworkXNoPath:
        return math.inf


def office_team(duration_s: float, protocol: dict, flows: tuple = ()):
    """12 static robots from a connected start on the office map, under log-distance
    through its walls, with the clustering's ``protocol`` keys (and ``flows``)."""
    return from_dict(
        {
            **({"traffic": {"flows": list(flows)}} if flows else {}),
            "seed": 1,
            "duration_s": duration_s,
            "world": {"n_robots": 12, "map": "office", "bounds_m": "map", "placement": "connected"},
            "mobility": {"model": "static"},
            "channel": {"propagation": "log_distance"},
            "protocol": protocol,
        }
    )


@pytest.mark.slow
def test_through_walls_the_oracle_routes_and_measures_on_the_channels_links():
    """On the office map, where walls decide the links, the oracle forwards over the links
    the channel makes and the shortest path is measured on them (links.parquet's): on a
    static connected team every message arrives in exactly its shortest path's hops. On the
    range circles a message bounced between two robots to the hop limit."""
    sim = build(office_team(20.0, {"routing": "oracle", "message_rate_hz": 2.0}))
    sim.run()
    frames = collect(sim)
    msgs, links = frames["messages"], frames["links"]
    assert len(msgs) >= 30 and msgs.delivered.all()
    assert msgs.shortest_hops.max() >= 3  # paths around walls, longer than the range circles give
    truth = [_hops_on_links_table(links, 12, m.t_sent_s, m.src, m.dst) for m in msgs.itertuples()]
    assert msgs.shortest_hops.tolist() == truth
    assert (msgs.hops == msgs.shortest_hops).all() and (msgs.transmissions == msgs.hops).all()


def test_under_shadowing_the_oracle_forwards_over_the_links_it_measures_on():
    """Under shadowing a link's state is the channel's last decision on it (links.parquet):
    the oracle picks its next hop among the holder's links up there, the links it measures
    the hops to the destination on. Every hop then goes over a pair up in the table just
    before it, and no message visits a robot twice. Asking the channel for the holder's
    hearers instead drew the shadowing afresh and offered robots the table had out of reach:
    hops over links down in the table, loops, fewer hops than the shortest path."""
    sim = build(
        from_dict(
            {
                "seed": 1,
                "duration_s": 60.0,
                "world": {"n_robots": 30, "side_m": 600.0},
                "channel": {"propagation": "log_distance", "shadowing_sigma_db": 4.0},
                "protocol": {"routing": "oracle", "message_rate_hz": 1.0},
            }
        )
    )
    sim.run()
    frames = collect(sim)
    hops, links, msgs = frames["hops"], frames["links"], frames["messages"]
    assert len(hops) >= 50
    a, b = np.minimum(hops.sender, hops.receiver), np.maximum(hops.sender, hops.receiver)
    pairs = links.set_index(["a", "b"]).sort_index()
    for x, y, t in zip(a.tolist(), b.tolist(), hops.t_sent_s.tolist()):
        g = pairs.loc[(x, y)] if (x, y) in pairs.index else pairs.iloc[:0]
        assert ((g.t_up_s < t) & (g.t_down_s >= t)).any(), f"hop {x}-{y} at {t} over a link down"
    assert (hops.groupby(["msg_id", "receiver"]).size() == 1).all()
    done = msgs[msgs.delivered]
    assert len(done) >= 20 and (done.hops >= done.shortest_hops).all()


@pytest.mark.parametrize("routing, tracked", [("backbone", False), ("oracle", True)])
def test_only_the_oracle_tracks_a_radios_links_during_the_run(routing, tracked):
    """Tracking the links walls decide during the run costs a walled run more than the run:
    the oracle, which routes on them, starts it; backbone routing does not."""
    assert (build(office_team(5.0, {"routing": routing})).links is not None) is tracked


@pytest.mark.slow
def test_an_oracle_message_sent_at_t0_under_a_radio_waits_for_the_links():
    """Sent at t = 0, before the channel's links are first solved (after everything else
    due then), an oracle message through walls is routed once they are: delivered in its
    shortest path's hops, not dropped for want of a route."""
    sim = build(office_team(5.0, {"routing": "oracle", "message_rate_hz": 0.0}))
    sim.send(0, 11)
    sim.run()
    msgs, links = (frame := collect(sim))["messages"], frame["links"]
    assert msgs.delivered.tolist() == [True]
    assert msgs.shortest_hops.iloc[0] == _hops_on_links_table(links, 12, 0.0, 0, 11) == msgs.hops.iloc[0]


@pytest.mark.slow
def test_an_oracle_packet_sent_at_t0_under_a_radio_has_the_shortest_path_of_the_links():
    """A flow's packets of three frames from t = 0 through the office's walls: each packet's
    shortest_hops is its first frame's (messages.parquet's), measured once the channel's
    links are first solved, on them (links.parquet's): finite, not the ``inf`` of a
    search before any link was solved."""
    flow = {"src": 0, "dst": 11, "start_s": 0.0, "stop_s": 4.0, "rate_bps": 16000.0, "packet_bytes": 4000}
    sim = build(office_team(5.0, {"routing": "oracle", "message_rate_hz": 0.0}, (flow,)))
    sim.run()
    frames = collect(sim)
    packets, msgs, links = frames["packets"], frames["messages"], frames["links"]
    assert len(packets) == 2 and (packets["frames"] == 3).all() and packets["t_sent_s"].iloc[0] == 0.0
    truth = _hops_on_links_table(links, 12, 0.0, 0, 11)
    assert math.isfinite(truth) and truth >= 2
    assert packets["shortest_hops"].iloc[0] == truth
    firsts = msgs.groupby("t_sent_s")["shortest_hops"].first()
    assert packets["shortest_hops"].tolist() == firsts.loc[packets["t_sent_s"]].tolist()


def test_strict_backbone_can_miss_what_distributed_gateways_reach():
    """Two groups that touch only through two members: leaders and gateways alone do not
    connect them."""
    # Leader 0 with member 1; leader 3 with member 2; only 1 and 2 hear each other.
    pos = [[0, 0], [9, 0], [18, 0], [27, 0]]
    for distributed, expect in ((True, True), (False, False)):
        sim, stack = static_run(
            pos, duration=30.0, run=False, phase_s=[0.1, 0.5, 0.6, 0.2], distributed_gateways=distributed
        )
        sim.run(until_s=15.0)
        assert stack.role.tolist() in ([LEADER, MEMBER, MEMBER, LEADER],)
        stack.relay.send(0, 3)
        sim.run()
        assert bool(stack.messages_frame().delivered.iloc[0]) is expect


@pytest.mark.parametrize("ttl, delivered", [(6, True), (5, False)])
def test_relay_a_message_takes_at_most_message_ttl_hops_and_its_destination_relays_nothing(ttl, delivered):
    """On a line of 7 robots 9 m apart (range 10 m), a message from one end to the other
    needs 6 hops: with message_ttl = 6 it arrives in 6, with 5 it is dropped for the hop
    limit; and no copy is ever sent by its destination, which has it (the flood stops there,
    even where the destination is a leader or a gateway)."""
    pos = [[9.0 * k, 0.0] for k in range(7)]
    sim, stack = static_run(pos, duration=40.0, run=False, message_ttl=ttl)
    dropped = []
    sim.events.on("message_dropped", lambda e: dropped.append((e.msg_id, e.cause)))
    sim.run(until_s=15.0)
    stack.relay.send(0, 6)
    stack.relay.send(6, 3)
    sim.run()
    msgs = stack.messages_frame().set_index("msg_id")
    first = msgs.iloc[0]
    assert bool(first.delivered) is delivered
    assert first.hops == 6 if delivered else (int(msgs.index[0]), "ttl") in dropped
    hops = sim.trace.frame("hops")
    assert len(hops) and not ((hops.msg_id == msgs.index[1]) & (hops.sender == 3)).any()
    assert not ((hops.msg_id == msgs.index[0]) & (hops.sender == 6)).any()


@pytest.mark.slow
def test_delivery_ratio_falls_with_loss():
    pos = connected_positions(60, 5, 45.0)
    ratios = []
    for p in (0.0, 0.5):
        sim, stack = static_run(pos, duration=80.0, run=False)
        sim.channel.survives.p = p  # lossless formation first, then loss for the messages
        sim.run(until_s=20.0)
        rng = np.random.default_rng(1)
        for _ in range(60):
            src, dst = rng.choice(60, 2, replace=False)
            stack.relay.send(int(src), int(dst))
            sim.run(until_s=sim.now + 0.5)
        sim.run()
        ratios.append(stack.messages_frame().delivered.mean())
    assert ratios[0] == 1.0 and ratios[1] < 0.95


def test_members_execute_their_own_leaders_latest_command():
    pos = [[0, 0], [5, 0], [5, 4], [40, 0], [45, 0]]
    sim, stack = static_run(pos, duration=20.0, run=False)
    sim.run(until_s=10.0)
    leaders = np.flatnonzero(stack.role == LEADER).tolist()
    assert len(leaders) == 2
    executed = []
    stack.on_command.append(lambda r, cmd: executed.append((r, cmd.payload)))
    a, b = leaders
    stack.send_command(a, "hold")
    stack.send_command(b, "spread")
    sim.run(until_s=11.0)
    stack.send_command(a, "go north")
    sim.run()
    members_a = np.flatnonzero((stack.role == MEMBER) & (stack.leader == a)).tolist()
    members_b = np.flatnonzero((stack.role == MEMBER) & (stack.leader == b)).tolist()
    assert members_a and members_b
    for r in members_a:
        assert stack.command[r].payload == "go north"
    for r in members_b:
        assert stack.command[r].payload == "spread"
    assert {r for r, _ in executed} == set(members_a) | set(members_b)


def test_belief_vs_truth_shows_staleness():
    """After a robot leaves, its former neighbours still believe in it until tau passes."""
    sim, stack = static_run([[0, 0], [5, 0], [0, 5]], duration=30.0, run=False)
    sim.run(until_s=10.0)
    view = stack.belief_vs_truth(sim.now).set_index("robot")
    assert (view.role == "beta").sum() == 2 and view.leader_in_range.all()
    sim.state.set_leg(2, sim.now, (0.0, 0.0), start_m=(500.0, 500.0))
    sim.run(until_s=10.5)
    view = stack.belief_vs_truth(sim.now).set_index("robot")
    assert view.loc[0, "stale_neighbours"] == 1 and view.loc[0, "true_neighbours"] == 1
    sim.run(until_s=14.0)
    view = stack.belief_vs_truth(sim.now).set_index("robot")
    assert view.loc[0, "stale_neighbours"] == 0 and view.loc[2, "true_neighbours"] == 0


def test_belief_vs_truth_is_per_direction():
    """Robot 0 (range 5 m) hears robot 1 (range 15 m) 10 m away; 1 cannot hear 0. That 0
    believes 1 live is true (1's Acks reach 0), not stale; 1 has nothing to believe."""
    sim, stack = static_run([[0, 0], [10, 0], [0, 40]], duration=20.0, range_m=[5.0, 15.0, 50.0], run=False)
    sim.run(until_s=5.0)
    view = stack.belief_vs_truth(sim.now).set_index("robot")
    # 0 hears 1 and 2 (40 m, within 2's range); 1 hears 2 (41 m); 2 hears nobody.
    cols = ["believed_neighbours", "true_neighbours", "stale_neighbours", "missing_neighbours"]
    assert view[cols].values.tolist() == [[2, 2, 0, 0], [1, 1, 0, 0], [0, 0, 0, 0]]
    # Robot 2 jumps away: 0 and 1 still believe in it (stale) until tau passes.
    sim.state.set_leg(2, sim.now, (0.0, 0.0), start_m=(500.0, 500.0))
    sim.run(until_s=5.5)
    view = stack.belief_vs_truth(sim.now).set_index("robot")
    assert view[cols].values.tolist() == [[2, 1, 1, 0], [1, 0, 1, 0], [0, 0, 0, 0]]


def test_with_no_message_sent_the_delivery_ratio_is_undefined():
    """The summary's message_delivery_ratio is the share of the messages sent that arrived:
    with none sent (message_rate_hz = 0) there is no share, NaN, not a ratio of 0."""
    cfg = from_dict(
        {
            "duration_s": 10.0,
            "world": {"n_robots": 3, "side_m": 100.0},
            "protocol": {"model": "clustering", "message_rate_hz": 0.0},
        }
    )
    sim = build(cfg)
    sim.run()
    frames = collect(sim)
    summary = sim.models["protocol"].summary(frames, 10.0)
    assert summary["messages"] == 0 and math.isnan(summary["message_delivery_ratio"])


def test_run_outputs_for_clustering(tmp_path):
    cfg = from_dict(
        {
            "seed": 3,
            "duration_s": 60.0,
            "world": {"n_robots": 40, "side_m": 500.0},
            "protocol": {"model": "clustering", "message_rate_hz": 1.0},
        }
    )
    sim = build(cfg)
    sim.run()
    frames = collect(sim)
    for name in ("roles", "groups", "messages", "beliefs"):
        assert not frames[name].empty, name
    assert {"msg_id", "src", "dst", "delivered", "hops", "latency_s", "transmissions"} <= set(frames["messages"])
    assert set(frames["roles"].cause) >= {"rule1_start", "rule4_no_leader", "rule2_join"}


@pytest.mark.parametrize("ttl, delivered", [(6, True), (5, False)])
def test_an_oracle_message_takes_at_most_message_ttl_hops(ttl, delivered):
    """routing = oracle on the line of 7 robots 9 m apart: the message from one end to the
    other needs 6 hops; message_ttl = 6 delivers it in 6, 5 drops it for the hop limit at
    the fifth robot it reached (the holder forwards only while its TTL is above 1). Its
    latency runs from its sending: 6 hops of channel.latency_s (1 ms), not the last one's."""
    pos = [[9.0 * k, 0.0] for k in range(7)]
    sim, stack = static_run(pos, duration=40.0, run=False, message_ttl=ttl, routing="oracle")
    dropped = []
    sim.events.on("message_dropped", lambda e: dropped.append((e.msg_id, e.cause)))
    sim.run(until_s=15.0)
    mid = stack.relay.send(0, 6)
    sim.run()
    first = stack.messages_frame().set_index("msg_id").loc[mid]
    assert bool(first.delivered) is delivered
    if delivered:
        assert first.hops == 6 and first.latency_s == pytest.approx(6 * 0.001)
    else:
        assert dropped == [(mid, "ttl")]


def test_a_flood_under_latency_jitter_waits_for_every_receivers_copy():
    """With channel.latency_jitter_s each receiver of a broadcast gets its copy at an
    instant of its own: the flood is over once the last copy has arrived, not the first
    (robot 1's broadcast reaches both ends of the line 0-1-2; it was declared over at the
    first copy, and the second found no flood to join)."""
    pos = [[9.0 * k, 0.0] for k in range(3)]
    sim, stack = clustering(pos, core={"duration_s": 40.0, "seed": 1, "range_m": 10.0, "latency_jitter_s": 0.05})
    dropped = []
    sim.events.on("message_dropped", lambda e: dropped.append(e.cause))
    sim.run(until_s=15.0)
    stack.relay.send(1, 0)
    stack.relay.send(1, 2)
    sim.run()
    assert stack.messages_frame()["delivered"].all() and dropped == []
