"""The tables a replay is drawn from: legs (every course change) and hops (every
reception of every relayed transmission)."""

import numpy as np
import pandas as pd
import pytest

from netsim.run import build, execute
from tests.fixtures import make_config

CONFIG = dict(
    seed=4,
    duration_s=40.0,
    world={"n_robots": 30, "side_m": 500.0},
    channel={"range_m": 150.0},
    protocol={"message_rate_hz": 1.0},
)


@pytest.fixture(scope="module")
def frames():
    return execute(make_config(**CONFIG)).frames


def test_positions_are_where_the_robots_were_during_the_run(frames):
    """positions.parquet holds, at each sampling instant, the positions the run's own robot
    state gave at that instant while the run went on (stopped there, not reconstructed
    from the tables afterwards)."""
    pos = frames["positions"]
    times = np.sort(pos["t_s"].unique())
    assert len(times) == 41
    sim = build(make_config(**CONFIG))
    for t in times[::7].tolist():
        sim.run(until_s=t)
        row = pos[pos["t_s"] == t].sort_values("robot")
        live = sim.state.positions_at(t)
        np.testing.assert_allclose(row[["x_m", "y_m"]].to_numpy(), live, rtol=0, atol=1e-9)


def test_every_delivery_is_a_recorded_hop(frames):
    """A delivered message's last hop reaches its destination at the delivery time, on
    the hop count the message reports."""
    msgs, hops = frames["messages"], frames["hops"]
    delivered = msgs[msgs["delivered"]]
    assert len(delivered) > 5
    for m in delivered.itertuples():
        first = hops[(hops.msg_id == m.msg_id) & (hops.receiver == m.dst)].sort_values("t_received_s").iloc[0]
        assert first.t_received_s == m.t_delivered_s
        assert first.hop == m.hops


def test_hops_chain_back_to_the_source(frames):
    """Each transmission's sender is the source (hop 1) or received the message on the
    hop before, no later than it sends; transmissions never exceed the message's count."""
    msgs, hops = frames["messages"].set_index("msg_id"), frames["hops"]
    assert (hops["t_received_s"] > hops["t_sent_s"]).all()
    first = hops[hops.hop == 1]
    assert (first.sender.to_numpy() == msgs.loc[first.msg_id, "src"].to_numpy()).all()
    got = hops.groupby(["msg_id", "receiver"])["t_received_s"].min()
    later = hops[hops.hop > 1]
    when = got.reindex(pd.MultiIndex.from_arrays([later.msg_id, later.sender])).to_numpy()
    assert (when <= later.t_sent_s.to_numpy()).all()
    sent = hops.drop_duplicates(["msg_id", "hop", "sender", "t_sent_s"]).groupby("msg_id").size()
    assert (sent <= msgs.loc[sent.index, "transmissions"]).all()
