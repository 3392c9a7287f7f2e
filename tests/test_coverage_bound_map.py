"""On a map coverage is of the free region the team starts in, and the bound is over its
area: ``min(1, U(N) / A_free)`` (docs/model.md 5.3). Checked against closed forms on maps
whose free region is a rectangle."""

from __future__ import annotations

import math

import numpy as np
import pytest

from netsim.area import Bounds
from netsim.metrics import bound_fraction, covered_fraction, covered_fraction_exact
from netsim.world.free_space import free_region, region_polygon
from netsim.world.maps import load_map, save_map

RES_M = 0.5
AREA = Bounds(0.0, 0.0, 100.0, 60.0)
ROOM = Bounds(20.0, 10.0, 70.0, 40.0)  # the free rectangle


def _px(x_m: float) -> int:
    return int(round(x_m / RES_M))


def rectangle_map(tmp_path, second_room: bool = False):
    """100 m x 60 m of wall but for the free rectangle ROOM (and, if asked, a second free
    room [80, 95] x [45, 55] that ROOM does not reach)."""
    occ = np.ones((_px(60.0), _px(100.0)), dtype=bool)
    occ[_px(ROOM.y_min) : _px(ROOM.y_max), _px(ROOM.x_min) : _px(ROOM.x_max)] = False
    if second_room:
        occ[_px(45.0) : _px(55.0), _px(80.0) : _px(95.0)] = False
    return save_map(tmp_path / "rect.yaml", occ, ~occ, RES_M)


def _region(tmp_path, second_room=False, seeds=((40.0, 20.0),)):
    m = load_map(rectangle_map(tmp_path, second_room))
    return region_polygon(m, AREA, free_region(m, AREA, np.array(seeds)))


def test_free_region_bound_on_a_rectangle_is_the_open_space_bound_there(tmp_path):
    """A map whose free region is a rectangle: its area is the rectangle's, and the bound
    over it is the open-space bound ``min(1, U(N) / A)`` of that rectangle, for teams below
    and above the area (U(N) < A and U(N) > A)."""
    region = _region(tmp_path)
    assert region.area == pytest.approx(ROOM.area, abs=1e-9)
    for n in (2, 5, 40):
        expected = bound_fraction(n, 6.0, ROOM, 6.0)
        assert bound_fraction(n, 6.0, AREA, 6.0, free_area_m2=region.area) == pytest.approx(expected, rel=1e-12)
    assert bound_fraction(2, 6.0, AREA, 6.0, free_area_m2=region.area) < 1.0 == bound_fraction(40, 6.0, ROOM, 6.0)


def test_covered_fraction_of_a_rectangular_region_is_that_of_the_rectangle(tmp_path):
    """The covered fraction of the free region equals that of the rectangle in open space
    (disks reaching over the walls count only inside), exact and on the grid."""
    region = _region(tmp_path)
    centres = np.array([[22.0, 12.0], [45.0, 25.0], [69.0, 39.0], [60.0, 15.0]])
    for r in (5.0, 12.0):
        f, err = covered_fraction_exact(centres, r, AREA, region=region)
        g, err_g = covered_fraction_exact(centres, r, ROOM)
        assert abs(f - g) <= err + err_g
        # One disk whose centre is in the corner: a quarter of it lies in the room.
        q, _ = covered_fraction_exact([[ROOM.x_min, ROOM.y_min]], r, AREA, region=region)
        assert q == pytest.approx(math.pi * r * r / 4 / ROOM.area, abs=1e-3)
    f, err = covered_fraction(centres, 12.0, AREA, 400, region=region)
    g, _ = covered_fraction_exact(centres, 12.0, ROOM)
    assert abs(f - g) <= err


@pytest.mark.parametrize("compiled", ["0", "1"])
def test_no_robot_covers_nothing_and_the_regions_edge_stays_uncertain(tmp_path, monkeypatch, compiled):
    """The grid's covered fraction of no robot, in a region: 0, with the error bound of the
    cells the region's boundary crosses, as for a robot that covers none of them; and the
    environments' grid fraction of no robot is 0."""
    from netsim.compiled import load

    monkeypatch.setenv("NETSIM_COMPILED", compiled)
    region = _region(tmp_path)
    none = covered_fraction(np.empty((0, 2)), 12.0, AREA, 400, region=region, n_robots=30)
    far = covered_fraction([[-1e6, -1e6]], 12.0, AREA, 400, region=region, n_robots=30)
    assert none == far and none[0] == 0.0 and none[1] > 0.0
    env = load("netsim.envs._kernels", 30)
    assert env.covered_fraction_grid(np.empty((0, 2)), 12.0, 0.0, 0.0, 100.0, 60.0, 50) == 0.0


def test_free_region_leaves_out_free_space_the_team_cannot_reach(tmp_path):
    """Free cells that no free path joins to the team's start are not in its region; a
    start in both rooms takes both."""
    assert _region(tmp_path, second_room=True).area == pytest.approx(ROOM.area, abs=1e-9)
    both = _region(tmp_path, second_room=True, seeds=((40.0, 20.0), (90.0, 50.0)))
    assert both.area == pytest.approx(ROOM.area + 150.0, abs=1e-9)


@pytest.mark.slow
def test_coverage_run_on_a_map_reports_fractions_and_bound_of_the_free_region(tmp_path):
    """A coverage run on the rectangle map: the coverage table's ``coverage_bound`` is the
    open-space bound of the rectangle, and ``covered_fraction_all`` at t = 0 the fraction of
    the rectangle the start covers (not of the whole area, walls included)."""
    from netsim.config import load
    from netsim.run import build, execute

    n, r = 8, 8.0
    keys = [
        f"world.map={rectangle_map(tmp_path)}",
        "world.bounds_m=map",
        f"world.n_robots={n}",
        "world.placement=connected",
        "world.start_m=[45.0, 25.0]",
        "world.centre_side_m=20",
        f"channel.range_m={r}",
        "mobility.model=static",
        "coverage.enabled=true",
        "protocol.message_rate_hz=0",
        "output.position_interval_s=0",
        "duration_s=20",
    ]
    start = build(load(None, keys)).state.positions_at(0.0)
    cov = execute(load(None, keys)).frames["coverage"]
    first = cov.iloc[0]
    assert first["t_s"] == 0.0
    assert first["coverage_bound"] == pytest.approx(bound_fraction(n, r, ROOM, r), rel=1e-12)
    f, err = covered_fraction_exact(start, r, ROOM)
    assert abs(first["covered_fraction_all"] - f) <= err + first["covered_error_bound_all"]
    assert first["covered_of_bound_all"] == pytest.approx(first["covered_fraction_all"] / first["coverage_bound"])


@pytest.mark.parametrize("expansion, moves", [(0.1, False), (0.0, True)])
def test_on_a_map_the_global_plan_moves_by_the_expansion_alone(tmp_path, expansion, moves):
    """On a map the global plan's wish is its expansion toward the free space not yet
    covered, with no pushes of robots or walls (docs/model.md 5.3): a team that covers its
    whole room from the start stays where it is. With the expansion off, the pushes move
    it as in open space."""
    from netsim.config import load
    from netsim.run import execute

    keys = [
        f"world.map={rectangle_map(tmp_path)}",
        "world.bounds_m=map",
        "world.n_robots=5",
        "world.placement=connected",
        "world.start_m=[45.0, 25.0]",
        "world.centre_side_m=10",
        "channel.range_m=40",
        "mobility.model=static",
        "coverage.enabled=true",
        "coverage.plan=global",
        f"coverage.expansion={expansion}",
        "protocol.message_rate_hz=0",
        "duration_s=40",
    ]
    summary = execute(load(None, keys)).summary
    assert summary["covered_of_bound_all_start"] == 1.0
    assert (summary["distance_mean_m"] > 1.0) is moves


def test_walls_push_within_the_borders_margin(tmp_path):
    """On a map the walls push as the area's border does: within sqrt(3) r_c / 2 of the
    nearest wall, not within a smaller margin."""
    from netsim import config
    from netsim.run import build
    from netsim.world.free_space import wall_forces

    occupied = np.zeros((100, 100), bool)
    occupied[:, 50] = True  # a wall down the middle of a 100 m square of 1 m cells
    path = save_map(tmp_path / "wall.yaml", occupied, ~occupied, 1.0)
    sim = build(
        config.load(
            None,
            [
                "world.n_robots=4",
                "world.side_m=100",
                f"world.map={str(path)!r}".replace("'", '"'),
                "world.placement='centre'",
                "world.centre_side_m=10",
                "mobility.model='static'",
                "channel.range_m=30",
                "coverage.enabled=true",
                "coverage.plan='global'",
                "coverage.expansion=0",
                "duration_s=20",
            ],
        )
    )
    cov = sim.models["coverage"]
    margin = math.sqrt(3) * 30.0 / 2
    # Points 20 m (within the margin, beyond r_c / 2) and 30 m (beyond it) left of the wall.
    push = cov._wall_push(np.array([[30.5, 40.5], [20.5, 40.5]]))
    assert push[0, 0] < 0 and push[0, 1] == 0.0
    assert np.array_equal(
        push, wall_forces(cov.occupancy, cov.obstacles, [[30.5, 40.5], [20.5, 40.5]], margin, cov.cfg.gain)
    )
    assert not push[1].any()
