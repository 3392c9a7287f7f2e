"""Each neighbour table entry's last received power, ``sim.link_quality(robot)``, and the
learning environment's ``link_quality`` option."""

import numpy as np
import pytest

from netsim.cosim import CommandError
from netsim.run import build, collect
from tests.fixtures import make_config

LATENCY_S = 0.002
NOW_S = 12.0
TAU_S = 3.0

SHADOWED = {
    "propagation": "log_distance",
    "shadowing_sigma_db": 4.0,
    "sensitivity_dbm": -80.0,
    "loss_model": "bernoulli",
    "loss_probability": 0.2,
}
# A slow medium: many Acks lost to collisions, the others delivered.
MEDIUM = {"propagation": "log_distance", "sensitivity_dbm": -80.0, "mac": "aloha", "data_rate_bps": 20000.0}


def _sim(channel: dict, protocol: str = "clustering"):
    config = make_config(
        seed=4,
        duration_s=20.0,
        world={"n_robots": 16, "side_m": 250.0},
        channel={"latency_s": LATENCY_S, **channel},
        protocol={"model": protocol, "message_rate_hz": 0.0} if protocol == "clustering" else {"model": protocol},
        output={"position_interval_s": 1.0, "receptions": True},
    )
    sim = build(config)
    sim.run(until_s=NOW_S)
    return sim


def _last_acks(sim) -> dict:
    """Per (receiver, sender), the last Ack received by now in receptions.parquet: arrived,
    its frame's start (``t_s``) plus its airtime under a medium, plus the latency, by now."""
    rx = collect(sim)["receptions"]
    airtime_s = sim.config.channel.airtime_s(sim.config.protocol.params.ack_bytes) or 0.0
    acks = rx[(rx["kind"] == "ack") & rx["received"] & (rx["t_s"] + airtime_s + LATENCY_S <= NOW_S)]
    return {(int(r.dst), int(r.src)): r for r in acks.itertuples()}


@pytest.mark.slow
@pytest.mark.parametrize("channel", [SHADOWED, MEDIUM], ids=["shadowing_loss", "aloha"])
def test_table_power_is_that_of_the_last_ack_received(channel):
    """Each live entry's rx_power_dbm is, bit for bit, the rx_power_dbm of the last Ack of
    that pair received (receptions.parquet), under shadowing with loss and under a medium."""
    sim = _sim(channel)
    last = _last_acks(sim)
    checked = 0
    for i in range(sim.state.n):
        for row in sim.link_quality(i).itertuples():
            ack = last[(i, row.neighbour)]
            assert row.rx_power_dbm == ack.rx_power_dbm, (i, row.neighbour)
            checked += 1
    assert checked > 50


@pytest.mark.slow
def test_age_is_now_less_the_last_acks_arrival():
    """age_s = now - the arrival (send + latency) of the pair's last Ack received."""
    sim = _sim(SHADOWED)
    last = _last_acks(sim)
    for i in range(sim.state.n):
        lq = sim.link_quality(i)
        arrived = np.array([last[(i, j)].t_s + LATENCY_S for j in lq["neighbour"]])
        assert np.allclose(lq["age_s"].to_numpy(), NOW_S - arrived, rtol=0.0, atol=1e-9)


def test_rows_are_exactly_the_live_entries():
    """link_quality's rows are the live entries, by neighbour ascending: the pairs whose
    last Ack arrived less than tau ago (receptions.parquet), as sim.neighbours lists them."""
    sim = _sim(SHADOWED)
    last = _last_acks(sim)
    stale = 0
    for i in range(sim.state.n):
        lq = sim.link_quality(i)
        live = sorted(j for (r, j), ack in last.items() if r == i and NOW_S - (ack.t_s + LATENCY_S) < TAU_S)
        stale += sum(1 for (r, j) in last if r == i) - len(live)
        assert lq["neighbour"].tolist() == live == sim.neighbours(i).tolist()
        assert list(lq.columns) == ["neighbour", "rx_power_dbm", "age_s"]
    assert stale > 0  # some pairs heard once, no longer live


def test_power_is_nan_under_the_unit_disk():
    """Under the unit disk no power is measured: every live entry's rx_power_dbm is NaN."""
    sim = _sim({})
    rows = [sim.link_quality(i) for i in range(sim.state.n)]
    assert sum(len(r) for r in rows) > 20
    assert all(r["rx_power_dbm"].isna().all() for r in rows)
    assert all(((r["age_s"] >= 0) & (r["age_s"] < TAU_S)).all() for r in rows)


@pytest.mark.parametrize("robot", [16, -1, 1.5, "a", True])
def test_bad_robot_id_is_a_one_line_error(robot):
    """A robot id that is not an integer in [0, N) is a one-line error naming it."""
    sim = _sim({})
    with pytest.raises(CommandError) as err:
        sim.link_quality(robot)
    assert "\n" not in str(err.value) and repr(robot) in str(err.value)


def test_neighbour_tables_without_received_power_are_a_one_line_error():
    """A protocol whose tables keep no received power (a neighbour view without
    ``link_quality``, as a user's protocol may be) is named, not a traceback."""
    from tests.fixtures import static_core

    class HeardOnly:
        def heard(self, now):
            return np.full((2, 1), -1), np.zeros((2, 1, 2)), np.zeros((2, 1))

    sim = static_core([[0.0, 0.0], [5.0, 0.0]])
    sim.neighbour_view = HeardOnly()
    assert sim.neighbours(0).tolist() == []
    with pytest.raises(CommandError, match="^protocol.model = 'none' keeps no received power in its neighbour tables$"):
        sim.link_quality(0)


def test_without_neighbour_tables_is_a_one_line_error():
    """A run whose protocol keeps no neighbour tables (protocol none) has no link quality:
    a one-line error naming the protocol."""
    sim = _sim({}, protocol="none")
    with pytest.raises(CommandError, match="protocol.model = 'none' keeps no neighbour tables") as err:
        sim.link_quality(0)
    assert "\n" not in str(err.value)
