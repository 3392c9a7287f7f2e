"""receptions.parquet (``output.receptions``): one row per reception the channel decides,
agreeing row by row with its deliveries and drops, and nothing when off."""

from collections import Counter
from pathlib import Path

import numpy as np
import pytest

from netsim.radio.receptions import RECEPTIONS_SCHEMA
from netsim.run import execute
from netsim.tools.cli import main
from tests.fixtures import make_config

LATENCY_S = 0.002
SENSITIVITY_DBM = -80.0


def _config(channel: dict, receptions: bool = True, n: int = 16, side_m: float = 250.0, duration_s: float = 20.0):
    return make_config(
        seed=4,
        duration_s=duration_s,
        world={"n_robots": n, "side_m": side_m},
        channel={"latency_s": LATENCY_S, **channel},
        protocol={"model": "clustering", "message_rate_hz": 1.0},
        output={"position_interval_s": 1.0, "receptions": receptions},
    )


SHADOWED = {
    "propagation": "log_distance",
    "shadowing_sigma_db": 4.0,
    "sensitivity_dbm": SENSITIVITY_DBM,
    "loss_model": "bernoulli",
    "loss_probability": 0.2,
}
MEDIUM = {"propagation": "log_distance", "sensitivity_dbm": SENSITIVITY_DBM, "mac": "aloha"}


def _run(config):
    """The run's tables, and the bus's deliveries and drops as (kind, src, dst, cause) rows."""
    deliveries, drops = [], []

    def built(sim):
        sim.events.on(
            "delivery", lambda e: deliveries.extend((e.kind, e.sender, r, None) for r in e.receivers.tolist())
        )
        sim.events.on("drop", lambda e: drops.extend((e.kind, e.sender, r, e.cause) for r in e.receivers.tolist()))

    result = execute(config, built=built)
    return result, deliveries, drops


def _rows(table, mask):
    sub = table[mask]
    cause = [None if not isinstance(c, str) else c for c in sub["cause"]]
    return list(zip(sub["kind"], sub["src"].tolist(), sub["dst"].tolist(), cause))


def _check_rows_are_the_channels(result, deliveries, drops):
    r = result.frames["receptions"]
    duration = result.sim.duration_s
    # A frame decided within the latency of the end arrives after it: no delivery.
    arrived = r["t_s"] + LATENCY_S < duration - 1e-6
    assert Counter(_rows(r, r["received"] & arrived)) == Counter(d for d in deliveries)
    failed = Counter(_rows(r, ~r["received"]))
    told = Counter(drops)
    # Every drop the bus tells has its row; the rows beyond are the radio's rejections of
    # broadcasts (not counted as drops): out_of_range, below the sensitivity.
    assert not told - failed
    extra = failed - told
    assert {cause for (_, _, _, cause) in extra} <= {"out_of_range"}
    # Per cause and receiver, the failed rows are the channel's drop counters.
    for kind, c in result.sim.channel.counters.items():
        for k, cause in enumerate(c.causes):
            if cause == "out_of_range":
                continue
            mine = r[(r["kind"] == kind) & (r["cause"] == cause)]
            per_robot = np.bincount(mine["dst"].to_numpy(), minlength=len(c.sent))
            assert (per_robot == c.dropped[k]).all(), (kind, cause)


@pytest.mark.slow
def test_receptions_are_the_channels_decisions_under_shadowing():
    """Under log-distance with 4 dB shadowing and 20 % loss, the received rows are the
    deliveries, the failed rows the drops (per cause), and a row is received iff its power
    clears the sensitivity and the loss model spared it."""
    result, deliveries, drops = _run(_config(SHADOWED))
    r = result.frames["receptions"]
    assert r["received"].sum() > 100 and (r["cause"] == "loss").sum() > 20 and (r["cause"] == "out_of_range").sum() > 20
    _check_rows_are_the_channels(result, deliveries, drops)
    clears = r["rx_power_dbm"] >= SENSITIVITY_DBM - 1e-9
    assert (r["received"] == (clears & (r["cause"] != "loss"))).all()
    assert (r["cause"][~clears] == "out_of_range").all()
    assert np.isinf(r["sinr_db"]).all()


@pytest.mark.slow
def test_receptions_power_is_the_log_distance_law_with_the_pairs_shadowing():
    """Each row's power is the path loss at its distance, recomputed here, plus a shadowing
    within the clip (without shadowing: the law exactly); its distance is the pair's."""
    plain = {k: v for k, v in SHADOWED.items() if k != "shadowing_sigma_db"}
    for channel, clip_db in ((plain, 0.0), (SHADOWED, 4.0 * 4.0)):
        result, _, _ = _run(_config(channel, duration_s=8.0))
        r = result.frames["receptions"]
        p = result.sim.channel.reception.propagation
        radio = result.sim.config.channel.radio
        d = np.maximum(r["distance_m"].to_numpy(), radio.reference_distance_m)
        law = (
            p.radio.tx_power_dbm
            - radio.reference_loss_db
            - 10 * radio.path_loss_exponent * np.log10(d / radio.reference_distance_m)
        )
        gap = r["rx_power_dbm"].to_numpy() - law
        assert np.abs(gap).max() <= clip_db + 1e-9
        if clip_db:
            assert np.abs(gap).max() > 1.0  # the shadowing is in the power
        state = result.sim.state
        sample = r.sample(20, random_state=0)
        for _, row in sample.iterrows():
            pos = state.positions_at(row["t_s"], [row["src"], row["dst"]])
            assert row["distance_m"] == pytest.approx(float(np.hypot(*(pos[0] - pos[1]))), abs=1e-9)


@pytest.mark.slow
def test_receptions_under_a_shared_medium_are_its_captures():
    """Under ALOHA with a power model, collisions and half duplex are rows too: the received
    rows are the deliveries, the failed rows the drops; a frame that reached its end is
    received iff it was not lost to half duplex and its SINR clears the capture threshold."""
    config = _config(MEDIUM, n=19, side_m=150.0)
    result, deliveries, drops = _run(config)
    r = result.frames["receptions"]
    assert (r["cause"] == "collision").sum() > 5
    _check_rows_are_the_channels(result, deliveries, drops)
    capture = config.channel.medium.capture_threshold_db
    ended = r["cause"].isna() | r["cause"].isin(["collision", "half_duplex"])
    assert np.isfinite(r["sinr_db"][ended]).all()
    clear = r["sinr_db"] >= capture
    judged = ended & (r["cause"] != "half_duplex")
    assert (r["received"][judged] == clear[judged]).all()
    assert (r["rx_power_dbm"][r["received"]] >= SENSITIVITY_DBM - 1e-9).all()


def test_receptions_under_the_unit_disk_have_no_power():
    """Under the unit disk the rows are the robots within the sender's range, their power
    and SINR NaN (no power law) and inf (no medium); the received ones are the deliveries."""
    config = _config({"range_m": 80.0, "loss_model": "bernoulli", "loss_probability": 0.2})
    result, deliveries, drops = _run(config)
    r = result.frames["receptions"]
    assert len(r) > 100
    assert r["rx_power_dbm"].isna().all() and np.isinf(r["sinr_db"]).all()
    assert (r["distance_m"] <= 80.0).all()
    _check_rows_are_the_channels(result, deliveries, drops)
    assert list(r.columns) == list(RECEPTIONS_SCHEMA)


@pytest.mark.parametrize("torus", [False, True], ids=["plane", "torus"])
def test_receptions_ends_are_where_the_robots_stood_at_the_frames_start(torus):
    """``src_x_m`` ... ``dst_y_m`` are both robots' positions at the row's ``t_s`` (moving
    robots: at another instant they would be elsewhere): their distance, the nearest
    image's on a torus, is the channel's ``distance_m``; on a torus they lie in the square,
    as in positions.parquet."""
    config = make_config(
        seed=4,
        duration_s=20.0,
        world={"n_robots": 16, "side_m": 250.0, "torus": torus},
        mobility={"model": "random_waypoint", "speed_min_mps": 5.0, "speed_max_mps": 10.0},
        channel={"latency_s": LATENCY_S, "range_m": 80.0},
        protocol={"model": "clustering"},
        output={"position_interval_s": 1.0, "receptions": True},
    )
    r = execute(config).frames["receptions"]
    ends = r[["src_x_m", "src_y_m", "dst_x_m", "dst_y_m"]].to_numpy()
    off = ends[:, 2:] - ends[:, :2]
    if torus:
        assert ((ends >= 0.0) & (ends < 250.0)).all()
        off -= 250.0 * np.rint(off / 250.0)
    assert len(r) > 100
    np.testing.assert_allclose(np.hypot(*off.T), r["distance_m"], rtol=0, atol=1e-9)


@pytest.mark.slow
@pytest.mark.parametrize(
    "channel", [{"loss_model": "bernoulli", "loss_probability": 0.2, "range_m": 80}, {**SHADOWED, "mac": "aloha"}]
)
def test_receptions_off_writes_no_file_and_changes_no_other_table(tmp_path: Path, channel):
    """With ``output.receptions`` off no receptions.parquet is written, and every other
    table is the same byte for byte as with it on."""
    outs = {}
    for on in (False, True):
        out = tmp_path / f"run-{on}"
        sets = [f"channel.{k}={v}" for k, v in channel.items()]
        sets += ["world.n_robots=12", "world.side_m=200", "duration_s=10"]
        sets += ["protocol.message_rate_hz=1", f"output.receptions={'true' if on else 'false'}"]
        args = ["run", "--out", str(out)] + [a for s in sets for a in ("--set", s)]
        assert main(args) in (0, None)
        outs[on] = out
    off = sorted(p.name for p in outs[False].glob("*.parquet"))
    on = sorted(p.name for p in outs[True].glob("*.parquet"))
    assert "receptions.parquet" not in off
    assert on == sorted(off + ["receptions.parquet"])
    for name in off:
        assert (outs[False] / name).read_bytes() == (outs[True] / name).read_bytes(), name


def test_receptions_power_on_a_map_is_the_law_less_every_wall_crossed():
    """On a map with a wall loss, each row's power is the log-distance law at its distance
    less ``wall_loss_db`` for every wall the pair's segment crosses, all of them counted
    (rows far below the sensitivity too), the walls recomputed here from where the robots
    stand."""
    from netsim.world.los import walls_crossed

    wall_db = 5.0
    channel = {"propagation": "log_distance", "sensitivity_dbm": SENSITIVITY_DBM, "wall_loss_db": wall_db}
    config = make_config(
        seed=4,
        duration_s=4.0,
        world={"n_robots": 14, "side_m": 200.0, "map": "office"},
        mobility={"model": "static"},
        channel={"latency_s": LATENCY_S, **channel},
        protocol={"model": "clustering"},
        output={"position_interval_s": 1.0, "receptions": True},
    )
    result, _, _ = _run(config)
    r = result.frames["receptions"]
    sim = result.sim
    radio = sim.config.channel.radio
    d = np.maximum(r["distance_m"].to_numpy(), radio.reference_distance_m)
    law = (
        radio.tx_power_dbm
        - radio.reference_loss_db
        - 10 * radio.path_loss_exponent * np.log10(d / radio.reference_distance_m)
    )
    pos = sim.state.positions_at(0.0)  # robots that stand: where they are at every frame
    walls = walls_crossed(sim.channel.reception.map, pos[r["src"].to_numpy()], pos[r["dst"].to_numpy()])
    assert np.allclose(r["rx_power_dbm"].to_numpy(), law - wall_db * walls, rtol=0, atol=1e-9)
    assert (walls >= 3).sum() > 10 and len(np.unique(walls)) >= 5  # many walls, of many counts


@pytest.mark.parametrize("mac", ["aloha", "csma"])
def test_receptions_of_a_frame_on_the_air_at_the_end_are_its_counted_drops(mac):
    """A run that ends while a frame is on the air: the receivers it lost where it went on
    the air (to the loss model) were counted as drops, so they have their rows; those left
    to its end, which never came, have none. The run is cut just after a frame with a loss
    went on the air."""
    channel = {**MEDIUM, "mac": mac, "loss_model": "bernoulli", "loss_probability": 0.3}
    whole = _run(_config(channel, n=19, side_m=150.0, duration_s=8.0))[0].frames["receptions"]
    t0 = float(whole["t_s"][(whole["cause"] == "loss") & (whole["t_s"] > 5.0)].iloc[0])
    result, deliveries, drops = _run(_config(channel, n=19, side_m=150.0, duration_s=t0 + 1e-6))
    assert len(result.sim.channel.mac.on_air) == 1
    r = result.frames["receptions"]
    last = r[r["t_s"] == t0]
    assert (last["cause"] == "loss").any() and not last["received"].any()
    _check_rows_are_the_channels(result, deliveries, drops)
