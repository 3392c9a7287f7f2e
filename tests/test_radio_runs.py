"""The radio in real runs: propagation, shadowing and walls in the channel, in links.parquet,
in the summary; robots kept in free space; bad maps and dB values refused."""

from __future__ import annotations

import warnings

import numpy as np
import pandas as pd
import pytest

from netsim.config import from_dict
from netsim.errors import ConfigError
from netsim.run import execute
from netsim.tools.radio_checks import wall_test_map
from netsim.world.free_space import legs_free
from netsim.world.los import line_of_sight
from netsim.world.maps import cached_map, load_map, save_map


def wall_map(tmp_path) -> str:
    """40 m x 40 m, walls at x = 10, 20, 30 m; a doorway in the wall at x = 20 m for y in [2, 4)."""
    m = wall_test_map()
    return str(save_map(tmp_path / "walls.yaml", m.occupied, m.free, m.resolution_m))


def run(**tree):
    tree.setdefault("output", {"position_interval_s": 0.0})
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        return execute(from_dict(tree))


def static_pair(tmp_path, a, b, channel):
    csv = tmp_path / "pos.csv"
    pd.DataFrame({"x_m": [a[0], b[0]], "y_m": [a[1], b[1]]}).to_csv(csv, index=False)
    return run(
        duration_s=5.0,
        world={"n_robots": 2, "side_m": 40.0, "map": wall_map(tmp_path), "placement": str(csv)},
        mobility={"model": "static"},
        channel=channel,
        protocol={"model": "ack"},
    )


def acks_received(result) -> int:
    return int(result.sim.channel.counters_for("ack").received.sum())


# -- propagation -----------------------------------------------------------------------------
@pytest.mark.slow
def test_log_distance_without_shadowing_is_the_unit_disk_of_the_implied_range():
    """Same links (exact, solved) and the same receptions as a unit disk of 100 m."""
    base = {"seed": 4, "duration_s": 60.0, "world": {"n_robots": 60, "side_m": 600.0}, "protocol": {"model": "ack"}}
    radio = run(**base, channel={"propagation": "log_distance"})
    disk = run(**base, channel={"range_m": 100.0})
    assert radio.summary["implied_range_m"] == pytest.approx(100.0, rel=1e-15)
    pd.testing.assert_frame_equal(radio.frames["links"], disk.frames["links"], check_exact=True)
    assert acks_received(radio) == acks_received(disk) > 0


def test_summary_reports_the_implied_range():
    r = run(
        duration_s=2.0,
        world={"n_robots": 5, "side_m": 100.0},
        channel={"propagation": "log_distance", "sensitivity_dbm": -90.0, "path_loss_exponent": 2.0},
        protocol={"model": "none"},
    )
    assert r.summary["implied_range_m"] == pytest.approx(10 ** (70 / 20))
    assert r.summary["propagation"] == "log_distance"


def test_default_run_summary_has_no_radio_keys():
    r = run(duration_s=2.0, world={"n_robots": 5}, protocol={"model": "none"})
    assert "implied_range_m" not in r.summary and "radio_reach_m" not in r.summary


# -- shadowing -------------------------------------------------------------------------------
def shadowed_run(sigma=6.0, seed=3):
    return run(
        seed=seed,
        duration_s=30.0,
        world={"n_robots": 40, "side_m": 300.0},
        mobility={"speed_min_mps": 1.0, "speed_max_mps": 2.0},
        channel={"propagation": "log_distance", "shadowing_sigma_db": sigma},
        protocol={"model": "ack"},
    )


@pytest.mark.slow
def test_shadowing_links_are_the_channels_decisions():
    """Under shadowing the links table records what the channel decided: a pair linked at a
    send time of an Ack heard is inside one of its link intervals."""
    r = shadowed_run()
    links = r.frames["links"]
    assert len(links) > 0
    assert (links.t_up_s < links.t_down_s).all() or (links.t_up_s <= links.t_down_s).all()
    # Intervals of one pair do not overlap.
    for _, g in links.groupby(["a", "b"]):
        assert (g.t_up_s.to_numpy()[1:] >= g.t_down_s.to_numpy()[:-1]).all()
    # Some links start away from Ack boundaries of a unit disk: shadowing makes links flap
    # even between robots well inside the implied range.
    assert (
        r.summary["link_lifetimes"]
        > run(
            seed=3,
            duration_s=30.0,
            world={"n_robots": 40, "side_m": 300.0},
            mobility={"speed_min_mps": 1.0, "speed_max_mps": 2.0},
            channel={"propagation": "log_distance"},
            protocol={"model": "ack"},
        ).summary["link_lifetimes"]
    )


@pytest.mark.slow
def test_shadowed_run_is_reproducible_and_sigma_zero_draws_nothing():
    a, b = shadowed_run(seed=5), shadowed_run(seed=5)
    pd.testing.assert_frame_equal(a.frames["links"], b.frames["links"])
    assert a.sim.channel.reception.shadowing.draws > 0
    r = shadowed_run(sigma=0.0)
    assert r.sim.channel.reception.shadowing is None


def test_static_pair_shadowing_is_constant_and_reciprocal(tmp_path):
    """Two robots at rest: every Ack either way is decided the same (constant, reciprocal X)."""
    r = run(
        seed=7,
        duration_s=20.0,
        world={"n_robots": 30, "side_m": 400.0},
        mobility={"model": "static"},
        channel={"propagation": "log_distance", "shadowing_sigma_db": 8.0},
        protocol={"model": "ack"},
    )
    links = r.frames["links"]
    # A pair is linked from the first Ack between them to the end, or never.
    assert links.groupby(["a", "b"]).size().max() == 1
    assert links.censored_end.all()
    assert (links.t_up_s <= 1.2).all()


# -- walls -----------------------------------------------------------------------------------
def test_unit_disk_across_a_wall_does_not_link(tmp_path):
    r = static_pair(tmp_path, (15.0, 15.0), (25.0, 15.0), {"range_m": 30.0})
    assert acks_received(r) == 0 and len(r.frames["links"]) == 0


def test_unit_disk_through_a_doorway_links(tmp_path):
    r = static_pair(tmp_path, (15.0, 3.0), (25.0, 3.0), {"range_m": 30.0})
    assert acks_received(r) > 0 and len(r.frames["links"]) == 1


def test_log_distance_loses_wall_loss_per_wall(tmp_path):
    """10 m apart across one wall: 70 dB path loss + 20 dB wall = 90 dB; received at a
    sensitivity of -70 dBm, not at -69 dBm."""
    pair = (15.0, 15.0), (25.0, 15.0)
    ch = {"propagation": "log_distance", "wall_loss_db": 20.0}
    assert acks_received(static_pair(tmp_path, *pair, {**ch, "sensitivity_dbm": -70.0})) > 0
    assert acks_received(static_pair(tmp_path, *pair, {**ch, "sensitivity_dbm": -69.9})) == 0
    assert acks_received(static_pair(tmp_path, *pair, {**ch, "wall_loss_db": 0.0, "sensitivity_dbm": -69.9})) > 0


def office_run(channel, mobility=None, n=40, duration_s=40.0, seed=2):
    return run(
        seed=seed,
        duration_s=duration_s,
        world={"n_robots": n, "side_m": 100.0, "map": "office"},
        mobility=mobility or {"stationary_start": False, "speed_min_mps": 1.0, "speed_max_mps": 3.0},
        channel=channel,
        protocol={"model": "ack"},
    )


def linked_now(links: pd.DataFrame, t: float) -> set:
    up = links[(links.t_up_s <= t) & (t < links.t_down_s)]
    return set(zip(up.a.tolist(), up.b.tolist()))


def brute_force(legs, n, t, range_m, m):
    from netsim.links.radio_links import positions
    from netsim.trajectory import LegTable

    L = LegTable(legs, n)
    pos = positions(L, np.arange(n), np.full(n, t))
    i, j = np.triu_indices(n, 1)
    d = np.hypot(*(pos[i] - pos[j]).T)
    ok = (d <= range_m) & line_of_sight(m, pos[i], pos[j])
    return set(zip(i[ok].tolist(), j[ok].tolist()))


@pytest.mark.slow
def test_walled_links_match_line_of_sight_at_random_times():
    """links.parquet under the unit disk on a map: at random instants (away from its event
    times) exactly the pairs in range with line of sight."""
    r = office_run({"range_m": 30.0})
    links, legs = r.frames["links"], r.frames["legs"]
    m = cached_map("office")
    events = np.sort(np.r_[links.t_up_s, links.t_down_s])
    rng = np.random.default_rng(1)
    checked = 0
    for t in rng.uniform(0, 40.0, 60):
        if np.min(np.abs(events - t)) < 1e-6:
            continue
        assert linked_now(links, t) == brute_force(legs, 40, t, 30.0, m), t
        checked += 1
    assert checked > 50 and len(links) > 20


@pytest.mark.parametrize("channel", [{"range_m": 30.0}, {"propagation": "log_distance", "wall_loss_db": 3.0}])
def test_walled_links_are_the_channels_receptions(channel):
    """Robots at rest on a map: each robot received exactly the Acks its linked neighbours
    (links.parquet) sent: the channel and the links table agree."""
    r = office_run(channel, {"model": "static"}, n=60, duration_s=10.0)
    links = r.frames["links"]
    c = r.sim.channel.counters_for("ack")
    expected = np.zeros(60, dtype=np.int64)
    np.add.at(expected, links.a.to_numpy(), c.sent[links.b.to_numpy()])
    np.add.at(expected, links.b.to_numpy(), c.sent[links.a.to_numpy()])
    assert len(links) > 10
    np.testing.assert_array_equal(c.received, expected)


# -- robots on the map -----------------------------------------------------------------------
def every_leg_free(result, m) -> bool:
    legs = result.frames["legs"].sort_values(["robot", "t_s"])
    starts = legs[["x_m", "y_m"]].to_numpy()
    same = legs.robot.to_numpy()[1:] == legs.robot.to_numpy()[:-1]
    ends = starts[1:][same]
    return bool(legs_free(m, starts[:-1][same], ends).all() and m.is_free(starts).all())


@pytest.mark.parametrize(
    "mobility",
    [
        {"stationary_start": False, "speed_min_mps": 1.0, "speed_max_mps": 3.0},
        {"model": "random_direction", "speed_min_mps": 1.0, "speed_max_mps": 3.0, "pause_s": 0.0},
    ],
)
def test_robots_stay_in_free_space(mobility):
    r = office_run({"range_m": 30.0}, mobility, n=30, duration_s=60.0)
    assert len(r.frames["legs"]) > 60
    assert every_leg_free(r, cached_map("office"))


@pytest.mark.slow
def test_placement_draws_free_cells():
    r = run(
        duration_s=1.0,
        world={"n_robots": 500, "side_m": 200.0, "map": "cave"},
        mobility={"model": "static"},
        protocol={"model": "none"},
    )
    assert cached_map("cave").is_free(r.sim.state.positions_at(0.0)).all()


@pytest.mark.slow
def test_coverage_keeps_robots_off_walls():
    r = run(
        seed=3,
        duration_s=60.0,
        world={"n_robots": 20, "side_m": 100.0, "map": "office", "placement": "centre", "centre_side_m": 30.0},
        mobility={"model": "static"},
        channel={"range_m": 25.0},
        coverage={"enabled": True, "start_s": 5.0, "metrics_interval_s": 10.0},
    )
    moved = r.frames["legs"].groupby("robot").size().max()
    assert moved > 2
    assert every_leg_free(r, cached_map("office"))


def test_a_model_that_cannot_respect_a_map_refuses_it(tmp_path):
    trace = tmp_path / "t.tcl"
    trace.write_text("$node_(0) set X_ 1.0\n$node_(0) set Y_ 1.0\n")
    with pytest.raises(ConfigError) as err:
        from_dict(
            {
                "world": {"n_robots": 1, "side_m": 100.0, "map": "office"},
                "mobility": {"model": "trace", "trace_file": str(trace)},
            }
        )
    assert err.value.key == "world.map" and "'trace'" in str(err.value)


def test_stationary_start_is_refused_on_a_map():
    """Asked for explicitly: the default ("auto") starts at rest on a map instead."""
    with pytest.raises(ConfigError, match="mobility.stationary_start"):
        from_dict({"world": {"side_m": 100.0, "map": "office"}, "mobility": {"stationary_start": True}})


def test_map_on_a_torus_is_refused():
    with pytest.raises(ConfigError, match="world.map"):
        from_dict(
            {
                "world": {"side_m": 100.0, "map": "office", "torus": True},
                "mobility": {"model": "static"},
                "channel": {"range_m": 20.0},
            }
        )


def test_grid_placement_in_a_wall_is_refused():
    with pytest.raises(ConfigError, match="world.placement"):
        run(world={"n_robots": 25, "side_m": 200.0, "map": "office", "placement": "grid"}, mobility={"model": "static"})


def test_example_maps_load_by_name():
    assert load_map("office").shape == (800, 800)


def test_positions_at_many_instants_follow_the_legs():
    """The vectorised lookup of (robot, time) positions used by the walled links solver
    gives each robot's leg at that time, also exactly at a leg's start."""
    from netsim.links.radio_links import positions
    from netsim.trajectory import LegTable

    rng = np.random.default_rng(1)
    rows = []
    for r in range(20):
        for t in np.sort(np.r_[0.0, rng.uniform(0, 100, rng.integers(0, 8))]):
            rows.append((t, r, *rng.uniform(0, 50, 2), *rng.uniform(-1, 1, 2)))
    legs = pd.DataFrame(rows, columns=["t_s", "robot", "x_m", "y_m", "vx_mps", "vy_mps"])
    L = LegTable(legs, 20)
    robots, times = rng.integers(0, 20, 3000), rng.uniform(0, 100, 3000)
    robots[:40], times[:40] = legs.robot.to_numpy()[:40], legs.t_s.to_numpy()[:40]

    def leg_at(i, t):  # the oracle: robot i's last leg starting at or before t
        lo, hi = L.first[i], L.end[i]
        return lo + int(np.searchsorted(L.t[lo:hi], t, "right")) - 1

    want = np.array([L.p[k] + L.v[k] * (t - L.t[k]) for k, t in ((leg_at(r, t), t) for r, t in zip(robots, times))])
    np.testing.assert_array_equal(positions(L, robots, times), want)


@pytest.mark.parametrize("compiled", ["1", "0"])
def test_leg_lookup_equals_the_oracle(compiled, monkeypatch):
    """Positions from the legs: the per-query search (compiled and plain) finds the legs of
    the oracle's merge."""
    import netsim.links.radio_links as rl
    from tests.oracles import radio as oracle

    monkeypatch.setenv("NETSIM_COMPILED", compiled)
    from netsim.state import RobotState
    from netsim.trajectory import LegTable

    rng = np.random.default_rng(4)
    st = RobotState(30, 100.0, 10.0)
    st.place(rng.uniform(0, 100, (30, 2)))
    for t in np.sort(rng.uniform(0, 50, 200)).tolist():
        st.set_leg(int(rng.integers(30)), t, rng.normal(0, 1, 2))
    st.set_leg(3, 50.0, (1.0, 0.0), start_m=(10.0, 10.0))
    st.set_leg(3, 50.0, (0.0, 1.0), start_m=(20.0, 20.0))  # two jumps at one instant: the later holds
    L = LegTable(st.legs(), 30)
    robots = rng.integers(0, 30, 5000)
    times = np.r_[rng.uniform(0, 60, 4990), np.full(10, 50.0)]
    robots[-10:] = 3
    got = rl.positions(L, robots, times)
    leg = oracle.leg_index(L, robots, times)
    assert np.array_equal(got, L.p[leg] + L.v[leg] * (times - L.t[leg])[:, None])
    assert np.array_equal(got[-1], [20.0, 20.0])
    # Every robot's current leg at an instant, as the sampled positions and the link
    # solvers advance to it: the same legs, also when the instants go back.
    for t in (7.5, 50.0, 3.0):
        L.advance(t)
        assert np.array_equal(L.cur, oracle.leg_index(L, np.arange(30), np.full(30, t)))
