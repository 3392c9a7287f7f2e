"""The area as a rectangle in the world (map's) frame: ``world.bounds_m`` (docs/model.md
section 1, docs/radio.md "Maps")."""

from __future__ import annotations

import math
import warnings

import numpy as np
import pandas as pd
import pytest
import simpy
from netsim.mobility.forces import SQRT3, border_forces
from netsim.mobility.gauss_markov import GaussMarkovParams, gauss_markov_robot
from netsim.mobility.random_waypoint import stationary_start
from netsim.mobility.steps import box_limit

from netsim import load, metrics
from netsim.area import Bounds
from netsim.config import ConfigWarning, world_bounds
from netsim.formats import bonnmotion
from netsim.metrics import MEAN_LEG_UNIT_SQUARE, mean_distance_rectangle
from netsim.placement import grid, initial_positions
from netsim.rng import Streams
from netsim.run import build, collect
from netsim.state import RobotState
from netsim.tools.cli import main
from netsim.tools.validate import rwp_density
from netsim.world.maps import cached_map, save_map
from tests.fixtures import check_refused

# A rectangle across the origin, wider than high, nowhere near [0, side_m]^2.
RECT = [-300.0, 100.0, 200.0, 400.0]


def _run(settings: list[str]) -> dict[str, pd.DataFrame]:
    sim = build(load(None, ["protocol.model=none", "output.position_interval_s=0", *settings]))
    sim.run()
    return collect(sim)


def _leg_ends(legs: pd.DataFrame, t_end: float) -> np.ndarray:
    """Every robot's position at the start and the end of each of its legs (a straight
    leg between two points of a rectangle stays in it)."""
    legs = legs.sort_values(["robot", "t_s"], kind="stable")
    nxt = legs.groupby("robot")["t_s"].shift(-1).fillna(t_end).to_numpy()
    start = legs[["x_m", "y_m"]].to_numpy()
    end = start + legs[["vx_mps", "vy_mps"]].to_numpy() * (nxt - legs["t_s"].to_numpy())[:, None]
    return np.concatenate([start, end])


def ros_map(tmp_path, width_m=60.0, height_m=40.0, resolution_m=0.05, origin=(-10.0, -20.0)):
    """A map as ``map_saver`` writes one of a 60 m x 40 m floor at 5 cm, origin [-10, -20]
    (the start pose 10 m and 20 m inside), with an outer wall and two inner walls with doors."""
    h, w = round(height_m / resolution_m), round(width_m / resolution_m)
    occ = np.zeros((h, w), dtype=bool)
    t = round(0.2 / resolution_m)
    occ[:t], occ[-t:], occ[:, :t], occ[:, -t:] = True, True, True, True
    # A wall at x = 10 m (column) with a door at y in [-2, 2], and one at y = 5 m (row)
    # from x = 25 m on, with a door at x in [35, 38].
    col = round((10.0 - origin[0]) / resolution_m)
    occ[:, col : col + t] = True
    door = slice(round((-2.0 - origin[1]) / resolution_m), round((2.0 - origin[1]) / resolution_m))
    occ[door, col : col + t] = False
    row = round((5.0 - origin[1]) / resolution_m)
    occ[row : row + t, round((25.0 - origin[0]) / resolution_m) :] = True
    occ[row : row + t, round((35.0 - origin[0]) / resolution_m) : round((38.0 - origin[0]) / resolution_m)] = False
    occ[:t], occ[-t:], occ[:, :t], occ[:, -t:] = True, True, True, True
    return save_map(tmp_path / "floor.yaml", occ, ~occ, resolution_m, origin)


# -- the key -----------------------------------------------------------------------------


def test_default_bounds_are_the_square_of_side_m():
    """Without ``world.bounds_m`` the area is ``[0, 0, side_m, side_m]``."""
    c = load(None, ["world.side_m=321"])
    assert c.world.bounds_m == (0.0, 0.0, 321.0, 321.0)
    assert world_bounds(c.world) == Bounds(0.0, 0.0, 321.0, 321.0)


def test_map_bounds_are_the_map_extent(tmp_path):
    """``world.bounds_m = "map"`` is the map's whole extent, in its own frame."""
    c = load(None, [f"world.map={ros_map(tmp_path)}", "world.bounds_m=map", "mobility.model=static"])
    b = world_bounds(c.world)
    assert (b.x_min, b.y_min, b.x_max, b.y_max) == pytest.approx((-10.0, -20.0, 50.0, 20.0))


@pytest.mark.parametrize(
    "overrides, words",
    [
        (["world.bounds_m=[0, 0, -5, 100]"], "x_max > x_min"),
        (["world.bounds_m=[0, 10, 100, 10]"], "x_max > x_min"),
        (["world.bounds_m=[0, 0, inf, 100]"], "x_max > x_min"),
        (["world.bounds_m=[0, 0, nan, 100]"], "x_max > x_min"),
        (["world.bounds_m=[0, 0, 100]"], "x_max > x_min"),
        (["world.bounds_m=wide"], "x_max > x_min"),
        (["world.bounds_m=map"], "needs a map"),
        (["world.torus=true", "world.bounds_m=[0, 0, 1000, 500]"], "torus"),
        (["world.torus=true", "world.bounds_m=[-500, -500, 500, 500]"], "torus"),
    ],
)
def test_bad_bounds_are_one_line_exit_2_nothing_written(tmp_path, capsys, overrides, words):
    """A bad ``world.bounds_m`` is refused in one line naming it: exit 2, nothing written."""
    check_refused(tmp_path, capsys, overrides, "world.bounds_m", words)


def test_bounds_outside_the_map_arecheck_refused(tmp_path, capsys):
    """Bounds the map does not cover: one line naming ``world.bounds_m`` and the map's extent."""
    path = ros_map(tmp_path)
    overrides = [f"world.map={path}", "world.bounds_m=[-20, -20, 40, 20]", "mobility.model=static"]
    check_refused(tmp_path, capsys, overrides, "world.bounds_m", "is not inside world.map")


@pytest.mark.parametrize(
    "overrides, key, words",
    [
        (
            ["world.bounds_m=[0, 0, 2000, 2000]"],
            "world.bounds_m",
            "world.bounds_m = [0.0, 0.0, 2000.0, 2000.0]: is not inside world.map = 'office', "
            "which covers x in [0, 200], y in [0, 200]",
        ),
        (
            ["world.side_m=2000"],
            "world.map",
            "world.map = 'office': covers 200 m x 200 m, smaller than the area (2000 m x 2000 m, world.side_m)",
        ),
    ],
    ids=["bounds-set", "side-set"],
)
def test_an_area_the_map_does_not_cover_is_told_by_the_key_that_made_it(tmp_path, capsys, overrides, key, words):
    """An area the map does not cover names the key the user set and its value: bounds set
    (a square at the origin included) name ``world.bounds_m`` and its numbers, never the
    map's name as their value nor world.side_m; an area from ``world.side_m`` names the map
    as too small."""
    check_refused(tmp_path, capsys, ["world.map=office", "mobility.model=static", *overrides], key, words)


# -- placement -----------------------------------------------------------------------------


@pytest.mark.parametrize("placement", ["uniform", "grid", "centre"])
def test_placement_fills_the_rectangle(placement):
    """Every placement puts robots in the rectangle, spread over it (``centre``: around its middle)."""
    c = load(None, [f"world.bounds_m={RECT}", f"world.placement={placement}", "world.n_robots=400"])
    xy = initial_positions(c.world, Streams(1, 0))
    b = Bounds(*RECT)
    assert b.contains(xy).all()
    if placement == "centre":
        assert np.allclose(xy.mean(axis=0), [-50.0, 250.0], atol=15.0)
    else:
        assert xy[:, 0].min() < -280 and xy[:, 0].max() > 180
        assert xy[:, 1].min() < 120 and xy[:, 1].max() > 380


def test_csv_placement_is_in_the_world_frame_and_checked_against_the_bounds(tmp_path, capsys):
    """CSV positions are world coordinates: negative ones inside the bounds are kept as
    they are (in the positions table too), and one outside is refused naming the bounds."""
    csv = tmp_path / "at.csv"
    pd.DataFrame({"x_m": [-250.0, 150.0], "y_m": [120.0, 390.0]}).to_csv(csv, index=False)
    sets = ["world.n_robots=2", f"world.bounds_m={RECT}", f"world.placement={csv}", "mobility.model=static"]
    sim = build(load(None, ["protocol.model=none", "duration_s=5", *sets]))
    sim.run()
    pos = collect(sim)["positions"]
    assert np.array_equal(pos[pos["t_s"] == 5.0][["x_m", "y_m"]].to_numpy(), [[-250.0, 120.0], [150.0, 390.0]])
    pd.DataFrame({"x_m": [-250.0, 150.0], "y_m": [120.0, 50.0]}).to_csv(csv, index=False)
    check_refused(tmp_path, capsys, sets, "world.placement", "world.bounds_m")


def test_csv_placement_of_two_robots_on_one_point_is_warned_naming_them(tmp_path):
    """Robots a CSV file puts on one point are named in one warning (forces cannot part
    them); distinct points, however close, are not warned about."""
    csv = tmp_path / "at.csv"
    sets = ["world.n_robots=4", f"world.placement={csv}", "mobility.model=static", "protocol.model=none"]
    pd.DataFrame({"x_m": [10.0, 50.0, 10.0, 10.0], "y_m": [10.0, 50.0, 10.0, 20.0]}).to_csv(csv, index=False)
    with pytest.warns(ConfigWarning, match=r"robots 0, 2 share the position \(10, 10\):") as told:
        build(load(None, sets))
    assert len(told) == 1
    # Two pairs: the second pair's two robots are the more.
    pd.DataFrame({"x_m": [10.0, 50.0, 10.0, 50.0], "y_m": [10.0, 50.0, 10.0, 50.0]}).to_csv(csv, index=False)
    with pytest.warns(ConfigWarning, match=r"robots 0, 2 share the position \(10, 10\) \(and 2 more robots on"):
        build(load(None, sets))
    pd.DataFrame({"x_m": [10.0, 50.0, 10.0, 10.0], "y_m": [10.0, 50.0, 10.000001, 20.0]}).to_csv(csv, index=False)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        build(load(None, sets))


def test_grid_placement_fills_the_cells_row_by_row():
    """Grid placement: the centres of a ``ceil(sqrt(N))``-square grid of cells over the area,
    robot ``k`` in row ``k // side`` and column ``k % side`` from the lower-left corner."""
    xy = grid(5, Bounds(-30.0, 0.0, 30.0, 90.0))
    assert xy.tolist() == [[-20.0, 15.0], [0.0, 15.0], [20.0, 15.0], [-20.0, 45.0], [0.0, 45.0]]


def test_centre_placement_on_a_map_is_in_the_free_part_of_the_central_square():
    """On a map ``centre`` draws from the free cells of the central square only."""
    sets = ["world.map=office", "world.side_m=200", "world.placement=centre", "world.centre_side_m=60"]
    c = load(None, [*sets, "world.n_robots=200"])
    office = cached_map("office")
    xy = initial_positions(c.world, Streams(1, 0), occupancy=office)
    assert ((xy >= 70.0) & (xy <= 130.0)).all() and office.is_free(xy).all()


# -- every mobility model ------------------------------------------------------------------


@pytest.mark.parametrize(
    "settings",
    [
        ["mobility.model=random_waypoint", "mobility.stationary_start=true", "mobility.speed_max_mps=20"],
        [
            "mobility.model=random_waypoint",
            "mobility.stationary_start=false",
            "mobility.pause_s=2",
            "mobility.speed_max_mps=20",
        ],
        ["mobility.model=random_direction", "mobility.pause_s=1", "mobility.speed_max_mps=20"],
        ["mobility.model=gauss_markov", "mobility.mean_speed_mps=15", "mobility.alpha=0.3"],
        ["mobility.model=rpgm", "mobility.group_radius_m=30", "mobility.group_size=3", "mobility.speed_max_mps=20"],
    ],
    ids=["rwp_stationary", "rwp_fresh", "random_direction", "gauss_markov", "rpgm"],
)
def test_every_mobility_model_keeps_robots_in_the_rectangle_and_uses_all_of_it(settings):
    """Every leg starts and ends in the rectangle, and robots reach near each of its four borders."""
    sets = [f"world.bounds_m={RECT}", "world.n_robots=24", "duration_s=400"]
    legs = _run([*sets, *settings])["legs"]
    xy = _leg_ends(legs, 400.0)
    assert Bounds(*RECT).contains(xy, tol_m=1e-9).all()
    assert xy[:, 0].min() < -250 and xy[:, 0].max() > 150
    assert xy[:, 1].min() < 150 and xy[:, 1].max() > 350


class _West:
    """A stand-in random generator for Gauss-Markov: mean direction pi (west), no noise."""

    def uniform(self, lo, hi, size=None):
        return math.pi

    def standard_normal(self, size):
        return np.zeros(size)


def _gauss_markov_west(x0: float) -> np.ndarray:
    env = simpy.Environment()
    st = RobotState(1, 1000.0, 10.0, bounds=Bounds(*RECT))
    st.place(np.array([[x0, 250.0]]))
    p = GaussMarkovParams(alpha=0.5, mean_speed_mps=2.0, speed_sigma_mps=0.0, direction_sigma_rad=0.0)
    env.process(gauss_markov_robot(env, st, p, st.bounds, 0, _West()))
    env.run(until=10.5)
    return st.legs()[["vx_mps"]].to_numpy()[1:, 0]


def test_gauss_markov_turns_at_the_rectangle_border_not_at_zero():
    """Heading west, a robot crosses x = 0 inside the rectangle without turning, and turns
    back east at the rectangle's x_min."""
    assert np.all(_gauss_markov_west(3.0) < 0)
    vx = _gauss_markov_west(-297.0)
    assert vx[0] < 0 and np.all(vx[1:] > 0), vx


def test_static_robots_stay_where_placed_in_the_rectangle():
    """Static robots are placed in the rectangle and do not move."""
    legs = _run([f"world.bounds_m={RECT}", "world.n_robots=30", "duration_s=10", "mobility.model=static"])["legs"]
    assert len(legs) == 30 and Bounds(*RECT).contains(legs[["x_m", "y_m"]]).all()


def test_external_robots_stop_at_the_rectangle_border():
    """A robot driven from outside stops where it meets the rectangle's border, at its x_min."""
    sim = build(
        load(None, ["protocol.model=none", "world.n_robots=1", f"world.bounds_m={RECT}", "mobility.model=external"])
    )
    start = sim.state.positions_at(0.0)[0]
    sim.run(until_s=1.0)
    sim.drive([0], [[-10.0, 0.0]])
    sim.run(until_s=200.0)
    assert sim.state.positions_at(200.0)[0] == pytest.approx([-300.0, start[1]])


def test_trace_positions_must_lie_in_the_bounds(tmp_path, capsys):
    """A trace inside a negative rectangle replays as given; one leaving it is refused naming the bounds."""
    path = tmp_path / "s.movements"
    path.write_text("0 -290 110 10 190 390\n")
    sets = ["mobility.model=trace", f"mobility.trace_file={path}", "world.n_robots=1", f"world.bounds_m={RECT}"]
    sets.append("duration_s=10")  # as long as the trace: no standing still after its end
    legs = _run(sets)["legs"]
    assert legs.iloc[0][["x_m", "y_m"]].tolist() == [-290.0, 110.0]
    path.write_text("0 -290 110 10 190 410\n")
    check_refused(tmp_path, capsys, sets, "world.bounds_m", str(path))


# -- random waypoint's stationary start on a rectangle -----------------------------------


def test_mean_leg_on_a_rectangle_is_the_mean_distance_of_two_uniform_points():
    """``E[L]`` on an ``a x b`` rectangle (Ghosh's closed form) is the Monte Carlo mean, and
    the unit square's constant when ``a = b``."""
    rng = np.random.default_rng(5)
    p, q = rng.uniform(0, 1, (2, 400_000, 2)) * [4.0, 1.0]
    assert mean_distance_rectangle(4.0, 1.0) == pytest.approx(np.hypot(*(p - q).T).mean(), rel=3e-3)
    assert mean_distance_rectangle(3.0, 3.0) == pytest.approx(3 * MEAN_LEG_UNIT_SQUARE, rel=1e-12)


@pytest.mark.slow
def test_stationary_start_on_a_rectangle_is_stationary():
    """Started in the stationary regime on a rectangle, robots' positions and the fraction
    paused at t = 0 are those of a long run (Navidi and Camp's law, for any rectangle): the
    x and y histograms at 0 s and at 600 s agree, and differ from a uniform start's."""
    b = [-100.0, 0.0, 300.0, 100.0]
    sets = [f"world.bounds_m={b}", "world.n_robots=1500", "mobility.speed_min_mps=2", "mobility.speed_max_mps=6"]
    sim = build(load(None, ["protocol.model=none", "duration_s=600", "mobility.pause_s=20", *sets]))
    sim.run(until_s=1e-6)
    at0 = sim.state.positions_at(0.0)
    still0 = np.mean(np.hypot(*sim.state.velocity_mps.T) == 0)
    sim.run()
    at1 = sim.state.positions_at(600.0)
    still1 = np.mean(np.hypot(*sim.state.velocity_mps.T) == 0)
    edges = [np.linspace(-100, 300, 9), np.linspace(0, 100, 5)]
    for k in range(2):
        h0 = np.histogram(at0[:, k], edges[k])[0] / len(at0)
        h1 = np.histogram(at1[:, k], edges[k])[0] / len(at1)
        uniform = np.diff(edges[k]) / (edges[k][-1] - edges[k][0])
        assert np.abs(h0 - h1).max() < 0.035
        assert np.abs(h1 - uniform).max() > 0.04
    assert still0 == pytest.approx(still1, abs=0.04)


@pytest.mark.parametrize("pt", [(0.0, 0.5), (-0.9, 0.1), (0.6, 0.8)])
def test_stationary_start_spatial_density_on_a_rectangle(pt):
    """Items 3 and 4 on the rectangle ``[-1, 0, 1, 1]``: positions at t = 0 follow Hyytiä
    et al.'s exact density for a ``2 x 1`` rectangle, shifted to its corner (counts in a
    0.05 x 0.05 box within 4 Poisson standard deviations of the integrated density)."""
    n, h = 400_000, 0.05
    s = stationary_start(np.random.default_rng(3), n, Bounds(-1.0, 0.0, 1.0, 1.0), 0.01, 0.05, 0.0)
    offsets = (np.arange(5) + 0.5) / 5 * h - h / 2
    mass = np.mean([rwp_density(pt[0] + 1 + dx, pt[1] + dy, 2.0, 1.0) for dx in offsets for dy in offsets]) * h * h
    p = s.position_m
    count = int(((np.abs(p[:, 0] - pt[0]) < h / 2) & (np.abs(p[:, 1] - pt[1]) < h / 2)).sum())
    assert abs(count - n * mass) < 4 * math.sqrt(n * mass)


def test_stationary_start_draws_inside_the_rectangle():
    """Positions and destinations of the stationary start lie in the rectangle."""
    s = stationary_start(np.random.default_rng(2), 2000, Bounds(*RECT), 1.0, 5.0, 3.0)
    assert Bounds(*RECT).contains(s.position_m).all() and Bounds(*RECT).contains(s.destination_m).all()


# -- coverage: bound, covered fraction, border forces, step limits --------------------------


def test_coverage_bound_uses_the_rectangle_area():
    """``U(N) / A`` with ``A`` the rectangle's area ``width x height``."""
    u = metrics.connected_coverage_bound(10, 20.0, 30.0)
    assert metrics.bound_fraction(10, 20.0, Bounds(*RECT), 30.0) == pytest.approx(u / (500.0 * 300.0), rel=1e-15)


def test_covered_fraction_is_over_the_rectangle():
    """One disk inside the rectangle covers ``pi r^2 / A``; one outside it, nothing (exact and grid)."""
    b = Bounds(*RECT)
    exact, err = metrics.covered_fraction_exact([[-50.0, 250.0]], 20.0, b)
    assert abs(exact - math.pi * 400.0 / b.area) <= err + 1e-9
    grid, gerr = metrics.covered_fraction([[-50.0, 250.0]], 20.0, b, cells=400)
    assert abs(grid - math.pi * 400.0 / b.area) <= gerr
    assert metrics.covered_fraction_exact([[100.0, 50.0]], 20.0, b)[0] == 0.0
    assert metrics.covered_fraction([[100.0, 50.0]], 20.0, b)[0] == 0.0


def test_border_forces_push_inward_from_every_border_of_the_rectangle():
    """Within ``sqrt(3) r_c / 2`` of a border the push is ``gain (margin - distance)`` inward."""
    b = Bounds(*RECT)
    margin = SQRT3 * 40.0 / 2
    p = np.array([[-295.0, 250.0], [195.0, 250.0], [0.0, 105.0], [0.0, 395.0], [0.0, 250.0]])
    f = border_forces(p, b, 40.0, 2.0)
    push = 2 * (margin - 5)
    assert np.allclose(f, [[push, 0], [-push, 0], [0, push], [0, -push], [0, 0]], rtol=1e-12, atol=0)


def test_box_limit_stops_steps_at_the_rectangle_border():
    """A step toward a border is shortened to end (just) on it."""
    s = box_limit(np.array([[-290.0, 250.0], [0.0, 390.0]]), np.array([[-20.0, 0.0], [0.0, 40.0]]), Bounds(*RECT))
    assert s == pytest.approx([0.5, 0.25])


def test_box_limit_of_a_move_of_a_few_ulps_is_the_whole_move_without_a_warning():
    """The quotient overflows to inf (the suite turns a RuntimeWarning into an error)."""
    s = box_limit(np.array([[0.0, 250.0], [0.0, 250.0]]), np.array([[1e-310, 0.0], [-1e-310, 1e-310]]), Bounds(*RECT))
    assert s.tolist() == [1.0, 1.0]


@pytest.mark.slow
def test_coverage_run_on_a_rectangle_reports_the_rectangle_bound_and_stays_inside():
    """The coverage controller's ``coverage_bound`` is ``min(1, U(N) / A)`` for the
    rectangle, and its robots stay in the rectangle."""
    sets = [
        "world.n_robots=20",
        "duration_s=60",
        "world.bounds_m=[-200, -100, 200, 100]",
        "world.placement=centre",
        "world.centre_side_m=60",
        "mobility.model=static",
        "channel.range_m=40",
        "coverage.enabled=true",
        "protocol.message_rate_hz=0",
    ]
    sim = build(load(None, ["output.position_interval_s=0", *sets]))
    sim.run()
    frames = collect(sim)
    cov = frames["coverage"]
    u = metrics.connected_coverage_bound(20, 40.0, 40.0)
    assert cov["coverage_bound"].to_numpy() == pytest.approx(min(1.0, u / (400.0 * 200.0)))
    xy = _leg_ends(frames["legs"], 60.0)
    assert Bounds(-200, -100, 200, 100).contains(xy, tol_m=1e-9).all()
    assert xy[:, 0].min() < -30  # it spread into the negative half


# -- a real-sized ROS map in its own frame ----------------------------------------------------


@pytest.mark.slow
def test_run_on_a_ros_map_uses_the_whole_map(tmp_path):
    """On a 60 m x 40 m map at 5 cm with origin [-10, -20] and ``world.bounds_m = "map"``,
    placement covers the whole map and robots reach every part of it, negative coordinates
    included, in free cells only; positions are in the map's frame."""
    path = ros_map(tmp_path)
    sets = [
        f"world.map={path}",
        "world.bounds_m=map",
        "world.n_robots=40",
        "duration_s=150",
        "channel.range_m=15",
        "mobility.speed_min_mps=1",
        "mobility.speed_max_mps=3",
        "output.position_interval_s=5",
    ]
    sim = build(load(None, ["protocol.model=none", *sets]))
    start = sim.state.positions_at(0.0)
    sim.run()
    frames = collect(sim)
    assert start[:, 0].min() < 0 and start[:, 1].min() < 0
    assert start[:, 0].min() < -5 and start[:, 0].max() > 45 and start[:, 1].min() < -15 and start[:, 1].max() > 15
    xy = _leg_ends(frames["legs"], 150.0)
    assert xy[:, 0].min() < -8 and xy[:, 0].max() > 48 and xy[:, 1].min() < -18 and xy[:, 1].max() > 18
    pos = frames["positions"][["x_m", "y_m"]].to_numpy()
    from netsim.world.maps import load_map

    assert load_map(path).is_free(pos).all()
    # Every quadrant of the map's frame is visited (the start pose at 0, 0 is inside).
    for sx in (-1, 1):
        for sy in (-1, 1):
            assert ((np.sign(pos[:, 0]) == sx) & (np.sign(pos[:, 1]) == sy)).any()


# -- export --------------------------------------------------------------------------------


def test_bonnmotion_export_of_a_map_frame_run_round_trips(tmp_path):
    """A run whose area reaches below 0 exports positions in its own frame, its size as
    ``x``, ``y`` and its corner as ``x_min``, ``y_min``; read back, the same waypoints."""
    out = tmp_path / "run"
    sets = [f"world.bounds_m={RECT}", "world.n_robots=4", "duration_s=30", "mobility.stationary_start=false"]
    assert main(["run", "--quiet", "--out", str(out), *(a for s in sets for a in ("--set", s))]) == 0
    path = tmp_path / "s.movements"
    assert main(["export", str(out), "--format", "bonnmotion", "--out", str(path)]) == 0
    params = bonnmotion.read_params(bonnmotion.params_path(path))
    assert [float(params[k]) for k in ("x", "y", "x_min", "y_min")] == [500.0, 300.0, -300.0, 100.0]
    wp, _ = bonnmotion.read(path)
    assert Bounds(*RECT).contains(np.column_stack([wp.x_m, wp.y_m])).all()
    assert (wp.x_m < 0).any()


@pytest.mark.slow
def test_replay_data_carries_the_bounds(tmp_path):
    """The replay page gets the area's bounds to frame and draw it."""
    from netsim.tools.viewer.data import pack

    out = tmp_path / "run"
    sets = [f"world.bounds_m={RECT}", "world.n_robots=4", "duration_s=10"]
    assert main(["run", "--quiet", "--out", str(out), *(a for s in sets for a in ("--set", s))]) == 0
    assert pack(out)["meta"]["bounds_m"] == RECT


def test_a_robot_on_the_border_moving_out_leaves_at_plus_zero():
    """The time to leave a box is +0 for a robot on its border heading out, -0 coordinate
    included: a step scaled by it must not carry a negative zero into the tables."""
    from netsim.area import exit_times, time_to_border

    p = np.array([[-0.0, 5.0], [0.0, 5.0], [10.0, 5.0]])
    v = np.array([[-1.0, 0.0], [-2.0, 0.0], [3.0, 0.0]])
    t = exit_times(p, v, (0.0, 0.0), (10.0, 10.0))
    assert t.tolist() == [0.0, 0.0, 0.0] and not np.signbit(t).any()
    assert not np.signbit(time_to_border(p, v, 10.0)).any()
    assert exit_times(np.array([[5.0, 5.0]]), np.zeros((1, 2)), (0.0, 0.0), (10.0, 10.0)).tolist() == [math.inf]


@pytest.mark.parametrize("pause_s", [0.0, 5.0])
def test_random_direction_stops_exactly_on_the_border_and_leaves_inward(pause_s):
    """Every leg random direction logs at the border starts on it to the bit (along the axis
    it ran out at), so the heading it then takes points inward and no leg is a sliver: a
    robot put down a rounding error inside (1.1e-13 m) could head out again, reach the
    border picoseconds later, and pause there a second time."""
    settings = ["seed=1", "protocol.model=none", "world.n_robots=20", "duration_s=600"]
    settings += ["mobility.model=random_direction", f"mobility.pause_s={pause_s}", "mobility.speed_max_mps=20"]
    sim = build(load(None, settings))
    sim.run()
    legs = collect(sim)["legs"].sort_values(["robot", "t_s"], kind="stable")
    side = sim.config.world.side_m
    at_border = legs[legs["cause"].isin(["border", "pause_end"])]
    assert len(at_border) > 50
    p, v = at_border[["x_m", "y_m"]].to_numpy(), at_border[["vx_mps", "vy_mps"]].to_numpy()
    assert ((p == 0.0) | (p == side)).any(axis=1).all()
    assert not (((p == 0.0) & (v < 0)) | ((p == side) & (v > 0))).any()
    t, robot = legs["t_s"].to_numpy(), legs["robot"].to_numpy()
    later = (np.diff(robot) == 0) & (t[1:] > 0)  # the placement at t = 0 logs two rows
    assert (np.diff(t)[later] > 1e-6).all()


def _trace_args(tmp_path, name: str, text: str, n_robots: int, duration_s: float) -> list[str]:
    """``netsim run`` replaying ``text`` (a trace file written as ``name``), without --out."""
    trace = tmp_path / name
    trace.write_text(text)
    sets = ["mobility.model=trace", f"mobility.trace_file={trace}", f"world.n_robots={n_robots}"]
    return ["run", "--quiet", *(a for s in [*sets, f"duration_s={duration_s}"] for a in ("--set", s))]


# Node 0 starts at (-10.5, 4), below 0, and at t = 1 s heads for (X, 10) at 20 m/s.
BELOW_ZERO_NS2 = (
    "$node_(0) set X_ -10.5\n$node_(0) set Y_ 4.0\n$node_(1) set X_ 20.0\n$node_(1) set Y_ -3.25\n"
    '$ns_ at 1.0 "$node_(0) setdest {x} 10.0 20.0"\n'
)


def test_a_trace_below_zero_on_the_default_square_names_world_bounds_m(tmp_path, capsys):
    """A trace recorded in a map's frame (coordinates below 0) on the default square: the
    error says the square cannot hold it and names world.bounds_m with a frame of whole
    metres holding where the robots start and go up to duration_s (node 0's setdest takes
    it to (30, 10)); pasted as printed, the run goes ahead."""
    base = _trace_args(tmp_path, "frame.tcl", BELOW_ZERO_NS2.format(x="30.0"), 2, 5)
    assert main([*base, "--out", str(tmp_path / "a")]) == 2
    err = capsys.readouterr().err.strip()
    assert "has coordinates below 0" in err, err
    assert err.endswith(
        "set world.bounds_m to a frame holding them and the motion up to duration_s, such as [-11, -4, 30, 10]"
    ), err
    assert not (tmp_path / "a").exists()
    assert main([*base, "--set", "world.bounds_m=[-11, -4, 30, 10]", "--out", str(tmp_path / "b")]) == 0


def test_a_trace_that_leaves_the_bounds_names_the_frame_holding_its_motion(tmp_path, capsys):
    """An ns-2 trace that starts inside world.bounds_m and moves out of it: the one line
    names the robot and the time, and the frame (whole metres) holding the replay up to
    duration_s; one that starts outside them, the whole trace's frame. Coordinates read to
    fewer digits would cut them, so they are rounded outward: pasted, they hold the run."""
    base = _trace_args(tmp_path, "away.tcl", BELOW_ZERO_NS2.format(x="30.123456789"), 2, 5)
    assert main([*base, "--set", "world.bounds_m=[-11, -4, 20, 4]", "--out", str(tmp_path / "a")]) == 2
    err = capsys.readouterr().err.strip()
    assert "robot 0 leaves the area" in err and len(err.splitlines()) == 1, err
    assert err.endswith("; world.bounds_m = [-11, -4, 31, 10] holds its motion up to duration_s"), err
    assert not (tmp_path / "a").exists()
    assert main([*base, "--set", "world.bounds_m=[-11, -4, 31, 10]", "--out", str(tmp_path / "b")]) == 0


def test_a_frame_holding_positions_is_whole_metres_around_them():
    from netsim.mobility.trace_replay import frame_holding

    assert frame_holding(np.array([-5.13523, 44.5372]), np.array([-16.9728, 17.0515])) == "[-6, -17, 45, 18]"
    assert frame_holding(np.array([2.0, 2.0]), np.array([-1.0, -1.0])) == "[2, -1, 3, 0]"  # a metre across


# -- rules the mutation audit found unguarded ------------------------------------------------


def test_an_area_may_reach_the_farthest_coordinate_and_no_further_and_its_side_must_be_positive():
    """The limits of the area's keys are inclusive at the farthest coordinate, and a side of 0 is none."""
    from netsim.area import MAX_COORDINATE_M, area_side, within_reach_of_doubles

    assert within_reach_of_doubles(MAX_COORDINATE_M) is None and within_reach_of_doubles(-MAX_COORDINATE_M) is None
    assert within_reach_of_doubles(1.000001 * MAX_COORDINATE_M) == "must be at most 1e+12 m in size"
    assert area_side(MAX_COORDINATE_M) is None
    assert area_side(0.0) == area_side(-1.0) == area_side(2 * MAX_COORDINATE_M) == "must be in (0, 1e+12] (metres)"


def test_a_rectangles_diagonal_and_a_squares_are_their_lengths():
    assert Bounds(0.0, 0.0, 3.0, 4.0).diagonal == 5.0
    assert Bounds(-1.0, 2.0, 3.0, 6.0).diagonal == 4.0 * math.sqrt(2)


def test_points_uniform_over_a_square_off_the_origin_lie_in_it():
    """Only the square at the origin takes the draws of ``uniform(0, side)``: a square
    shifted along one axis alone is drawn over itself."""
    for b in (Bounds(0.0, 50.0, 10.0, 60.0), Bounds(50.0, 0.0, 60.0, 10.0)):
        p = b.uniform(np.random.default_rng(0), 200)
        assert b.contains(p).all()


def test_the_rectangle_is_closed_on_every_side():
    b = Bounds(-1.0, -2.0, 3.0, 4.0)
    corners = [[-1.0, -2.0], [3.0, -2.0], [3.0, 4.0], [-1.0, 4.0]]
    assert b.contains(corners).all()
    assert not b.contains([[3.0, 4.0 + 1e-12]]).any()
    assert b.contains([[3.0, 4.5]], tol_m=0.5).all()


def test_a_robot_already_outside_on_its_way_out_reaches_the_border_at_once():
    """``exit_times`` is negative there; the time to the border is 0, never a time past."""
    from netsim.area import exit_times, time_to_border

    p, v = np.array([[12.0, 5.0]]), np.array([[1.0, 0.0]])
    assert exit_times(p, v, (0.0, 0.0), (10.0, 10.0)).tolist() == [-2.0]
    assert time_to_border(p, v, 10.0).tolist() == [0.0]


@pytest.mark.parametrize(
    "value", [[0.0, 0.0, 0.0, 10.0], [0.0, 0.0, 10.0, 0.0], [True, 0.0, 10.0, 10.0], [0.0, 0.0, 10.0, False]]
)
def test_bounds_of_no_width_or_height_or_with_a_boolean_are_refused(value):
    from netsim.area import parse_bounds
    from netsim.errors import ConfigError

    with pytest.raises(ConfigError, match="x_max > x_min, y_max > y_min"):
        parse_bounds("world.bounds_m", value)


@pytest.mark.parametrize("value", [[float("nan"), 0.0], [0.0, float("inf")], [True, 0.0]])
def test_a_start_point_not_of_two_finite_numbers_is_refused(value):
    from netsim.area import parse_start
    from netsim.errors import ConfigError

    with pytest.raises(ConfigError, match=r"must be \[x, y\]"):
        parse_start("world.start_m", value)


def test_a_start_point_is_read_as_x_then_y():
    from netsim.area import parse_start

    assert parse_start("world.start_m", [1, 2.5]) == (1.0, 2.5)


def test_a_run_whose_map_moved_says_where_to_point_it(tmp_path, capsys):
    """A run on a map keeps the map's path as it ran: moved to where that path is gone, a
    command that reads the run says so in one line, with the two ways out (the map put
    back, or world.map in the run's config.toml); edited so, the command goes ahead."""
    from netsim.tools.cli import main

    yaml = ros_map(tmp_path)
    run = tmp_path / "run"
    argv = ["run", "--quiet", "--out", str(run), "--set", f"world.map={yaml}", "--set", "world.bounds_m=map"]
    assert main([*argv, "--set", "world.n_robots=3", "--set", "duration_s=5", "--set", "world.centre_side_m=5"]) == 0
    moved = tmp_path / "elsewhere"
    moved.mkdir()
    for p in (yaml, yaml.with_suffix(".pgm")):
        p.rename(moved / p.name)
    capsys.readouterr()
    assert main(["export", str(run), "--format", "ns2", "--out", str(tmp_path / "m.tcl")]) == 2
    err = capsys.readouterr().err.strip()
    assert err.startswith(f"netsim: error: world.map = '{yaml}': ") and "\n" not in err, err
    assert err.endswith(
        f": the run's map, read from where it ran; copy the map there, or set world.map in {run / 'config.toml'} "
        "to where it is now"
    ), err
    assert not (tmp_path / "m.tcl").exists()
    # A map there but broken is its own fault, not a move: no advice to move it.
    yaml.write_text("image: [unclosed\n")
    assert main(["export", str(run), "--format", "ns2", "--out", str(tmp_path / "m.tcl")]) == 2
    err = capsys.readouterr().err.strip()
    assert err.startswith(f"netsim: error: world.map = '{yaml}': ") and "copy the map" not in err, err
    yaml.unlink()
    config = run / "config.toml"
    config.write_text(config.read_text().replace(str(yaml), str(moved / yaml.name)))
    assert main(["export", str(run), "--format", "bonnmotion", "--out", str(tmp_path / "m.movements")]) == 0


def test_a_bonnmotion_export_in_a_maps_frame_proposes_the_area_its_params_state(tmp_path, capsys):
    """The BonnMotion export of a run in a map's frame states the area in its .params
    (x_min, y_min and the size): read back on the default square, the one line proposes
    that area, exactly, and pasted the run goes ahead."""
    from netsim.tools.cli import main

    yaml = ros_map(tmp_path)
    run = tmp_path / "run"
    sets = [f"world.map={yaml}", "world.bounds_m=map", "world.n_robots=3", "duration_s=5", "world.centre_side_m=5"]
    assert main(["run", "--quiet", "--out", str(run), *(a for s in sets for a in ("--set", s))]) == 0
    trace = tmp_path / "m.movements"
    assert main(["export", str(run), "--format", "bonnmotion", "--out", str(trace)]) == 0
    base = ["run", "--quiet", "--set", "mobility.model=trace", "--set", f"mobility.trace_file={trace}"]
    base += ["--set", "world.n_robots=3", "--set", "duration_s=5"]
    capsys.readouterr()
    assert main([*base, "--out", str(tmp_path / "a")]) == 2
    err = capsys.readouterr().err.strip()
    assert err.endswith("such as [-10.0, -20.0, 50.0, 20.0] (the area its .params states)"), err
    assert main([*base, "--set", "world.bounds_m=[-10.0, -20.0, 50.0, 20.0]", "--out", str(tmp_path / "b")]) == 0


def test_the_frame_proposed_for_an_ns2_trace_holds_where_a_jump_cut_a_leg(tmp_path, capsys):
    """A leg cut by a jump ends where the robot jumped from, which neither a leg's start nor
    the end of the run shows: node 0 heads east from (-10, 5) at 10 m/s and at t = 5 s,
    at x = 40, jumps to x = -20. The frame proposed holds x = 40, and pasted, runs."""
    from netsim.tools.cli import main

    jump = (
        '$node_(0) set X_ -10.0\n$node_(0) set Y_ 5.0\n$ns_ at 0.0 "$node_(0) setdest 100.0 5.0 10.0"\n'
        '$ns_ at 5.0 "$node_(0) set X_ -20.0"\n'
    )
    base = _trace_args(tmp_path, "jump.tcl", jump, 1, 10)
    assert main([*base, "--out", str(tmp_path / "a")]) == 2
    assert capsys.readouterr().err.strip().endswith("such as [-20, 5, 40, 6]")
    assert main([*base, "--set", "world.bounds_m=[-20, 5, 40, 6]", "--out", str(tmp_path / "b")]) == 0


@pytest.mark.parametrize(
    "params", ["x_min=-5\ny_min=-5\nx=10\ny=10\n", "x_min=0\ny_min=0\nx=1000\ny=1000\n"], ids=["too-small", "at-0"]
)
def test_a_params_area_that_cannot_hold_the_trace_is_not_proposed(tmp_path, capsys, params):
    """A .params area is proposed only when it reaches below 0 and holds the positions;
    otherwise the frame around the positions is."""
    from netsim.tools.cli import main

    (tmp_path / "m.params").write_text(params)
    argv = _trace_args(tmp_path, "m.movements", "0.0 -20.0 1.0 10.0 -20.0 2.0\n", 1, 5)
    assert main([*argv, "--out", str(tmp_path / "a")]) == 2
    assert capsys.readouterr().err.strip().endswith("such as [-20, 1, -19, 2]")


def test_a_trace_below_zero_on_a_torus_is_told_to_shift_not_given_a_frame(tmp_path, capsys):
    """A torus is the square [0, side]^2, which world.bounds_m cannot move: a trace below 0
    is told to shift into it, not given a frame the torus would refuse."""
    from netsim.tools.cli import main

    argv = _trace_args(tmp_path, "below.tcl", "$node_(0) set X_ -10.0\n$node_(0) set Y_ 5.0\n", 1, 5)
    argv += ["--set", "world.torus=true"]
    assert main([*argv, "--out", str(tmp_path / "a")]) == 2
    assert capsys.readouterr().err.strip().endswith("a torus is that square; shift the trace into it")
