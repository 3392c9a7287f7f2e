"""Links: unit disk, exact up/down times, censoring, link durations (docs/validation.md 5-7)."""

import math

import numpy as np
import pandas as pd
import pytest

from netsim.links.lifetimes import jump_times, link_lifetimes
from netsim.run import build, collect
from netsim.state import RobotState
from netsim.tools.validate import brute_force_mismatches, random_legs
from netsim.topology import geometric_edges, snapshot
from netsim.trajectory import LegTable
from tests.fixtures import make_config


def _legs(rows):
    return pd.DataFrame(rows, columns=["t_s", "robot", "x_m", "y_m", "vx_mps", "vy_mps"])


def test_unit_disk_adjacent_iff_within_range(rng):
    """Item 5: robots are neighbours if and only if their distance is at most R."""
    pos = rng.uniform(0, 100, (300, 2))
    st = RobotState(300, 100.0, 12.0)
    st.place(pos)
    g = snapshot(st, 0.0)
    for i in range(300):
        for j in range(i + 1, 300):
            d = math.dist(pos[i], pos[j])
            assert g.has_edge(i, j) == (d <= 12.0)
            if d <= 12.0:
                assert g.edges[i, j]["distance"] == pytest.approx(d)


def test_unit_disk_on_a_torus_uses_the_shortest_image():
    edges = geometric_edges(np.array([[1.0, 50.0], [99.0, 50.0]]), 5.0, side_m=100.0)
    assert edges == [(0, 1, pytest.approx(2.0))]
    assert geometric_edges(np.array([[1.0, 50.0], [99.0, 50.0]]), 5.0) == []


def test_a_snapshot_of_a_runs_links_on_a_torus_measures_them_by_the_shortest_image():
    """Given the run's links, a snapshot on a torus weighs each link by its shortest image,
    as the unit disk's snapshot does: the same edges with the same distances, some of them
    across the torus's edge."""
    sim = build(
        make_config(
            duration_s=20.0,
            world={"n_robots": 30, "side_m": 300.0, "torus": True},
            mobility={"model": "random_direction"},
            channel={"range_m": 80.0},
            protocol={"model": "none"},
        )
    )
    links = sim.link_events()
    sim.run()
    given = snapshot(sim.state, sim.now, links=links)
    disk = snapshot(sim.state, sim.now)
    assert set(map(frozenset, given.edges)) == set(map(frozenset, disk.edges))
    pos = sim.state.positions_at(sim.now)
    across = 0
    for a, b, d in given.edges(data="distance"):
        assert d == disk.edges[a, b]["distance"]
        across += bool(np.hypot(*(pos[a] - pos[b])) > 80.0)
    assert across > 0


def test_a_snapshot_with_the_runs_links_is_refused_at_another_instant():
    """The links a solver gives are those up now: a snapshot of them at another instant
    would draw the positions of one time with the links of another (edges longer than the
    range), so it is refused; without links the unit disk is drawn at any later t."""
    sim = build(
        make_config(
            duration_s=30.0,
            world={"n_robots": 40, "side_m": 600.0},
            channel={"range_m": 150.0},
            protocol={"model": "none"},
        )
    )
    links = sim.link_events()
    sim.run(until_s=20.0)
    with pytest.raises(ValueError, match=r"snapshot at t = 45 s with links: they are the links up now, at t = 20 s"):
        snapshot(sim.state, sim.now + 25.0, links=links)
    assert snapshot(sim.state, sim.now, links=links).number_of_edges() > 0
    assert snapshot(sim.state, sim.now + 25.0).number_of_nodes() == 40


def test_unequal_ranges_make_one_way_links():
    """i reaches j when d <= r_i; the undirected graph keeps only two-way links."""
    pos = np.array([[0.0, 0.0], [10.0, 0.0]])
    assert geometric_edges(pos, [15.0, 5.0], directed=True) == [(0, 1, 10.0)]
    assert geometric_edges(pos, [15.0, 5.0]) == []


def test_a_directed_snapshot_has_an_edge_to_every_robot_within_the_senders_range():
    """``snapshot(..., directed=True)`` is a DiGraph with i -> j when j is within i's range:
    a one-way link appears once, in its direction, which the undirected snapshot leaves out."""
    st = RobotState(3, 200.0, [15.0, 5.0, 5.0])
    st.place(np.array([[0.0, 0.0], [10.0, 0.0], [100.0, 0.0]]))
    g = snapshot(st, 0.0, directed=True)
    assert g.is_directed()
    assert list(g.edges(data="distance")) == [(0, 1, 10.0)]
    assert snapshot(st, 0.0).number_of_edges() == 0


def test_a_directed_snapshot_of_the_runs_links_holds_each_link_both_ways():
    """The links of a solver are two-way: the directed snapshot given them has both i -> j
    and j -> i for each, at the undirected snapshot's distance."""
    sim = build(
        make_config(
            duration_s=5.0,
            world={"n_robots": 12, "side_m": 200.0},
            channel={"range_m": 80.0},
            protocol={"model": "none"},
        )
    )
    links = sim.link_events()
    sim.run()
    both = snapshot(sim.state, sim.now, directed=True, links=links)
    one = snapshot(sim.state, sim.now, links=links)
    assert both.is_directed() and one.number_of_edges() > 0
    want = {(a, b, d) for a, b, d in one.edges(data="distance")}
    want |= {(b, a, d) for a, b, d in want}
    assert set(both.edges(data="distance")) == want


def test_link_times_are_exact_for_crossing_robots():
    """Item 7: a link comes up and down at the roots of |dp + dv t| = R, to 1e-9 s."""
    # Robot 1 passes robot 0 at impact parameter 3 with speed 2: in range for |x| <= 4.
    legs = _legs([(0.0, 0, 0.0, 0.0, 0.0, 0.0), (0.0, 1, -20.0, 3.0, 2.0, 0.0)])
    links = link_lifetimes(legs, 5.0, 40.0)
    assert len(links) == 1
    row = links.iloc[0]
    assert row.t_up_s == pytest.approx((20 - 4) / 2, abs=1e-9)
    assert row.t_down_s == pytest.approx((20 + 4) / 2, abs=1e-9)
    assert not row.censored


def test_link_times_exact_across_course_changes():
    """Item 7: times stay exact when a robot changes course inside the range."""
    legs = _legs(
        [
            (0.0, 0, 0.0, 0.0, 0.0, 0.0),
            (0.0, 1, -10.0, 0.0, 1.0, 0.0),  # reaches x = -5 at t = 5: link up
            (7.0, 1, -3.0, 0.0, 0.0, 1.0),  # turns north at (-3, 0); leaves when y = 4 at t = 11
        ]
    )
    links = link_lifetimes(legs, 5.0, 30.0)
    assert list(links.t_up_s) == [pytest.approx(5.0, abs=1e-9)]
    assert list(links.t_down_s) == [pytest.approx(11.0, abs=1e-9)]


@pytest.mark.parametrize("seed", [1, 2])
@pytest.mark.slow
def test_link_times_independent_of_window_and_match_brute_force(seed):
    """Item 7: random trajectories; every event agrees with a dense brute-force check,
    and every computed up/down time has its pair at distance R to 1e-6 m."""
    cfg = make_config(
        seed=seed,
        duration_s=120.0,
        world={"n_robots": 30, "side_m": 200.0},
        channel={"range_m": 40.0},
        mobility={"speed_min_mps": 1.0, "speed_max_mps": 8.0, "pause_s": 1.0},
        protocol={"model": "none"},
    )
    sim = build(cfg)
    sim.run()
    legs = sim.state.legs()
    links = link_lifetimes(legs, 40.0, 120.0)
    for window_s in (0.37, 20.0):  # the default is 0.5 R / v_max = 2.5 s
        other = link_lifetimes(legs, 40.0, 120.0, window_s=window_s)
        assert other[["a", "b"]].equals(links[["a", "b"]])
        assert np.abs(other[["t_up_s", "t_down_s"]].to_numpy() - links[["t_up_s", "t_down_s"]].to_numpy()).max() < 1e-9
    from netsim.trajectory import sample_positions

    # Every uncensored up or down time, in time order: the positions at all of them in one pass.
    events = sorted(
        (t, row.a, row.b)
        for row in links.itertuples()
        for t, censored in ((row.t_up_s, row.censored_start), (row.t_down_s, row.censored_end))
        if not censored
    )
    at = sample_positions(legs, 30, [t for t, _, _ in events])[["x_m", "y_m"]].to_numpy().reshape(len(events), 30, 2)
    for (_, a, b), p in zip(events, at):
        assert math.dist(p[a], p[b]) == pytest.approx(40.0, abs=1e-6)
    # Brute force at many instants: linked iff some lifetime covers the instant.
    times = np.linspace(0.05, 119.95, 397)
    pos = sample_positions(legs, 30, times)[["x_m", "y_m"]].to_numpy().reshape(len(times), 30, 2)
    a_, b_, up, down = (links[c].to_numpy() for c in ("a", "b", "t_up_s", "t_down_s"))
    for k, t in enumerate(times):
        d = np.hypot(*(pos[k][:, None, :] - pos[k][None, :, :]).transpose(2, 0, 1))
        truth = {(a, b) for a in range(30) for b in range(a + 1, 30) if d[a, b] <= 40.0}
        live = (up <= t) & (down > t)
        assert set(zip(a_[live].tolist(), b_[live].tolist())) == truth


def test_censoring_flags():
    """Links up at the start or the end are censored and flagged as such."""
    legs = _legs(
        [
            (0.0, 0, 0.0, 0.0, 0.0, 0.0),
            (0.0, 1, 1.0, 0.0, 1.0, 0.0),  # in range at t = 0, leaves at t = 4
            (0.0, 2, -10.0, 0.0, 0.0, 0.0),  # static, out of range of 0 ...
            (6.0, 2, -10.0, 0.0, 1.0, 0.0),  # ... until it moves in at t = 11 and stays
        ]
    )
    links = link_lifetimes(legs, 5.0, 20.0).set_index(["a", "b"])
    start = links.loc[(0, 1)]
    assert (start.t_up_s, start.t_down_s) == (0.0, pytest.approx(4.0))
    assert start.censored and start.censored_start and not start.censored_end
    end = links.loc[(0, 2)]
    assert end.t_up_s == pytest.approx(11.0) and end.t_down_s == 20.0
    assert end.censored and end.censored_end and not end.censored_start


@pytest.mark.slow
def test_link_duration_on_torus_matches_closed_form():
    """Item 6: constant equal speeds v, uniform headings, torus: E[T] = pi^2 R / (8 v).

    Links born in the first half of a run ten times longer than E[T]^2-tail matters are
    averaged (censoring beyond the run end is rare: P(T > 500 s) ~ 1e-3).
    """
    R, v, T = 10.0, 1.0, 1000.0
    cfg = make_config(
        seed=11,
        duration_s=T,
        world={"n_robots": 200, "side_m": 200.0, "torus": True},
        channel={"range_m": R},
        mobility={"model": "random_direction", "speed_min_mps": v, "speed_max_mps": v},
        protocol={"model": "none"},
        output={"position_interval_s": 0.0},
    )
    sim = build(cfg)
    sim.run()
    links = collect(sim)["links"]
    born = links[(links.t_up_s > 0) & (links.t_up_s < T / 2)]
    assert born.censored_end.mean() < 0.01
    dur = (born.t_down_s - born.t_up_s).to_numpy()
    theory = math.pi**2 * R / (8 * v)
    assert len(dur) > 3000
    # The duration has a heavy (log-divergent variance) tail: allow 5 %.
    assert dur.mean() == pytest.approx(theory, rel=0.05)


# -- jumps: a robot placed somewhere else at T (a trace's "set X_", any model's start_m) ----
def test_jump_into_range_opens_the_link_at_the_jump_instant():
    legs = _legs(
        [
            (0.0, 0, 0.0, 0.0, 0.0, 0.0),
            (0.0, 1, 50.0, 0.0, 0.0, 0.0),
            (5.0, 1, 3.0, 0.0, 0.0, 0.0),  # jumps into range at 5 ...
            (12.0, 1, 100.0, 0.0, 0.0, 0.0),  # ... and out again at 12
        ]
    )
    links = link_lifetimes(legs, 5.0, 20.0)
    assert links[["a", "b", "t_up_s", "t_down_s"]].values.tolist() == [[0, 1, 5.0, 12.0]]
    assert not links.censored.any()


def test_jump_apart_closes_the_link_at_the_jump_instant():
    legs = _legs(
        [
            (0.0, 0, 0.0, 0.0, 0.0, 0.0),
            (0.0, 1, 1.0, 0.0, 0.5, 0.0),  # in range, drifting: leaves by motion at t = 8
            (7.0, 1, 40.0, 0.0, -1.0, 0.0),  # jumps away at 7; drives back in range at 42
        ]
    )
    links = link_lifetimes(legs, 5.0, 50.0)
    assert links[["t_up_s", "t_down_s"]].values.tolist() == [[0.0, 7.0], [pytest.approx(42.0), 50.0]]
    assert links.censored_start.tolist() == [True, False] and links.censored_end.tolist() == [False, True]


def test_jump_within_range_and_simultaneous_jumps():
    """A jump from in range to in range changes nothing; two robots that jump at the same
    instant are judged on both new positions."""
    legs = _legs(
        [
            (0.0, 0, 0.0, 0.0, 0.0, 0.0),
            (0.0, 1, 2.0, 0.0, 0.0, 0.0),
            (3.0, 1, 0.0, 4.0, 0.0, 0.0),  # still in range: the lifetime goes on
            (6.0, 0, 100.0, 0.0, 0.0, 0.0),  # both jump at 6, together: still linked
            (6.0, 1, 103.0, 0.0, 0.0, 0.0),
            (9.0, 0, 200.0, 0.0, 0.0, 0.0),  # both jump at 9, apart
            (9.0, 1, 300.0, 0.0, 0.0, 0.0),
        ]
    )
    links = link_lifetimes(legs, 5.0, 20.0)
    assert links[["t_up_s", "t_down_s"]].values.tolist() == [[0.0, 9.0]]


def test_a_jump_is_one_rule_for_the_link_solver_and_the_writers():
    """The link solver (``jump_times``) and the writers of movement files
    (``LegTable.ends``) call the same placements jumps: a micrometre at 50 m is one, for
    both; the rounding of a leg's end is none; on a torus a move by a whole side is none
    for the links (the writers see folded legs, where the border's jump is written)."""
    legs = _legs(
        [
            (0.0, 0, 50.0, 0.0, 0.0, 0.0),
            (2.0, 0, 50.0 + 1e-6, 0.0, 0.0, 0.0),  # put a micrometre away
            (4.0, 0, 50.0 + 1e-6 + 1e-14, 0.0, 0.0, 0.0),  # the rounding of a leg's end
            (6.0, 0, 50.0 + 1e-6 + 100.0, 0.0, 0.0, 0.0),  # a whole side of a 100 m torus
        ]
    )
    table = LegTable(legs, 1)
    t, _ = jump_times(table)
    _, _, written = table.ends(10.0)
    assert t.tolist() == [2.0, 6.0] and table.t[1:][written[:-1]].tolist() == [2.0, 6.0]
    t_torus, _ = jump_times(table, 100.0)
    assert t_torus.tolist() == [2.0]


def test_a_logged_jump_however_short_is_one_for_the_links():
    """A robot put 1.1e-7 m across the range's edge (a trace's ``set X_``, logged as a
    jump) takes its link down at that instant, as the run's radio did: shorter than the
    rounding a distance can tell from a leg's end, it is a jump by its cause."""
    rows = [(0.0, 0, 0.0, 0.0, 0.0, 0.0, "start"), (0.0, 1, 149.99999999, 0.0, 0.0, 0.0, "start")]
    jump = (5.0, 1, 150.0000001, 0.0, 0.0, 0.0, "jump")
    legs = pd.DataFrame([*rows, jump], columns=["t_s", "robot", "x_m", "y_m", "vx_mps", "vy_mps", "cause"])
    links = link_lifetimes(legs, 150.0, 10.0)
    assert links[["t_up_s", "t_down_s"]].values.tolist() == [[0.0, 5.0]]
    table = LegTable(legs, 2)
    assert table.jumps().tolist() == [False, False, True] and table.ends(10.0)[2].tolist() == [False, True, False]


def test_trace_jump_opens_and_closes_links_in_links_parquet(tmp_path):
    """ns-2 ``set X_`` at T: the link appears in the run's links table from T exactly."""
    f = tmp_path / "jump.tcl"
    f.write_text(
        "$node_(0) set X_ 10.0\n$node_(0) set Y_ 10.0\n$node_(1) set X_ 90.0\n$node_(1) set Y_ 10.0\n"
        '$ns_ at 4.25 "$node_(1) set X_ 15.0"\n$ns_ at 9.5 "$node_(1) set Y_ 80.0"\n'
    )
    cfg = make_config(
        duration_s=15.0,
        world={"n_robots": 2, "side_m": 100.0},
        mobility={"model": "trace", "trace_file": str(f)},
        channel={"range_m": 20.0},
        protocol={"model": "ack", "ack_jitter_s": 0.0},
    )
    sim = build(cfg)
    sim.run()
    frames = collect(sim)
    assert frames["links"][["t_up_s", "t_down_s"]].values.tolist() == [[4.25, 9.5]]
    assert (frames["acks"].received > 0).all()


# -- small tori: another image of a robot can come into range within a piece ----------------
def test_small_torus_every_image_counts():
    """250 m torus, r = 100 m: a robot 60 m away moving away at 10 m/s leaves at 4 s, comes
    back in range round the torus at 9 s, passes, leaves at 29 s, and is back at 34 s."""
    legs = _legs([(0.0, 0, 0.0, 0.0, 0.0, 0.0), (0.0, 1, 60.0, 0.0, 10.0, 0.0)])
    links = link_lifetimes(legs, 100.0, 40.0, side_m=250.0, torus=True)
    got = links[["t_up_s", "t_down_s"]].values.tolist()
    assert got == [[0.0, pytest.approx(4.0)], [pytest.approx(9.0), pytest.approx(29.0)], [pytest.approx(34.0), 40.0]]


@pytest.mark.parametrize(
    "seed, side, torus, window_s",
    [(1, 60.0, False, None), (2, 60.0, False, 0.7), (3, 41.0, True, None), (4, 41.0, True, 3.0), (5, 80.0, True, 0.2)],
)
@pytest.mark.slow
def test_jumps_and_tori_match_brute_force_for_any_window(seed, side, torus, window_s):
    """Random trajectories with jumps, unequal ranges, bounded or toroidal (down to a side
    just above twice the largest range): linked at an instant iff some lifetime covers it,
    whatever the solver's window."""
    rng = np.random.default_rng(seed)
    n, duration = 12, 60.0
    ranges = rng.uniform(12.0, 20.0, n)
    legs = random_legs(rng, n, duration, side, 3.0, jump_rate=0.3)
    links = link_lifetimes(legs, ranges, duration, side_m=side, torus=torus, window_s=window_s)
    reference = link_lifetimes(legs, ranges, duration, side_m=side, torus=torus)
    assert len(links) == len(reference)
    assert np.abs(links[["t_up_s", "t_down_s"]].to_numpy() - reference[["t_up_s", "t_down_s"]].to_numpy()).max() < 1e-9
    times = np.sort(rng.uniform(0, duration, 1500))
    assert brute_force_mismatches(legs, links, ranges, times, side if torus else None) == 0


def few_windows(monkeypatch, solver, most: int = 10_000) -> None:
    """Fail a link solver's run that opens more than ``most`` windows (each asks
    ``near_pairs`` for its candidates): a hang becomes a failure."""
    near_pairs, calls = solver.near_pairs, [0]

    def counted(*args, **kwargs):
        calls[0] += 1
        assert calls[0] <= most, "the run was cut into tiny windows"
        return near_pairs(*args, **kwargs)

    monkeypatch.setattr(solver, "near_pairs", counted)


def test_a_fast_short_leg_widens_its_windows_only(monkeypatch):
    """A recorded trace's near-equal stamps make legs of a metre in a microsecond. Sizing
    every window by the run's fastest leg cut a 60 s run into millions of windows; now such
    a leg only widens the candidate pairs of the windows it falls in. The links still agree
    with brute force, around the fast legs too."""
    import netsim.links.lifetimes as lifetimes

    rng = np.random.default_rng(5)
    legs = random_legs(rng, 20, 60.0, 200.0, 3.0)
    # Robot 0 darts 100 m in 0.1 ms at t = 20 s, and robot 1 back and forth at 1e300 m/s.
    p0 = legs[legs.robot == 0].iloc[0]
    dart = [
        (20.0, 0, 50.0, 50.0, 1e6, 0.0),
        (20.0001, 0, 150.0, 50.0, 0.0, 0.0),
        (30.0, 1, 10.0, 10.0, 1e300, 0.0),
        (30.0 + 90.0 / 1e300, 1, 100.0, 10.0, 0.0, 0.0),
    ]
    extra = pd.DataFrame(dart, columns=legs.columns)
    legs = pd.concat([legs[(legs.robot > 1) | (legs.t_s < 20.0)], extra], ignore_index=True)
    legs.loc[(legs.robot == 1) & (legs.t_s < 20.0), ["vx_mps", "vy_mps"]] = 0.0
    legs.loc[legs.robot == 1, ["x_m", "y_m"]] = [10.0, 10.0]
    legs.loc[(legs.robot == 1) & (legs.t_s == 30.0 + 90.0 / 1e300), ["x_m", "y_m"]] = [100.0, 10.0]
    assert p0.robot == 0

    few_windows(monkeypatch, lifetimes)
    links = link_lifetimes(legs, 40.0, 60.0)
    times = np.r_[np.linspace(0.05, 59.95, 300), 19.99999, 20.00005, 20.0002, 29.99999, 30.00001]
    assert brute_force_mismatches(legs, links, np.full(20, 40.0), times) == 0


@pytest.mark.parametrize("speed_mps", [1e7, 2.9e8])
def test_a_robot_driven_at_any_speed_leaves_the_runtime_windows_as_they_were(monkeypatch, speed_mps):
    """A drive is not capped in speed: the robot reaches the border at once and stops. The
    runtime solver's windows follow the speeds of the moment, so that one instant does not
    cut the rest of the run into microseconds, and its events still make links.parquet."""
    import netsim.links.kinetic as kinetic
    from netsim import load

    few_windows(monkeypatch, kinetic)
    keys = ["world.n_robots=10", "world.side_m=300", "world.placement='centre'", "world.centre_side_m=60"]
    keys += ["channel.range_m=40", "mobility.model='external'", "protocol.message_rate_hz=0", "duration_s=60"]
    sim = build(load(None, keys))
    ups, downs = [], []
    sim.events.on("link_up", ups.append)
    sim.events.on("link_down", downs.append)
    sim.run(until_s=2.0)
    sim.drive([4], [[speed_mps, 0.0]])
    sim.run()
    assert sim.positions()[4][0] == 300.0
    links = collect(sim)["links"]
    assert len(downs) == int((~links.censored_end).sum()) > 0
    assert len(ups) == len(links)  # those up at t = 0 are announced then too


def test_a_window_given_by_hand_still_counts_the_faster_legs_a_robot_starts_in_it():
    """``window_s`` does not change the links. Over a window given by hand a robot at rest
    at its start may set off fast within it: the candidate pairs must reach as far as it
    can go, or a link it makes in that window is never solved."""
    legs = _legs(
        [
            (0.0, 0, 0.0, 0.0, 0.0, 0.0),
            (0.0, 1, 60.0, 0.0, 0.0, 0.0),
            (10.0, 1, 60.0, 0.0, -10.0, 0.0),  # reaches x = 10, in range, at t = 15
            (20.0, 1, -40.0, 0.0, 0.0, 0.0),  # out of range again since t = 17
        ]
    )
    for window_s in (None, 100.0):
        links = link_lifetimes(legs, 10.0, 100.0, window_s=window_s)
        assert links[["a", "b"]].values.tolist() == [[0, 1]]
        assert links.t_up_s.tolist() == [pytest.approx(15.0, abs=1e-9)]
        assert links.t_down_s.tolist() == [pytest.approx(17.0, abs=1e-9)]


def test_a_leg_too_fast_for_its_window_to_register_on_the_clock_does_not_stall_the_solver(monkeypatch):
    """Half a range at the speed of a leg may be below the clock's resolution at its start:
    the window then keeps a floor of length, so time moves on and the run ends."""
    import netsim.links.lifetimes as lifetimes

    ulp = math.ulp(30.0)
    legs = _legs(
        [
            (0.0, 0, 0.0, 0.0, 0.0, 0.0),
            (0.0, 1, 50.0, 0.0, 0.0, 0.0),
            (30.0, 1, 50.0, 0.0, -100.0 / (2 * ulp), 0.0),  # 100 m in two ticks of the clock
            (30.0 + 2 * ulp, 1, -50.0, 0.0, 0.0, 0.0),
        ]
    )
    few_windows(monkeypatch, lifetimes)
    links = link_lifetimes(legs, 10.0, 60.0)
    assert len(links) == 1 and 30.0 <= links.t_up_s.iloc[0] <= links.t_down_s.iloc[0] <= 30.0 + 2 * ulp


def test_a_link_up_just_after_the_start_is_not_censored_at_the_start():
    """Only a link up at t = 0 itself is censored at the start: one that comes up a moment
    later has its whole lifetime in the run."""
    legs = _legs([(0.0, 0, 0.0, 0.0, 0.0, 0.0), (0.0, 1, 10.0 + 5e-10, 0.0, -1.0, 0.0)])
    row = link_lifetimes(legs, 10.0, 40.0).iloc[0]
    assert 0.0 < row.t_up_s < 1e-9 and row.t_down_s == pytest.approx(20.0)
    assert not row.censored_start and not row.censored


def test_link_lifetimes_rows_run_by_their_up_time_then_by_pair():
    """links.parquet lists lifetimes in the order they began, pairs at one instant by (a, b)."""
    legs = _legs(
        [
            (0.0, 0, 0.0, 0.0, 0.0, 0.0),
            (0.0, 1, 3.0, 0.0, 0.0, 0.0),  # 0-1 up from the start
            (0.0, 2, 100.0, 0.0, -1.0, 0.0),  # 1-2 up at t = 92, 0-2 at t = 95
            (0.0, 3, 100.0, 50.0, 0.0, 0.0),
            (0.0, 4, 100.0, 53.0, 0.0, 0.0),  # 3-4 up from the start
        ]
    )
    links = link_lifetimes(legs, 5.0, 100.0)
    assert links[["a", "b"]].values.tolist() == [[0, 1], [3, 4], [1, 2], [0, 2]]
    assert links.t_up_s.tolist() == [0.0, 0.0, pytest.approx(92.0), pytest.approx(95.0)]


def test_a_window_ends_where_a_faster_leg_begins_so_a_dart_widens_only_its_own_windows(monkeypatch):
    """A window sized by the slow legs of its start ends where a faster leg begins: a dart
    later in the run does not widen the candidate pairs of the slow windows before it."""
    import netsim.links.lifetimes as lifetimes

    reaches = []
    near_pairs = lifetimes.near_pairs

    def recorded(pos, reach, box=None):
        reaches.append(reach)
        return near_pairs(pos, reach, box)

    monkeypatch.setattr(lifetimes, "near_pairs", recorded)
    legs = _legs(
        [
            (0.0, 0, 0.0, 0.0, 0.0, 0.0),
            (0.0, 1, 200.0, 0.0, 0.0, 0.0),
            (20.0, 1, 200.0, 0.0, 1e6, 0.0),  # 100 m in 0.1 ms
            (20.0001, 1, 300.0, 0.0, 0.0, 0.0),
        ]
    )
    assert link_lifetimes(legs, 10.0, 60.0).empty
    # Half a range at the dart's speed is the dart's windows' length: each reaches the range
    # plus twice half of it.
    assert reaches[0] == 10.0 and max(reaches) == pytest.approx(20.0, rel=1e-6)
