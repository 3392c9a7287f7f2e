"""The bridge's relay of robots' own topics through the simulated channel
(netsim.bridge.relay), without DDS: what the channel makes of a message's size."""

import pytest

from netsim import config as cfgmod
from netsim.bridge.relay import ChannelRelay
from netsim.run import build

DATA_RATE_BPS = 1e6


def received_at(nbytes: int, mac: str) -> list[float]:
    """When robot 1 gets a message of ``nbytes`` robot 0 relays at t = 1 s."""
    channel = {"range_m": 40.0, "latency_s": 0.01, "mac": mac}
    if mac != "none":
        channel["data_rate_bps"] = DATA_RATE_BPS
    config = cfgmod.from_dict(
        {
            "duration_s": 5.0,
            "world": {"n_robots": 2, "side_m": 100.0, "placement": "centre", "centre_side_m": 10.0},
            "channel": channel,
            "mobility": {"model": "external"},
            "protocol": {"model": "none"},
        }
    )
    sim = build(config)
    relay = ChannelRelay(sim, ["chat"])
    sim.run(until_s=1.0)
    relay.send(0, "chat", "payload", nbytes)
    sim.run(until_s=4.0)
    rows = relay.frame()
    assert [(r, name) for r, name, _ in relay.take()] == [(1, "chat")] * len(rows)
    return rows.loc[rows["dst"] == 1, "t_received_s"].tolist()


def test_relayed_message_takes_the_airtime_of_its_size_on_a_shared_medium():
    """On a shared medium (CSMA) a relayed message occupies the air for its serialized size:
    1000 bytes more arrive 1000 x 8 / data_rate_bps later, all else equal (same seed)."""
    (small,) = received_at(100, "csma")
    (large,) = received_at(1100, "csma")
    assert large - small == pytest.approx(1000 * 8 / DATA_RATE_BPS, abs=1e-9)


def test_relayed_message_without_a_medium_arrives_after_the_latency_whatever_its_size():
    """Without a shared medium the channel's latency alone delays a relayed message."""
    assert received_at(100, "none") == received_at(5000, "none") == [pytest.approx(1.01)]


# -- rules a mutation audit found no test for ------------------------------------------------
def three_in_range():
    """Three robots all within range of each other, no medium, 10 ms latency."""
    config = cfgmod.from_dict(
        {
            "duration_s": 5.0,
            "world": {"n_robots": 3, "side_m": 100.0, "placement": "centre", "centre_side_m": 10.0},
            "channel": {"range_m": 40.0, "latency_s": 0.01},
            "mobility": {"model": "external"},
            "protocol": {"model": "none"},
        }
    )
    return build(config)


def test_relay_table_rows_name_each_message_its_sender_receiver_size_and_times_in_order_of_arrival():
    sim = three_in_range()
    relay = ChannelRelay(sim, ["chat"])
    sim.run(until_s=1.0)
    ids = [relay.send(0, "chat", "a", 100)]
    sim.run(until_s=2.0)
    ids.append(relay.send(2, "chat", "b", 300))
    sim.run(until_s=3.0)
    assert ids == [0, 1] and relay.sent == 2
    rows = relay.frame()
    got = list(rows[["msg_id", "src", "dst", "nbytes"]].itertuples(index=False, name=None))
    assert got == [(0, 0, 1, 100), (0, 0, 2, 100), (1, 2, 0, 300), (1, 2, 1, 300)]
    assert rows["t_sent_s"].tolist() == [1.0, 1.0, 2.0, 2.0]
    assert rows["t_received_s"].tolist() == pytest.approx([1.01, 1.01, 2.01, 2.01])


def test_relayed_receptions_are_taken_once():
    sim = three_in_range()
    relay = ChannelRelay(sim, ["chat"])
    relay.send(1, "chat", "a", 10)
    sim.run(until_s=1.0)
    assert sorted(relay.take()) == [(0, "chat", "a"), (2, "chat", "a")]
    assert relay.take() == []


def test_a_relayed_topic_is_counted_as_a_frame_kind_of_its_own():
    sim = three_in_range()
    relay = ChannelRelay(sim, ["chat"])
    relay.send(1, "chat", "a", 10)
    sim.run(until_s=1.0)
    counters = sim.channel.counters["relay/chat"]
    assert counters.sent.tolist() == [0, 1, 0] and counters.received.tolist() == [1, 0, 1]
