"""The messages between random pairs (``protocol.message_rate_hz``) under the routing
protocols: the clustering's pairs, carried as packets of flow -1."""

import numpy as np
import pytest

from netsim.errors import ConfigError
from netsim.run import build, collect
from tests.fixtures import make_config

GRID = [(50 + 100 * i, 50 + 100 * j) for i in range(4) for j in range(4)]


def _run(tmp_path, protocol, duration_s=20.0, **flows):
    path = tmp_path / "robots.csv"
    path.write_text("x_m,y_m\n" + "".join(f"{x},{y}\n" for x, y in GRID))
    config = make_config(
        seed=4,
        duration_s=duration_s,
        world={"n_robots": len(GRID), "side_m": 1000.0, "placement": str(path)},
        mobility={"model": "static"},
        channel={"range_m": 120.0},
        protocol=protocol,
        output={"position_interval_s": 0.0},
        **flows,
    )
    sim = build(config)
    sim.run()
    return collect(sim)


@pytest.mark.parametrize("model", ["aodv", "olsr", "greedy"])
def test_routing_protocols_send_the_clusterings_random_pairs(tmp_path, model):
    """Under a routing protocol, ``protocol.message_rate_hz`` sends the messages the
    clustering's relay sends at the same seed (same times, same pairs), each a packet of
    ``message_bytes`` in ``packets.parquet`` with ``flow = -1``."""
    rate = {"message_rate_hz": 3.0, "message_bytes": 200}
    theirs = _run(tmp_path, {"model": "clustering", **rate})["messages"]
    ours = _run(tmp_path, {"model": model, **rate})["packets"]
    assert len(theirs) > 30
    assert (ours["flow"] == -1).all() and (ours["bytes"] == 200).all() and (ours["frames"] == 1).all()
    assert ours["packet"].tolist() == list(range(len(ours)))
    assert ours["t_sent_s"].tolist() == theirs["t_sent_s"].tolist()
    assert ours["src"].tolist() == theirs["src"].tolist()
    assert ours["dst"].tolist() == theirs["dst"].tolist()


def test_random_pairs_are_routed_over_shortest_paths_once_olsr_has_converged(tmp_path):
    """On a static grid, once OLSR's HELLOs and TCs have spread, every random pair's message
    is delivered over the grid's hop distance; the flows keep their own rows beside them."""
    flow = {"src": 0, "dst": 15, "start_s": 15.0, "stop_s": 25.0, "rate_bps": 8000.0, "packet_bytes": 1000}
    frames = _run(tmp_path, {"model": "olsr", "message_rate_hz": 2.0}, 40.0, traffic={"flows": [flow]})
    packets = frames["packets"]
    pairs = packets[(packets["flow"] == -1) & (packets["t_sent_s"] > 20.0)]
    assert len(pairs) > 20
    assert pairs["delivered"].all()
    hops = [abs(s // 4 - d // 4) + abs(s % 4 - d % 4) for s, d in zip(pairs["src"], pairs["dst"])]
    assert pairs["hops"].tolist() == hops
    assert (packets["flow"] == 0).sum() == 10
    assert frames["flows"]["flow"].tolist() == [0]


def test_routing_protocol_without_message_rate_sends_no_random_pairs(tmp_path):
    """A routing protocol's ``message_rate_hz`` defaults to 0: the flows alone, no packets
    table without them."""
    frames = _run(tmp_path, {"model": "aodv"}, 10.0)
    assert "packets" not in frames or len(frames["packets"]) == 0


def test_routing_message_rate_out_of_range_is_refused():
    """A negative message rate or a size that is not positive is refused, naming the key."""
    with pytest.raises(ConfigError, match="protocol.message_rate_hz"):
        make_config(protocol={"model": "olsr", "message_rate_hz": -1.0})
    with pytest.raises(ConfigError, match="protocol.message_bytes"):
        make_config(protocol={"model": "greedy", "message_bytes": 0})


@pytest.mark.parametrize("model", ["aodv", "olsr", "greedy"])
def test_routing_hops_list_every_frames_path_from_source_to_destination(tmp_path, model):
    """Under a routing protocol ``hops.parquet`` lists each data frame's reception by its
    next hop: on a static, loss-free grid one row per data transmission, and each
    delivered frame's rows are a chain from its packet's source to its destination, hop
    1, 2, ... in time order, every frame of a delivered packet there, as many hops as the
    packet's ``hops``; ``flow`` and ``packet`` name its row of ``packets.parquet``."""
    flow = {"src": 0, "dst": 15, "start_s": 15.0, "stop_s": 25.0, "rate_bps": 32000.0, "packet_bytes": 4000}
    path = tmp_path / "robots.csv"
    path.write_text("x_m,y_m\n" + "".join(f"{x},{y}\n" for x, y in GRID))
    config = make_config(
        seed=4,
        duration_s=30.0,
        world={"n_robots": len(GRID), "side_m": 1000.0, "placement": str(path)},
        mobility={"model": "static"},
        channel={"range_m": 120.0},
        protocol={"model": model, "message_rate_hz": 2.0},
        traffic={"flows": [flow]},
        output={"position_interval_s": 0.0},
    )
    sim = build(config)
    sim.run()
    frames = collect(sim)
    hops, packets = frames["hops"], frames["packets"]
    assert list(hops.columns) == ["msg_id", "hop", "sender", "receiver", "t_sent_s", "t_received_s", "flow", "packet"]
    assert len(hops) == sim.models["protocol"].data_transmissions > 0
    assert hops["t_received_s"].is_monotonic_increasing
    assert (hops["t_received_s"] > hops["t_sent_s"]).all()
    by_packet = packets.set_index(["flow", "packet"])
    delivered = by_packet[by_packet["delivered"]]
    assert (delivered["frames"] == 3).sum() > 5 and (delivered["frames"] == 1).sum() > 5
    for (f, p), row in delivered.iterrows():
        ours = hops[(hops["flow"] == f) & (hops["packet"] == p)]
        assert ours["msg_id"].nunique() == row["frames"]
        longest = 0
        for _, chain in ours.groupby("msg_id"):
            chain = chain.sort_values("hop")
            assert chain["hop"].tolist() == list(range(1, len(chain) + 1))
            assert chain["sender"].iloc[0] == row["src"] and chain["receiver"].iloc[-1] == row["dst"]
            assert chain["sender"].iloc[1:].tolist() == chain["receiver"].iloc[:-1].tolist()
            assert (chain["t_sent_s"].iloc[1:].to_numpy() >= chain["t_received_s"].iloc[:-1].to_numpy()).all()
            longest = max(longest, len(chain))
        assert longest == row["hops"]


# Robot 1 starts far from the line between 0 and 2 (200 m apart, range 150 m) and joins it
# at 5 s, at 1000 m/s: 0.4 s later the two are two hops apart.
JOIN = """$node_(0) set X_ 100.0
$node_(0) set Y_ 500.0
$node_(1) set X_ 200.0
$node_(1) set Y_ 900.0
$node_(2) set X_ 300.0
$node_(2) set Y_ 500.0
$ns_ at 5.0 "$node_(1) setdest 200.0 500.0 1000.0"
"""


@pytest.mark.parametrize("model", ["aodv", "olsr", "greedy"])
def test_routed_packets_shortest_hops_is_the_shortest_path_when_sent(tmp_path, model):
    """Under a routing protocol each packet's ``shortest_hops`` is the shortest path from
    its source to its destination on the true topology when it was sent: none (``inf``)
    before robot 1 joins the two ends, 2 hops after, where those sent after took it
    (packets.parquet's ``hops``; a packet sent before may wait for a route and take it too)."""
    from tests.fixtures import flow_over_trace

    flow = {"src": 0, "dst": 2, "start_s": 1.0, "stop_s": 12.0, "rate_bps": 4000.0, "packet_bytes": 500}
    _sim, frames = flow_over_trace(tmp_path, JOIN, 3, flow, 12.0, 1, {"range_m": 150.0}, {"model": model})
    packets = frames["packets"]
    assert packets["t_sent_s"].tolist() == [float(t) for t in range(1, 12)]
    before, after = packets[packets["t_sent_s"] < 5.0], packets[packets["t_sent_s"] > 5.4]
    assert np.isinf(before["shortest_hops"]).all() and len(before) == 4
    assert (after["shortest_hops"] == 2.0).all() and len(after) == 6
    took = after[after["delivered"]]
    assert len(took) >= 1 and (took["hops"] == 2).all(), after[["t_sent_s", "delivered", "drop_cause"]]


def test_routed_packets_shortest_hops_on_a_grid_is_the_breadth_first_distance(tmp_path):
    """On the static grid every random pair's packet has the hop distance of the unit-disk
    graph between its ends (networkx's breadth-first search), which OLSR's routes, once
    spread, take."""
    import networkx as nx

    frames = _run(tmp_path, {"model": "olsr", "message_rate_hz": 4.0}, 30.0)
    packets = frames["packets"]
    graph = nx.Graph()
    graph.add_nodes_from(range(len(GRID)))
    graph.add_edges_from(
        (a, b) for a in range(len(GRID)) for b in range(a) if np.hypot(*np.subtract(GRID[a], GRID[b])) <= 120.0
    )
    hops = dict(nx.all_pairs_shortest_path_length(graph))
    expected = [float(hops[s][d]) for s, d in zip(packets["src"], packets["dst"])]
    assert len(packets) > 50 and packets["shortest_hops"].tolist() == expected
    assert len(set(expected)) > 3
    settled = packets[packets["delivered"] & (packets["t_sent_s"] > 15.0)]
    assert len(settled) > 20 and (settled["hops"] == settled["shortest_hops"]).all()


def test_a_routed_packets_shortest_hops_sees_a_jump_at_its_own_instant(tmp_path):
    """Two packets from 0 to 2 sent at one instant, robot 1 set down between them at that
    instant where it joins the two (a trace's jump): the first has no path, the second the
    two hops the jump made (the search's reuse for a packet's frames must not carry a value
    over a jump)."""
    from netsim.traffic import Flow

    path = tmp_path / "robots.csv"
    path.write_text("x_m,y_m\n100,500\n200,900\n300,500\n")
    config = make_config(
        seed=1,
        duration_s=10.0,
        world={"n_robots": 3, "side_m": 1000.0, "placement": str(path)},
        mobility={"model": "static"},
        channel={"range_m": 150.0},
        protocol={"model": "greedy", "message_rate_hz": 1.0},
        output={"position_interval_s": 0.0},
    )
    sim = build(config)
    sim.run(until_s=5.0)
    flows = sim.models["protocol"].flows
    before = len(flows.packets_frame())
    packet = Flow(0, 2, 5.0, 6.0, 4000.0, 500)
    flows._send_packet(7, 0, packet, [500])
    sim.state.set_leg(1, 5.0, (0.0, 0.0), start_m=(200.0, 500.0))
    flows._send_packet(7, 1, packet, [500])
    ours = flows.packets_frame().iloc[before:]
    assert ours["flow"].tolist() == [7, 7] and ours["t_sent_s"].tolist() == [5.0, 5.0]
    assert ours["shortest_hops"].tolist() == [np.inf, 2.0]


def test_the_summary_counts_control_frames_and_the_messages_they_carry_apart(tmp_path):
    """docs/routing.md: the summary's control_frames and control_messages (and their rates
    over the run's duration) are the control table's frames and messages; under OLSR a frame
    carries one or more messages, so that a ``hello+tc`` frame counts two at least, and
    the messages outnumber the frames."""
    from netsim.run import summarize

    path = tmp_path / "robots.csv"
    path.write_text("x_m,y_m\n" + "".join(f"{x},{y}\n" for x, y in GRID))
    config = make_config(
        seed=4,
        duration_s=20.0,
        world={"n_robots": len(GRID), "side_m": 1000.0, "placement": str(path)},
        mobility={"model": "static"},
        channel={"range_m": 120.0},
        protocol={"model": "olsr"},
        output={"position_interval_s": 0.0},
    )
    sim = build(config)
    sim.run()
    frames = collect(sim)
    summary = summarize(sim, frames, 0.0)
    control = frames["control"].set_index("kind")
    assert summary["control_frames"] == control["sent"].sum()
    assert summary["control_messages"] == control["messages"].sum() > summary["control_frames"]
    assert control.loc["hello+tc", "messages"] >= 2 * control.loc["hello+tc", "sent"] > 0
    assert summary["control_frames_per_s"] == pytest.approx(summary["control_frames"] / 20.0)
    assert summary["control_messages_per_s"] == pytest.approx(summary["control_messages"] / 20.0)


def test_random_pairs_frames_in_the_run_are_capped_one_message_at_least():
    """docs/routing.md: under a routing protocol the random pairs' messages are held to
    100,000,000 frames in the run, a message of ``message_bytes`` counting its frames, and
    one message at least however short the run: half a message expected in a 1 s run, of
    150,000,000 frames, is refused naming protocol.message_bytes."""
    huge = 150_000_000 * 1500
    with pytest.raises(ConfigError, match="protocol.message_bytes"):
        make_config(duration_s=1.0, protocol={"model": "aodv", "message_rate_hz": 0.5, "message_bytes": huge})
    make_config(duration_s=1.0, protocol={"model": "aodv", "message_rate_hz": 0.5, "message_bytes": huge // 2})


def test_routing_protocols_random_pairs_default_to_none_of_512_bytes():
    """docs/routing.md: under a routing protocol protocol.message_rate_hz defaults to 0 (no
    random pairs) and protocol.message_bytes to 512."""
    for model in ("aodv", "olsr", "greedy"):
        params = make_config(protocol={"model": model}).protocol.params
        assert (params.message_rate_hz, params.message_bytes) == (0.0, 512), model


@pytest.mark.parametrize("model", ["aodv", "greedy"])
def test_a_team_of_one_robot_sends_no_random_pairs(model):
    """A robot alone has no pair to send to: under a routing protocol with random pairs, a
    team of one runs and sends no message (and draws none, as the clustering's relay)."""
    config = make_config(
        seed=4,
        duration_s=10.0,
        world={"n_robots": 1},
        mobility={"model": "static"},
        protocol={"model": model, "message_rate_hz": 5.0},
        output={"position_interval_s": 0.0},
    )
    sim = build(config)
    sim.run()
    frames = collect(sim)
    assert len(frames["packets"]) == 0
