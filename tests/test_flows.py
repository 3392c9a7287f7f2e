"""Traffic flows (traffic.flows): packets of a flow's size and rate, split into frames of
channel.max_frame_bytes and delivered only whole; the flows and packets tables; bad flows
refused in one line."""

import numpy as np
import pytest

from netsim.errors import ConfigError
from netsim.run import build, collect
from netsim.tools.cli import main
from netsim.traffic import Flow, fragment_bytes, send_times
from tests.fixtures import make_config


def _line_csv(tmp_path, n, spacing_m):
    path = tmp_path / "line.csv"
    path.write_text("x_m,y_m\n" + "".join(f"{50 + i * spacing_m},500\n" for i in range(n)))
    return str(path)


def _line_run(tmp_path, flows, n=5, spacing_m=100.0, duration_s=30.0, protocol=None, channel=None):
    config = make_config(
        seed=2,
        duration_s=duration_s,
        world={"n_robots": n, "side_m": 1000.0, "placement": _line_csv(tmp_path, n, spacing_m)},
        mobility={"model": "static"},
        channel={"range_m": 120.0, **(channel or {})},
        protocol={"message_rate_hz": 0.0, **(protocol or {})},
        traffic={"flows": flows},
        output={"position_interval_s": 0.0},
    )
    sim = build(config)
    sim.run()
    return collect(sim)


FLOW = {"src": 0, "dst": 4, "start_s": 10.0, "stop_s": 20.0, "rate_bps": 8000.0, "packet_bytes": 1000}


def test_send_times_follow_rate_and_stop_at_stop_s():
    """A flow sends a packet every packet_bytes * 8 / rate_bps seconds from start_s, none at
    or after stop_s, none after the run's end."""
    f = Flow(0, 1, 2.0, 12.0, 8000.0, 1000)
    assert send_times(f, 100.0) == [2.0 + k for k in range(10)]
    assert send_times(f, 5.5) == [2.0, 3.0, 4.0, 5.0]
    assert send_times(f, 1.0) == []


def test_payload_over_max_frame_bytes_is_split_into_frames():
    """A packet over channel.max_frame_bytes travels as full frames and the rest; the sizes
    add up to the packet."""
    for size in (1, 1499, 1500, 1501, 4000, 30000):
        frames = fragment_bytes(size, 1500)
        assert sum(frames) == size and all(0 < b <= 1500 for b in frames)
        assert len(frames) == -(-size // 1500)


@pytest.mark.parametrize("routing", ["oracle", "backbone"])
def test_flow_on_a_static_line_is_delivered_over_its_hops(tmp_path, routing):
    """On a connected static line without loss every packet of a flow from one end to the
    other arrives (once the backbone has formed), over the line's hops; the flows table
    sums the packets table."""
    frames = _line_run(tmp_path, [FLOW], protocol={"routing": routing})
    packets, flows = frames["packets"], frames["flows"]
    assert len(packets) == 10 and packets["delivered"].all()
    assert (packets["frames"] == 1).all()
    if routing == "oracle":
        assert (packets["hops"] == 4).all()
    # The line's shortest path, as messages.parquet measures each frame's.
    assert (packets["shortest_hops"] == 4.0).all()
    assert (frames["messages"]["shortest_hops"] == 4.0).all()
    row = flows.iloc[0]
    assert row["packets_sent"] == 10 and row["packets_delivered"] == 10 and row["delivery_ratio"] == 1.0
    assert row["goodput_bps"] == pytest.approx(8000.0)
    assert row["latency_p50_s"] == pytest.approx(np.percentile(packets["latency_s"], 50))
    assert list(flows.columns) == [
        "flow",
        "src",
        "dst",
        "packets_sent",
        "packets_delivered",
        "delivery_ratio",
        "goodput_bps",
        "latency_p50_s",
        "latency_p95_s",
        "mean_hops",
    ]


@pytest.mark.parametrize("routing", ["oracle", "backbone"])
def test_relays_per_robot_per_s_counts_the_flows_frames(tmp_path, routing):
    """The summary's relays_per_robot_per_s counts every frame relayed, the flows' as the
    random pairs' messages: 10 packets of 4000 bytes (3 frames each) over the 4 hops of a
    static line, 120 transmissions, are 1.2 a robot a second over 20 s (it said 0)."""
    from netsim.run import summarize

    flow = {**FLOW, "start_s": 2.0, "stop_s": 12.0, "rate_bps": 32000.0, "packet_bytes": 4000}
    config = make_config(
        seed=2,
        duration_s=20.0,
        world={"n_robots": 5, "side_m": 1000.0, "placement": _line_csv(tmp_path, 5, 100.0)},
        mobility={"model": "static"},
        channel={"range_m": 120.0},
        protocol={"message_rate_hz": 0.0, "routing": routing},
        traffic={"flows": [flow]},
        output={"position_interval_s": 0.0},
    )
    sim = build(config)
    sim.run()
    frames = collect(sim)
    relays = summarize(sim, frames, 0.0)["relays_per_robot_per_s"]
    assert relays == pytest.approx(frames["messages"]["transmissions"].sum() / (5 * 20.0))
    if routing == "oracle":
        assert relays == pytest.approx(1.2)


@pytest.mark.parametrize("protocol", [{"routing": "oracle"}, {"model": "aodv"}])
def test_summary_packet_delivery_ratio_is_the_packets_delivered_whole(tmp_path, protocol):
    """The summary's packet_delivery_ratio, under the clustering's relay as under a routing
    protocol: the packets of packets.parquet delivered whole over those sent (a lossy
    channel, so some frames of a 3-frame packet are lost and the figure lies inside (0, 1));
    no figure when no packet was sent."""
    from netsim.run import summarize

    def run(flows):
        config = make_config(
            seed=3,
            duration_s=30.0,
            world={"n_robots": 5, "side_m": 1000.0, "placement": _line_csv(tmp_path, 5, 100.0)},
            mobility={"model": "static"},
            channel={"range_m": 120.0, "loss_probability": 0.2},
            protocol={"message_rate_hz": 0.0, **protocol},
            traffic={"flows": flows},
            output={"position_interval_s": 0.0},
        )
        sim = build(config)
        sim.run()
        frames = collect(sim)
        return frames, summarize(sim, frames, 0.0)

    frames, summary = run([{**FLOW, "dst": 2, "packet_bytes": 4000, "rate_bps": 32000.0}])
    packets = frames["packets"]
    assert 0 < summary["packet_delivery_ratio"] < 1
    assert summary["packet_delivery_ratio"] == packets["delivered"].sum() / len(packets)
    # The line's packets take its two hops when they arrive: a stretch of 1.
    assert summary["packet_path_stretch"] == 1.0
    assert "packet_delivery_ratio" not in run([])[1] and "packet_path_stretch" not in run([])[1]


def test_summary_packet_path_stretch_is_hops_over_shortest_of_packets_that_had_a_path():
    """The summary's packet_path_stretch: the mean of hops / shortest_hops over the packets
    delivered that had a path when sent (one lost and one that arrived over a path formed
    later are left out); NaN when no delivered packet had one."""
    import pandas as pd
    from netsim.protocols.flows import packet_delivery

    packets = pd.DataFrame(
        {"delivered": [True, True, True, False], "hops": [3, 2, 4, 0], "shortest_hops": [2.0, 2.0, np.inf, 1.0]}
    )
    figures = packet_delivery({"packets": packets})
    assert figures == {"packet_delivery_ratio": 0.75, "packet_path_stretch": 1.25}
    none = packet_delivery({"packets": packets.iloc[2:]})
    assert np.isnan(none["packet_path_stretch"]) and none["packet_delivery_ratio"] == 0.5


def test_packet_is_delivered_only_whole(tmp_path):
    """A packet split into frames counts as delivered only if every frame arrives: with a
    lossy channel, a packet some of whose frames arrived and others not is not delivered,
    and every delivered packet had all its frames delivered."""
    big = {**FLOW, "dst": 2, "packet_bytes": 6000, "rate_bps": 48000.0}
    frames = _line_run(
        tmp_path,
        [big],
        n=3,
        protocol={"routing": "oracle"},
        channel={"loss_probability": 0.1},
    )
    packets = frames["packets"]
    assert (packets["frames"] == 4).all()
    assert (packets["frames_delivered"][packets["delivered"]] == 4).all()
    partial = packets[(packets["frames_delivered"] > 0) & (packets["frames_delivered"] < 4)]
    assert len(partial) > 0 and not partial["delivered"].any()
    assert (partial["drop_cause"] == "lost").all()
    assert packets["delivered"].any()
    assert packets.loc[packets["delivered"], "drop_cause"].isna().all()  # no cause, as receptions' cause


def _static_sim(tmp_path, xy: str, flows: list, routing: str, mac: str = "none", protocol=None):
    """A run, built, of ``flows`` among static robots at ``xy`` (CSV rows, one a robot),
    sending no random-pair message unless ``protocol`` says."""
    path = tmp_path / "static.csv"
    path.write_text("x_m,y_m\n" + xy)
    config = make_config(
        seed=2,
        duration_s=20.0,
        world={"n_robots": xy.count("\n"), "side_m": 1000.0, "placement": str(path)},
        mobility={"model": "static"},
        channel={"range_m": 120.0, "mac": mac},
        protocol={"message_rate_hz": 0.0, "routing": routing, **(protocol or {})},
        traffic={"flows": flows},
        output={"position_interval_s": 0.0},
    )
    return build(config)


def _static_run(tmp_path, xy: str, flow: dict, routing: str, mac: str = "none", protocol=None):
    """The packets of ``flow`` among static robots at ``xy`` (CSV rows, one a robot)."""
    sim = _static_sim(tmp_path, xy, [flow], routing, mac, protocol)
    sim.run()
    return collect(sim)["packets"]


def test_a_random_pair_flood_nobody_hears_on_a_shared_medium_dies_out(tmp_path):
    """Under a shared medium a flood ends when its last frame ends, heard or not: a robot out
    of everyone's range sends random-pair messages, each dropped as ``died_out`` when its one
    frame ends, none left in flight; the other two robots' messages between them arrive."""
    sim = _static_sim(tmp_path, "100,500\n200,500\n900,900\n", [], "backbone", "aloha", {"message_rate_hz": 1.0})
    dropped = []
    sim.events.on("message_dropped", dropped.append)
    sim.run()
    messages = collect(sim)["messages"].set_index("msg_id")
    from_far = messages.index[messages["src"] == 2]
    assert len(from_far) >= 3
    causes = {e.msg_id: e.cause for e in dropped}
    assert all(causes.get(m) == "died_out" for m in from_far)
    between = messages[(messages["src"] < 2) & (messages["dst"] < 2)]
    assert len(between) > 0 and between["delivered"].all()


def test_dropped_packet_says_where_and_why(tmp_path):
    """A packet that cannot reach its destination (a gap in the line) is dropped at the
    robot that held it, for want of a route (oracle routing)."""
    packets = _static_run(tmp_path, "100,500\n200,500\n600,500\n", {**FLOW, "dst": 2}, "oracle")
    assert not packets["delivered"].any()
    assert (packets["drop_cause"] == "no_route").all() and (packets["drop_robot"] == 0).all()


@pytest.mark.parametrize("mac", ["none", "aloha"])
def test_a_flood_no_one_hears_is_dropped_by_no_one_robot(tmp_path, mac):
    """Backbone flooding from a source no robot hears: its packets die out as a flood does,
    drop_robot -1, with or without a shared medium."""
    flow = {**FLOW, "src": 2, "dst": 0}
    packets = _static_run(tmp_path, "100,500\n200,500\n900,900\n", flow, "backbone", mac)
    assert len(packets) > 5 and not packets["delivered"].any()
    assert (packets["drop_cause"] == "died_out").all() and (packets["drop_robot"] == -1).all()


def test_a_flood_whose_last_copies_reach_no_new_robot_dies_out_not_on_its_ttl(tmp_path):
    """A flood ends on its hop limit (``ttl``) only when a copy at the limit reached a robot
    that had not had it: three robots within range of each other and a destination no one
    hears, message_ttl 2: the relayed copy (its last hop) reaches only robots that had the
    message, so the flood died out; message_ttl 1 cuts it at the first receivers."""
    triangle = "100,500\n150,500\n125,540\n900,900\n"
    flow = {**FLOW, "dst": 3}
    at_two = _static_run(tmp_path, triangle, flow, "backbone", protocol={"message_ttl": 2})
    assert len(at_two) == 10 and (at_two["drop_cause"] == "died_out").all()
    at_one = _static_run(tmp_path, triangle, flow, "backbone", protocol={"message_ttl": 1})
    assert (at_one["drop_cause"] == "ttl").all()


BAD_FLOWS = [
    ({**FLOW, "dst": 9}, "traffic.flows[0].dst = 9: no such robot"),
    ({**FLOW, "stop_s": 1.0}, "traffic.flows[0].stop_s = 1.0: must be after"),
    ({**FLOW, "stop_s": 10.0}, "traffic.flows[0].stop_s = 10.0: must be after"),  # stopping as it starts
    ({**FLOW, "dst": 5}, "traffic.flows[0].dst = 5: no such robot"),  # ids are 0 to 4
    ({**FLOW, "rate_bps": 0}, "traffic.flows[0].rate_bps = 0.0: must be > 0"),
    ({**FLOW, "packet_bytes": -5}, "traffic.flows[0].packet_bytes = -5: must be > 0"),
    ({**FLOW, "colour": 1}, "traffic.flows[0].colour"),
    (
        {**FLOW, "rate_bps": 1e12, "packet_bytes": 1},
        "would send 1,250,000,000,000 frames in the run (this one 1,250,000,000,000 packets of 1 bytes",
    ),
    ({**FLOW, "packet_bytes": 10**12}, "frames in the run (this one 1 packets of 1,000,000,000,000 bytes"),
    # A count past 10^15 in three digits (a rate of 1e300 printed a count of 298 digits).
    ({**FLOW, "rate_bps": 1e300, "packet_bytes": 100}, "would send 1.25e+298 frames in the run (this one 1.25e+298"),
]


@pytest.mark.parametrize("flow, words", BAD_FLOWS)
def test_bad_flow_is_refused_naming_it(flow, words):
    """A flow naming a robot that does not exist, stopping before it starts, or with a rate
    or size that is not positive is a ConfigError naming the flow's key."""
    with pytest.raises(ConfigError) as err:
        make_config(world={"n_robots": 5}, traffic={"flows": [flow]})
    assert words in str(err.value)


def test_flows_need_a_protocol_that_carries_them():
    """Flows under a protocol that relays nothing (ack) are refused, not silently unsent."""
    with pytest.raises(ConfigError, match="relays no messages"):
        make_config(world={"n_robots": 5}, protocol={"model": "ack"}, traffic={"flows": [FLOW]})


def test_cli_bad_flow_exits_2_with_one_line_and_writes_nothing(tmp_path, capsys):
    """`netsim run` with a bad flow: one line `netsim: error: ...`, exit 2, nothing written."""
    flow = "{src=0, dst=99, start_s=0, stop_s=5, rate_bps=1000, packet_bytes=100}"
    code = main(["run", "--quiet", "--out", str(tmp_path / "out"), "--set", f"traffic.flows=[{flow}]"])
    lines = capsys.readouterr().err.strip().splitlines()
    assert code == 2 and len(lines) == 1
    assert lines[0].startswith("netsim: error: traffic.flows[0].dst = 99")
    assert not (tmp_path / "out").exists()


def test_a_flow_that_starts_after_the_run_ends_is_told():
    """A flow starting at or after duration_s sends nothing: a warning says so (it was
    silent, its row all NaN)."""
    late = {**FLOW, "start_s": 30.0, "stop_s": 40.0}
    told = r"traffic.flows\[0\] starts at 30 s, at or after the run's end \(duration_s = 20\)"
    with pytest.warns(UserWarning, match=told):
        make_config(duration_s=20.0, world={"n_robots": 5}, traffic={"flows": [late]})


def test_the_frame_cap_counts_every_flow_of_the_run():
    """Flows that each stay under the cap but together pass it are refused at the flow
    that passes it (a cap by flow let a hundred flows under it pass)."""
    big = {**FLOW, "start_s": 0.0, "stop_s": 100.0, "rate_bps": 6.4e7, "packet_bytes": 1}  # 8e8 a flow
    small = {**big, "rate_bps": 4.0e6}  # 5e7 frames
    make_config(duration_s=100.0, world={"n_robots": 5}, traffic={"flows": [small]})
    with pytest.raises(ConfigError, match=r"^traffic.flows\[2\] = .*would send 150,000,000 frames"):
        make_config(duration_s=100.0, world={"n_robots": 5}, traffic={"flows": [small, small, small]})
    with pytest.raises(ConfigError, match=r"at most 100,000,000$"):
        make_config(duration_s=100.0, world={"n_robots": 5}, traffic={"flows": [big]})


def test_packet_count_is_the_number_of_send_times():
    """The count the cap uses is the schedule's length, at the run's end and at stop_s."""
    from netsim.traffic import packet_count

    cases = [
        (Flow(0, 1, 1.0, 2.0, 8000.0, 250), 10.0, 4),  # 1, 1.25, 1.5, 1.75 s: stop_s ends it
        (Flow(0, 1, 0.1, 0.7, 80.0, 1), 0.7, 6),  # 0.1 to 0.6 s, 0.1 s apart
        (Flow(0, 1, 0.0, 30.0, 8.0, 1), 10.0, 10),  # one a second, 0 to 9 s: the run's end ends it
    ]
    for flow, end, count in cases:
        assert packet_count(flow, end) == len(send_times(flow, end)) == count


def test_a_packets_hops_are_its_longest_frames_path_and_it_arrives_with_its_last_frame():
    """A packet of several frames, each relayed on its own, is delivered when its last
    frame arrives, after the longest path any of its frames took (the first frame's 3 hops
    here, not the last's 2); its latency runs from its sending to that arrival."""
    from netsim.protocols.flows import FlowTraffic

    row = {"frames": 2, "frames_delivered": 0, "hops": 0, "t_sent_s": 1.0, "drop_cause": ""}
    told = FlowTraffic._teller(row)
    told(0, True, 1.5, 3, -1, "")
    assert not row.get("delivered")
    told(1, True, 2.0, 2, -1, "")
    assert (row["delivered"], row["hops"], row["t_delivered_s"], row["latency_s"]) == (True, 3, 2.0, 1.0)


def test_a_packet_lost_is_told_where_and_why_its_first_frame_was_lost():
    """A packet is dropped when the first of its frames is, and that frame says where, when
    and why; a later frame lost elsewhere changes nothing."""
    from netsim.protocols.flows import FlowTraffic

    row = {"frames": 2, "frames_delivered": 0, "hops": 0, "t_sent_s": 1.0, "drop_cause": ""}
    told = FlowTraffic._teller(row)
    told(0, False, 1.5, 2, 2, "lost")
    told(1, False, 2.0, 3, 4, "no_route")
    assert (row["t_dropped_s"], row["drop_robot"], row["drop_cause"]) == (1.5, 2, "lost")


def test_a_flows_goodput_and_latency_quantiles_over_the_time_it_was_on():
    """The flows table: goodput is the delivered packets' bits over the time the flow was on
    within the run (from start_s to the earlier of stop_s and the run's end, 10 s here, not
    90 s); the latencies' 50th and 95th percentiles are numpy's (linear interpolation), and
    the mean hops are the delivered packets'."""
    import pandas as pd
    from netsim.protocols.flows import flows_table

    lat = np.arange(1, 21) * 0.01
    packets = pd.DataFrame(
        {"flow": 0, "delivered": np.arange(21) < 20, "latency_s": np.r_[lat, np.nan], "bytes": 100, "hops": 2}
    )
    packets.loc[19, "hops"] = 4
    (row,) = flows_table((Flow(0, 1, 10.0, 100.0, 800.0, 100),), packets, 20.0).to_dict("records")
    assert (row["packets_sent"], row["packets_delivered"]) == (21, 20)
    assert row["goodput_bps"] == pytest.approx(20 * 100 * 8 / 10.0)
    assert (row["latency_p50_s"], row["latency_p95_s"]) == pytest.approx((0.105, 0.1905))
    assert row["mean_hops"] == pytest.approx(2.1)


def _flow_traffic(send):
    import simpy
    from netsim.protocols.flows import FlowTraffic

    from netsim.traffic import Traffic

    env = simpy.Environment()
    return env, FlowTraffic(Traffic((), 1500), env, {}, send, lambda _msg_id: np.nan)


def test_a_packet_with_a_frame_lost_is_not_delivered_and_has_no_hops():
    """A packet one of whose frames arrived and another was lost is dropped, where its lost
    frame was; the packets table gives it 0 hops, as every packet not delivered (the frame
    that arrived counts in frames_delivered alone)."""
    outcomes = []
    _env, flows = _flow_traffic(lambda src, dst, kind, told: outcomes.append(told) or len(outcomes))
    flows._send_packet(0, 0, Flow(0, 1, 0.0, 1.0, 8000.0, 3000), [1500, 1500])
    outcomes[0](1, True, 0.5, 2, -1, "")
    outcomes[1](2, False, 0.6, 1, 1, "lost")
    (row,) = flows.packets_frame().to_dict("records")
    assert (row["delivered"], row["hops"], row["frames_delivered"], row["drop_cause"]) == (False, 0, 1, "lost")


class _PairDraws:
    """A stand-in for the traffic stream: every gap 1 s, then the given integers in turn."""

    def __init__(self, *ints):
        self.ints = list(ints)

    def exponential(self, _scale):
        return 1.0

    def integers(self, _high):
        return self.ints.pop(0)


def test_random_pairs_never_send_a_robot_a_message_of_its_own():
    """The random pairs' destination is drawn among the n - 1 other robots: a draw at or
    above the source's id moves up by one, so every ordered pair comes out and no robot
    sends to itself."""
    sent = []
    env, flows = _flow_traffic(lambda src, dst, kind, told: sent.append((src, dst)) or len(sent))
    flows.start_pairs(3, 1.0, 100, _PairDraws(1, 1, 1, 0, 0, 0, 2, 1, 2, 0))
    env.run(until=5.5)
    assert sent == [(1, 2), (1, 0), (0, 1), (2, 1), (2, 0)]


def test_a_packet_due_at_stop_s_is_not_sent_however_the_division_rounds():
    """A flow sends before stop_s, never at it: from 1.0 s to 1.1 s every 0.1 s is one
    packet, though (1.1 - 1.0) / 0.1 rounds above 1 and the count's ceiling says 2 (the
    second would leave at 1.0 + 0.1 = 1.1 s, at stop_s)."""
    from netsim.traffic import packet_count

    flow = Flow(0, 1, 1.0, 1.1, 8000.0, 100)
    assert (1.1 - 1.0) / flow.interval_s > 1
    assert send_times(flow, 10.0) == [1.0] and packet_count(flow, 10.0) == 1


def test_a_flow_that_starts_at_the_runs_end_is_told():
    """A flow starting at duration_s exactly sends nothing either (its first packet would
    leave as the run ends): the same warning."""
    at_end = {**FLOW, "start_s": 20.0, "stop_s": 40.0}
    with pytest.warns(UserWarning, match=r"traffic.flows\[0\] starts at 20 s, at or after the run's end"):
        make_config(duration_s=20.0, world={"n_robots": 5}, traffic={"flows": [at_end]})


def test_summary_packet_path_stretch_is_the_mean_not_the_median():
    """docs/routing.md: packet_path_stretch is the *mean* of hops / shortest_hops over the
    delivered packets that had a path: stretches 1, 1 and 2 give 4/3."""
    import pandas as pd
    from netsim.protocols.flows import packet_delivery

    packets = pd.DataFrame({"delivered": [True, True, True], "hops": [2, 3, 4], "shortest_hops": [2.0, 3.0, 2.0]})
    assert packet_delivery({"packets": packets})["packet_path_stretch"] == pytest.approx(4 / 3)


def test_no_packet_sent_gives_no_delivery_figures():
    """The summary's packet figures are over the packets sent: a packets table with no row
    (a flow that starts after the run's end, random pairs that had no time to send) gives
    neither packet_delivery_ratio nor packet_path_stretch, rather than a NaN ratio."""
    import pandas as pd
    from netsim.protocols.flows import PACKETS_SCHEMA, packet_delivery

    empty = pd.DataFrame({c: [] for c in PACKETS_SCHEMA}).astype(PACKETS_SCHEMA)
    assert packet_delivery({"packets": empty}) == {}


def test_each_frame_of_a_packet_takes_the_channel_size_of_its_own_bytes():
    """docs/routing.md: a packet of 4000 bytes travels as frames of 1500, 1500 and 1000
    bytes, and on a shared medium each frame's airtime is its own size's: the channel knows
    the flow's frame kinds by their own sizes, the last one's 1000 bytes, not 1500."""
    flow = {**FLOW, "packet_bytes": 4000}
    config = make_config(
        seed=2,
        duration_s=15.0,
        world={"n_robots": 5, "side_m": 1000.0},
        mobility={"model": "static"},
        channel={"range_m": 120.0, "mac": "csma"},
        protocol={"model": "aodv"},
        traffic={"flows": [flow]},
        output={"position_interval_s": 0.0},
    )
    sizes = build(config).channel.frame_bytes
    assert (sizes["flow_1500B"], sizes["flow_1000B"]) == (1500, 1000)


@pytest.mark.parametrize(
    "flow, words",
    [
        ({**FLOW, "start_s": -1.0}, "traffic.flows[0].start_s = -1.0: must be >= 0"),
        ({**FLOW, "start_s": float("inf")}, "traffic.flows[0].start_s = inf: must be >= 0 and finite"),
        ({**FLOW, "rate_bps": float("inf")}, "traffic.flows[0].rate_bps = inf: must be > 0 and finite"),
        ({**FLOW, "dst": 0}, "traffic.flows[0].dst = 0: must differ from src"),
        ({k: v for k, v in FLOW.items() if k != "rate_bps"}, "misses rate_bps"),
    ],
)
def test_a_flow_from_before_0_to_itself_at_an_infinite_rate_or_incomplete_is_refused(flow, words):
    """docs/routing.md: a negative start_s, a src equal to its dst, a rate that is not a
    positive finite number (an infinite one would send packets 0 s apart), or a flow missing
    one of its six keys is refused in one line naming the flow's key."""
    with pytest.raises(ConfigError) as err:
        make_config(world={"n_robots": 5}, traffic={"flows": [flow]})
    assert words in str(err.value)


def test_frame_count_is_the_number_of_frames_of_a_packet():
    """A packet of an exact multiple of max_frame_bytes is that many full frames, with no
    empty rest: the frame count the cap uses is fragment_bytes' length at every size."""
    from netsim.traffic import frame_count

    for size in (1, 1499, 1500, 1501, 3000, 4000, 4500, 30000):
        assert frame_count(size, 1500) == len(fragment_bytes(size, 1500)), size
    assert frame_count(3000, 1500) == 2


@pytest.mark.parametrize("value", [5, {"src": 0}])
def test_flows_that_are_not_a_list_are_refused(value):
    """traffic.flows is a list of tables: anything else is refused naming the key, one line
    (a number ended the run in a traceback)."""
    with pytest.raises(ConfigError, match=r"^traffic.flows = .*: must be a list of flows"):
        make_config(world={"n_robots": 5}, traffic={"flows": value})


@pytest.mark.parametrize(
    "flow, words",
    [
        ({**FLOW, "src": -1}, "traffic.flows[0].src = -1: must be a robot's id"),
        ("a flow", "traffic.flows[0] = 'a flow': must be a table"),
    ],
)
def test_a_flow_that_is_no_table_or_names_a_negative_id_is_refused(flow, words):
    """A flow is a table of the six keys, naming robots by their ids (0 and up): anything
    else is refused in one line naming it."""
    with pytest.raises(ConfigError) as err:
        make_config(world={"n_robots": 5}, traffic={"flows": [flow]})
    assert words in str(err.value)


def test_a_flow_of_exactly_the_frame_cap_in_the_run_is_accepted():
    """The cap counts the frames sent *in the run*, before its end: a flow going on past the
    run's end that sends exactly 100,000,000 one-byte packets (2^-20 s apart over 95.37 s)
    before it is accepted; the packet due at the end itself is not counted."""
    duration = 1e8 * 2.0**-20
    flow = {"src": 0, "dst": 1, "start_s": 0.0, "stop_s": 200.0, "rate_bps": 8.0 * 2**20, "packet_bytes": 1}
    make_config(duration_s=duration, world={"n_robots": 5}, traffic={"flows": [flow]})
    with pytest.raises(ConfigError, match="would send 100,000,001 frames"):
        make_config(duration_s=duration + 2.0**-20, world={"n_robots": 5}, traffic={"flows": [flow]})


def test_an_oracle_packet_out_of_hops_is_dropped_at_the_robot_that_holds_it(tmp_path):
    """docs/routing.md: a dropped packet says where (``drop_robot``, the robot that held it
    last) and why: down a line of five robots under the oracle, a message_ttl of 3 leaves
    every packet at robot 3, which received it on the third hop and may send it no further."""
    packets = _line_run(tmp_path, [FLOW], protocol={"routing": "oracle", "message_ttl": 3})["packets"]
    assert len(packets) == 10
    assert (packets["drop_cause"] == "ttl").all() and (packets["drop_robot"] == 3).all()
