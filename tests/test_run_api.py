"""Running a simulation from Python: how far ``sim.run`` may go, and what ``collect``
returns for a run stopped before its end."""

import math

import numpy as np
import pandas as pd
import pytest

from netsim.cosim import CommandError
from netsim.run import build, collect
from tests.fixtures import make_config

CONFIG = dict(
    seed=3,
    world={"n_robots": 20, "side_m": 400.0},
    channel={"range_m": 120.0},
    protocol={"message_rate_hz": 1.0},
    output={"position_interval_s": 1.0},
    events={"hooks": ["link_breaks"]},
)
STOP_S = 90.0
TIME_COLUMNS = ("t_s", "t_up_s", "t_down_s", "t_sent_s", "t_received_s", "t_delivered_s")


def _collected(duration_s: float, until_s: float | None = None) -> dict[str, pd.DataFrame]:
    sim = build(make_config(duration_s=duration_s, **CONFIG))
    sim.run(until_s=until_s)
    return collect(sim)


@pytest.fixture(scope="module")
def stopped():
    """A 3,000 s run collected at 90 s."""
    return _collected(3000.0, STOP_S)


def test_collect_before_the_end_ends_every_table_at_now(stopped):
    """Tables collected before the run's end end at ``sim.now``: no time in any table is
    later than now (positions are not carried along the legs to ``duration_s``)."""
    for name, frame in stopped.items():
        for col in TIME_COLUMNS:
            if col in frame and len(frame):
                assert frame[col].max() <= STOP_S, f"{name}.{col} reaches {frame[col].max()}"
    assert stopped["positions"]["t_s"].max() == STOP_S


def test_collect_before_the_end_keeps_robots_in_the_area(stopped):
    """Every position collected before the run's end is inside the area."""
    pos = stopped["positions"]
    side = CONFIG["world"]["side_m"]
    assert pos["x_m"].between(0, side).all() and pos["y_m"].between(0, side).all()


def test_collect_before_the_end_is_the_run_that_ended_there(stopped):
    """Positions, links and the sampled tables collected at ``now`` are those of a run whose
    duration is now: links still up are censored at now, and groups and beliefs have their
    sample at now, as an ended run has at its end."""
    ended = _collected(STOP_S)
    assert stopped["groups"]["t_s"].max() == STOP_S
    for name in ("positions", "links", "groups", "beliefs", "neighbour_beliefs"):
        pd.testing.assert_frame_equal(stopped[name], ended[name])
    assert stopped["links"]["censored_end"].any()
    assert (stopped["links"].loc[stopped["links"]["censored_end"], "t_down_s"] == STOP_S).all()


def _sim(duration_s: float = 60.0):
    return build(make_config(duration_s=duration_s, **CONFIG))


@pytest.mark.parametrize("until, named", [(120.0, "120"), (math.inf, "inf"), (60.000001, "60.000001")])
def test_run_beyond_the_end_is_refused(until, named):
    """``sim.run(until_s=...)`` later than ``duration_s`` raises a ValueError naming the
    value and the run's end, and the run has not moved."""
    sim = _sim()
    with pytest.raises(ValueError, match=r"until_s = .* is after the run's end \(duration_s = 60\)") as info:
        sim.run(until_s=until)
    assert isinstance(info.value, CommandError)
    assert "\n" not in str(info.value)
    assert str(info.value).startswith(f"until_s = {named} is after")
    assert sim.now == 0.0


def test_run_before_now_is_refused():
    """``sim.run(until_s=...)`` earlier than ``sim.now`` raises a ValueError naming both."""
    sim = _sim()
    sim.run(until_s=20.0)
    with pytest.raises(ValueError, match=r"^until_s = 10 is before now \(20 s\)"):
        sim.run(until_s=10.0)
    assert sim.now == 20.0


@pytest.mark.parametrize("until", [math.nan, "soon", None])
def test_run_at_nan_or_not_a_time_is_refused(until):
    """``sim.run(until_s=nan)`` (or a value that is not a number) raises a ValueError
    naming the value; ``None`` is the run's end."""
    sim = _sim(10.0)
    if until is None:
        sim.run(until_s=until)
        assert sim.now == 10.0
        return
    with pytest.raises(ValueError, match=r"^until_s = "):
        sim.run(until_s=until)
    assert sim.now == 0.0


def test_run_to_now_and_to_the_end_are_allowed():
    """``until_s`` equal to now (nothing happens) and equal to ``duration_s`` are allowed."""
    sim = _sim(10.0)
    sim.run(until_s=0.0)
    sim.run(until_s=4.0)
    sim.run(until_s=4.0)
    sim.run(until_s=10.0)
    assert sim.now == 10.0
    np.testing.assert_array_equal(collect(sim)["positions"]["t_s"].max(), 10.0)


@pytest.mark.slow
@pytest.mark.parametrize(
    "radio",
    [
        {},
        {"channel": {"propagation": "log_distance", "shadowing_sigma_db": 4.0}},
        {"world": {"n_robots": 20, "side_m": 200.0, "map": "office"}, "mobility": {"stationary_start": False}},
    ],
    ids=["unit_disk", "shadowing", "office_map"],
)
def test_collect_mid_run_leaves_the_rest_of_the_run_as_it_was(radio):
    """Collecting the tables mid-run changes nothing after it: a run collected at 40 s and
    then run to its end announces the same link events, and writes the same links,
    link_breaks and sampled tables (a sample taken for the collection is not kept), as the
    same run never collected before its end."""
    config = {**CONFIG, **radio, "events": {"hooks": ["link_breaks"], "runtime_links": "on"}}
    if "world" in radio:
        config["world"] = {**CONFIG["world"], **radio["world"]}
    if "channel" in radio:
        config["channel"] = radio["channel"]

    def run(stop_at: float | None):
        sim = build(make_config(duration_s=100.0, **config))
        ups: list = []
        sim.events.on("link_up", ups.append)
        if stop_at is not None:
            sim.run(until_s=stop_at)
            collect(sim)
        sim.run()
        return ups, collect(sim)

    (ups_once, once), (ups_twice, twice) = run(None), run(40.0)
    assert len(ups_once) > 10
    assert ups_twice == ups_once
    for table in ("links", "link_breaks", "groups", "beliefs", "neighbour_beliefs"):
        pd.testing.assert_frame_equal(twice[table], once[table])


@pytest.mark.slow
def test_a_coverage_table_collected_mid_run_ends_at_now_and_is_not_kept():
    """The coverage table collected at ``now`` is that of a run that ended at now (its
    sample at now included), and the run, continued, writes the table it would have."""
    coverage = dict(
        world={"n_robots": 20, "side_m": 800.0, "placement": "centre", "centre_side_m": 200.0},
        mobility={"model": "static"},
        channel={"range_m": 100.0},
        protocol={"message_rate_hz": 0.0},
        coverage={"enabled": True},
    )

    def sim(duration_s: float):
        return build(make_config(duration_s=duration_s, seed=3, **coverage))

    stopped, ended, whole = sim(100.0), sim(52.0), sim(100.0)
    stopped.run(until_s=52.0)
    ended.run()
    mid = collect(stopped)["coverage"]
    assert mid["t_s"].max() == 52.0
    pd.testing.assert_frame_equal(mid, collect(ended)["coverage"])
    stopped.run()
    whole.run()
    pd.testing.assert_frame_equal(collect(stopped)["coverage"], collect(whole)["coverage"])


@pytest.mark.parametrize("protocol", ["aodv", "ack"])
def test_collect_holds_every_table_as_its_parquet_file_reads_back(tmp_path, protocol):
    """``collect(sim)`` and the run's Parquet files read back agree in values and dtypes:
    text is pandas' own text dtype, a missing text NaN, in tables with rows and without.
    (Under aodv, packets' drop_cause held None in an object column and control's kind was
    object; the empty roles table of a protocol without roles was object.)"""
    from netsim.tools.output import write_table

    flows = [{"src": 0, "dst": 5, "start_s": 2.0, "stop_s": 12.0, "rate_bps": 8000.0, "packet_bytes": 500}]
    config = make_config(
        seed=2,
        duration_s=20.0,
        world={"n_robots": 8, "side_m": 300.0},
        protocol={"model": protocol},
        output={"receptions": True},
        traffic={"flows": flows if protocol == "aodv" else []},
    )
    sim = build(config)
    sim.run()
    frames = collect(sim)
    assert {"packets", "control"} <= set(frames) if protocol == "aodv" else len(frames["roles"]) == 0
    for name, frame in frames.items():
        write_table(frame, tmp_path / f"{name}.parquet")  # as netsim run writes it
        back = pd.read_parquet(tmp_path / f"{name}.parquet")
        pd.testing.assert_frame_equal(frame.reset_index(drop=True), back, obj=name)


def test_every_time_column_is_float_in_a_run_shorter_than_its_first_change():
    """Rows made at t = 0 held the kernel's integer start time: in a run (or a collect)
    before any role changed, roles' t_s was int64 where a longer run's is float64, and two
    runs' files of one sweep did not read as one dataset; the summary's duration was 0."""
    from netsim.run import summarize

    sim = build(make_config(duration_s=1.0, **CONFIG))
    sim.run(until_s=0.0)
    early = collect(sim)
    assert len(early["roles"]) > 0
    assert float(summarize(sim, early, 0.0)["duration_s"]) == 0.0
    assert isinstance(summarize(sim, early, 0.0)["duration_s"], float)
    sim.run()
    for frames in (early, collect(sim)):
        for name, frame in frames.items():
            for column in set(TIME_COLUMNS) & set(frame.columns):
                assert frame[column].dtype == np.float64, (name, column)


def test_a_table_collect_handed_out_is_the_callers_to_change():
    """The sampled tables (groups, beliefs, neighbour beliefs) were handed out over the
    run's own buffers: a script that wrote into one changed what every later collect and
    summary read."""
    sim = build(make_config(duration_s=20.0, **CONFIG))
    sim.run()
    before = {name: table.copy() for name, table in collect(sim).items()}
    names = ("groups", "beliefs", "neighbour_beliefs")
    for name in names:
        table = collect(sim)[name]
        assert len(table) > 0, name
        table.loc[:, "t_s"] = -1.0
        table.iloc[0, 1] = 12345
        table["t_s"] += 1.0
    after = collect(sim)
    for name in names:
        pd.testing.assert_frame_equal(after[name], before[name], obj=name)


@pytest.mark.parametrize("run", [-1, 1.7, True])
def test_a_replication_that_is_not_a_whole_number_from_zero_is_refused(run):
    """``run=1.7`` and ``run=True`` were taken as replication 1, ``-1`` failed in numpy's
    seeding without naming ``run``."""
    with pytest.raises(ValueError, match=r"run = .*: must be a whole number >= 0"):
        build(make_config(duration_s=1.0, **CONFIG), run=run)


def test_overrides_given_as_one_string_are_refused():
    """A string is an iterable of characters: ``load(None, "world.n_robots=5")`` said that
    ``w`` must look like key=value."""
    from netsim.config import load

    with pytest.raises(TypeError, match="must be a list of 'key=value' strings, not one string"):
        load(None, "world.n_robots=5")
