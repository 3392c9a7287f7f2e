"""Link events on a map, solved exactly: the links table against the radio itself, sampled
every millisecond, on the shipped maps and on a real-world-sized one."""

from __future__ import annotations

import numpy as np
import pandas as pd
import pytest

from netsim.links.radio_links import positions, radio_link_lifetimes
from netsim.links.wall_sweeps import envelope_radii, linked
from netsim.run import collect, simulation
from netsim.trajectory import LegTable
from netsim.world.maps import cached_map, save_map
from tests.building_map import building_map
from tests.fixtures import make_config


def _core(n, duration_s, world_map, side_m, channel):
    return simulation(
        make_config(
            duration_s=duration_s,
            world={"n_robots": n, "side_m": side_m, "map": world_map},
            mobility={"model": "static"},
            channel=channel,
            protocol={"model": "none"},
            events={"runtime_links": "on"},
            output={"position_interval_s": 0.0},
        )
    )


def waypoint_legs(rng, n, duration_s, speed_mps, points, pause_share=0.2):
    """Trajectories that stay on the map: straight legs between waypoints drawn from
    ``points`` at speeds drawn from ``speed_mps`` (low, high), some legs pauses."""
    rows = []
    for r in range(n):
        t, p = 0.0, points[rng.integers(len(points))]
        while t < duration_s:
            if rng.random() < pause_share:
                dt, v = rng.uniform(0.5, 3.0), np.zeros(2)
            else:
                goal = points[rng.integers(len(points))] + rng.uniform(-0.5, 0.5, 2) * 0.01
                speed = rng.uniform(*speed_mps)
                dt = float(np.hypot(*(goal - p))) / speed
                v = (goal - p) / dt
            rows.append((t, r, p[0], p[1], v[0], v[1]))
            p = p + v * dt
            t += dt
    legs = pd.DataFrame(rows, columns=["t_s", "robot", "x_m", "y_m", "vx_mps", "vy_mps"])
    legs["cause"] = "command"
    return legs


def free_points(occupancy, lo_m, hi_m):
    """Centres of the free cells in the square ``[lo_m, hi_m]^2``."""
    xs, ys = occupancy.cell_centres_m()
    gx, gy = np.meshgrid(xs, ys)
    keep = occupancy.free & (gx >= lo_m) & (gx <= hi_m) & (gy >= lo_m) & (gy <= hi_m)
    return np.c_[gx[keep], gy[keep]]


def mismatches(reception, legs, ranges_m, duration_s, step_s=1e-3, away_s=1e-6):
    """Instants of a grid of ``step_s`` (midway, more than ``away_s`` from the pair's own
    events) at which a pair's state in the links table differs from the radio's decision
    (:func:`netsim.links.wall_sweeps.linked`, the channel's arithmetic) at the robots' positions;
    and how many pair-instants were looked at."""
    links = radio_link_lifetimes(reception, legs, ranges_m, duration_s)
    n = len(ranges_m)
    radii, equal = envelope_radii(reception, ranges_m)
    L = LegTable(legs, n)
    times = (np.arange(int(np.floor(duration_s / step_s))) + 0.5) * step_s
    wrong = seen = 0
    for a in range(n):
        for b in range(a + 1, n):
            pa = positions(L, np.full(len(times), a), times)
            pb = positions(L, np.full(len(times), b), times)
            near = np.hypot(*(pb - pa).T) <= min(radii[a], radii[b]) * 1.01
            truth = np.zeros(len(times), bool)
            idx = np.flatnonzero(near)
            if len(idx):
                truth[idx] = linked(reception, equal, np.full(len(idx), a), np.full(len(idx), b), pa[idx], pb[idx])
            mine = links[(links.a == a) & (links.b == b)]
            claimed = np.zeros(len(times), bool)
            away = np.ones(len(times), bool)
            for up, down in zip(mine.t_up_s, mine.t_down_s):
                claimed |= (times >= up) & (times < down)
                away &= (np.abs(times - up) > away_s) & (np.abs(times - down) > away_s)
            wrong += int((away & (truth != claimed)).sum())
            seen += int(away.sum())
    return wrong, seen, len(links)


CHANNELS = {
    "unit_disk": {"range_m": 30.0},
    "log_distance": {"propagation": "log_distance", "sensitivity_dbm": -64.0, "wall_loss_db": 5.0},
}


@pytest.mark.slow
@pytest.mark.parametrize("name", ["office", "cave"])
@pytest.mark.parametrize("kind", list(CHANNELS))
def test_map_links_equal_the_radio_every_millisecond_on_shipped_maps(name, kind, monkeypatch):
    """On the shipped maps (robots at 0.5-4 m/s), no pair's state in links.parquet differs
    from the radio's at any millisecond more than 1e-6 s from the pair's events."""
    # Millions of pair-instants through the radio: compiled (the plain loops are checked
    # against their oracles elsewhere).
    monkeypatch.setenv("NETSIM_COMPILED", "1")
    n, duration = 14, 30.0
    sim = _core(n, duration, name, 200.0, CHANNELS[kind])
    # Waypoints in the free cells of the map's middle, so that pairs meet.
    points = free_points(cached_map(name), 70.0, 130.0)
    legs = waypoint_legs(np.random.default_rng(11), n, duration, (0.5, 4.0), points)
    wrong, seen, count = mismatches(sim.channel.reception, legs, sim.state.range_m, duration)
    assert count > 10 and seen > 2_000_000
    assert wrong == 0


@pytest.fixture(scope="module")
def building_yaml(tmp_path_factory):
    m = building_map()
    return str(save_map(tmp_path_factory.mktemp("map") / "building.yaml", m.occupied, m.free, m.resolution_m))


def _building_points():
    return free_points(building_map(), 1.0, 39.0)


BUILDING_CHANNELS = {
    "unit_disk": {"range_m": 15.0},
    "log_distance": {"propagation": "log_distance", "sensitivity_dbm": -55.0, "wall_loss_db": 5.0},
}


@pytest.mark.slow
@pytest.mark.parametrize("kind", list(BUILDING_CHANNELS))
def test_map_links_equal_the_radio_every_millisecond_on_a_building_map(building_yaml, kind, monkeypatch):
    """On a 40 m x 40 m map of 5 cm cells with robots at 0.1-0.5 m/s, no pair's state in
    links.parquet differs from the radio's at any millisecond more than 1e-6 s from the
    pair's events."""
    monkeypatch.setenv("NETSIM_COMPILED", "1")  # as on the shipped maps
    n, duration = 12, 40.0
    sim = _core(n, duration, building_yaml, 40.0, BUILDING_CHANNELS[kind])
    legs = waypoint_legs(np.random.default_rng(12), n, duration, (0.1, 0.5), _building_points())
    wrong, seen, count = mismatches(sim.channel.reception, legs, sim.state.range_m, duration)
    assert count > 10 and seen > 2_000_000
    assert wrong == 0


def test_map_links_equal_the_radio_on_a_building_map_quick(building_yaml, monkeypatch):
    """The same, shorter, every 10 ms: slow robots on 5 cm cells."""
    # Thousands of lines over fine cells: the loops compiled (their plain Python is checked
    # against the oracles, tests/oracles/radio.py).
    monkeypatch.setenv("NETSIM_COMPILED", "1")
    n, duration = 8, 20.0
    sim = _core(n, duration, building_yaml, 40.0, BUILDING_CHANNELS["unit_disk"])
    legs = waypoint_legs(np.random.default_rng(13), n, duration, (0.1, 0.5), _building_points())
    wrong, seen, count = mismatches(sim.channel.reception, legs, sim.state.range_m, duration, step_s=1e-2)
    assert count > 5 and seen > 30_000
    assert wrong == 0


@pytest.mark.parametrize("kind", list(BUILDING_CHANNELS))
def test_runtime_map_links_equal_posthoc_on_a_building_map(building_yaml, kind, monkeypatch):
    """Slow robots on 5 cm cells: the link events solved during the run make the post-hoc
    table, bit for bit."""
    from tests.test_events import _announced, _assert_same_links, _fed, _replay

    monkeypatch.setenv("NETSIM_COMPILED", "1")  # fine cells: as in the test above

    n, duration = 16, 30.0
    sim = _fed(_core(n, duration, building_yaml, 40.0, BUILDING_CHANNELS[kind]))
    _replay(sim, waypoint_legs(np.random.default_rng(14), n, duration, (0.1, 0.5), _building_points()))
    sim.run()
    frames = collect(sim)
    posthoc = radio_link_lifetimes(sim.channel.reception, frames["legs"], sim.state.range_m, duration)
    assert len(posthoc) > 10
    _assert_same_links(_announced(sim), posthoc)


def test_a_nearly_parallel_pair_does_not_hang_the_chunk_count():
    """A pair whose relative speed is a rounding error leaves the envelope after ages
    (1e16 s): its chunk count is beyond what a float counts by ones, and is taken as
    estimated instead of settled one sample at a time; likewise samples too fine for
    their floats to move."""
    from netsim.links.wall_sweeps import count_below

    u, h = np.array([13.001, 0.0]), np.array([2.0, 0.5])
    got = count_below(u, h, np.array([6.525667902804318e16, 10.0]))
    assert got[0] == pytest.approx((6.525667902804318e16 - 13.001) / 2.0, rel=1e-12)
    assert got[1] == 20.0
    fine = count_below(np.array([1e6]), np.array([1e-12]), np.array([1e6 + 1.0]))
    assert fine[0] == pytest.approx(1e12, rel=1e-3)


def test_a_tiny_wall_loss_keeps_the_table_of_wall_counts_to_the_map():
    """A wall loss so small that the budget affords billions of walls: the table of ranges
    per wall count stops at the most walls a segment on the map can cross (it held one
    entry per affordable wall: terabytes), and the links still equal the radio's."""
    from netsim.links.wall_sweeps import map_radio

    channel = {"propagation": "log_distance", "sensitivity_dbm": -64.0, "wall_loss_db": 1e-9}
    n, duration = 6, 4.0
    sim = _core(n, duration, "office", 200.0, channel)
    occupancy = sim.channel.reception.map
    assert len(map_radio(sim.channel.reception).radii_m) <= sum(occupancy.shape) + 2
    points = free_points(cached_map("office"), 70.0, 130.0)
    legs = waypoint_legs(np.random.default_rng(3), n, duration, (0.5, 4.0), points)
    wrong, seen, _ = mismatches(sim.channel.reception, legs, sim.state.range_m, duration, step_s=1e-2)
    assert seen > 500 and wrong == 0


@pytest.mark.parametrize("kind", list(BUILDING_CHANNELS))
def test_map_links_solved_in_blocks_equal_one_solve(building_yaml, kind, monkeypatch, capsys):
    """A map's links solved a few stretches and chunks at a time (as a team large for its
    map is, to fit in memory) are the table solved at once, bit for bit (robots fast enough
    for stretches of several chunks)."""
    from netsim.links import radio_links

    monkeypatch.setenv("NETSIM_COMPILED", "1")  # fine cells: as in the tests above
    n, duration = 10, 20.0
    sim = _core(n, duration, building_yaml, 40.0, BUILDING_CHANNELS[kind])
    legs = waypoint_legs(np.random.default_rng(15), n, duration, (1.0, 4.0), _building_points())
    whole = radio_link_lifetimes(sim.channel.reception, legs, sim.state.range_m, duration)
    assert len(whole) > 10
    blocks = radio_links._blocks(np.array([1, 2, 5, 1, 1, 1, 9]), 3)
    assert blocks == [(0, 2), (2, 3), (3, 6), (6, 7)]
    for stretches, chunks in ((3, 7), (40, 1), (40, 3)):
        monkeypatch.setattr(radio_links, "BLOCK_STRETCHES", stretches)
        monkeypatch.setattr(radio_links, "BLOCK_CHUNKS", chunks)
        got = radio_link_lifetimes(sim.channel.reception, legs, sim.state.range_m, duration)
        pd.testing.assert_frame_equal(got, whole)
    assert "links on the map" not in capsys.readouterr().err
    # More than one block: the solve reports its progress when asked to.
    radio_link_lifetimes(sim.channel.reception, legs, sim.state.range_m, duration, progress=True)
    assert "links on the map: 100%" in capsys.readouterr().err
