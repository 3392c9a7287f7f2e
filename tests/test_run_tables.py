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


@pytest.mark.parametrize("duration_s", [30.0, 30.5])
def test_sampled_tables_end_at_the_runs_end(duration_s):
    """The groups, beliefs, neighbour_beliefs and coverage tables are sampled every
    interval from 0 and once more at the run's end T, whether or not T is a multiple of
    the interval; the coverage table's last row is the summary's final values."""
    cfg = make_config(
        seed=2,
        duration_s=duration_s,
        world={"n_robots": 20, "side_m": 400.0, "placement": "centre", "centre_side_m": 150.0},
        mobility={"model": "static"},
        channel={"range_m": 100.0},
        coverage={"enabled": True, "start_s": 10.0},
    )
    res = execute(cfg)
    for name, interval in (("beliefs", 1.0), ("neighbour_beliefs", 1.0), ("groups", 1.0), ("coverage", 5.0)):
        times = np.unique(res.frames[name]["t_s"].to_numpy())
        grid = np.arange(0.0, duration_s - 1e-9, interval)
        assert times[-1] == duration_s, name
        assert set(grid[grid >= times[0]]) <= set(times) and len(times) == len(grid[grid >= times[0]]) + 1, name
    last = res.frames["coverage"].iloc[-1]
    assert last["covered_fraction_all"] == res.summary["covered_fraction_all_final"]
    assert last["components"] == res.summary["components_final"]


def test_a_sample_the_intervals_bring_to_the_end_is_not_taken_twice():
    """Sampling every 0.1 s for 1 s gives 11 samples, the last at 1 s: the sum of ten
    intervals falls a rounding error short of 1 s, and that sample is the last one, not a
    second sample beside it."""
    cfg = make_config(
        seed=1,
        duration_s=1.0,
        world={"n_robots": 10, "side_m": 300.0},
        mobility={"model": "static"},
        output={"position_interval_s": 0.1},
        coverage={"enabled": True, "start_s": 0.0, "metrics_interval_s": 0.1, "stop_hold_s": 0.5},
    )
    frames = execute(cfg).frames
    for name in ("beliefs", "coverage"):
        times = np.unique(frames[name]["t_s"].to_numpy())
        assert len(times) == 11 and times[-1] == pytest.approx(1.0) and np.diff(times).min() > 0.09, name


@pytest.mark.parametrize("interval_s, duration_s, multiples", [(0.7, 5.0, 8), (0.7, 4.2, 6), (0.1, 2.3, 23)])
def test_every_sampled_table_names_the_same_instants(interval_s, duration_s, multiples):
    """positions, beliefs, neighbour_beliefs and groups name the same instants: k x the
    interval (not a sum of intervals) while short of the end, then the run's end itself
    (a multiple a rounding error from it is that instant): a join on ``(t_s, robot)`` keeps
    every row. The beliefs said 4.2 where positions said 4.199999999999999; positions had
    no sample at 5 s, and one at 2.3000000000000003, past a 2.3 s run."""
    cfg = make_config(
        seed=1,
        duration_s=duration_s,
        world={"n_robots": 5, "side_m": 300.0},
        output={"position_interval_s": interval_s},
    )
    frames = execute(cfg).frames
    expected = [k * interval_s for k in range(multiples)] + [duration_s]
    assert np.unique(frames["positions"]["t_s"]).tolist() == expected
    for name in ("beliefs", "neighbour_beliefs"):
        assert np.unique(frames[name]["t_s"]).tolist() == expected, name
    groups = np.unique(frames["groups"]["t_s"]).tolist()
    assert set(groups) <= set(expected)  # from the first sample with a group
    joined = frames["beliefs"].merge(frames["positions"], on=["t_s", "robot"])
    assert len(joined) == len(frames["beliefs"])


@pytest.mark.parametrize("interval_s, end_s, count", [(0.05, 45.65000004565, 914), (0.05, 27.500000027500004, 552)])
def test_sample_times_are_the_multiples_short_of_the_end_however_the_quotient_rounds(interval_s, end_s, count):
    """The instants are every multiple of the interval short of the end by more than a
    rounding error, then the end: ends where the quotient end / interval rounds one
    multiple past that last one (45.65...) or one short of it (27.5...), as the products
    place them; counted as made."""
    from netsim.samples import sample_count, sample_times

    times = sample_times(interval_s, end_s)
    band = end_s - 1e-9 * end_s
    assert len(times) == count == sample_count(interval_s, end_s)
    assert times[:-1].tolist() == [k * interval_s for k in range(count - 1)] and times[-1] == end_s
    assert times[-2] < band <= (count - 1) * interval_s


def test_a_sample_within_a_rounding_error_of_the_end_is_the_end():
    """The band is 1e-9 of the end (at least 1e-9 s), its edge included: 1e-4 s and 1e-3 s
    (the edge) short of a run of 1e6 s are its end, 2e-3 s short is not; 1e-9 s short of a
    run of 1 s is its end, 2e-9 s is not."""
    from netsim.samples import ended_at

    end = 1e6
    assert ended_at([end - 1e-4], end) and ended_at([end - 1e-9 * end], end)
    assert not ended_at([end - 2e-3], end) and not ended_at([], end)
    assert ended_at([1.0 - 1e-9], 1.0) and not ended_at([1.0 - 2e-9], 1.0)


def test_a_count_of_samples_past_any_float_is_still_a_number_to_refuse():
    """An interval so small against the end that their quotient overflows counts as many
    samples as an int can say (it counted one: a run past any memory let through)."""
    import sys

    from netsim.samples import sample_count

    assert sample_count(1e-300, 1e300) == sys.maxsize
