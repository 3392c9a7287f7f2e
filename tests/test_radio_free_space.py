"""Map helpers for mobility: free positions, free legs, waypoints, the push from walls; example maps."""

import numpy as np
import pytest

from netsim.errors import ConfigError
from netsim.world import examples
from netsim.world.free_space import (
    clearance_field_m,
    draw_destinations,
    free_fraction,
    legs_free,
    nearest_free_cells,
    obstacle_field,
    sample_free,
    wall_forces,
)
from netsim.world.los import walls_crossed
from netsim.world.maps import OccupancyMap, load_map


def _rooms():
    """A 20 m x 10 m map, 0.5 m cells: a wall at x = 10 m with a door for y in [4, 6)."""
    occ = np.zeros((20, 40), dtype=bool)
    occ[:, 20] = True
    occ[8:12, 20] = False
    unknown = np.zeros_like(occ)
    unknown[0:4, 0:4] = True  # an unexplored corner
    return OccupancyMap(occ, ~occ & ~unknown, 0.5, (0.0, 0.0), "rooms")


def test_sample_free_is_uniform_over_free_cells(rng):
    """Every draw is free; per-cell counts match the free area (chi-square-like bound)."""
    m = _rooms()
    pos = sample_free(m, rng, 40000, 10.0)
    assert m.is_free(pos).all()
    assert ((pos >= 0) & (pos <= 10.0)).all()
    # The area [0, 10]^2 holds 20 x 20 cells of which 16 are unknown: each free cell gets 1/384.
    i, j = m.cells(pos)
    counts = np.bincount(j * 40 + i, minlength=800).reshape(20, 40)[:, :20]
    free_counts = counts[m.free[:, :20]]
    assert len(free_counts) == 384
    expected = 40000 / 384
    assert np.abs(free_counts - expected).max() < 5 * np.sqrt(expected)
    assert counts[~m.free[:, :20]].sum() == 0


def test_sample_free_with_clearance(rng):
    m = _rooms()
    pos = sample_free(m, rng, 2000, 20.0, clearance_m=2.0)
    occ_x = 10.25  # the wall's centre line
    assert (np.abs(pos[:, 0] - occ_x) >= 2.0).all()
    with pytest.raises(ConfigError, match="world.map = 'rooms': has no free cell.*clearance of 50 m"):
        sample_free(m, rng, 1, 20.0, clearance_m=50.0)


def test_legs_free_refuses_walls_and_unknown_but_passes_doors():
    m = _rooms()
    s = np.array([[5.0, 8.0], [5.0, 5.0], [1.0, 5.0], [5.0, 9.0]])
    e = np.array([[15.0, 8.0], [15.0, 5.0], [1.0, 1.0], [6.0, 9.5]])
    assert legs_free(m, s, e).tolist() == [False, True, False, True]


def test_free_fraction_stops_short_of_the_wall():
    m = _rooms()
    s = np.array([[5.0, 8.0], [5.0, 5.0], [5.0, 8.0]])
    e = np.array([[15.0, 8.0], [15.0, 5.0], [15.0, 8.0 + 1e-7]])
    f = free_fraction(m, s, e)
    assert f[1] == 1.0
    assert f[0] == pytest.approx(0.5, abs=1e-6) and f[0] < 0.5
    stop = s + f[:, None] * (e - s)
    assert legs_free(m, s, stop).all()
    assert m.is_free(stop).all()


def test_destinations_are_free_and_reachable_in_a_straight_line(rng):
    m = _rooms()
    here = sample_free(m, rng, 300, 20.0)
    dest = draw_destinations(m, rng, here, 20.0)
    assert m.is_free(dest).all()
    assert legs_free(m, here, dest).all()
    # Robots do leave their room through the door.
    assert ((here[:, 0] < 10) & (dest[:, 0] > 10.5)).any()


def _pocket() -> OccupancyMap:
    occ = np.zeros((10, 10), dtype=bool)
    occ[7:, :] = True
    occ[9, 9] = False  # a one-cell pocket, walled off from the room below
    return OccupancyMap(occ, ~occ, 1.0, (0.0, 0.0), "cells")


def test_a_robot_that_sees_little_free_space_still_gets_a_destination():
    """A robot in a pocket sees 1 of the 71 free cells: once the first rounds miss, the draws
    go on (in larger rounds) until one is visible, uniform over what it sees, its pocket,
    rather than give up on a robot that does see free space."""
    m = _pocket()
    dest = draw_destinations(m, np.random.default_rng(1), [[9.5, 9.5]] * 3, 10.0, batch=2, max_rounds=2)
    assert ((dest >= 9.0) & (dest <= 10.0)).all()
    assert legs_free(m, [[9.5, 9.5]] * 3, dest).all()


def test_a_robot_that_sees_almost_nothing_is_reported():
    with pytest.raises(
        ConfigError,
        match=r"world.map = 'cells': a robot at \(9.5, 9.5\) found no destination it can reach in a straight line"
        r" in 8 tries",
    ):
        draw_destinations(_pocket(), np.random.default_rng(1), [[9.5, 9.5]], 10.0, batch=2, max_rounds=2, max_tries=6)


def test_wall_forces_push_away_within_the_margin():
    m = _rooms()
    field = obstacle_field(m)
    f = wall_forces(m, field, [[9.0, 8.0], [11.6, 8.0], [3.0, 8.0]], margin_m=2.0, gain=1.0)
    assert f[0, 0] < 0 and abs(f[0, 1]) < 1e-9  # left of the wall: pushed left
    assert f[1, 0] > 0  # right of it: pushed right
    assert np.array_equal(f[2], [0.0, 0.0])  # beyond the margin: nothing
    assert abs(f[0, 0]) > abs(wall_forces(m, field, [[8.5, 8.0]], 2.0, 1.0)[0, 0])  # stronger closer


def test_wall_forces_push_a_point_on_the_wall_face():
    """A point on a wall's left face lies, by the floor, in the wall's cell, whose field is
    flat (so is a point a hair inside it). It is read from the free cell nearest it and
    feels the strongest push, not none."""
    m = _rooms()
    field = obstacle_field(m)
    near = wall_forces(m, field, [[9.9, 8.0]], 2.0, 1.0)[0]
    for x in (10.0, 10.0 + 1e-7):  # the wall's left face, and just inside the wall
        f = wall_forces(m, field, [[x, 8.0]], 2.0, 1.0)[0]
        assert f[0] < 0 and f[0] <= near[0]
    assert wall_forces(m, field, [[10.5 - 1e-7, 8.0]], 2.0, 1.0)[0, 0] > 0  # the right face, from inside
    i, j = nearest_free_cells(m.free, m.origin_m, m.resolution_m, [[10.0, 8.2], [10.5 - 1e-7, 2.2], [3.1, 3.1]], 1)
    assert i.tolist() == [19, 21, 6] and j.tolist() == [16, 4, 6]


def test_wall_forces_read_a_point_off_the_map_from_the_nearest_cell_at_its_edge():
    """A point beyond any edge of the map (below and left of its origin too) feels the push
    of the map's cell nearest it, the same as a point just inside that cell."""
    m = _rooms()
    field = obstacle_field(m)
    x_max, y_max = m.shape[1] * m.resolution_m, m.shape[0] * m.resolution_m
    off = [[-3.0, 2.5], [x_max + 3.0, 8.0], [9.6, -3.0], [10.9, y_max + 3.0], [-1.0, -1.0]]
    inside = [[0.1, 2.5], [x_max - 0.1, 8.0], [9.6, 0.1], [10.9, y_max - 0.1], [0.1, 0.1]]
    i, j = m.nearest_cells(off)
    assert i.tolist() == [0, m.shape[1] - 1, 19, 21, 0] and j.tolist() == [5, 16, 0, m.shape[0] - 1, 0]
    f_off = wall_forces(m, field, off, 2.0, 1.0)
    assert np.array_equal(f_off, wall_forces(m, field, inside, 2.0, 1.0))
    assert f_off[0, 1] > 0 and f_off[2, 0] < 0 and f_off[3, 0] > 0  # pushed off the corner, the wall


def test_clearance_field_is_distance_to_nearest_non_free_cell():
    m = _rooms()
    d = clearance_field_m(m)
    assert d[15, 15] == pytest.approx(2.5)  # 5 cells left of the wall column
    assert d[10, 15] == pytest.approx(0.5 * np.hypot(5, 2))  # beside the door: to the door's jamb
    assert d[15, 21] == pytest.approx(0.5)


@pytest.mark.parametrize("name", ["office", "cave"])
def test_shipped_examples_match_their_generator(name):
    """The shipped PGMs are what the generator draws (regenerate: python -m netsim.world.examples)."""
    occ, free = examples.MAKERS[name]()
    m = load_map(name)
    assert m.resolution_m == examples.RESOLUTION_M
    assert (m.occupied != occ).mean() < 1e-4 and (m.free != free).mean() < 1e-4


def test_office_has_rooms_and_doors():
    """Across a room wall robots have no line of sight; a door lets a straight leg through."""
    m = load_map("office")
    # Two rooms side by side (x in [0, 10] and [10, 20], y in [0, 23.5]).
    assert walls_crossed(m, [[5.0, 10.0]], [[15.0, 10.0]]).tolist() == [1]
    # From a room through its door (x in [4.25, 5.75]) into the corridor at y = 25.
    assert legs_free(m, [[5.0, 20.0]], [[5.0, 25.0]]).tolist() == [True]
    assert legs_free(m, [[2.0, 20.0]], [[2.0, 25.0]]).tolist() == [False]
    # The free space is one connected region.
    from scipy.ndimage import label

    assert label(m.free)[1] == 1


def test_cave_is_one_connected_tunnel():
    from scipy.ndimage import label

    m = load_map("cave")
    assert label(m.free)[1] == 1
    assert 0.03 < m.free.mean() < 0.2


@pytest.mark.parametrize("name", ["office", "cave"])
@pytest.mark.parametrize("compiled", ["1", pytest.param("0", marks=pytest.mark.slow)])
def test_destinations_equal_the_oracle(name, compiled, monkeypatch):
    """A round's loop (compiled and plain) draws, checks and picks exactly as sample_free
    and legs_free do (the oracle)."""
    from tests.oracles import radio as oracle

    monkeypatch.setenv("NETSIM_COMPILED", compiled)
    m = load_map(name)
    here = sample_free(m, np.random.default_rng(3), 40 if compiled == "0" else 200, examples.SIDE_M)
    rng_a, rng_b = np.random.default_rng(7), np.random.default_rng(7)
    got = draw_destinations(m, rng_a, here, examples.SIDE_M)
    want = oracle.draw_destinations(m, rng_b, here, examples.SIDE_M)
    assert np.array_equal(got, want)
    assert rng_a.random() == rng_b.random()  # the same draws were made


def test_first_above_is_searchsorted_right():
    """The galloping search returns numpy's side="right" index, ties and empty steps included."""
    pytest.importorskip("numba")
    from netsim.world._kernels import first_above

    rng = np.random.default_rng(0)
    for trial in range(200):
        n = int(rng.integers(1, 500))
        steps = rng.choice([0.0, 1.0, 0.5, 3.0], n, p=[0.1, 0.6, 0.2, 0.1]) if trial % 2 else np.full(n, 0.0625)
        cdf = np.cumsum(steps)
        xs = np.r_[rng.random(30) * cdf[-1], cdf[rng.integers(0, n, 10)], [0.0, cdf[-1], -1.0, cdf[-1] + 1.0]]
        for x in xs.tolist():
            assert first_above(cdf, x) == np.searchsorted(cdf, x, side="right")


def test_a_waypoint_on_a_map_is_uniform_over_the_free_space_visible_from_the_robot(rng):
    """The law of destinations on a map (docs/radio.md, "Robots on a map"): from where a
    robot stands, its next waypoint is uniform over the free points it sees along a free
    straight leg. Binned counts of many draws from one point against the visible free area
    of each bin (a Monte Carlo of free points whose leg is free): a chi-square test, and no
    draw in a bin that cannot be seen."""
    from scipy.stats import chisquare

    m = _rooms()
    here = np.array([[3.0, 7.0]])  # in the left room, seeing the right room through the door only in part
    draws = draw_destinations(m, rng, np.repeat(here, 20000, axis=0), 20.0)
    probe = sample_free(m, np.random.default_rng(99), 400000, 20.0)
    visible = probe[legs_free(m, np.repeat(here, len(probe), axis=0), probe)]

    def counts(points):
        return np.histogram2d(points[:, 0], points[:, 1], bins=(10, 5), range=((0, 20), (0, 10)))[0].ravel()

    expected, got = counts(visible), counts(draws)
    seen = expected > 0
    assert got[~seen].sum() == 0
    assert got[25:].sum() > 100  # beyond the wall (x > 10 m), seen through the door and drawn
    pooled = expected[seen] >= 100  # the bins at the edge of what is seen, pooled into one
    exp, obs = expected[seen][pooled], got[seen][pooled]
    if (~pooled).any():
        exp, obs = np.append(exp, expected[seen][~pooled].sum()), np.append(obs, got[seen][~pooled].sum())
    assert chisquare(obs, exp / exp.sum() * obs.sum()).pvalue > 1e-4


def test_a_draw_from_free_cells_lands_in_their_part_of_the_box_and_refuses_none(rng):
    """``free_cells`` keeps the free cells' parts inside the box (positive area only) and
    ``draw_free`` draws in them (a start on a map, waypoints alike); no cell to draw from is
    an error, not a read past the cells."""
    from netsim.area import Bounds
    from netsim.world.free_space import draw_free, free_cells

    m = _rooms()
    mask = np.zeros(m.shape, dtype=bool)
    mask[2, 3] = True  # the cell [1.5, 2) x [1, 1.5)
    mask[5, 30] = True  # outside the box below
    cells = free_cells(m, mask, Bounds(1.75, 0.0, 10.0, 10.0))
    assert cells.x0.tolist() == [1.75] and cells.x1.tolist() == [2.0] and cells.cdf.tolist() == [0.125]
    p = draw_free(m, cells, rng, 200)
    assert ((p[:, 0] >= 1.75) & (p[:, 0] <= 2.0) & (p[:, 1] >= 1.0) & (p[:, 1] <= 1.5)).all()
    empty = free_cells(m, np.zeros(m.shape, dtype=bool), Bounds(0.0, 0.0, 20.0, 10.0))
    with pytest.raises(ValueError, match="no free cell"):
        draw_free(m, empty, rng, 1)
