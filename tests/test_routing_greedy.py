"""Greedy geographic forwarding (protocol.model = "greedy"): its forwarding rule, its
documented behaviour at a local maximum, and its parameters' ranges."""

import numpy as np
import pytest
from netsim.protocols._kernels import TIE_S
from netsim.protocols.greedy import greedy_next_hop

from netsim.errors import ConfigError
from netsim.run import build, collect
from netsim.tools.cli import main
from tests.fixtures import flow_over_trace, make_config
from tests.oracles.protocols import deadline

FLOW = {"src": 0, "dst": 4, "start_s": 10.0, "stop_s": 20.0, "rate_bps": 8000.0, "packet_bytes": 1000}


def _run(tmp_path, xy, flows, duration_s=30.0, torus=False, **protocol):
    path = tmp_path / "robots.csv"
    path.write_text("x_m,y_m\n" + "".join(f"{x},{y}\n" for x, y in xy))
    config = make_config(
        seed=4,
        duration_s=duration_s,
        world={"n_robots": len(xy), "side_m": 1000.0, "placement": str(path), "torus": torus},
        mobility={"model": "static"},
        channel={"range_m": 120.0},
        protocol={"model": "greedy", **protocol},
        traffic={"flows": flows},
        output={"position_interval_s": 0.0},
    )
    sim = build(config)
    sim.run()
    return sim, collect(sim)


def test_a_neighbour_not_heard_for_the_timeout_is_forgotten(tmp_path):
    """A neighbour whose deadline (when it was heard, plus the timeout, plus the instants
    that round into it) is now is forgotten, one heard a moment later is not (the neighbour
    entry's rule: live while its deadline is still to come)."""
    sim, _ = _run(tmp_path, [(0, 0), (50, 0), (100, 0)], [], duration_s=5.0)
    greedy, now = sim.models["protocol"], sim.env.now
    timeout = greedy.params.neighbour_timeout_s
    at = now - timeout - TIE_S
    while deadline(at, timeout) < now:
        at = np.nextafter(at, np.inf)
    assert deadline(at, timeout) == now  # the tie is exact
    later = at
    while not deadline(later, timeout) > now:  # the first instant whose deadline is past now
        later = np.nextafter(later, np.inf)
    greedy.heard_t[0, 1] = at
    greedy.heard_t[0, 2] = later
    assert greedy.neighbours(0).tolist() == [2]


def test_greedy_never_forwards_away_from_the_destination():
    """The next hop is always strictly closer to the destination than the holder (by the
    positions the holder knows), the closest such neighbour; and there is none (-1, a local
    maximum) exactly when no neighbour is closer. Random neighbourhoods, many of them with
    every neighbour farther."""
    rng = np.random.default_rng(7)
    maxima = forwarded = 0
    for _ in range(3000):
        k = int(rng.integers(0, 8))
        own, dst = rng.uniform(0, 100, 2), rng.uniform(0, 100, 2)
        ids = rng.choice(50, k, replace=False)
        xy = own + rng.uniform(-20, 20, (k, 2))
        nxt = greedy_next_hop(own, dst, ids, xy)
        d = np.hypot(*(xy - dst).T)
        own_d = np.hypot(*(own - dst))
        if nxt < 0:
            maxima += 1
            assert not (d < own_d).any()
        else:
            forwarded += 1
            j = int(np.flatnonzero(ids == nxt)[0])
            assert d[j] < own_d and d[j] == d.min()
    assert maxima > 300 and forwarded > 300


def test_greedy_delivers_along_a_static_line(tmp_path):
    """On a connected static line, every packet goes straight down the line: delivered, in
    as many hops as robots in between plus one; position beacons are counted as control."""
    sim, frames = _run(tmp_path, [(50 + 100 * i, 500) for i in range(5)], [FLOW])
    packets = frames["packets"]
    assert packets["delivered"].all() and (packets["hops"] == 4).all()
    control = frames["control"].set_index("kind")
    sent = control.loc["beacon", "sent"]
    assert sent > 0 and control.loc["beacon", "bytes_sent"] == 24 * sent


def test_local_maximum_drops_the_packet_there(tmp_path):
    """A holder with no neighbour closer to the destination than itself drops the packet
    (drop_cause local_maximum, at that holder): no perimeter recovery, no transmission."""
    xy = [(100, 500), (50, 580), (400, 500)]  # robot 1 is behind robot 0; the destination is alone
    sim, frames = _run(tmp_path, xy, [{**FLOW, "dst": 2}])
    packets = frames["packets"]
    assert len(packets) == 10 and not packets["delivered"].any()
    assert (packets["drop_cause"] == "local_maximum").all() and (packets["drop_robot"] == 0).all()
    assert sim.models["protocol"].data_transmissions == 0


def test_on_a_torus_greedy_measures_to_the_nearest_image(tmp_path):
    """On a torus the distances to the destination are to its nearest image: from x = 900 m
    of a 1000 m torus a destination at x = 60 m is 160 m ahead across the seam, so the
    packet goes to the neighbour toward the seam and arrives in two hops (measured on the
    plane it would go back to the neighbour behind, 760 m from it, and die there at a
    local maximum). The plain rule, the same with the side."""
    xy = [(900, 500), (980, 500), (60, 500), (820, 500)]
    _, frames = _run(tmp_path, xy, [{**FLOW, "dst": 2}], torus=True)
    packets = frames["packets"]
    assert len(packets) == 10 and packets["delivered"].all() and (packets["hops"] == 2).all()
    own, dst, ids, nbr = (
        np.array(xy[0], float),
        np.array(xy[2], float),
        np.array([1, 3]),
        np.array([xy[1], xy[3]], float),
    )
    assert greedy_next_hop(own, dst, ids, nbr, 1000.0) == 1
    assert greedy_next_hop(own, dst, ids, nbr) == 3


@pytest.mark.parametrize(
    "key, value, words",
    [
        ("beacon_jitter_s", 0.6, "protocol.beacon_jitter_s = 0.6: must be less than half"),
        ("beacon_period_s", 0.0, "protocol.beacon_period_s = 0.0: must be > 0"),
        ("neighbour_timeout_s", 1.0, "protocol.neighbour_timeout_s = 1.0: must be greater than"),
        ("hop_limit", 0, "protocol.hop_limit = 0: must be > 0"),
    ],
)
def test_greedy_parameter_out_of_range_is_refused(key, value, words):
    """A greedy parameter out of its range is a ConfigError naming the key."""
    with pytest.raises(ConfigError) as err:
        make_config(protocol={"model": "greedy", key: value})
    assert words in str(err.value)


def test_cli_greedy_parameter_out_of_range_exits_2(tmp_path, capsys):
    """`netsim run` with a routing parameter out of range: one line, exit 2, nothing written."""
    out = tmp_path / "out"
    sets = ["--set", "protocol.model=greedy", "--set", "protocol.hop_limit=0"]
    code = main(["run", "--quiet", "--out", str(out), *sets])
    lines = capsys.readouterr().err.strip().splitlines()
    assert code == 2 and len(lines) == 1 and lines[0].startswith("netsim: error: protocol.hop_limit = 0")
    assert not out.exists()


LEAVES = """$node_(0) set X_ 100.0
$node_(0) set Y_ 500.0
$node_(1) set X_ 200.0
$node_(1) set Y_ 500.0
$node_(2) set X_ 300.0
$node_(2) set Y_ 500.0
$node_(3) set X_ 400.0
$node_(3) set Y_ 500.0
$node_(4) set X_ 500.0
$node_(4) set Y_ 500.0
$ns_ at 8.0 "$node_(4) setdest 900.0 500.0 100.0"
"""


@pytest.mark.parametrize("mac", ["none", "csma"])
def test_a_unicast_that_does_not_get_through_forgets_its_neighbour_at_once(tmp_path, mac):
    """The destination of the line 0-1-2-3-4 walks away at 8 s. The packet robot 3 sends it
    then does not get through, and 3 forgets 4 at once: that one packet is lost, the later
    ones end at 3 as a local maximum. On a shared medium the unicast that fails after its
    retries says so too (3 kept sending to 4 until its timeout: 10 packets lost)."""
    flow = {"src": 0, "dst": 4, "start_s": 2.0, "stop_s": 12.0, "rate_bps": 16000, "packet_bytes": 500}
    channel = {"range_m": 150.0, "mac": mac}
    _sim, frames = flow_over_trace(tmp_path, LEAVES, 5, flow, 20.0, 1, channel, {"model": "greedy"})
    packets = frames["packets"]
    causes = packets.loc[~packets["delivered"], "drop_cause"].value_counts().to_dict()
    assert causes == {"local_maximum": 13, "lost": 1}, causes


def test_a_frame_that_does_not_get_through_a_medium_is_one_link_failure(tmp_path, monkeypatch):
    """Under a medium each frame the router hands over and that does not get through (its
    queue full, or its retries spent) tells the router once, by the medium's notice: as
    many link failures as frames dropped, and as many packets lost (the refusal at the
    queue told it a second time)."""
    from netsim.protocols.greedy import Greedy

    calls = []
    real = Greedy.link_failed
    monkeypatch.setattr(Greedy, "link_failed", lambda self, h, n, p: (calls.append((h, n)), real(self, h, n, p)))
    flow = {**FLOW, "start_s": 5.0, "stop_s": 10.0, "rate_bps": 400000.0, "packet_bytes": 1000}
    path = tmp_path / "robots.csv"
    path.write_text("x_m,y_m\n" + "".join(f"{50 + 100 * i},500\n" for i in range(5)))
    config = make_config(
        seed=4,
        duration_s=12.0,
        world={"n_robots": 5, "side_m": 1000.0, "placement": str(path)},
        mobility={"model": "static"},
        channel={"range_m": 120.0, "mac": "csma", "queue_frames": 1},
        protocol={"model": "greedy"},
        traffic={"flows": [flow]},
        output={"position_interval_s": 0.0},
    )
    sim = build(config)
    sim.run()
    frames = collect(sim)
    medium = frames["medium"]
    flow_rows = medium[medium["kind"].str.startswith("flow_")]
    dropped = int(flow_rows["dropped_queue_full"].sum() + flow_rows["dropped_retry_limit"].sum())
    lost = int((frames["packets"]["drop_cause"] == "lost").sum())
    assert dropped > 0 and len(calls) == dropped == lost


@pytest.mark.parametrize("hop_limit", [3, 4])
def test_a_packet_takes_at_most_hop_limit_hops(tmp_path, hop_limit):
    """Each hop takes one from the packet's TTL (protocol.hop_limit at the source); a holder
    that is not the destination drops a packet whose TTL is spent (drop_cause ttl): down a
    line of five robots, four hops, a limit of 3 drops every packet at robot 3 and a limit
    of 4 delivers every one. Every hop is one data transmission."""
    sim, frames = _run(tmp_path, [(50 + 100 * i, 500) for i in range(5)], [FLOW], hop_limit=hop_limit)
    packets = frames["packets"]
    assert sim.models["protocol"].data_transmissions == min(hop_limit, 4) * len(packets) > 0
    if hop_limit == 4:
        assert packets["delivered"].all() and (packets["hops"] == 4).all()
    else:
        assert (packets["drop_cause"] == "ttl").all() and (packets["drop_robot"] == 3).all()


def test_control_receptions_count_every_robot_that_got_a_frame(tmp_path):
    """The control table's ``received`` counts receptions, one per robot that got a frame:
    three robots all in range of one another receive every beacon twice."""
    _sim, frames = _run(tmp_path, [(100, 500), (150, 500), (200, 500)], [], duration_s=10.0)
    control = frames["control"].set_index("kind")
    assert control.loc["beacon", "sent"] > 0
    assert control.loc["beacon", "received"] == 2 * control.loc["beacon", "sent"]


def test_a_neighbour_as_far_from_the_destination_as_the_holder_is_no_next_hop():
    """Greedy forwards only to a neighbour strictly closer to the destination than the
    holder: one exactly as far (10 m on the other side) leaves the holder a local maximum,
    as the packet could otherwise go back and forth between the two."""
    own, dst = np.array([0.0, 0.0]), np.array([10.0, 0.0])
    assert greedy_next_hop(own, dst, np.array([3]), np.array([[20.0, 0.0]])) == -1
    assert greedy_next_hop(own, dst, np.array([3]), np.array([[19.0, 0.0]])) == 3


def test_greedy_ties_go_to_the_lowest_id():
    """Of two neighbours equally close to the destination, the lower id is the next hop,
    whatever their order."""
    own, dst = np.array([0.0, 0.0]), np.array([10.0, 0.0])
    nbr_xy = np.array([[4.0, 3.0], [4.0, -3.0]])
    assert greedy_next_hop(own, dst, np.array([5, 3]), nbr_xy) == 3
    assert greedy_next_hop(own, dst, np.array([3, 5]), nbr_xy) == 3


def test_a_holder_that_hears_the_destination_sends_it_the_packet_straight():
    """A destination among the holder's neighbours is the next hop, whatever their beaconed
    positions say: here its last beacon is stale and another neighbour beaconed from the
    very point the packet is bound for."""
    from netsim.protocols.routing import Packet

    greedy = build(make_config(world={"n_robots": 3}, protocol={"model": "greedy"})).models["protocol"]
    greedy.heard_t[0, [1, 2]] = 0.0
    greedy.heard_xy[0, 1] = (1e5, 1e5)
    greedy.heard_xy[0, 2] = (7.0, 7.0)
    pkt = Packet(0, src=0, dst=1, ttl=64, hops=0, kind="data", t_sent_s=0.0, dst_xy=(7.0, 7.0))
    assert greedy.next_hop(0, pkt) == (1, "")


def test_a_robot_that_died_beacons_no_more():
    """A dead robot sends nothing: its beacon timer goes on, but no beacon leaves it; a live
    robot's does."""
    greedy = build(make_config(world={"n_robots": 3}, protocol={"model": "greedy"})).models["protocol"]
    sent = []
    greedy.control = lambda i, payload, deliver, kind, dest=-1, messages=1: sent.append((i, kind))
    greedy.state.alive[1] = False
    greedy._tick(1)
    greedy._tick(0)
    assert sent == [(0, "beacon")]


def test_greedy_beacons_start_at_a_phase_of_their_own_then_every_period_jittered_both_ways(tmp_path):
    """docs/routing.md: a robot beacons every beacon_period_s plus U(-beacon_jitter_s,
    +beacon_jitter_s): successive beacons of a robot are 0.9 to 1.1 s apart by default, some
    shorter than the period and some longer; each robot's first beacon is at a time of its
    own within the first period (robots do not beacon in lock step)."""
    xy = [(100 + 50 * i, 500) for i in range(4)]
    path = tmp_path / "robots.csv"
    path.write_text("x_m,y_m\n" + "".join(f"{x},{y}\n" for x, y in xy))
    config = make_config(
        seed=4,
        duration_s=30.0,
        world={"n_robots": 4, "side_m": 1000.0, "placement": str(path)},
        mobility={"model": "static"},
        channel={"range_m": 120.0},
        protocol={"model": "greedy"},
        output={"position_interval_s": 0.0},
    )
    sim = build(config)
    greedy = sim.models["protocol"]
    times: dict[int, list[float]] = {}
    real = greedy.control

    def control(i, payload, deliver, kind, dest=-1, messages=1):
        times.setdefault(i, []).append(greedy.env.now)
        return real(i, payload, deliver, kind, dest, messages)

    greedy.control = control
    sim.run()
    gaps = np.concatenate([np.diff(t) for t in times.values()])
    assert len(gaps) > 100 and gaps.min() >= 0.9 - 1e-9 and gaps.max() <= 1.1 + 1e-9
    assert gaps.min() < 0.95 and gaps.max() > 1.05
    first = [t[0] for t in times.values()]
    assert len(set(first)) == 4 and 0.0 <= min(first) and max(first) < 1.0


@pytest.mark.parametrize(
    "key, value, words",
    [
        ("beacon_jitter_s", 0.5, "protocol.beacon_jitter_s = 0.5: must be less than half"),
        ("neighbour_timeout_s", 1.1, "protocol.neighbour_timeout_s = 1.1: must be greater than"),
    ],
)
def test_greedy_parameter_at_the_limit_of_its_range_is_refused(key, value, words):
    """The limits are strict: a jitter of exactly half the period (a beacon could follow the
    previous one at once), and a timeout of exactly the longest gap between two beacons
    (period + jitter: a neighbour whose every beacon arrives could still be forgotten), are
    refused."""
    with pytest.raises(ConfigError) as err:
        make_config(protocol={"model": "greedy", key: value})
    assert words in str(err.value)


def test_greedy_defaults_are_the_documented_ones():
    """docs/routing.md: beacons every 1 s, jittered by 0.1 s, of 24 bytes; a neighbour
    forgotten after 3 periods; a packet may take 64 hops."""
    from netsim.protocols.greedy import GreedyParams

    p = GreedyParams()
    assert (p.beacon_period_s, p.beacon_jitter_s, p.beacon_bytes, p.neighbour_timeout_s, p.hop_limit) == (
        1.0,
        0.1,
        24,
        3.0,
        64,
    )


MOVED = """$node_(0) set X_ 100.0
$node_(0) set Y_ 500.0
$node_(1) set X_ 300.0
$node_(1) set Y_ 500.0
$node_(2) set X_ 600.0
$node_(2) set Y_ 500.0
$ns_ at 1.0 "$node_(0) setdest 500.0 500.0 40.0"
"""


def test_a_holder_compares_its_neighbours_with_where_it_is_now(tmp_path):
    """The greedy rule's "strictly closer than the holder itself" is to the holder's position
    at the instant it forwards: robot 0, moving at 40 m/s from 100 m since 1 s, is at 380 m
    at 8 s, 220 m short of the destination at 600 m; its one neighbour, at 300 m, is
    farther, so 0 is a local maximum (by where its leg puts it at 0 s, 540 m away, the
    neighbour was closer and the packet went back and forth until its hop limit)."""
    flow = {"src": 0, "dst": 2, "start_s": 8.0, "stop_s": 8.5, "rate_bps": 8000.0, "packet_bytes": 500}
    _sim, frames = flow_over_trace(tmp_path, MOVED, 3, flow, 9.0, 1, {"range_m": 150.0}, {"model": "greedy"})
    packets = frames["packets"]
    assert len(packets) == 1
    assert (packets["drop_cause"].iloc[0], packets["drop_robot"].iloc[0]) == ("local_maximum", 0)
