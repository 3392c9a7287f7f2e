"""Links: unit disk, exact up/down times, censoring, link durations (docs/validation.md 5-7)."""

import math

import numpy as np
import pandas as pd
import pytest

from netsim.links import link_lifetimes
from netsim.run import build, collect
from netsim.state import RobotState
from netsim.topology import geometric_edges, snapshot
from tests.conftest import make_config


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


def test_unequal_ranges_make_one_way_links():
    """i reaches j when d <= r_i; the undirected graph keeps only two-way links."""
    pos = np.array([[0.0, 0.0], [10.0, 0.0]])
    assert geometric_edges(pos, [15.0, 5.0], directed=True) == [(0, 1, 10.0)]
    assert geometric_edges(pos, [15.0, 5.0]) == []


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
    from netsim.trajectory import sample_positions

    for row in links.itertuples():
        for t, censored in ((row.t_up_s, row.censored_start), (row.t_down_s, row.censored_end)):
            if censored:
                continue
            p = sample_positions(legs, 30, [t])[["x_m", "y_m"]].to_numpy()
            assert math.dist(p[row.a], p[row.b]) == pytest.approx(40.0, abs=1e-6)
    # Brute force at many instants: linked iff some lifetime covers the instant.
    times = np.linspace(0.05, 119.95, 397)
    pos = sample_positions(legs, 30, times)[["x_m", "y_m"]].to_numpy().reshape(len(times), 30, 2)
    for k, t in enumerate(times):
        d = np.hypot(*(pos[k][:, None, :] - pos[k][None, :, :]).transpose(2, 0, 1))
        truth = {(a, b) for a in range(30) for b in range(a + 1, 30) if d[a, b] <= 40.0}
        live = links[(links.t_up_s <= t) & (links.t_down_s > t)]
        assert set(zip(live.a, live.b)) == truth


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
