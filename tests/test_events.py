"""Events as they happen (docs/events.md): course changes with their causes, link up/down
solved during the run (equal to the post-hoc solver), subscriptions and their order, the
live topology and its time-averaged levels, the example hook."""

from __future__ import annotations

import math

import networkx as nx
import numpy as np
import pandas as pd
import pytest

from netsim.config import load
from netsim.errors import ConfigError
from netsim.events import EVENT_NAMES, EventBus, LinkDown, LinkUp
from netsim.links.lifetimes import link_lifetimes
from netsim.links.radio_links import radio_link_lifetimes
from netsim.links.walled_links import WalledLinks
from netsim.run import build, collect, execute, simulation
from netsim.scheduling import NORMAL, URGENT, scheduled_event
from netsim.state import CAUSES
from netsim.tools.validate import random_legs
from netsim.topology import snapshot
from netsim.world.maps import save_map
from tests.fixtures import make_config
from tests.link_feed import Feed


# -- helpers ---------------------------------------------------------------------------------
def _core(n, ranges, duration_s, side_m=1e6, torus=False, **events):
    config = make_config(
        duration_s=duration_s,
        world={"n_robots": n, "side_m": side_m, "torus": torus},
        mobility={"model": "static"},
        channel={"range_m": ranges},
        protocol={"model": "none"},
        events=events,
        output={"position_interval_s": 0.0},
    )
    return simulation(config)


def _replay(sim, legs: pd.DataFrame) -> None:
    """Drive the robots of ``sim`` along ``legs`` (first row of each robot: its start);
    a leg that does not start where the robot is becomes a jump."""
    legs = legs.sort_values(["t_s", "robot"], kind="stable")
    first = legs.groupby("robot").head(1).sort_values("robot")
    st, env = sim.state, sim.env
    st.place(first[["x_m", "y_m"]].to_numpy())
    rows = list(legs.itertuples(index=False))

    def drive():
        for t, r, x, y, vx, vy in ((row.t_s, row.robot, row.x_m, row.y_m, row.vx_mps, row.vy_mps) for row in rows):
            if t > env.now:
                yield env.timeout(t - env.now)
            here = st.origin_m[r] + st.velocity_mps[r] * (t - st.t0_s[r])
            scale = 1.0 + abs(here).max() + max(abs(x), abs(y))
            jump = math.hypot(here[0] - x, here[1] - y) > 1e-9 * scale
            st.set_leg(int(r), t, (vx, vy), start_m=(x, y) if jump else None)

    env.process(drive())


def _fed(sim):
    """``sim`` with a :class:`~tests.link_feed.Feed` of its link events (before the run)."""
    sim.feed = Feed(sim.events)
    return sim


def _announced(sim) -> pd.DataFrame:
    """The link events ``sim`` announced (after :func:`collect`), as a links table."""
    return sim.feed.table(sim, sim.env.now)


def _assert_same_links(runtime: pd.DataFrame, posthoc: pd.DataFrame) -> None:
    key = ["a", "b", "t_up_s"]
    r = runtime.sort_values(key, kind="stable").reset_index(drop=True)
    p = posthoc.sort_values(key, kind="stable").reset_index(drop=True)
    assert len(r) == len(p)
    for col in ("a", "b", "censored", "censored_start", "censored_end"):
        assert (r[col].to_numpy() == p[col].to_numpy()).all(), col
    for col in ("t_up_s", "t_down_s"):
        # Bit for bit: both solvers solve each crossing from the pair's legs, not their windows.
        assert (r[col].to_numpy() == p[col].to_numpy()).all(), col


def _runtime_vs_posthoc(legs, n, ranges, duration_s, side_m=1e6, torus=False):
    sim = _fed(_core(n, list(ranges), duration_s, side_m, torus, runtime_links="on"))
    _replay(sim, legs)
    sim.run()
    frames = collect(sim)
    assert sim.links is not None
    posthoc = link_lifetimes(frames["legs"], sim.state.range_m, duration_s, side_m, torus)
    assert len(posthoc) > 3  # the case has links to compare
    _assert_same_links(_announced(sim), posthoc)
    pd.testing.assert_frame_equal(frames["links"], posthoc)
    return sim


@pytest.mark.parametrize("torus", [False, True])
@pytest.mark.parametrize("then", ["stops", "turns back", "stops as another jumps"])
def test_a_pair_that_comes_to_rest_exactly_at_range_stays_linked(torus, then):
    """A robot that stops exactly at the range (d = R to the last bit) is in range from then
    on, as the channel hears it: its link is up again at that instant, in links.parquet and
    in the live feed alike (it was down for the rest of the run, the exit found at the end
    of the leg kept and nothing to undo it at rest), also when a far robot jumps then and
    nobody moves after (the runtime solver's new window solves no pair). Turning back
    there, it comes up again as it heads inward. Either way the link goes down and up at
    that instant (docs/events.md)."""
    rows = [
        (0.0, 0, 210.0, 100.0, 0.0, 0.0),
        (0.0, 1, 10.0, 100.0, 10.0, 0.0),
        (30.0, 1, 310.0, 100.0, -10.0 if then == "turns back" else 0.0, 0.0),
        (0.0, 2, 20.0, 380.0, 0.0, 0.0),
    ]
    if then == "stops as another jumps":
        rows.append((30.0, 2, 30.0, 390.0, 0.0, 0.0))
    legs = pd.DataFrame(rows, columns=["t_s", "robot", "x_m", "y_m", "vx_mps", "vy_mps"])
    sim = _fed(_core(3, [100.0, 100.0, 100.0], 40.0, 400.0 if torus else 1e6, torus, runtime_links="on"))
    _replay(sim, legs)
    sim.run()
    frames = collect(sim)
    links = frames["links"][["t_up_s", "t_down_s", "censored_end"]].values.tolist()
    # Turning back, it stays in range until x = 110, at t = 50, past the run's end.
    assert links == [[10.0, 30.0, False], [30.0, 40.0, True]]
    _assert_same_links(_announced(sim), frames["links"])
    pd.testing.assert_frame_equal(
        frames["links"], link_lifetimes(frames["legs"], sim.state.range_m, 40.0, sim.state.side_m, torus)
    )


# -- runtime link events equal the post-hoc solution -------------------------------------------
def _random_case(seed: int, kind: str):
    """Random trajectories (speeds drawn per case) of one of four kinds, and the runtime
    links compared with the post-hoc ones."""
    rng = np.random.default_rng(seed)
    n = int(rng.integers(10, 40))
    speed = float(rng.uniform(0.5, 6.0))
    torus = kind == "torus"
    # The smallest torus allowed: other images come into range within a piece.
    side = 101.0 if torus else 300.0
    ranges = rng.uniform(20.0, 80.0, n) if kind == "unequal_ranges" else np.full(n, 50.0)
    legs = random_legs(rng, n, 60.0, side, speed, jump_rate=0.3 if kind == "jumps" else 0.0)
    return _runtime_vs_posthoc(legs, n, ranges, 60.0, side if torus else 1e6, torus)


KINDS = ["bounded", "torus", "jumps", "unequal_ranges"]


@pytest.mark.parametrize("kind", KINDS)
@pytest.mark.parametrize("seed", [0, 1, *(pytest.param(s, marks=pytest.mark.slow) for s in (2, 3))])
def test_runtime_links_equal_posthoc_on_random_trajectories(kind, seed):
    sim = _random_case(1000 + 4 * seed + KINDS.index(kind), kind)
    if kind == "jumps":
        assert sim.state.jumps > 0


@pytest.mark.slow
@pytest.mark.parametrize("kind", KINDS)
def test_runtime_links_equal_posthoc_on_many_random_trajectories(kind):
    for seed in range(12):
        _random_case(5000 + 4 * seed + KINDS.index(kind), kind)


@pytest.mark.parametrize(
    "overrides",
    [
        [],
        ["mobility.model=random_direction", "mobility.pause_s=1"],
        ["mobility.model=random_direction", "world.torus=true", "mobility.turn_interval_s=7"],
        ["channel.range_m=[{}]".format(", ".join(str(60.0 + 5 * (i % 9)) for i in range(30)))],
    ],
    ids=["random_waypoint", "random_direction", "torus", "unequal_ranges"],
)
def test_runtime_links_equal_posthoc_in_runs(overrides):
    base = ["world.n_robots=30", "duration_s=120", "world.side_m=500", "channel.range_m=100", "protocol.model=none"]
    config = load(None, base + overrides + ["events.runtime_links=on"])
    result = execute(config, built=_fed)
    st = result.sim.state
    posthoc = link_lifetimes(result.frames["legs"], st.range_m, 120.0, st.side_m, st.torus)
    _assert_same_links(_announced(result.sim), posthoc)


TRACE = """\
$node_(0) set X_ 10.0
$node_(0) set Y_ 10.0
$node_(1) set X_ 200.0
$node_(1) set Y_ 10.0
$node_(2) set X_ 100.0
$node_(2) set Y_ 300.0
$ns_ at 1.0 "$node_(0) setdest 300.0 20.0 4.0"
$ns_ at 2.0 "$node_(2) setdest 100.0 0.0 3.0"
$ns_ at 20.0 "$node_(1) set X_ 80.0"
$ns_ at 30.0 "$node_(2) set Y_ 250.0"
$ns_ at 30.0 "$node_(0) set X_ 150.0"
$ns_ at 40.0 "$node_(1) setdest 390.0 390.0 5.0"
$ns_ at 50.0 "$node_(2) setdest 120.0 15.0 2.0"
"""


def test_runtime_links_equal_posthoc_on_a_trace_with_jumps(tmp_path):
    path = tmp_path / "jumps.tcl"
    path.write_text(TRACE)
    config = load(
        None,
        [
            "world.n_robots=3",
            "world.side_m=400",
            "duration_s=200",
            "channel.range_m=150",
            "mobility.model=trace",
            f"mobility.trace_file={path}",
            "protocol.model=none",
            "events.runtime_links=on",
        ],
    )
    result = execute(config, built=_fed)
    st = result.sim.state
    assert st.jumps >= 3
    posthoc = link_lifetimes(result.frames["legs"], st.range_m, 200.0)
    assert len(posthoc) >= 3
    _assert_same_links(_announced(result.sim), posthoc)
    legs = result.frames["legs"]
    assert (legs["cause"] == "jump").sum() == 3
    assert set(legs["cause"]) == {"start", "trace", "waypoint", "jump"}


def test_a_trace_jump_to_a_standstill_is_a_jump_for_the_runtime_links(tmp_path):
    """A robot put somewhere at an instant and left standing (a BonnMotion pause after a
    repeated instant, the shape an exported ``set X_`` takes) jumped: its leg says so, and
    the link it opens is announced at that instant, as the table after the run has it."""
    path = tmp_path / "jump_then_stand.movements"
    path.write_text("0 10 10 40 10 10\n0 180 180 5 180 180 5 20 10 10 20 10 30 150 10\n")
    config = load(
        None,
        [
            "world.n_robots=2",
            "world.side_m=200",
            "duration_s=40",
            "channel.range_m=50",
            "mobility.model=trace",
            f"mobility.trace_file={path}",
            "protocol.model=none",
            "events.runtime_links=on",
        ],
    )
    result = execute(config, built=_fed)
    legs = result.frames["legs"]
    at_jump = legs[(legs["robot"] == 1) & (legs["t_s"] == 5.0)]
    assert list(at_jump["cause"]) == ["jump"]
    assert result.sim.state.jumps == 1
    posthoc = link_lifetimes(legs, result.sim.state.range_m, 40.0)
    assert list(posthoc["t_up_s"]) == [5.0]
    _assert_same_links(_announced(result.sim), posthoc)


# -- course changes ----------------------------------------------------------------------------
def test_legs_record_every_course_change_with_its_cause():
    result = execute(load(None, ["world.n_robots=20", "duration_s=200", "world.side_m=300", "protocol.model=none"]))
    legs = result.frames["legs"]
    assert list(legs.columns) == ["t_s", "robot", "x_m", "y_m", "vx_mps", "vy_mps", "cause"]
    assert set(legs["cause"]) <= set(CAUSES)
    # Random waypoint with a pause: a robot stops at its waypoint, then leaves at the pause's end.
    assert {"start", "waypoint", "pause_end"} <= set(legs["cause"])
    moving = np.hypot(legs["vx_mps"], legs["vy_mps"]) > 0
    assert (~moving[legs["cause"] == "waypoint"]).all()
    assert moving[legs["cause"] == "pause_end"].all()


def test_course_change_events_are_the_legs_as_they_happen():
    config = load(None, ["world.n_robots=15", "duration_s=150", "world.side_m=300", "protocol.model=none"])
    sim = build(config)
    seen = []
    sim.events.on("course_change", lambda ev: seen.append((sim.now, *ev)))
    sim.run()
    legs = collect(sim)["legs"]
    assert all(now == t_s for now, t_s, *_ in seen)
    got = pd.DataFrame([s[1:] for s in seen], columns=list(legs.columns))
    # Every leg but the placements at t = 0 (made before anyone could subscribe).
    want = legs[~((legs["t_s"] == 0) & (legs["cause"] == "start") & (legs["vx_mps"] == 0) & (legs["vy_mps"] == 0))]
    key = ["robot", "t_s", "vx_mps"]
    got = got.sort_values(key, kind="stable").reset_index(drop=True)
    want = want.sort_values(key, kind="stable").reset_index(drop=True)
    pd.testing.assert_frame_equal(got, want)


@pytest.mark.slow
def test_control_commands_are_legs_with_cause_command():
    config = load(
        None,
        [
            "world.n_robots=20",
            "duration_s=30",
            "world.side_m=800",
            "world.placement=centre",
            "world.centre_side_m=200",
            "mobility.model=static",
            "channel.range_m=100",
            "coverage.enabled=true",
            "protocol.message_rate_hz=0",
        ],
    )
    legs = execute(config).frames["legs"]
    later = legs[legs["t_s"] > 0]
    assert len(later) > 0
    assert set(later["cause"]) == {"command"}


# -- subscriptions and their order -------------------------------------------------------------
def _scripted(sim, moves):
    """``moves``: (t, robot, velocity, start or None), applied in order by one process."""

    def drive():
        for t, r, v, start in moves:
            if t > sim.env.now:
                yield sim.env.timeout(t - sim.env.now)
            sim.state.set_leg(r, t, v, start_m=start)

    sim.env.process(drive())


def test_subscribers_see_events_in_time_order_with_the_documented_tie_order():
    """At one instant link events come first, by (a, b); a jump's link events follow the
    course change that causes them."""
    sim = _core(6, 10.0, 60.0)
    # Pairs (0, 1) and (2, 3) meet at t = 20 exactly and part at t = 40 exactly; robot 5
    # jumps next to robot 4 at t = 20.
    sim.state.place([[0, 0], [30, 0], [100, 0], [130, 0], [500, 0], [900, 0]])
    _scripted(sim, [(0.0, 3, (-1.0, 0.0), None), (0.0, 1, (-1.0, 0.0), None), (20.0, 5, (0.0, 0.0), (505.0, 0.0))])
    log = []
    for name in ("link_up", "link_down", "course_change"):
        sim.events.on(name, lambda ev, name=name: log.append((name, sim.now, ev)))

    def kernel_event(t):
        yield sim.env.timeout(t)
        log.append(("kernel", sim.now, None))

    sim.env.process(kernel_event(20.0))
    sim.env.process(kernel_event(40.0))
    # An URGENT event (as deliveries are) due at 20, scheduled before any link event.
    scheduled_event(sim.env, 20.0, URGENT, lambda _e: log.append(("urgent", sim.now, None)))
    sim.run()
    times = [t for _, t, _ in log]
    assert times == sorted(times)
    at20 = [(name, ev) for name, t, ev in log if t == 20.0]
    assert at20 == [
        ("link_up", LinkUp(20.0, 0, 1)),
        ("link_up", LinkUp(20.0, 2, 3)),
        ("urgent", None),
        ("course_change", at20[3][1]),
        ("link_up", LinkUp(20.0, 4, 5)),
        ("kernel", None),
    ]
    assert at20[3][1].robot == 5 and at20[3][1].cause == "jump"
    at40 = [(name, ev) for name, t, ev in log if t == 40.0]
    assert at40 == [
        ("link_down", LinkDown(40.0, 0, 1, 20.0)),
        ("link_down", LinkDown(40.0, 2, 3, 20.0)),
        ("kernel", None),
    ]
    assert all(ev.t_s == t for name, t, ev in log if name.startswith("link"))


def test_link_events_of_later_instants_wait_for_kernel_events_due_before_them():
    """One wake announces the link events of several instants only while the kernel has
    nothing due before them: a kernel event between two link instants, and one a subscriber
    schedules, run in time order; every link event sees ``sim.now`` equal to its ``t_s``."""
    sim = _core(8, 10.0, 60.0)
    # Pair (2k, 2k + 1) meets at t = 10 + 5k (k = 0..3): the gaps close at 1 m/s.
    sim.state.place([[0, 0], [20, 0], [100, 0], [125, 0], [200, 0], [230, 0], [300, 0], [335, 0]])
    _scripted(sim, [(0.0, 2 * k + 1, (-1.0, 0.0), None) for k in range(4)])
    log = []

    def on_up(ev):
        log.append(("link_up", sim.now, ev.t_s))
        if ev.t_s == 10.0:  # a kernel event due between two link instants, scheduled by a subscriber
            scheduled_event(sim.env, 2.5, NORMAL, lambda _e: log.append(("subscriber's", sim.now, None)))

    sim.events.on("link_up", on_up)
    scheduled_event(sim.env, 17.5, NORMAL, lambda _e: log.append(("kernel", sim.now, None)))
    sim.run()
    assert log == [
        ("link_up", 10.0, 10.0),
        ("subscriber's", 12.5, None),
        ("link_up", 15.0, 15.0),
        ("kernel", 17.5, None),
        ("link_up", 20.0, 20.0),
        ("link_up", 25.0, 25.0),
    ]


def test_a_subscriber_may_change_course_on_a_link_break():
    """Stop a robot when its link breaks: the run takes the new leg from that instant."""
    sim = _core(2, 10.0, 100.0)
    sim.state.place([[0, 0], [5, 0]])
    _scripted(sim, [(0.0, 1, (1.0, 0.0), None)])

    def turn_back(ev):
        sim.state.set_leg(1, ev.t_s, (-1.0, 0.0))

    sim.events.on("link_down", turn_back)
    ups = []
    sim.events.on("link_up", ups.append)
    sim.run()
    links = collect(sim)["links"]
    # Out of range at t = 5 (x = 10), back in at once: one lifetime ends at 5, the next starts at 5.
    assert links["t_down_s"].iloc[0] == pytest.approx(5.0)
    assert [u.t_s for u in ups] == [0.0, pytest.approx(5.0)]
    assert links["t_down_s"].iloc[1] == pytest.approx(25.0)


def test_role_changes_deliveries_and_drops_are_announced():
    config = load(None, ["world.n_robots=20", "duration_s=40", "world.side_m=400", "channel.loss_probability=0.2"])
    sim = build(config)
    roles, got, lost = [], [], []
    sim.events.on("role_change", roles.append)
    sim.events.on("delivery", got.append)
    sim.events.on("drop", lost.append)
    sim.run()
    frames = collect(sim)
    # Every role change but the initial roles, set when the protocol is built.
    table = frames["roles"].iloc[20:].reset_index(drop=True)
    assert (frames["roles"]["t_s"].iloc[:20] == 0).all()
    pd.testing.assert_frame_equal(pd.DataFrame(roles, columns=list(table.columns)), table)
    assert len(roles) > 20
    acks = frames["acks"]
    assert sum(len(d.receivers) for d in got if d.kind == "ack") == acks["received"].sum()
    assert sum(len(d.receivers) for d in lost if d.kind == "ack" and d.cause == "loss") == acks["dropped_loss"].sum()
    assert acks["dropped_loss"].sum() > 0


def test_the_bus_rejects_unknown_events_and_late_link_subscriptions():
    bus = EventBus()
    with pytest.raises(ValueError, match="unknown event 'link_broke'"):
        bus.on("link_broke", print)
    with pytest.raises(TypeError):
        bus.on("link_up", 3)
    assert set(EVENT_NAMES) >= {"course_change", "link_up", "link_down", "role_change", "delivery", "drop"}
    sim = _core(2, 10.0, 10.0)
    sim.state.place([[0, 0], [5, 0]])
    sim.run(5.0)
    with pytest.raises(RuntimeError, match="before the run starts"):
        sim.events.on("link_down", print)
    sim.events.on("course_change", print)  # any other event may be subscribed to at any time


def test_subscribing_returns_the_subscriber():
    """``on`` hands back the function it subscribed, so that it serves as a decorator."""
    bus = EventBus()

    def dropped(event):
        pass

    assert bus.on("drop", dropped) is dropped and bus.subscribers("drop") == [dropped]


def test_with_link_events_solved_from_the_start_they_may_be_subscribed_to_mid_run():
    """runtime_links = 'on' solves link events from t = 0: a subscriber to them added mid-run
    is taken, and called from then on (robot 1, set moving at 5 s, leaves robot 0's range at
    10 s)."""
    sim = _core(2, 10.0, 20.0, runtime_links="on")
    sim.state.place([[0, 0], [5, 0]])
    sim.run(5.0)
    sim.state.set_leg(1, 5.0, (1.0, 0.0))
    seen: list = []
    down = sim.events.on("link_down", lambda ev: seen.append((ev.t_s, ev.a, ev.b)))
    sim.run()
    assert down in sim.events.subscribers("link_down") and seen == [(pytest.approx(10.0), 0, 1)]


def test_runtime_links_are_off_unless_someone_subscribes():
    sim = _core(2, 10.0, 10.0)
    sim.state.place([[0, 0], [5, 0]])
    sim.run()
    assert sim.links is None
    sim = _core(2, 10.0, 10.0)
    sim.state.place([[0, 0], [5, 0]])
    sim.events.on("link_up", lambda ev: None)
    sim.run()
    assert sim.links is not None


def test_link_events_asked_for_after_the_run_started_are_refused():
    """Link events solved from the middle of a run would lack the links already up: once
    the run has started without them, asking for them is one clear error."""
    sim = _core(2, 10.0, 10.0)
    sim.state.place([[0, 0], [5, 0]])
    sim.run(5.0)
    with pytest.raises(RuntimeError, match="^link events during the run must be asked for before it starts$"):
        sim.link_events()
    assert sim.links is None


def test_link_events_are_refused_when_runtime_links_are_off():
    sim = _core(2, 10.0, 10.0, runtime_links="off")
    with pytest.raises(RuntimeError, match="^events.runtime_links = 'off': no link events during the run$"):
        sim.link_events()
    assert sim.links is None


def test_runtime_links_off_refuses_link_subscribers():
    sim = _core(2, 10.0, 10.0, runtime_links="off")
    sim.state.place([[0, 0], [5, 0]])
    sim.events.on("link_up", lambda ev: None)
    with pytest.raises(ConfigError, match="events.runtime_links = 'off'"):
        sim.run()


@pytest.mark.parametrize(
    "override, key",
    [
        ("events.runtime_links=sometimes", "events.runtime_links"),
        ('events.hooks=["no_such_hook"]', "events.hooks[0]"),
        ("events.hooks=3", "events.hooks"),
        ("events.live_topology=1", "events.live_topology"),
        ("events.colour=red", "events.colour"),
    ],
)
def test_bad_events_keys_are_named(override, key):
    with pytest.raises(ConfigError) as err:
        load(None, [override])
    assert str(err.value).startswith(key)


def test_live_topology_needs_runtime_links():
    with pytest.raises(ConfigError, match="events.live_topology"):
        load(None, ["events.live_topology=true", "events.runtime_links=off"])


# -- the live topology -------------------------------------------------------------------------
@pytest.mark.slow
def test_the_live_graph_equals_the_snapshot_at_random_instants():
    config = load(None, ["world.n_robots=40", "duration_s=120", "world.side_m=500", "channel.range_m=110"])
    sim = build(config)
    live = sim.live_topology()
    instants = np.sort(np.random.default_rng(5).uniform(0.0, 120.0, 40))
    wrong = []

    def compare():
        for t in instants.tolist():
            yield sim.env.timeout(t - sim.env.now)
            g = snapshot(sim.state, sim.now, groups=sim.groups)
            if set(g.edges) != set(live.graph.edges):
                wrong.append((t, "edges"))
            for i in g.nodes:
                mine = live.graph.nodes[i]
                if (mine["pos"], mine["role"], mine["leader"]) != (
                    g.nodes[i]["pos"],
                    g.nodes[i]["role"],
                    g.nodes[i]["leader"],
                ):
                    wrong.append((t, i))
            for a, b, since in live.graph.edges(data="up_since"):
                if not since <= sim.now:
                    wrong.append((t, a, b))

    sim.env.process(compare())
    sim.run()
    assert wrong == []
    assert live.graph.number_of_edges() > 20
    assert {"alpha", "beta"} <= {live.graph.nodes[i]["role"] for i in live.graph.nodes}


def test_the_live_graph_equals_the_snapshot_of_the_channels_links_under_shadowing():
    """Under shadowing the live graph is the channel's network: the snapshot given the
    run's links (``links=sim.link_events()``) at every instant tried, where the plain
    snapshot, a unit disk, differs at some of them (docs/events.md)."""
    config = load(
        None,
        ["world.n_robots=20", "duration_s=40", "world.side_m=300"]
        + ["channel.propagation=log_distance", "channel.shadowing_sigma_db=4", "protocol.model=none"],
    )
    sim = build(config)
    live = sim.live_topology()
    links = sim.link_events()
    same, disk_differs = [], 0

    def compare():
        nonlocal disk_differs
        for t in np.linspace(2.5, 37.5, 15).tolist():
            yield sim.env.timeout(t - sim.env.now)
            edges = set(map(frozenset, live.graph.edges))
            same.append(edges == set(map(frozenset, snapshot(sim.state, sim.now, links=links).edges)))
            disk_differs += edges != set(map(frozenset, snapshot(sim.state, sim.now).edges))

    sim.env.process(compare())
    sim.run()
    assert len(same) == 15 and all(same)
    assert disk_differs > 0


def test_time_weighted_levels_match_brute_force_sampling():
    config = load(
        None,
        [
            "world.n_robots=40",
            "duration_s=150",
            "world.side_m=600",
            "channel.range_m=90",
            "protocol.model=none",
            "events.live_topology=true",
        ],
    )
    result = execute(config)
    links = result.frames["links"]
    legs = result.frames["legs"]
    n, T = 40, 150.0
    # Brute force: the geometric graph sampled at the midpoint of every interval between
    # consecutive link events (the graph is constant on each), weighted by its length.
    from netsim.trajectory import sample_positions

    cuts = np.unique(np.r_[0.0, links["t_up_s"], links["t_down_s"], T])
    mids = 0.5 * (cuts[:-1] + cuts[1:])
    pos = sample_positions(legs, n, mids)[["x_m", "y_m"]].to_numpy().reshape(len(mids), n, 2)
    from netsim.topology import geometric_pairs

    area = np.zeros(3)
    for k, (lo, hi) in enumerate(zip(cuts[:-1].tolist(), cuts[1:].tolist())):
        i, j, _ = geometric_pairs(pos[k], 90.0)
        g = nx.Graph()
        g.add_nodes_from(range(n))
        g.add_edges_from(zip(i.tolist(), j.tolist()))
        comps = [len(c) for c in nx.connected_components(g)]
        area += np.array([len(comps), max(comps), 2 * g.number_of_edges() / n]) * (hi - lo)
    want = area / T
    s = result.summary
    got = (s["time_mean_components"], s["time_mean_largest_component"], s["time_mean_degree"])
    assert got == pytest.approx(tuple(want), rel=1e-9)
    assert s["time_mean_degree"] == pytest.approx(s["mean_degree"], rel=1e-9)
    assert 1 < want[0] < n and want[1] > 5  # several components, one of them large


# -- the example hook --------------------------------------------------------------------------
def test_link_breaks_hook_counts_breaks_per_robot_per_minute():
    config = load(
        None,
        [
            "world.n_robots=3",
            "world.side_m=1000",
            "duration_s=150",
            "channel.range_m=10",
            "mobility.model=static",
            "protocol.model=none",
            'events.hooks=["link_breaks"]',
        ],
    )
    sim = build(config)
    sim.state.place([[200, 200], [230, 200], [200, 300]])
    # Robot 1 passes robot 0: up at 20, down at 40 (minute 0). Robot 2 passes robot 0
    # twice: up at 90, down at 110 (minute 1), turns back at 115: up at 120, down at 140
    # (minute 2).
    _scripted(sim, [(0.0, 1, (-1.0, 0.0), None), (0.0, 2, (0.0, -1.0), None), (115.0, 2, (0.0, 1.0), None)])
    sim.run()
    frames = collect(sim)
    table = frames["link_breaks"]
    assert list(table.columns) == ["minute", "t_s", "robot", "breaks"]
    got = table.pivot(index="minute", columns="robot", values="breaks").to_numpy()
    assert got.tolist() == [[1, 1, 0], [1, 0, 1], [1, 0, 1]]
    assert table["t_s"].tolist()[::3] == [0.0, 60.0, 120.0]


@pytest.mark.parametrize(
    "args, fragment",
    [
        (["--set", "events.runtime_links=maybe"], "events.runtime_links = 'maybe': must be one of 'auto', 'on', 'off'"),
        (["--set", 'events.hooks=["nope"]'], "events.hooks[0] = 'nope': unknown"),
        (["--set", "events.live_topology=true", "--set", "events.runtime_links=off"], "events.live_topology"),
        (["--set", 'events.hooks=["link_breaks"]', "--set", "events.runtime_links=off"], "events.runtime_links"),
    ],
)
def test_cli_bad_events_keys_exit_2_with_one_line(tmp_path, capsys, args, fragment):
    from netsim.tools.cli import main

    code = main(["run", "--quiet", "--out", str(tmp_path / "out"), *args])
    lines = capsys.readouterr().err.strip().splitlines()
    assert code == 2
    assert len(lines) == 1 and lines[0].startswith("netsim: error: ") and fragment in lines[0]
    assert not (tmp_path / "out").exists()


def test_cli_run_with_the_hook_writes_its_table_and_the_levels(tmp_path):
    import json

    from netsim.tools.cli import main

    out = tmp_path / "out"
    args = ["--set", "world.n_robots=20", "--set", "duration_s=90", "--set", "protocol.model=none"]
    args += ["--set", 'events.hooks=["link_breaks"]', "--set", "events.live_topology=true"]
    assert main(["run", "--quiet", "--out", str(out), *args]) == 0
    table = pd.read_parquet(out / "link_breaks.parquet")
    links = pd.read_parquet(out / "links.parquet")
    assert len(table) == 20 * 2
    assert table["breaks"].sum() == 2 * (~links["censored_end"]).sum()
    summary = json.loads((out / "summary.json").read_text())
    assert summary["time_mean_degree"] == pytest.approx(summary["mean_degree"], rel=1e-9)
    assert "link_breaks_per_robot_per_minute" in summary


def test_the_live_graph_equals_the_snapshot_on_a_torus_with_unequal_ranges():
    ranges = ", ".join(str(70.0 + 7 * (i % 6)) for i in range(30))
    config = load(
        None,
        [
            "world.n_robots=30",
            "duration_s=100",
            "world.side_m=300",
            "world.torus=true",
            "mobility.model=random_direction",
            "mobility.turn_interval_s=5",
            f"channel.range_m=[{ranges}]",
            "protocol.model=none",
        ],
    )
    sim = build(config)
    live = sim.live_topology()
    wrong, seen = [], []

    def compare():
        for t in np.sort(np.random.default_rng(8).uniform(0.0, 100.0, 30)).tolist():
            yield sim.env.timeout(t - sim.env.now)
            g = snapshot(sim.state, sim.now)
            seen.append(g.number_of_edges())
            if set(g.edges) != set(live.graph.edges):
                wrong.append(t)
            if any(live.graph.nodes[i]["pos"] != g.nodes[i]["pos"] for i in g.nodes):
                wrong.append(t)

    sim.env.process(compare())
    sim.run()
    assert wrong == []
    assert min(seen) > 10


@pytest.mark.parametrize(
    "overrides",
    [
        pytest.param(["protocol.routing=backbone", "channel.loss_probability=0.3"], marks=pytest.mark.slow),
        pytest.param(
            ["protocol.routing=backbone", "channel.latency_jitter_s=0.01", "protocol.message_ttl=2"],
            marks=pytest.mark.slow,
        ),
        pytest.param(["protocol.routing=oracle", "channel.loss_probability=0.3"], marks=pytest.mark.slow),
        ["protocol.routing=oracle", "protocol.message_ttl=2"],
    ],
)
def test_messages_end_to_end_are_announced_once_with_their_outcome(overrides):
    config = load(
        None,
        ["world.n_robots=40", "duration_s=60", "world.side_m=900", "protocol.message_rate_hz=2", *overrides],
    )
    sim = build(config)
    delivered, dropped = [], []
    sim.events.on("message_delivered", delivered.append)
    sim.events.on("message_dropped", dropped.append)
    sim.run()
    messages = collect(sim)["messages"].set_index("msg_id")
    ids = [e.msg_id for e in delivered + dropped]
    assert len(ids) == len(set(ids))  # at most one outcome per message
    # Every delivered message, and only those, announced as delivered, with its row's figures.
    got = pd.DataFrame(delivered).set_index("msg_id").sort_index()
    rows = messages[messages["delivered"]]
    assert got.index.tolist() == rows.index.tolist()
    assert (got["t_s"] == rows["t_delivered_s"]).all() and (got["hops"] == rows["hops"]).all()
    assert (got["latency_s"] == rows["latency_s"]).all()
    # Dropped: never delivered, known after being sent, for a documented cause.
    lost = pd.DataFrame(dropped).set_index("msg_id")
    assert len(lost) > 0 and not messages.loc[lost.index, "delivered"].any()
    assert (lost["t_s"] >= messages.loc[lost.index, "t_sent_s"]).all()
    assert set(lost["cause"]) <= {"no_route", "lost", "ttl", "died_out"}
    # The rest were still on their way when the run ended.
    silent = messages.index.difference(got.index.union(lost.index))
    relay = sim.models["protocol"].relay
    if config.protocol.routing == "backbone":
        assert all(relay._pending[m] > 0 for m in silent)
        assert all(relay._pending[m] == 0 for m in lost.index)
    assert len(silent) < 0.1 * len(messages)
    times = [e.t_s for e in delivered + dropped]
    assert len(times) > 20


@pytest.mark.parametrize("model", ["aodv", "olsr", "greedy"])
def test_routed_packets_are_announced_end_to_end_with_their_rows_figures(model):
    """Under a routing protocol each packet's frame gets message_delivered or message_dropped
    (a one-frame packet: its row of packets.parquet), none in flight at the end; they
    never fired there."""
    config = load(
        None,
        ["world.n_robots=25", "duration_s=60", "seed=4", f"protocol.model={model}", "protocol.message_rate_hz=0.5"],
    )
    sim = build(config)
    delivered, dropped = [], []
    sim.events.on("message_delivered", delivered.append)
    sim.events.on("message_dropped", dropped.append)
    sim.run()
    packets = collect(sim)["packets"]
    assert (packets["frames"] == 1).all()
    ids = [e.msg_id for e in delivered + dropped]
    assert len(ids) == len(set(ids))
    rows = packets[packets["delivered"]]
    assert len(rows) > 0
    got = sorted((e.src, e.dst, e.t_s, e.hops, e.latency_s) for e in delivered)
    assert got == sorted(zip(rows["src"], rows["dst"], rows["t_delivered_s"], rows["hops"], rows["latency_s"]))
    rows = packets[~packets["delivered"] & (packets["drop_cause"] != "in_flight")]
    assert len(rows) > 0
    lost = sorted((e.src, e.dst, e.t_s, e.cause) for e in dropped)
    assert lost == sorted(zip(rows["src"], rows["dst"], rows["t_dropped_s"], rows["drop_cause"]))


@pytest.mark.slow
def test_runtime_links_under_log_distance_without_shadowing_or_walls():
    """Path loss alone is the unit disk of the implied range: its link events run live."""
    base = ["world.n_robots=30", "duration_s=120", "world.side_m=500", "protocol.model=ack"]
    radio = ["channel.propagation=log_distance", "channel.sensitivity_dbm=-80"]
    config = load(None, base + radio + ["events.runtime_links=on", "events.live_topology=true"])
    result = execute(config, built=_fed)
    assert result.sim.links is not None
    st = result.sim.state
    posthoc = link_lifetimes(result.frames["legs"], st.range_m, 120.0, st.side_m, st.torus)
    assert len(posthoc) > 3
    _assert_same_links(_announced(result.sim), posthoc)
    # The same run, links solved after it, writes the same receptions.
    after = execute(load(None, base + radio))
    assert after.sim.links is None
    pd.testing.assert_frame_equal(after.frames["acks"], result.frames["acks"])


# Fast robots and rare Acks: many links are cut where the pair leaves the reach (341 m)
# before the next decision.
SHADOWED = [
    "world.n_robots=40",
    "duration_s=60",
    "world.side_m=1500",
    "protocol.model=ack",
    "protocol.ack_period_s=10",
    "mobility.speed_min_mps=10",
    "mobility.speed_max_mps=30",
    "mobility.stationary_start=false",
    "channel.propagation=log_distance",
    "channel.shadowing_sigma_db=4",
]


@pytest.mark.slow
@pytest.mark.parametrize("torus", [[], ["world.torus=true"]], ids=["plane", "torus"])
def test_runtime_links_under_shadowing_equal_the_record_after_the_run(torus):
    """Under shadowing, link events run live: up at the send that brings a link up, down at
    the send that brings it down or where the pair leaves the reach; their table equals
    the post-hoc record (radio_links.recorded_lifetimes) bit for bit, and the run's
    receptions are those of the run that solves links after it."""
    overrides = SHADOWED + torus
    sim = _fed(build(load(None, overrides)))
    announced = []
    sim.events.on("link_up", lambda ev: announced.append((sim.now, ev.t_s, "up", ev.a, ev.b)))
    sim.events.on("link_down", lambda ev: announced.append((sim.now, ev.t_s, "down", ev.a, ev.b)))
    sim.run()
    frames = collect(sim)
    assert sim.links is not None
    st, reception = sim.state, sim.channel.reception
    posthoc = radio_link_lifetimes(reception, frames["legs"], st.range_m, 60.0, st.side_m, st.torus)
    assert len(posthoc) > 50
    _assert_same_links(_announced(sim), posthoc)
    # Some links were cut where the pair left the reach, before the decision that ended them.
    decided = reception.recorder.intervals(60.0)
    cut = frames["links"].merge(decided, on=["a", "b", "t_up_s"], suffixes=("", "_decided"))
    assert (cut["t_down_s"] < cut["t_down_s_decided"]).sum() >= 5
    # Announced as they happened, and each lifetime's ends announced.
    assert all(now == t for now, t, *_ in announced)
    assert [t for _, t, *_ in announced] == sorted(t for _, t, *_ in announced)
    links = frames["links"]
    assert sorted(ev[3:] for ev in announced if ev[2] == "up") == sorted(zip(links["a"], links["b"]))
    after = execute(load(None, overrides))
    assert after.sim.links is None
    pd.testing.assert_frame_equal(after.frames["acks"], frames["acks"])
    pd.testing.assert_frame_equal(after.frames["links"], frames["links"])


def test_a_shadowed_link_decided_at_t0_is_cut_where_the_pair_leaves_the_reach():
    """A decision at t = 0 comes before the reach's state at t = 0 is set (the solver starts
    last): the link still ends where the pair leaves the reach, as after the run."""
    config = make_config(
        duration_s=30.0,
        world={"n_robots": 2, "side_m": 1e4},
        mobility={"model": "static"},
        channel={"propagation": "log_distance", "shadowing_sigma_db": 4.0},
        protocol={"model": "none"},
        events={"runtime_links": "on"},
        output={"position_interval_s": 0.0},
    )
    sim = _fed(simulation(config))
    sim.state.place([[0.0, 0.0], [50.0, 0.0]])
    _scripted(sim, [(0.0, 1, (20.0, 0.0), None)])
    sim.env.process(_broadcast_at(sim, 0.0))
    downs = []
    sim.events.on("link_down", downs.append)
    sim.run()
    frames = collect(sim)
    reception = sim.channel.reception
    posthoc = radio_link_lifetimes(reception, frames["legs"], sim.state.range_m, 30.0, sim.state.side_m)
    _assert_same_links(_announced(sim), posthoc)
    # Up at the broadcast, down where the pair is 341 m apart (not at a decision: there is none).
    assert frames["links"]["t_up_s"].tolist() == [0.0]
    assert frames["links"]["t_down_s"].tolist() == [downs[0].t_s]
    assert downs[0].t_s == pytest.approx((reception.reach_m - 50.0) / 20.0)


def _broadcast_at(sim, t):
    if t > sim.env.now:
        yield sim.env.timeout(t - sim.env.now)
    sim.channel.broadcast(0, None, lambda *_: None)
    yield sim.env.timeout(0)


def test_the_live_graph_under_shadowing_holds_the_links_up():
    """The live topology follows the shadowed link events: at the end its edges are the
    links still up (censored at the end in links.parquet)."""
    result = execute(load(None, SHADOWED + ["events.live_topology=true"]))
    links = result.frames["links"]
    still = links[links["censored_end"]]
    graph = result.sim.models["live_topology"].graph
    assert sorted(graph.edges()) == sorted(zip(still["a"], still["b"]))
    assert len(still) > 5


WALLS = ["world.map=office", "world.side_m=200", "channel.range_m=40", "mobility.stationary_start=false"]


# -- on a map ----------------------------------------------------------------------------------
def _map_core(n, duration_s, world_map="office", side_m=200.0, **channel):
    config = make_config(
        duration_s=duration_s,
        world={"n_robots": n, "side_m": side_m, "map": world_map},
        mobility={"model": "static"},
        channel=channel or {"range_m": 40.0},
        protocol={"model": "none"},
        events={"runtime_links": "on"},
        output={"position_interval_s": 0.0},
    )
    return _fed(simulation(config))


def _walled_runtime_vs_posthoc(sim, duration_s, window_s=None):
    """Run ``sim`` (links solved during it, on a map), and compare its table with the
    post-hoc solver's on the legs it ran."""
    if window_s is not None:
        env, state, events, reception = sim.env, sim.state, sim.events, sim.channel.reception
        sim.link_solver = lambda: WalledLinks(env, state, events, reception, window_s=window_s)
    sim.run()
    frames = collect(sim)
    assert isinstance(sim.links, WalledLinks)
    st = sim.state
    posthoc = radio_link_lifetimes(sim.channel.reception, frames["legs"], st.range_m, duration_s)
    _assert_same_links(_announced(sim), posthoc)
    return frames["links"]


MAP_KINDS = ["unit_disk", "log_distance", "unequal_ranges", "jumps"]


def _random_map_case(seed: int, kind: str, window_s=None):
    """Random trajectories on the office map (speeds drawn per case; robots cross walls,
    which the radio does not mind), links solved during the run and after it."""
    rng = np.random.default_rng(seed)
    n = int(rng.integers(25, 50))
    speed = float(rng.uniform(0.5, 4.0))
    channel = {
        "unit_disk": {"range_m": 40.0},
        "log_distance": {"propagation": "log_distance", "sensitivity_dbm": -68.0, "wall_loss_db": 4.0},
        "unequal_ranges": {"range_m": rng.uniform(20.0, 60.0, n).tolist()},
        "jumps": {"range_m": 40.0},
    }[kind]
    sim = _map_core(n, 40.0, **channel)
    legs = random_legs(rng, n, 40.0, 200.0, speed, jump_rate=0.3 if kind == "jumps" else 0.0)
    _replay(sim, legs)
    links = _walled_runtime_vs_posthoc(sim, 40.0, window_s)
    assert len(links) > 3  # the case has links to compare
    if kind == "jumps":
        assert sim.state.jumps > 0
    return links


@pytest.mark.slow
@pytest.mark.parametrize("kind", MAP_KINDS)
def test_runtime_links_on_a_map_equal_posthoc_on_random_trajectories(kind):
    """On a map, the link events solved during the run make the post-hoc table, bit for bit
    (both solve each stretch's chunks alike)."""
    _random_map_case(7000 + MAP_KINDS.index(kind), kind)


@pytest.mark.slow
@pytest.mark.parametrize("kind", MAP_KINDS)
def test_runtime_links_on_a_map_equal_posthoc_on_many_random_trajectories(kind):
    for seed in range(6):
        _random_map_case(7100 + 4 * seed + MAP_KINDS.index(kind), kind)


@pytest.mark.slow
def test_runtime_links_on_a_map_do_not_depend_on_the_sampling_window():
    """The runtime solver solves its chunks a window at a time; the table is the same
    whatever the window (each stretch's chunks are its own)."""
    tables = [_random_map_case(7050, "unit_disk", window_s=w) for w in (0.05, 0.7, 100.0)]
    for other in tables[1:]:
        _assert_same_links(other, tables[0])


@pytest.mark.slow
@pytest.mark.parametrize(
    "overrides",
    [
        [],
        ["mobility.model=random_direction", "channel.propagation=log_distance", "channel.sensitivity_dbm=-68"],
    ],
    ids=["random_waypoint", "random_direction_log_distance"],
)
@pytest.mark.filterwarnings("ignore:.*not used by")
def test_runtime_links_on_a_map_equal_posthoc_in_runs(overrides):
    """Runs on a map: the same links table with link events during the run or after it,
    and the same receptions."""
    base = ["world.n_robots=30", "duration_s=40", "protocol.model=ack", *WALLS, *overrides]
    during = execute(load(None, [*base, "events.runtime_links=on"]), built=_fed)
    assert isinstance(during.sim.links, WalledLinks)
    after = execute(load(None, base))
    assert after.sim.links is None
    assert len(after.frames["links"]) > 20
    _assert_same_links(_announced(during.sim), after.frames["links"])
    pd.testing.assert_frame_equal(during.frames["links"], after.frames["links"])
    pd.testing.assert_frame_equal(during.frames["acks"], after.frames["acks"])


def _one_wall_map(tmp_path) -> str:
    """100 m x 100 m, 1 m cells, a wall along x in [50, 51) m from y = 0 to y = 60 m."""
    occ = np.zeros((100, 100), bool)
    occ[:60, 50] = True  # grid order: row j holds y in [j, j + 1)
    return str(save_map(tmp_path / "wall.yaml", occ, ~occ, 1.0))


@pytest.mark.parametrize("runtime_links", ["on", "auto"])
def test_a_pair_crossing_behind_a_wall_goes_down_at_the_instant(tmp_path, runtime_links):
    """Robot 0 stands at (45, 70), left of a wall that ends at y = 60; robot 1 walks down
    x = 55 from y = 80 at 1 m/s. The line between them grazes the wall's corner (51, 60)
    when robot 1 is at y = 70 - 10 / 0.6, at t = 80 / 3 s: the link goes down then (to the
    rounding of the root), announced at that instant, during the run and after it alike."""
    sim = _map_core(2, 60.0, _one_wall_map(tmp_path), 100.0, range_m=100.0)
    sim.runtime_links = runtime_links
    sim.state.place([[45.0, 70.0], [55.0, 80.0]])
    _scripted(sim, [(0.0, 1, (0.0, -1.0), None)])
    downs = []
    if runtime_links == "on":
        sim.events.on("link_down", lambda ev: downs.append((sim.now, ev)))
    sim.run()
    frames = collect(sim)
    links = frames["links"]
    assert len(links) == 1 and links["t_up_s"].tolist() == [0.0]
    assert abs(links["t_down_s"].iloc[0] - 80.0 / 3.0) <= 1e-12
    posthoc = radio_link_lifetimes(sim.channel.reception, frames["legs"], sim.state.range_m, 60.0)
    _assert_same_links(links, posthoc)
    if runtime_links == "on":
        assert len(downs) == 1 and downs[0][1].t_s == links["t_down_s"].iloc[0]
        assert downs[0][0] == pytest.approx(downs[0][1].t_s, abs=1e-9)


def test_a_pair_that_jumps_out_of_the_envelope_keeps_no_changes(tmp_path):
    """Robot 1 walks up x = 55 from y = 52, behind the wall: its line of sight to robot 0 at
    (45, 70) would clear the wall's end at t = 4 / 3 s, but it jumps 56 m away at t = 0.5 s,
    out of range: its stretch's changes, left to be solved at t = 1 s, are dropped with it
    (no link comes up), during the run as after it."""
    sim = _map_core(2, 10.0, _one_wall_map(tmp_path), 100.0, range_m=30.0)
    sim.state.place([[45.0, 70.0], [55.0, 52.0]])
    _scripted(sim, [(0.0, 1, (0.0, 1.0), None), (0.5, 1, (0.0, 0.0), (95.0, 95.0))])
    links = _walled_runtime_vs_posthoc(sim, 10.0)
    assert len(links) == 0


@pytest.mark.slow
def test_the_live_graph_on_a_map_equals_the_links_and_the_channel_at_random_instants():
    """On a map the live graph holds, at any instant, the links up in links.parquet; and away
    from the events, the pairs the channel lets through."""
    sim = build(load(None, ["world.n_robots=30", "duration_s=40", "protocol.model=none", *WALLS]))
    live = sim.live_topology()
    instants = np.sort(np.random.default_rng(8).uniform(0.0, 40.0, 40))
    seen = []

    def look():
        for t in instants.tolist():
            yield sim.env.timeout(t - sim.env.now)
            heard = set()
            for r in range(sim.state.n):
                for other in sim.channel.in_range(r)[0].tolist():
                    heard.add((min(r, other), max(r, other)))
            seen.append((sim.now, set(live.graph.edges), heard))

    sim.env.process(look())
    sim.run()
    frames = collect(sim)
    links = frames["links"]
    events = np.r_[links["t_up_s"], links["t_down_s"]]
    compared = 0
    for t, edges, heard in seen:
        up = links[(links["t_up_s"] <= t) & (t < links["t_down_s"])]
        assert edges == set(zip(up["a"].tolist(), up["b"].tolist())), t
        if np.min(np.abs(events - t)) <= 1e-6:
            continue
        compared += 1
        assert edges == heard, t
    assert compared > 30 and len(links) > 20


@pytest.mark.slow
def test_a_hook_on_link_events_runs_on_a_map_and_sees_them_in_time_order():
    """The example hook runs on a map: link events during the run, announced in time order
    at their instants, its table counts the breaks of links.parquet."""
    config = load(None, ["world.n_robots=30", "duration_s=60", *WALLS, 'events.hooks=["link_breaks"]'])
    sim = build(config)
    seen = []
    sim.events.on("link_up", lambda ev: seen.append((sim.now, ev.t_s)))
    sim.events.on("link_down", lambda ev: seen.append((sim.now, ev.t_s)))
    sim.run()
    frames = collect(sim)
    assert isinstance(sim.links, WalledLinks)
    times = [t for _, t in seen]
    assert times == sorted(times) and len(times) > 20
    assert all(now == pytest.approx(t, abs=1e-9) for now, t in seen)
    links = frames["links"]
    assert frames["link_breaks"]["breaks"].sum() == 2 * int((~links["censored_end"]).sum())


def _shadowed_static_run(runtime_links, duration_s, positions):
    """Robots at rest at ``positions`` on a 5 km square, shadowing at 6 dB (reach 631 m), no
    protocol: the sends are the test's."""
    config = make_config(
        seed=3,
        duration_s=duration_s,
        world={"n_robots": len(positions), "side_m": 5000.0},
        mobility={"model": "static"},
        channel={"propagation": "log_distance", "shadowing_sigma_db": 6.0},
        protocol={"model": "none"},
        events={"runtime_links": runtime_links},
        output={"position_interval_s": 0.0},
    )
    sim = simulation(config)
    sim.state.place(positions)
    return sim


def _shadowed_pair_run(runtime_links):
    """Two robots 40 m apart under shadowing (reach 631 m); robot 1 runs out to 640 m and
    back between t = 2 and 3.2 while nobody sends; 0 sends at t = 1 and 4, 1 at t = 5."""
    sim = _shadowed_static_run(runtime_links, 6.0, [[1000.0, 1000.0], [1040.0, 1000.0]])
    _scripted(sim, [(2.0, 1, (1000.0, 0.0), None), (2.6, 1, (-1000.0, 0.0), None), (3.2, 1, (0.0, 0.0), None)])
    got = []

    def sends():
        for t, sender in ((1.0, 0), (4.0, 0), (5.0, 1)):
            yield sim.env.timeout(t - sim.env.now)
            sim.channel.broadcast(sender, None, lambda s, rr, p: got.append((sim.env.now, s, rr.tolist())))

    sim.env.process(sends())
    return sim, got


@pytest.mark.parametrize("runtime_links", ["on", "off"])
def test_a_shadowed_link_cut_at_the_reach_comes_back_at_the_next_transmission_that_gets_through(runtime_links):
    """After the reach cuts a link the pair counts as down: the next transmission between
    the two that gets through opens a new lifetime (and announces link_up), though no
    transmission failed in between, at run time and after the run alike."""
    sim, got = _shadowed_pair_run(runtime_links)
    ups, downs = [], []
    if runtime_links == "on":
        sim.events.on("link_up", ups.append)
        sim.events.on("link_down", downs.append)
    sim.run()
    assert (sim.links is not None) == (runtime_links == "on")
    assert [(s, rr) for _, s, rr in got] == [(0, [1]), (0, [1]), (1, [0])]  # all delivered
    frames = collect(sim)
    links = frames["links"]
    exit_s = 2.0 + (sim.channel.reception.reach_m - 40.0) / 1000.0
    assert links["t_up_s"].tolist() == [1.0, 4.0]
    assert links["t_down_s"].tolist() == [pytest.approx(exit_s), 6.0]
    assert links["censored_end"].tolist() == [False, True]
    st = sim.state
    posthoc = radio_link_lifetimes(sim.channel.reception, frames["legs"], st.range_m, 6.0, st.side_m)
    _assert_same_links(links, posthoc)
    if runtime_links == "on":
        assert [e.t_s for e in ups] == [1.0, 4.0]
        assert [e.t_s for e in downs] == [links["t_down_s"][0]]


def test_a_shadowed_link_up_beyond_the_reach_by_rounding_is_cut_at_once():
    """A decision that gets through while the envelope has the pair beyond the reach (the
    range's edge, by rounding) is cut at once, keyed to the envelope's current interval: its
    lifetime ends where it begins, never at an earlier exit."""
    sim = _fed(_shadowed_pair_run("on")[0])
    recorder = sim.channel.reception.recorder

    def fake():  # robot 1 is 640 m away at t = 2.6, beyond the reach: a forged success
        yield sim.env.timeout(2.6)
        recorder.observe(sim.env.now, 0, np.array([1]), np.array([True]))

    sim.env.process(fake())
    sim.run()
    frames = collect(sim)
    links = frames["links"]
    assert (links["t_up_s"] <= links["t_down_s"]).all()
    assert links["t_up_s"].tolist() == [1.0, 2.6, 4.0]
    assert links["t_down_s"].tolist()[1] == 2.6
    st = sim.state
    _assert_same_links(
        _announced(sim), radio_link_lifetimes(sim.channel.reception, frames["legs"], st.range_m, 6.0, st.side_m)
    )


def _rule_lifetimes(decisions, env: pd.DataFrame, n: int, duration_s: float) -> set:
    """links.parquet's rule under shadowing from every decision, by brute force: a link is up
    from a decision that gets through while it is down, to the first that does not or the
    exit of the reach interval it came up in (an exit before the decisions at its instant);
    beyond the reach by the envelope's account, it is cut at once."""
    spans: dict = {}
    for a, b, u, d in zip(env["a"], env["b"], env["t_up_s"], env["t_down_s"]):
        spans.setdefault((a, b), []).append((u, d))
    current: dict = {}  # pair -> (since, cut at)
    rows = set()
    for t, sender, receivers, linked in decisions:
        heard = set(receivers[linked].tolist())
        for r in range(n):
            if r == sender:
                continue
            key = (min(sender, r), max(sender, r))
            mine = current.get(key)
            if mine is not None and mine[1] <= t:
                rows.add((*key, mine[0], mine[1]))
                del current[key]
                mine = None
            if r in heard and mine is None:
                before = [s for s in spans.get(key, []) if s[0] <= t]
                cut = np.inf if not before else max(before[-1][1], t)
                if cut == t:
                    rows.add((*key, t, t))
                else:
                    current[key] = (t, cut)
            elif r not in heard and mine is not None:
                rows.add((*key, mine[0], t))
                del current[key]
    for key, (since, cut) in current.items():
        rows.add((*key, since, min(cut, duration_s)))
    return rows


def _random_shadowed_run(seed: int, torus: bool):
    """Robots in a cluster under shadowing (reach 631 m) making random excursions beyond the
    reach and back, sending at random instants: links cut at the reach and coming back."""
    rng = np.random.default_rng(seed)
    n, duration_s, side_m = 6, 20.0, 2000.0
    config = make_config(
        seed=seed,
        duration_s=duration_s,
        world={"n_robots": n, "side_m": side_m, "torus": torus},
        mobility={"model": "static"},
        channel={"propagation": "log_distance", "shadowing_sigma_db": 6.0},
        protocol={"model": "none"},
        events={"runtime_links": "on"},
        output={"position_interval_s": 0.0},
    )
    sim = _fed(simulation(config))
    sim.state.place(1000.0 + rng.uniform(-100.0, 100.0, (n, 2)))
    moves = []
    for r in range(n):
        t = rng.uniform(0.0, 3.0)
        while t < duration_s - 2.0:
            heading = rng.uniform(0.0, 2.0 * np.pi)
            speed, out_s = rng.uniform(300.0, 800.0), rng.uniform(0.5, 1.5)
            v = speed * np.array([np.cos(heading), np.sin(heading)])
            moves += [(t, r, tuple(v), None), (t + out_s, r, tuple(-v), None), (t + 2.0 * out_s, r, (0.0, 0.0), None)]
            t += 2.0 * out_s + rng.uniform(0.2, 3.0)
    moves.sort(key=lambda m: m[0])
    _scripted(sim, moves)
    sends = sorted(zip(rng.uniform(0.0, duration_s, 8 * n).tolist(), rng.integers(0, n, 8 * n).tolist()))

    def send():
        for t, sender in sends:
            yield sim.env.timeout(t - sim.env.now)
            sim.channel.broadcast(sender, None, lambda *_: None)

    sim.env.process(send())
    decisions = []
    recorder = sim.channel.reception.recorder
    observe = recorder.observe

    def logged(t, sender, receivers, linked):
        decisions.append((t, sender, receivers.copy(), linked.copy()))
        observe(t, sender, receivers, linked)

    recorder.observe = logged
    return sim, decisions


@pytest.mark.slow
@pytest.mark.parametrize("torus", [False, True], ids=["plane", "torus"])
def test_shadowed_links_follow_the_rule_at_run_time_and_after_on_random_excursions(torus):
    """On random runs whose links leave the reach and come back between transmissions: every
    lifetime has t_up_s <= t_down_s, the run-time table equals the post-hoc one bit for bit,
    and both equal the rule applied by brute force to every decision the channel made."""
    reopened = 0
    for seed in range(6):
        sim, decisions = _random_shadowed_run(seed, torus)
        sim.run()
        frames = collect(sim)
        st, reception = sim.state, sim.channel.reception
        links = frames["links"]
        assert (links["t_up_s"] <= links["t_down_s"]).all()
        posthoc = radio_link_lifetimes(reception, frames["legs"], st.range_m, 20.0, st.side_m, st.torus)
        _assert_same_links(_announced(sim), posthoc)
        env = link_lifetimes(frames["legs"], np.full(st.n, reception.reach_m), 20.0, st.side_m, st.torus)
        rule = _rule_lifetimes(decisions, env, st.n, 20.0)
        assert set(zip(links["a"], links["b"], links["t_up_s"], links["t_down_s"])) == rule
        assert len(rule) == len(links)
        decided = reception.recorder.intervals(20.0)
        opened = links.merge(decided[["a", "b", "t_up_s"]], how="left", indicator=True)
        reopened += int((opened["_merge"] == "left_only").sum())
    assert reopened >= 5  # lifetimes opened after a cut at the reach, not by a change of decision


@pytest.mark.parametrize("runtime_links", ["on", "off"])
def test_a_unicast_under_shadowing_decides_its_own_link_alone(runtime_links):
    """A unicast's decision covers the sender's link with its destination only: robot 0's
    unicast to 1 leaves its link with 2 up (a broadcast, which decides every pair within
    reach, would have taken it down had 2 not heard it)."""
    sim = _shadowed_static_run(runtime_links, 4.0, [[1000.0, 1000.0], [1001.0, 1000.0], [1000.0, 1001.0]])
    got = []

    def sends():
        yield sim.env.timeout(1.0)
        sim.channel.broadcast(0, None, lambda s, rr, p: got.append(rr.tolist()))
        yield sim.env.timeout(1.0)
        assert sim.channel.unicast(0, 1, None, lambda s, rr, p: got.append(rr.tolist()))
        yield sim.env.timeout(1.0)
        sim.channel.broadcast(0, None, lambda s, rr, p: got.append(rr.tolist()))

    sim.env.process(sends())
    sim.run()
    assert got == [[1, 2], [1], [1, 2]]
    links = collect(sim)["links"]
    rows = sorted(zip(links["a"], links["b"], links["t_up_s"], links["t_down_s"]))
    assert rows == [(0, 1, 1.0, 4.0), (0, 2, 1.0, 4.0)]


def test_snapshot_nodes_carry_role_and_leader_only_with_groups():
    """`snapshot(state, t)` gives nodes with `pos` only; `snapshot(state, t, groups=sim.groups)`
    adds each robot's `role` label and `leader`, the protocol's current values."""
    sim = build(load(None, ["world.n_robots=12", "duration_s=10", "world.side_m=200", "channel.range_m=80"]))
    sim.run()
    bare = snapshot(sim.state, sim.now)
    assert all(set(attrs) == {"pos"} for _, attrs in bare.nodes(data=True))
    full = snapshot(sim.state, sim.now, groups=sim.groups)
    for i, attrs in full.nodes(data=True):
        assert set(attrs) == {"pos", "role", "leader"}
        assert attrs["role"] == sim.groups.role_names[sim.groups.role[i]] and attrs["leader"] == sim.groups.leader[i]
    assert {attrs["role"] for _, attrs in full.nodes(data=True)} & {"alpha", "beta"}


def test_a_snapshot_of_an_instant_the_state_no_longer_holds_is_refused():
    """After the run, a robot's current leg began after 5 s: a snapshot at 5 s would place
    it on that leg carried backwards (wrong by tens of metres), so it is refused; at the
    run's present it is the positions table's last sample."""
    keys = ["world.n_robots=30", "duration_s=60", "world.side_m=500", "mobility.speed_max_mps=10"]
    sim = build(load(None, [*keys, "output.position_interval_s=5"]))
    sim.run()
    assert sim.state.t0_s.max() > 5.0
    with pytest.raises(ValueError, match=r"snapshot at t = 5 s: a robot's current leg began at"):
        snapshot(sim.state, 5.0)
    p = collect(sim)["positions"]
    last = p[p.t_s == p.t_s.max()].sort_values("robot")[["x_m", "y_m"]].to_numpy()
    g = snapshot(sim.state, sim.now)
    assert np.allclose([g.nodes[i]["pos"] for i in range(30)], last, atol=1e-9)


KEYS_15 = ["world.n_robots=15", "world.side_m=300", "world.placement='centre'", "world.centre_side_m=60"]
KEYS_15 += ["channel.range_m=40", "protocol.message_rate_hz=0", "duration_s=60"]


def test_a_run_a_subscriber_raised_in_cannot_go_on():
    """The event it interrupted was made in part (the other subscribers and the rest of the
    instant never saw it): going on would stop early and lose events silently, so a later
    run refuses in one line; collect still gives the tables."""
    from netsim.cosim import CommandError

    sim = build(load(None, KEYS_15))
    downs = []

    def on_down(ev):
        downs.append(ev)
        if len(downs) == 1:
            raise RuntimeError("a bug in my callback")

    sim.events.on("link_down", on_down)
    with pytest.raises(RuntimeError, match="a bug in my callback"):
        sim.run(until_s=20)
    stopped = sim.now
    with pytest.raises(CommandError, match=r"the run cannot go on: RuntimeError was raised inside it at t = "):
        sim.run(until_s=60)
    assert sim.now == stopped
    assert len(collect(sim)["links"]) > 0


def test_a_subscriber_that_unsubscribes_while_called_makes_no_other_miss_the_event():
    sim = build(load(None, KEYS_15))
    got_a, got_b = [], []

    def a(ev):
        got_a.append(ev)
        sim.events.off("course_change", a)

    sim.events.on("course_change", a)
    sim.events.on("course_change", got_b.append)
    sim.run(until_s=5)
    assert len(got_a) == 1 and got_b[0] == got_a[0]


def test_unsubscribing_what_is_not_subscribed_is_one_clear_error():
    sim = build(load(None, KEYS_15))
    with pytest.raises(ValueError, match="unknown event 'linkdown'"):
        sim.events.off("linkdown", print)
    with pytest.raises(ValueError, match="is not subscribed to 'link_down'"):
        sim.events.off("link_down", print)


def test_a_run_with_progress_to_now_does_nothing_and_the_run_goes_on():
    """Advancing to now in reported parts, as in one call, is allowed and moves nothing."""
    sim = build(load(None, KEYS_15))
    sim.run(until_s=4)
    sim.run(until_s=4, progress=True, steps=3)
    assert sim.now == 4
    sim.run(until_s=10)
    assert sim.now == 10


def test_a_run_with_progress_advances_in_equal_parts_each_reported():
    """``steps`` parts of equal length, from now to ``until_s``, the last ending exactly there."""
    sim = build(load(None, KEYS_15))
    sim.run(until_s=2)
    ends = []
    run = sim.env.run
    sim.env.run = lambda until: (ends.append(until), run(until=until))[1]
    sim.run(until_s=10, progress=True, steps=4)
    assert ends == [4.0, 6.0, 8.0, 10]


def test_the_models_of_a_run_cannot_be_changed_through_it():
    """``sim.models`` is read-only: components get their collaborators when built."""
    sim = build(load(None, KEYS_15))
    assert "protocol" in sim.models
    with pytest.raises(TypeError):
        sim.models["protocol"] = None


def test_a_live_topology_asked_for_after_the_run_started_is_refused_even_with_runtime_links_on():
    """It is built from the link events as they come: begun late it would lack every link
    already up (and give the summary wrong averages)."""
    sim = build(load(None, [*KEYS_15, "events.runtime_links='on'"]))
    sim.run(until_s=2)
    with pytest.raises(RuntimeError, match="the live topology must be asked for before the run starts"):
        sim.live_topology()


@pytest.mark.parametrize("steps", [0, -5, 2.5, True])
def test_run_with_progress_refuses_steps_below_one(steps):
    from netsim.cosim import CommandError

    sim = build(load(None, KEYS_15))
    with pytest.raises(CommandError, match="steps = "):
        sim.run(until_s=10, progress=True, steps=steps)
    sim.run(until_s=10)  # a refused call leaves the run able to go on
    assert sim.now == 10


@pytest.mark.parametrize(
    "subscription, fragment",
    [
        ('parts.events.on("link_dwn", print)', "unknown event 'link_dwn'; events are"),
        ('parts.events.on("link_down", "not a function")', "must be callable, not str"),
    ],
)
def test_cli_a_hook_that_subscribes_wrongly_is_one_line_naming_it(
    tmp_path, monkeypatch, capsys, subscription, fragment
):
    """A hook subscribing to an event that does not exist, or subscribing what cannot be
    called, is refused as the run is built: one line naming its key, exit 2, nothing
    written (it was a traceback)."""
    from netsim.tools.cli import main

    module = f"typo_hook_{len(fragment)}"  # one module a case: imports are cached
    (tmp_path / f"{module}.py").write_text(
        "from netsim.params import Params\n"
        "from netsim.plugins import PluginSpec\n"
        "def build(params, parts):\n"
        f"    {subscription}\n"
        "TYPO = PluginSpec(Params=Params, build=build)\n"
    )
    monkeypatch.syspath_prepend(str(tmp_path))
    out = tmp_path / "out"
    hooks = f'events.hooks=["{module}:TYPO"]'
    code = main(["run", "--quiet", "--out", str(out), "--set", "duration_s=5", "--set", hooks])
    lines = capsys.readouterr().err.strip().splitlines()
    assert code == 2, lines
    assert len(lines) == 1 and lines[0].startswith(f"netsim: error: events.hooks[0] = '{module}:TYPO': ")
    assert fragment in lines[0]
    assert not out.exists()


def test_a_mobility_model_that_subscribes_wrongly_is_named_by_its_key_and_value(tmp_path, monkeypatch):
    """The refusal names the model's key and the model given (it named the value 'mobility')."""
    from netsim.errors import ConfigError
    from netsim.run import build

    (tmp_path / "typo_mobility.py").write_text(
        "from netsim.params import Params\n"
        "from netsim.plugins import PluginSpec\n"
        "def build(params, parts):\n"
        "    parts.state.place([[1.0, 1.0]] * parts.state.n)\n"
        "    parts.events.on('link_dwn', print)\n"
        "STILL = PluginSpec(Params=Params, build=build, moves_robots=False)\n"
    )
    monkeypatch.syspath_prepend(str(tmp_path))
    config = load(None, ["mobility.model=typo_mobility:STILL", "world.n_robots=3", "duration_s=5"])
    with pytest.raises(ConfigError, match=r"^mobility.model = 'typo_mobility:STILL': subscribes wrongly: unknown"):
        build(config)


@pytest.mark.parametrize("pause_s", [0.0, 1.0])
def test_random_direction_on_a_map_gives_its_legs_its_own_causes(pause_s):
    """On a map a random-direction robot heads for a wall as for the border: its legs are
    `start`, `border` and `pause_end` (docs/events.md), never `command` (the control loop's)
    or `waypoint`."""
    config = load(
        None,
        [
            "mobility.model=random_direction",
            f"mobility.pause_s={pause_s}",
            "world.map=cave",
            "world.side_m=200",
            "world.n_robots=6",
            "duration_s=60",
            "protocol.model=none",
        ],
    )
    legs = execute(config).frames["legs"]
    causes = set(legs["cause"].astype(str))
    expected = {"start", "border", "pause_end"} if pause_s else {"start", "border"}
    assert causes == expected


def test_a_run_called_from_a_subscriber_is_refused():
    """The event being made would be finished after the later ones the inner run made (a
    run that ended without a word, its beliefs and groups not the run's): refused, and the
    run, stopped inside an event, cannot go on."""
    from netsim.cosim import CommandError

    sim = build(load(None, KEYS_15))

    def runs_on(ev):
        sim.run(until_s=ev.t_s + 1.0)

    sim.events.on("link_down", runs_on)
    with pytest.raises(CommandError, match=r"run was called while the run is going on \(from a subscriber\?\)"):
        sim.run()
    with pytest.raises(CommandError, match="the run cannot go on: CommandError was raised inside it"):
        sim.run()


def test_ctrl_c_inside_a_compiled_loop_is_raised_as_a_keyboard_interrupt():
    """numba's dispatcher turns a KeyboardInterrupt raised inside a compiled call into
    ``SystemError: ... returned a result with an exception set``: ``except
    KeyboardInterrupt`` around ``sim.run`` missed Ctrl-C."""
    from netsim.cosim import CommandError

    sim = build(load(None, KEYS_15))

    def pressed(ev):
        try:
            raise KeyboardInterrupt
        except KeyboardInterrupt:
            raise SystemError("CPUDispatcher(<function step>) returned a result with an exception set") from None

    sim.events.on("link_down", pressed)
    with pytest.raises(KeyboardInterrupt):
        sim.run()
    with pytest.raises(CommandError, match="the run cannot go on: KeyboardInterrupt was raised inside it"):
        sim.run()


def test_a_run_with_progress_after_a_part_ends_at_the_runs_end_exactly():
    """Its last part ended at ``start + (end - start) * k / k``, which rounds: a run of
    0.3 s went on from 0.1 s to 0.30000000000000004 s, past its end."""
    for duration_s, part_s in ((0.3, 0.1), (7.7, 1.3)):
        keys = [*KEYS_15, f"duration_s={duration_s}"]
        sim = build(load(None, keys))
        sim.run(until_s=part_s)
        sim.run(progress=True)
        assert sim.now == duration_s
        whole = build(load(None, keys))
        whole.run()
        for name, frame in collect(whole).items():
            pd.testing.assert_frame_equal(collect(sim)[name], frame, obj=name)


@pytest.mark.parametrize("event", ["delivery", "drop"])
def test_a_subscriber_cannot_write_the_receivers_it_is_handed(event):
    """A delivery's (a drop's) receivers were the channel's own array: a subscriber that
    wrote into it changed who received the frame (roles, groups and messages changed, or
    a KeyError later)."""
    sim = build(load(None, [*KEYS_15, "channel.loss_probability=0.3"]))
    seen = []

    def writes(ev):
        seen.append(len(ev.receivers))
        ev.receivers[:] = 0

    sim.events.on(event, writes)
    with pytest.raises(ValueError, match="read-only"):
        sim.run()
    assert seen


def test_runtime_links_start_a_new_window_when_a_robot_outruns_its_speed_bound():
    """A window is solved for the speeds of its start: a robot that speeds up past that
    bound (here to 1.9 m/s, under twice the window's 1 m/s) may meet another before the
    window ends, so the window must be solved again. Two robots 140 m apart (range 50 m)
    set off towards each other at t = 1 s: the feed announces their link as the table
    has it."""
    legs = pd.DataFrame(
        [
            (0.0, 0, 0.0, 0.0, 0.0, 0.0),
            (0.0, 1, 140.0, 0.0, 0.0, 0.0),
            (0.0, 2, 1000.0, 1000.0, 1.0, 0.0),  # the window's speed: 1 m/s
            (1.0, 0, 0.0, 0.0, 1.9, 0.0),
            (1.0, 1, 140.0, 0.0, -1.9, 0.0),
        ],
        columns=["t_s", "robot", "x_m", "y_m", "vx_mps", "vy_mps"],
    )
    sim = _fed(_core(3, [50.0, 50.0, 50.0], 60.0, runtime_links="on"))
    _replay(sim, legs)
    sim.run()
    posthoc = collect(sim)["links"]
    assert len(posthoc) == 1 and posthoc["t_up_s"].iloc[0] == pytest.approx(1.0 + 90.0 / 3.8)
    _assert_same_links(_announced(sim), posthoc)


# -- rules a mutation audit found no test for ------------------------------------------------
def test_the_live_levels_over_no_time_are_not_a_number():
    """Asked at t = 0, the time averages have no time to average over: NaN, not a division
    by zero."""
    sim = build(load(None, ["world.n_robots=4", "duration_s=10"]))
    levels = sim.live_topology().levels(0.0)
    assert set(levels) == {"time_mean_components", "time_mean_largest_component", "time_mean_degree"}
    assert all(math.isnan(v) for v in levels.values())


def test_a_live_nodes_computed_attribute_cannot_be_set():
    sim = build(load(None, ["world.n_robots=4", "duration_s=10"]))
    node = sim.live_topology().graph.nodes[0]
    for key in ("pos", "role", "leader"):
        with pytest.raises(KeyError, match=f"node attribute '{key}' is computed from the run; it cannot be set"):
            node[key] = 1
    node["mine"] = 1
    assert node["mine"] == 1
