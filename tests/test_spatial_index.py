"""The range index answers exactly as a brute-force scan, however stale its list."""

import numpy as np
import pytest

from netsim.run import build
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
