"""The ``ack_delivery`` table: the Acks' fate per interval of send time, and the Ack
delivery ratio over time derived from it."""

import math

import numpy as np
import pytest
from netsim.protocols.ack import ACK_DELIVERY_SCHEMA, delivery_ratio

from netsim.radio.channel import SendTimeBins
from netsim.run import build, collect, execute, tables
from tests.fixtures import make_config


def _static(positions, duration=10.0, interval=1.0, **channel):
    cfg = make_config(
        duration_s=duration,
        world={"n_robots": len(positions), "side_m": 10_000.0},
        mobility={"model": "static"},
        channel={"range_m": 10.0, **channel},
        protocol={"model": "ack", "ack_jitter_s": 0.0},
        output={"position_interval_s": interval},
    )
    sim = build(cfg)
    sim.state.place(np.asarray(positions, dtype=float))
    return sim


def _frames(sim):
    sim.run()
    return collect(sim)


def test_scripted_acks_counted_per_interval_of_send_time():
    """Robots 0 and 1 in range of each other, 2 in range of both but switched off, 3 far
    away. One Ack a second each from phases in [0, 1): every 1 s interval holds exactly
    one Ack of each robot that is on, heard by the other of the pair; robot 2 hears
    nothing, 3 nobody."""
    sim = _static([[0, 0], [5, 0], [2, 3], [500, 0]], duration=10.0)
    sim.state.alive[2] = False
    d = _frames(sim)["ack_delivery"]
    assert d["t_s"].tolist() == [float(k) for k in range(10)]
    assert (d["sent"] == 3).all()  # 0, 1 and 3
    assert (d["in_range"] == 2).all()  # 0 -> 1 and 1 -> 0
    assert (d["dropped_not_alive"] == 2).all()  # 0 -> 2 and 1 -> 2
    assert (d["dropped_loss"] == 0).all()
    # The last Ack of each, sent in [9, 10), arrives 1 ms later: still within the run
    # unless its phase is above 0.999 (not with this seed).
    assert (d["received"] == 2).all()
    assert (d["delivery_ratio"] == 1.0).all()


def test_no_loss_gives_a_ratio_of_exactly_one():
    run = execute(
        make_config(
            seed=5,
            duration_s=40.0,
            world={"n_robots": 25, "side_m": 400.0},
            channel={"range_m": 120.0, "latency_jitter_s": 0.3},
            protocol={"message_rate_hz": 0.0},
        )
    )
    d = run.frames["ack_delivery"]
    assert len(d) == 40 and (d["received"] > 0).all()
    assert (d["delivery_ratio"] == 1.0).all()
    # Every reception attempted has arrived, but for Acks still in flight at the end
    # (sent less than the latency jitter before it, so in the last interval).
    assert (d["in_range"].iloc[:-1] == d["received"].iloc[:-1]).all()
    assert 0 <= d["in_range"].iloc[-1] - d["received"].iloc[-1] < d["in_range"].iloc[-1]


@pytest.fixture(scope="module")
def lossy():
    """Bernoulli loss p = 0.3, latency jitter (receptions arrive in later intervals than
    they were sent in, some out of order), robots moving."""
    cfg = make_config(
        seed=11,
        duration_s=60.0,
        world={"n_robots": 30, "side_m": 500.0},
        channel={"range_m": 130.0, "loss_probability": 0.3, "latency_jitter_s": 0.8},
        protocol={"message_rate_hz": 0.0},
        output={"position_interval_s": 2.0},
    )
    return execute(cfg)


def test_interval_sums_are_the_channels_end_of_run_counts(lossy):
    d, acks = lossy.frames["ack_delivery"], lossy.frames["acks"]
    assert d["t_s"].tolist() == [2.0 * k for k in range(30)]
    for col in ("sent", "received", "dropped_loss", "dropped_not_alive"):
        assert d[col].sum() == acks[col].sum()
    whole = d["received"].sum() / (d["received"].sum() + d["dropped_loss"].sum())
    assert whole == lossy.summary["ack_delivery_ratio"]
    # Attempted = received + lost, but for what was still in flight at the end.
    decided = d["received"] + d["dropped_loss"]
    assert (d["in_range"].iloc[:-1] == decided.iloc[:-1]).all()
    assert d["in_range"].iloc[-1] >= decided.iloc[-1]


def test_bernoulli_loss_ratio_is_one_minus_p_within_binomial_bounds(lossy):
    """Each interval's ratio is a binomial proportion of its decided receptions: within
    4.5 standard deviations of 1 - p in every interval (30 intervals: a false alarm has
    probability ~2e-4), and the whole run's within 3.5."""
    p = 0.3
    d = lossy.frames["ack_delivery"]
    decided = (d["received"] + d["dropped_loss"]).to_numpy(float)
    assert decided.min() > 100
    sd = np.sqrt(p * (1 - p) / decided)
    assert (np.abs(d["delivery_ratio"].to_numpy() - (1 - p)) < 4.5 * sd).all()
    whole = d["received"].sum() / decided.sum()
    assert abs(whole - (1 - p)) < 3.5 * math.sqrt(p * (1 - p) / decided.sum())


def test_the_ratio_is_undefined_where_no_reception_was_possible():
    assert np.isnan(delivery_ratio([0, 3], [0, 1])[0]) and delivery_ratio([0, 3], [0, 1])[1] == 0.75


def test_bins_are_half_open_at_the_tables_times():
    """A time belongs to the bin whose ``t_s`` is at or before it and whose successor's
    is after it, also at the edges, where ``t // dt`` alone is off by one."""
    bins = SendTimeBins(0.1)
    edges = np.arange(200) * 0.1
    for t in np.r_[edges[:-1], np.nextafter(edges[1:-1], 0), np.random.default_rng(1).uniform(0, 19.8, 500)]:
        k = bins.bin(float(t))
        assert edges[k] <= t < edges[k + 1]


def test_the_bin_of_the_last_send_is_reused_only_within_its_edges():
    """The channel's shortcut to the bin of a send (the bin of the last send, while the
    time stays within its edges) gives the bin of every time, at the edges, going back and
    after the counts have grown."""
    bins = SendTimeBins(0.1)
    edges = np.arange(300) * 0.1
    rng = np.random.default_rng(2)
    times = np.r_[
        edges[:-1], np.nextafter(edges[1:-1], 0), np.sort(rng.uniform(0, 29.8, 500)), rng.uniform(0, 29.8, 50)
    ]
    for t in times:
        t = float(t)
        assert bins.at(t).k == bins.bin(t)
        assert bins.at(t) is bins.at(t)


@pytest.mark.parametrize("model", ["ack", "clustering"])
def test_the_protocol_declares_the_table_it_writes(model):
    cfg = make_config(duration_s=5.0, world={"n_robots": 5, "side_m": 200.0}, protocol={"model": model})
    schema = tables(cfg)["ack_delivery"]
    assert schema == ACK_DELIVERY_SCHEMA
    frame = execute(cfg).frames["ack_delivery"]
    assert {c: str(t) for c, t in frame.dtypes.items()} == schema


def test_on_a_shared_medium_the_ratio_counts_the_mediums_losses_as_lost():
    """On a shared medium an Ack a receiver in range lost to a collision or to its own
    transmission (half duplex) was lost on the way like one the loss model dropped: the
    summary's ratio and each interval's count it among the receptions that could have
    arrived. Six robots in range on ALOHA with Acks a tenth of a period long collide."""
    sim = _static(
        [[0.0, 0.0], [3.0, 0.0], [0.0, 3.0], [3.0, 3.0], [6.0, 0.0], [0.0, 6.0]],
        duration=20.0,
        mac="aloha",
        data_rate_bps=5120.0,
        preamble_s=0.0,
    )
    frames = _frames(sim)
    acks = frames["acks"]
    medium_lost = int(acks[["dropped_collision", "dropped_half_duplex"]].to_numpy().sum())
    assert medium_lost > 0
    received = int(acks["received"].sum())
    lost = int(acks["dropped_loss"].sum()) + medium_lost
    assert sim.models["protocol"].summary(frames, 20.0)["ack_delivery_ratio"] == received / (received + lost)
    series = frames["ack_delivery"]
    lost_by_interval = series[["dropped_loss", "dropped_collision", "dropped_half_duplex"]].sum(axis=1)
    expected = series["received"] / (series["received"] + lost_by_interval)
    np.testing.assert_array_equal(series["delivery_ratio"].to_numpy(), expected.to_numpy())
    assert (series["delivery_ratio"] < 1).any()
