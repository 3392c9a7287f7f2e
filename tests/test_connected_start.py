"""world.placement = "connected": a start whose links at t = 0 form one network on the run's
own radio (line of sight, wall loss), inside the free region of world.start_m; and its bad
inputs, each one line, exit 2."""

from __future__ import annotations

import numpy as np
import pytest

from netsim.metrics import components_in_links_table, components_of_links
from netsim.run import build
from netsim.world.los import line_of_sight
from netsim.world.maps import load_map, save_map
from tests.fixtures import check_refused, make_config

RES_M = 0.25


def _px(x_m: float) -> int:
    return int(round(x_m / RES_M))


def two_rooms(tmp_path, door: bool = True):
    """A 40 m x 20 m floor, outer walls, split at x = 20 m by a wall with (or without) a
    1.5 m door at y in [9.25, 10.75]."""
    w, h = _px(40.0), _px(20.0)
    occ = np.zeros((h, w), dtype=bool)
    occ[[0, -1], :] = True
    occ[:, [0, -1]] = True
    occ[:, _px(20.0)] = True
    if door:
        occ[_px(9.25) : _px(10.75), _px(20.0)] = False
    return save_map(tmp_path / ("rooms.yaml" if door else "closed.yaml"), occ, ~occ, RES_M)


def _world(path, n, channel=None, **extra):
    return make_config(
        seed=extra.pop("seed", 3),
        duration_s=1.0,
        world={"n_robots": n, "side_m": 20.0, "bounds_m": "map", "map": str(path), "placement": "connected", **extra},
        mobility={"model": "static"},
        channel=channel or {"range_m": 12.0},
        protocol={"model": "none"},
        output={"position_interval_s": 0.0},
    )


def _placed(config):
    sim = build(config)
    return sim.state.positions_at(0.0)


def _sight_components(path, pos, range_m):
    """Components of the line-of-sight unit disk, computed here from the map itself."""
    m = load_map(path)
    a, b = np.triu_indices(len(pos), 1)
    near = np.hypot(*(pos[a] - pos[b]).T) <= range_m
    a, b = a[near], b[near]
    seen = line_of_sight(m, pos[a], pos[b], blocked=m.occupied)
    return len(np.unique(components_of_links(len(pos), a[seen], b[seen])))


@pytest.mark.slow
def test_connected_start_is_one_network_through_a_door(tmp_path):
    """Robots placed "connected" on two rooms joined by a door, the start square covering
    both, form one network of line-of-sight links at t = 0 (walls cut the links a plain
    distance test would keep)."""
    path = two_rooms(tmp_path)
    both_rooms = 0
    for seed in range(1, 9):
        pos = _placed(_world(path, 10, seed=seed, start_m=[10.0, 10.0], centre_side_m=60.0))
        assert _sight_components(path, pos, 12.0) == 1
        both_rooms += bool((pos[:, 0] > 20.0).any() and (pos[:, 0] < 20.0).any())
    # Robots reached the second room (through the door), so the walls were in play.
    assert both_rooms > 0


def test_connected_start_stays_in_the_start_points_free_region(tmp_path):
    """Without a door the second room is another free region: every robot starts in the
    start point's room, even under a radio whose links cross the wall (5 dB a wall)."""
    path = two_rooms(tmp_path, door=False)
    radio = {"propagation": "log_distance", "wall_loss_db": 5.0, "sensitivity_dbm": -64.3}
    pos = _placed(_world(path, 15, channel=radio, start_m=[30.0, 10.0], centre_side_m=60.0))
    assert (pos[:, 0] > 20.25).all()


def test_connected_start_is_the_same_for_the_same_seed(tmp_path):
    """The start is drawn from the seed's placement stream alone: same seed, same positions,
    bit for bit; another seed, another start."""
    path = two_rooms(tmp_path)
    a = _placed(_world(path, 10, seed=5, centre_side_m=60.0))
    b = _placed(_world(path, 10, seed=5, centre_side_m=60.0))
    c = _placed(_world(path, 10, seed=6, centre_side_m=60.0))
    assert np.array_equal(a, b)
    assert not np.array_equal(a, c)


def test_connected_start_is_one_network_in_open_space():
    """In open space the links are the unit disk of the ranges: one network at t = 0, on a
    start square far wider than the range."""
    config = make_config(
        seed=2,
        world={"n_robots": 30, "side_m": 1000.0, "placement": "connected", "centre_side_m": 600.0},
        mobility={"model": "static"},
        channel={"range_m": 50.0},
        protocol={"model": "none"},
    )
    pos = _placed(config)
    a, b = np.triu_indices(30, 1)
    near = np.hypot(*(pos[a] - pos[b]).T) <= 50.0
    assert len(np.unique(components_of_links(30, a[near], b[near]))) == 1


def test_connected_start_square_is_about_the_areas_middle_and_clipped_to_the_area():
    """By default the start square is centred on the area's middle, a rectangle in the world
    frame included; about a start point at a corner it is clipped to the area."""
    common = {"mobility": {"model": "static"}, "channel": {"range_m": 50.0}, "protocol": {"model": "none"}}
    world = {"n_robots": 20, "placement": "connected", "centre_side_m": 100.0}
    rect = _placed(make_config(seed=2, world={**world, "bounds_m": [-400.0, 100.0, 0.0, 300.0]}, **common))
    assert (np.abs(rect - [-200.0, 200.0]) <= 50.0).all()
    corner = _placed(make_config(seed=2, world={**world, "side_m": 1000.0, "start_m": [0.0, 0.0]}, **common))
    assert ((corner >= 0.0) & (corner <= 50.0)).all()


@pytest.mark.parametrize("channel", [{"range_m": 100.0}, {"propagation": "log_distance"}])
def test_connected_start_on_a_torus_links_across_the_seam(channel):
    """On a torus a robot may be placed linked to the team across the seam only: the
    placement measures links to the nearest image, as the channel does (on the plane it
    would never place one there). Robot 1 of two, over a whole 1,000 m torus, reach 100 m."""
    across = 0
    for seed in range(100):
        config = make_config(
            seed=seed,
            world={"n_robots": 2, "side_m": 1000.0, "torus": True, "placement": "connected", "centre_side_m": 2000.0},
            mobility={"model": "static"},
            channel=channel,
            protocol={"model": "none"},
        )
        pos = _placed(config)
        on_plane = float(np.hypot(*(pos[0] - pos[1])))
        offset = (pos[0] - pos[1] + 500.0) % 1000.0 - 500.0
        assert np.hypot(*offset) <= 100.0
        across += on_plane > 100.0
    assert across > 0


@pytest.mark.slow
def test_connected_start_is_one_network_on_the_office_links(tmp_path):
    """On the office map (40 robots, range 30 m, a 60 m start square) the run's own links
    (links.parquet) at t = 0 form one network, under line of sight and under 5 dB a wall;
    the same start square drawn "centre" falls apart (the scenario this placement fixes)."""
    from netsim.config import load
    from netsim.run import execute

    common = ["world.map=office", "world.side_m=200", "world.n_robots=40", "world.centre_side_m=60"]
    common += ["mobility.model=static", "duration_s=1", "protocol.message_rate_hz=0", "output.position_interval_s=0"]
    radios = {
        "sight": ["channel.range_m=30"],
        "walls": ["channel.propagation=log_distance", "channel.wall_loss_db=5", "channel.sensitivity_dbm=-64.3"],
    }
    for radio in radios.values():
        links = execute(load(None, [*common, *radio, "world.placement=connected"])).frames["links"]
        assert components_in_links_table(links, 40, [0.0])[0] == 1
    links = execute(load(None, [*common, *radios["sight"], "world.placement=centre"])).frames["links"]
    assert components_in_links_table(links, 40, [0.0])[0] > 1


@pytest.mark.parametrize(
    "overrides, key, words",
    [
        (["world.start_m=[1.0, 2.0, 3.0]"], "world.start_m", "must be [x, y]"),
        (["world.start_m=centre2"], "world.start_m", "must be [x, y]"),
        (["world.placement=connected", "world.start_m=[5000.0, 10.0]"], "world.start_m", "is outside the area"),
        (
            ["world.placement=connected", "world.map=office", 'world.bounds_m="map"', "world.start_m=[500.0, 10.0]"],
            "world.start_m",
            "is outside the area [0.0, 0.0, 200.0, 200.0]",
        ),
        (
            ["world.placement=connected", "world.map=office", "world.side_m=200", "world.start_m=[100.0, 0.1]"],
            "world.start_m",
            "is not in a free cell of world.map",
        ),
        (
            ["world.placement=connected", "channel.range_m=0.02", "world.n_robots=3", "world.centre_side_m=900"],
            "world.placement",
            "found no place for robot 1",
        ),
        (
            ["world.placement=connected", "channel.propagation=log_distance", "channel.shadowing_sigma_db=4"],
            "world.placement",
            "needs links that positions decide",
        ),
    ],
)
def test_bad_connected_start_is_refused_in_one_line(tmp_path, capsys, overrides, key, words):
    """Each bad input of the connected start: one line naming the key, exit 2, nothing written."""
    check_refused(tmp_path, capsys, ["mobility.model=static", "duration_s=1", *overrides], key, words)
