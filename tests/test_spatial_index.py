"""The range index answers exactly as a brute-force scan, however stale its list."""

import numpy as np
import pytest

from netsim.radio.spatial import RangeIndex
from netsim.run import build
from netsim.state import RobotState
from tests.fixtures import make_config


@pytest.mark.parametrize("torus", [False, True])
def test_index_matches_brute_force_over_a_run(torus):
    model = "random_direction" if torus else "random_waypoint"
    cfg = make_config(
        seed=4,
        duration_s=200.0,
        world={"n_robots": 80, "side_m": 300.0, "torus": torus},
        channel={"range_m": 40.0},
        mobility={"model": model, "speed_min_mps": 1.0, "speed_max_mps": 10.0},
        protocol={"model": "none"},
    )
    sim = build(cfg)
    st, index = sim.state, sim.channel.index
    rng = np.random.default_rng(0)
    checked = 0
    for t in np.sort(rng.uniform(0, 199, 150)):
        sim.env.run(until=t)
        pos = st.positions_at(t)
        i = int(rng.integers(80))
        d = st.displacement(pos, pos[i])
        dist = np.hypot(d[:, 0], d[:, 1])
        truth = np.flatnonzero(dist <= 40.0)
        truth = truth[truth != i]
        got, got_d = index.within(t, i)
        assert got.tolist() == truth.tolist()
        assert got_d == pytest.approx(dist[truth])
        checked += len(truth)
    assert checked > 100 and index.rebuilds > 5


def test_two_indexes_on_one_state_each_see_every_robot_in_range():
    """A second index built later (a shared medium keeps its own) does not make the first
    trust lists its robots have outrun: robot 1 races towards robot 0, then slows down just
    before a second index is built; the first index, built before the race, still finds it
    in range."""
    st = RobotState(2, 1000.0, 10.0)
    st.place(np.array([[0.0, 0.0], [30.0, 0.0]]))
    st.set_leg(1, 0.0, np.array([-40.0, 0.0]), cause="waypoint")
    first, second = RangeIndex(st, slack_m=2.0), RangeIndex(st, slack_m=2.0)
    assert first.within(0.0, 0)[0].tolist() == []  # 30 m away: not even on the list
    st.set_leg(1, 0.5, np.array([-0.1, 0.0]), cause="waypoint")  # 10 m away, now slow
    second.within(0.5, 0)
    assert first.within(0.6, 0)[0].tolist() == [1]  # 9.99 m away


def test_an_index_built_while_everyone_rests_finds_a_robot_that_starts_moving():
    """Its lists hold while no robot moves; the first leg with a speed must make them
    stale (the robots' speed bound rises), or a robot driven close after a rest at the
    start (coverage before control starts, a trace that begins at rest) is never found."""
    st = RobotState(2, 1000.0, 100.0)
    st.place(np.array([[0.0, 0.0], [300.0, 0.0]]))
    index = RangeIndex(st, slack_m=2.0)
    assert index.within(10.0, 0)[0].tolist() == []
    st.set_leg(1, 40.0, np.array([-50.0, 0.0]), cause="command")  # 50 m away at 45 s
    assert index.within(45.0, 0)[0].tolist() == [1]
