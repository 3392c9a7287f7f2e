"""Coverage pushes that follow free space on a map (netsim.mobility.geodesic; docs/model.md 5.3)."""

from __future__ import annotations

import numpy as np
import pytest
from netsim.mobility.geodesic import FreeGrid, _kernels, expansion_to_uncovered, in_sight, slide

from netsim.area import Bounds
from netsim.world.maps import OccupancyMap

SIDE_M = 20.0
RES_M = 0.25


def room_with_a_door() -> OccupancyMap:
    """A 20 m x 20 m floor at 25 cm a cell with a wall along x = 10 m, one 2 m door in it
    at y from 2 to 4 m."""
    n = int(SIDE_M / RES_M)
    occupied = np.zeros((n, n), bool)
    occupied[:, 40] = True  # x in [10, 10.25)
    occupied[8:16, 40] = False  # y in [2, 4)
    return OccupancyMap(occupied, ~occupied, RES_M, (0.0, 0.0))


def distance_field(grid: FreeGrid, sources, within, targets, out) -> None:
    """The search of ``FreeGrid.to_outside`` (the kernel ``search``), over the whole grid."""
    out[:] = np.inf
    none = np.empty(0)
    kern = _kernels(0)
    kern.search(
        grid.free, grid.allowed, grid.w, grid.h, np.asarray(sources, np.int64), grid.cell_m, *grid.moves,
        within, targets, out, kern.search_work(grid.w * grid.h), none, none, none,
    )  # fmt: skip


def ascent(grid: FreeGrid, field: np.ndarray, points_m: np.ndarray):
    """At each point, the direction of the field's steepest ascent over the grid's moves
    from its cell and the field's value there (inf: not reached or no cell)."""
    x, y = grid.cells(points_m)
    direction, value = np.zeros((len(x), 2)), np.full(len(x), np.inf)
    ok = np.flatnonzero(x >= 0)
    d, v = np.zeros((len(ok), 2)), np.empty(len(ok))
    _kernels(0).ascent(grid.free, grid.w, grid.h, field, x[ok], y[ok], grid.cell_m, *grid.moves, d, v)
    direction[ok], value[ok] = d, v
    return direction, value


def _field(grid: FreeGrid, sources_m, targets=None, within=None) -> np.ndarray:
    """Distances through free space from the grid cells of ``sources_m``."""
    targets = np.zeros(0, np.int64) if targets is None else targets
    x, y = grid.cells(np.asarray(sources_m, float).reshape(-1, 2))
    out = np.empty(grid.w * grid.h)
    within = grid.free if within is None else within
    distance_field(grid, y * grid.w + x, within, targets, out)
    return out


def test_distance_through_free_space_goes_round_the_wall_through_the_door():
    """The field is the length of the shortest path through free cells: from one side of a
    wall to the point straight across it, the way through the door, not the straight 4 m."""
    grid = FreeGrid(room_with_a_door(), Bounds.square(SIDE_M))
    field = _field(grid, [8.0, 15.0])
    _, d = ascent(grid, field, np.array([[12.0, 15.0], [8.0, 12.0]]))
    through_door = np.hypot(2.2, 11.0) + np.hypot(1.8, 11.0)  # via (10.1, 4)
    assert through_door - 1.0 < d[0] < 1.05 * through_door + 1.0
    # In sight: the straight distance, to within the grid's moves.
    assert 3.0 - 0.5 < d[1] < 1.03 * 3.0 + 0.5


def test_distances_from_several_sources_are_to_the_nearest_and_final_at_the_targets():
    """From several sources each cell's distance is to the nearest of them (the minimum of
    the single fields); a search stopped once its targets are settled gives them, and every
    cell nearer the sources than the farthest target, the same values."""
    grid = FreeGrid(room_with_a_door(), Bounds.square(SIDE_M))
    sources = [[2.0, 18.0], [18.0, 2.0], [12.0, 15.0]]
    both = _field(grid, sources)
    np.testing.assert_array_equal(both, np.minimum.reduce([_field(grid, s) for s in sources]))
    x, y = grid.cells(np.array([[5.0, 5.0], [15.0, 18.0]]))
    targets = (y * grid.w + x).astype(np.int64)
    stopped = _field(grid, sources, targets)
    settled = both <= both[targets].max() - 1e-9
    assert settled.sum() > 100 and (stopped[targets] == both[targets]).all()
    np.testing.assert_array_equal(stopped[settled], both[settled])
    assert (stopped >= both).all()


@pytest.mark.parametrize("seed", range(4))
def test_distances_are_the_shortest_paths_over_the_moves_to_the_last_bit(seed):
    """The search's values are the shortest paths over the grid's moves (each into a cell
    ``within`` marks) from the nearest source, as scipy's Dijkstra finds them on the same
    graph, to the last bit: on a random floor of blocks, from many sources, every cell."""
    from scipy.sparse import csr_array
    from scipy.sparse.csgraph import dijkstra

    rng = np.random.default_rng(seed)
    n = 120
    occupied = np.zeros((n, n), bool)
    for x, y, w, h in zip(*rng.integers(0, n, (2, 40)), *rng.integers(1, 12, (2, 40))):
        occupied[y : y + h, x : x + w] = True
    grid = FreeGrid(OccupancyMap(occupied, ~occupied, RES_M, (0.0, 0.0)), Bounds.square(n * RES_M))
    cells = grid.w * grid.h
    within = grid.free & (rng.random(cells) < 0.9)
    sources = rng.choice(np.flatnonzero(grid.free), 6, replace=False).astype(np.int64)
    got = np.empty(cells)
    distance_field(grid, sources, within, np.zeros(0, np.int64), got)
    moves_x, moves_y = grid.moves
    rows, cols, lengths = [], [], []
    for m in range(len(moves_x)):
        start = np.flatnonzero(grid.allowed >> m & 1)
        end = start + moves_y[m] * grid.w + moves_x[m]
        into = within[end]
        rows.append(start[into])
        cols.append(end[into])
        lengths.append(np.full(into.sum(), grid.cell_m * np.sqrt(float(moves_x[m] ** 2 + moves_y[m] ** 2))))
    graph = csr_array((np.concatenate(lengths), (np.concatenate(rows), np.concatenate(cols))), shape=(cells, cells))
    want = dijkstra(graph, indices=sources, min_only=True)
    assert np.isfinite(want).sum() > cells // 4 and np.isinf(want).any()
    np.testing.assert_array_equal(got, want)


def test_distances_keep_to_the_cells_within():
    """Paths leave the sources only through the cells ``within`` marks: with the cells in
    and beside the door left out (a knight's move passes beside a cell), the far side of
    the wall is not reached."""
    grid = FreeGrid(room_with_a_door(), Bounds.square(SIDE_M))
    within = grid.free.copy()
    door_x, door_y = grid.cells(np.array([[10.1, 3.0]]))
    for dy in range(-5, 6):
        for dx in (-1, 0, 1):
            within[(door_y[0] + dy) * grid.w + door_x[0] + dx] = False
    field = _field(grid, [8.0, 15.0], within=within)
    _, d = ascent(grid, field, np.array([[12.0, 15.0], [5.0, 5.0]]))
    assert np.isinf(d[0]) and np.isfinite(d[1])


def test_the_expansion_on_a_map_leads_through_the_door_to_the_free_space_not_yet_covered():
    """With the first room all covered, each robot is pushed, at the expansion's cap, along
    the path through free space to the nearest free cell no robot covers (through the door,
    on the other side of the wall), not straight at that cell through the wall; once every
    free cell is covered, none is pushed."""
    from netsim.mobility.forces import EXPANSION_CAP

    grid = FreeGrid(room_with_a_door(), Bounds.square(SIDE_M))
    pos = np.array([[5.0, 15.0], [5.0, 5.0]])
    push, d_m = expansion_to_uncovered(grid, pos, 12.0, 30.0, 1.0)
    np.testing.assert_allclose(np.hypot(*push.T), EXPANSION_CAP * 30.0)
    to_door = np.array([10.0, 3.0]) - pos[0]
    assert push[0] @ to_door > 0.95 * np.hypot(*push[0]) * np.hypot(*to_door)  # down, to the door
    assert push[1, 0] > 2 * abs(push[1, 1])  # right, through it
    direction, d = grid.to_uncovered(pos, 12.0)
    assert 12.0 < d[1] < 14.0 and d[0] > d[1] + 5.0
    np.testing.assert_array_equal(d_m, d)
    push, d_m = expansion_to_uncovered(grid, pos, 40.0, 30.0, 1.0)
    assert (push == 0.0).all() and np.isinf(d_m).all()


def test_robots_push_each_other_only_in_sight():
    """Two robots on either side of the wall do not push each other; two in one room do,
    and so do two that see each other through the door."""
    m = room_with_a_door()
    a = np.array([[8.0, 15.0], [8.0, 15.0], [8.0, 3.0]])
    b = np.array([[12.0, 15.0], [3.0, 12.0], [12.0, 3.0]])
    assert in_sight(m, a, b).tolist() == [False, True, True]


def test_a_wish_that_runs_into_a_wall_slides_along_it():
    """A robot pushed obliquely at a wall within its reach moves along the wall, by the
    component of its wish parallel to it, instead of stopping at the wall."""
    m = room_with_a_door()
    pos = np.array([[9.9, 15.0]])
    out = slide(m, pos, np.array([[1.5, 1.0]]), 1.0, 2.0)
    assert out.tolist() == [[0.0, 1.0]]


def test_a_wish_that_reaches_no_wall_is_left_as_it_is():
    """Only a step that would run into a wall within the robot's reach changes."""
    m = room_with_a_door()
    pos = np.array([[5.0, 15.0], [9.5, 15.0]])
    wish = np.array([[1.5, 1.0], [-1.5, 1.0]])
    assert (slide(m, pos, wish, 1.0, 2.0) == wish).all()


def test_a_link_whose_sight_the_wished_step_would_sweep_past_a_wall_does_not_last():
    """LinkRules.lasting: two robots translating side by side past a wall lose line of
    sight during the step (though not at its ends): that link does not last; standing
    still, it does."""
    from tests.test_coverage_radio import one_link, wall_rules

    rules, _ = wall_rules([(9.0, 11.0, 10.0, 12.0)])
    pos = np.array([[5.0, 5.0], [15.0, 5.0]])
    links = one_link(pos)
    assert rules.lasting(pos, np.array([[0.0, 20.0], [0.0, 20.0]]), links, 1.0).tolist() == [False]
    assert rules.lasting(pos, np.zeros((2, 2)), links, 1.0).tolist() == [True]


def test_the_forest_prefers_the_links_that_last_over_the_wished_step():
    """Of a triangle whose shortest link would not last over the step, the spanning forest
    keeps the two that would (as many links: the network stays one component)."""
    from netsim.mobility.keep import prefer
    from netsim.mobility.spread import forest_rows
    from netsim.mobility.steps import Candidates

    d = np.array([10.0, 20.0, 25.0])  # links (0, 1), (0, 2), (1, 2)
    links = Candidates(np.array([0, 0, 1]), np.array([1, 2, 2]), d, d + 30.0, d, np.full(3, np.inf), np.full(3, 30.0))
    assert sorted(forest_rows(3, links).tolist()) == [0, 1]
    lasting = np.array([False, True, True])
    assert sorted(forest_rows(3, prefer(links, lasting)).tolist()) == [1, 2]


def test_a_link_through_a_wall_does_not_last_however_short():
    """LinkRules.lasting under line of sight: a link whose segment crosses a wall is never up
    ("not up at any length"), even between two robots closer than a metre, where a range of
    -1 squared would pass for a metre's reach."""
    from tests.test_coverage_radio import one_link, wall_rules

    rules, _ = wall_rules([(10.0, 10.5, 0.0, 40.0)])
    pos = np.array([[9.8, 5.0], [10.7, 5.0]])
    assert rules.lasting(pos, np.zeros((2, 2)), one_link(pos), 1.0).tolist() == [False]


def test_the_push_to_the_uncovered_is_the_descent_of_the_whole_field():
    """``FreeGrid.to_uncovered`` searches from the frontier alone, through covered cells
    alone, and stops at the robots' own cells: on the office map, for teams crowded and
    spread, its directions and distances are those of the whole field from every free cell
    not covered, searched over all free space."""
    from netsim.world.maps import load_map

    grid = FreeGrid(load_map("office", "world.map"), Bounds.square(200.0))
    rng = np.random.default_rng(3)
    for n, spread_m, radius_m in ((40, 30.0, 30.0), (12, 90.0, 20.0), (3, 5.0, 8.0)):
        pos = np.array([100.0, 100.0]) + rng.uniform(-spread_m, spread_m, (n, 2))
        direction, d = grid.to_uncovered(pos, radius_m)
        uncovered = np.flatnonzero(grid.free & ~grid.covered(pos, radius_m))
        whole = np.empty(grid.w * grid.h)
        everywhere, none = grid.free, np.zeros(0, np.int64)
        distance_field(grid, uncovered, everywhere, none, whole)
        want_direction, want = ascent(grid, -whole, pos)
        reached = np.isfinite(d)
        assert reached.sum() >= n - 2
        np.testing.assert_array_equal(direction, want_direction)
        np.testing.assert_array_equal(d[reached], -want[reached])


def _whole_descent(grid: FreeGrid, covered: np.ndarray, pos: np.ndarray):
    """The descent of the field searched from every free cell not covered over all free space."""
    whole = np.empty(grid.w * grid.h)
    sources = np.flatnonzero(grid.free & ~covered)
    distance_field(grid, sources, grid.free, np.zeros(0, np.int64), whole)
    direction, value = ascent(grid, -whole, pos)
    return direction, np.where(np.isfinite(value), -value, np.inf)


def _assert_put_back(grid: FreeGrid) -> None:
    _, where, done, wanted, _, _ = grid.work
    assert (grid.field == np.inf).all() and (where == -1).all() and not done.any() and not wanted.any()


@pytest.mark.parametrize("guess", ["none", "latest", "just short", "too short", "too long"])
def test_the_push_to_the_uncovered_searches_near_the_robots_and_gives_the_whole_fields_descent(guess, monkeypatch):
    """``FreeGrid.to_outside`` leaves out the sources and paths too far from every robot to
    decide the distances its descent reads, from a guess of how far that is (the latest
    found nearby, none, or one wrong either way, which it must find out and mend): for
    robots deep inside a wide covered part, near its edge, and in a part all covered, it
    gives exactly what the whole field gives, and puts back what it worked in."""
    from netsim.world.maps import load_map

    grid = FreeGrid(load_map("office", "world.map"), Bounds.square(200.0))
    rng = np.random.default_rng(5)
    kern = _kernels(0)
    calls: list[tuple[int, int]] = []  # (sources taken, the whole frontier)

    class Counting:
        def __getattr__(self, name):
            return getattr(kern, name)

        def frontier(self, free, w, h, covered, mx, my, cx, cy, reach):
            out = kern.frontier(free, w, h, covered, mx, my, cx, cy, reach)
            every = np.full(1, np.inf)
            calls.append((len(out), len(kern.frontier(free, w, h, covered, mx, my, cx[:1], cy[:1], every))))
            return out

    monkeypatch.setattr("netsim.mobility.geodesic._kernels", lambda values: Counting())
    left_out = []  # whether a case's first search left sources out
    for case in range(7):
        walkers = np.array([100.0, 100.0]) + rng.uniform(-80.0, 80.0, (60, 2))
        covered = grid.covered(walkers, 15.0) if case < 6 else grid.free.copy()  # the last: all covered
        pos = np.r_[walkers[:6], walkers[6:9] + rng.uniform(-20.0, 20.0, (3, 2))]
        want_direction, want = _whole_descent(grid, covered, pos)
        block = grid._block_of(*grid.cells(pos))
        if guess == "none":
            grid.recent_m[:] = np.inf
        elif guess == "just short":
            grid.recent_m[:] = np.inf
            grid.recent_m[block] = np.where(np.isfinite(want), np.maximum(want - 1.0, 0.0), np.inf)
        elif guess == "too short":
            grid.recent_m[:] = 0.5
        elif guess == "too long":
            grid.recent_m[:] = 1e4
        calls.clear()
        direction, d = grid.to_outside(pos, lambda covered=covered: covered)
        reached = np.isfinite(d)  # a robot whose own cell is not covered has nothing to descend
        np.testing.assert_array_equal(direction, want_direction)
        np.testing.assert_array_equal(d[reached], want[reached])
        _assert_put_back(grid)
        if case < 6:
            assert reached.sum() >= len(pos) - 2 and d[reached].max() > 10.0
            left_out.append(calls[0][0] < calls[0][1])
            if guess == "just short":
                assert len(calls) >= 2  # found beyond the guess, searched again
        else:
            assert not reached.any() and not np.isfinite(want).any() and not direction.any()
    if guess != "latest":
        assert any(left_out) == (guess in ("just short", "too short"))


def test_a_search_with_no_free_target_puts_back_what_it_worked_in():
    """A search whose targets are all walls settles nothing and leaves its work as it found
    it: the next search from the same sources finds them."""
    grid = FreeGrid(room_with_a_door(), Bounds.square(SIDE_M))
    kern = _kernels(0)
    sources = np.flatnonzero(grid.free)[:3]
    wall = np.flatnonzero(~grid.free)[:1]
    none = np.empty(0)
    for targets in (wall, sources[2:]):
        used = kern.search(
            grid.free, grid.allowed, grid.w, grid.h, sources, grid.cell_m, *grid.moves, grid.free,
            targets, grid.field, grid.work, none, none, none,
        )  # fmt: skip
        assert used >= 3 and (grid.field[sources] == 0).all()
        kern.forget(grid.field, grid.work, used)
        _assert_put_back(grid)


@pytest.mark.slow
def test_control_goes_on_while_the_robots_near_the_free_space_not_yet_covered():
    """On the office map, 40 robots from a connected 40 m start: through the first
    stopping window the global plan's robots file toward the doors and the coverage does
    not rise, but their distance to the free space not yet covered falls, so control goes
    on until they have spread (docs/model.md 5.3)."""
    from netsim.config import load
    from netsim.run import execute
    from netsim.tools.validate import coverage_settings

    keys = coverage_settings("office, line of sight", "global", 40, 0.0, 1, 600.0, ["world.placement=connected"])
    config = load(None, keys)
    summary = execute(config, run=0).summary
    c = config.coverage
    assert summary["control_settled_s"] > c.start_s + 3 * c.hold_s
    assert summary["covered_of_bound_all_final"] > 0.5


def test_the_team_nears_the_uncovered_while_its_mean_distance_falls_by_the_stop_speed_over_the_window():
    """The stopping rule's reading of the expansion on a map: the robots' mean distance to
    the free space not yet covered fell by more than ``stop_speed_mps x stop_hold_s``
    (here 0.4 m) from the window's first step to some later one; steps before the window
    do not count, nor does a rise, nor a single step."""
    from collections import deque
    from types import SimpleNamespace

    from netsim.mobility.coverage import CoverageController

    def nearing(steps, now=30.0):
        ctl = SimpleNamespace(
            cfg=SimpleNamespace(hold_s=20.0, stop_speed_mps=0.02),
            env=SimpleNamespace(now=now),
            _mean_to_uncovered_m=deque(steps),
        )
        return CoverageController._nearing_uncovered(ctl)

    assert not nearing([])
    assert not nearing([(30.0, 10.0)])
    assert nearing([(10.0, 10.0), (20.0, 9.5), (30.0, 9.8)])
    assert not nearing([(10.0, 10.0), (20.0, 9.7), (30.0, 9.65)])
    assert not nearing([(9.0, 50.0), (10.0, 10.0), (30.0, 9.7)])
    assert not nearing([(10.0, 10.0), (20.0, 12.0), (30.0, 14.0)])


@pytest.mark.slow
def test_the_local_plan_on_a_map_is_not_stopped_by_what_its_robots_learn():
    """The local plan on the office map, 20 robots from a connected start: at the first
    control step each robot knows only the cells it explored itself, so the mean distance
    to unexplored space is low, then rises as the Acks tell of the team's, then falls as
    the team spreads: the stopping rule must see that fall, not end control on the first
    window, whose first value is low."""
    from netsim.config import load
    from netsim.run import execute

    keys = [
        "seed=2",
        "duration_s=200",
        "world.n_robots=20",
        "world.side_m=200",
        "world.map=office",
        "world.placement=connected",
        "world.centre_side_m=60",
        "mobility.model=static",
        "channel.range_m=30",
        "coverage.enabled=true",
        "coverage.plan=local",
        "protocol.message_rate_hz=0",
    ]
    summary = execute(load(None, keys), run=0).summary
    settled = summary["control_settled_s"]
    assert not settled <= 150.0  # NaN: control ran to the end
    assert summary["covered_of_bound_all_final"] > 0.25
