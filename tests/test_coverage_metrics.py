"""The coverage metric itself (docs/validation.md items 14 and 15)."""

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy.spatial import cKDTree

from netsim.metrics import (
    CONNECTED_AREA_PER_ROBOT,
    KERSHNER_DENSITY,
    LENS_AREA_AT_HEX_SPACING,
    LENS_AREA_AT_RANGE,
    bound_fraction,
    components,
    connected_coverage_bound,
    covered_fraction,
    covered_fraction_exact,
    hex_lattice,
    hexagonality,
    lens_area,
    nearest_spacing,
    random_coverage,
    union_area_bracket,
)


def test_reference_constants():
    assert KERSHNER_DENSITY == pytest.approx(1.2092, abs=1e-4)
    assert LENS_AREA_AT_HEX_SPACING == pytest.approx(0.1812, abs=1e-4)
    assert LENS_AREA_AT_RANGE == pytest.approx(1.2284, abs=1e-4)
    assert CONNECTED_AREA_PER_ROBOT == pytest.approx(1.9132, abs=1e-4)
    assert lens_area(1.0, math.sqrt(3)) == pytest.approx(LENS_AREA_AT_HEX_SPACING)
    assert lens_area(1.0, 1.0) == pytest.approx(LENS_AREA_AT_RANGE)


def test_hexagonal_lattice_covers_everything_with_kershner_density():
    """Item 14: centres on a triangular lattice of spacing sqrt(3) r leave no point farther
    than r; disk area over covered area tends to 2 pi / (3 sqrt 3)."""
    r = 10.0
    lattice = hex_lattice(40, 40, math.sqrt(3) * r)
    # An interior window, away from the lattice's ragged edge.
    lo, side = 100.0, 400.0
    inside = lattice[
        (lattice[:, 0] > lo - 2 * r)
        & (lattice[:, 0] < lo + side + 2 * r)
        & (lattice[:, 1] > lo - 2 * r)
        & (lattice[:, 1] < lo + side + 2 * r)
    ]
    frac, bound = covered_fraction(inside - lo, r, side, cells=800)
    assert frac == 1.0
    # Density: cells of area (3 sqrt 3 / 2) r^2, one disk each.
    cell = 3 * math.sqrt(3) / 2 * r**2
    assert math.pi * r**2 / cell == pytest.approx(KERSHNER_DENSITY, rel=1e-12)
    # No point farther than r, and some points at almost exactly r (the cell corners).
    pts = np.random.default_rng(0).uniform(lo, lo + side, (20_000, 2))
    from scipy.spatial import cKDTree

    d, _ = cKDTree(lattice).query(pts)
    assert d.max() <= r + 1e-9 and d.max() > 0.99 * r
    assert hexagonality(lattice, math.sqrt(3) * r) == pytest.approx(1.0)
    assert np.median(nearest_spacing(lattice)) == pytest.approx(math.sqrt(3) * r)


@pytest.mark.slow
def test_lens_area_at_hexagonal_spacing():
    """Item 14: two disks of radius r, sqrt(3) r apart, share 0.1812 r^2."""
    r = 1.0
    c = np.array([[2.0, 2.0], [2.0 + math.sqrt(3), 2.0]])
    # Area within r of both = area(A) + area(B) - area(A or B).
    side = 5.0
    union, _ = covered_fraction(c, r, side, cells=2000)
    lens = 2 * math.pi * r**2 - union * side**2
    assert lens == pytest.approx(LENS_AREA_AT_HEX_SPACING, rel=0.01)


@pytest.mark.slow
def test_random_deployment_coverage_on_a_torus():
    """Item 15: n uniform centres cover 1 - (1 - pi r^2 / A)^n (on a torus: no border)."""
    n, r, side, reps = 40, 8.0, 100.0, 40
    rng = np.random.default_rng(15)
    fractions = [covered_fraction(rng.uniform(0, side, (n, 2)), r, side, cells=300, torus=True)[0] for _ in range(reps)]
    theory = random_coverage(n, r, side**2)
    assert 0.3 < theory < 0.9
    assert np.mean(fractions) == pytest.approx(theory, abs=4 * np.std(fractions) / math.sqrt(reps) + 0.002)


def test_covered_fraction_error_bound_holds():
    """The grid estimate of one disk is within its stated bound of the exact area."""
    frac, bound = covered_fraction([[50.0, 50.0]], 20.0, 100.0, cells=100)
    assert abs(frac - math.pi * 400 / 10_000) <= bound


def test_components_and_random_hexagonality():
    pos = np.array([[0, 0], [5, 0], [10, 0], [100, 0], [104, 0]], dtype=float)
    labels = components(pos, 6.0)
    assert len(set(labels)) == 2 and labels[0] == labels[2] != labels[3] == labels[4]
    random_pts = np.random.default_rng(1).uniform(0, 300, (300, 2))
    assert hexagonality(random_pts, 30.0) < 0.5


# -- the exact covered fraction -----------------------------------------------------------


def test_exact_covered_fraction_against_monte_carlo():
    """Random disks, some cut by the border: the exact fraction against 400 000 uniform
    points (standard error about 8e-4; tolerance four of them plus the stated bound)."""
    rng = np.random.default_rng(21)
    side, r = 1000.0, 80.0
    centres = rng.uniform(0, side, (40, 2))
    exact, err = covered_fraction_exact(centres, r, side)
    assert err < 2e-3
    points = rng.uniform(0, side, (400_000, 2))
    d, _ = cKDTree(centres).query(points)
    mc = float(np.mean(d <= r))
    assert 0.3 < exact < 0.8
    assert exact == pytest.approx(mc, abs=4 * math.sqrt(mc * (1 - mc) / len(points)) + err)


def test_exact_covered_fraction_brackets_the_truth():
    """One disk: the bracket holds pi r^2, and the estimate is far closer than its bound."""
    lower, upper = union_area_bracket([[500.0, 500.0]], 100.0, 1000.0)
    assert lower < math.pi * 100.0**2 < upper
    f, err = covered_fraction_exact([[500.0, 500.0]], 100.0, 1000.0)
    assert abs(f - math.pi / 100) < err / 10
    # A disk cut in half by the border.
    f, err = covered_fraction_exact([[0.0, 500.0]], 100.0, 1000.0)
    assert abs(f - math.pi / 200) <= err


def test_exact_union_of_a_hexagonal_flower_and_the_hexagonal_cell():
    """Item 14: a disk and its six neighbours sqrt(3) r away overlap in twelve lenses of
    0.1812 r^2 and nowhere three at once; the centre disk's cell (its own area plus half of
    each lens it shares) is the hexagon (3 sqrt 3 / 2) r^2."""
    r, c = 10.0, np.array([50.0, 50.0])
    ring = c + math.sqrt(3) * r * np.array([[math.cos(k * math.pi / 3), math.sin(k * math.pi / 3)] for k in range(6)])
    flower, err7 = covered_fraction_exact(np.vstack([c, ring]), r, 100.0)
    petals, err6 = covered_fraction_exact(ring, r, 100.0)
    area = 100.0**2
    lens = LENS_AREA_AT_HEX_SPACING * r**2
    assert flower * area == pytest.approx(7 * math.pi * r**2 - 12 * lens, abs=err7 * area)
    cell = (flower - petals) * area + 3 * lens
    assert cell == pytest.approx(1.5 * math.sqrt(3) * r**2, abs=(err7 + err6) * area)


def test_hexagonal_lattice_covers_a_window_exactly():
    """Item 14: disks on the triangular lattice of spacing sqrt(3) r leave nothing uncovered."""
    r = 10.0
    lattice = hex_lattice(30, 30, math.sqrt(3) * r, origin=(-2 * r, -2 * r))
    f, err = covered_fraction_exact(lattice, r, 300.0)
    assert f == pytest.approx(1.0, abs=err) and err < 1e-3


def test_grid_estimate_is_within_its_stated_bound_of_the_exact_fraction():
    rng = np.random.default_rng(5)
    for n in (5, 30, 100):
        centres = rng.uniform(0, 1000, (n, 2))
        exact, err = covered_fraction_exact(centres, 70.0, 1000.0)
        grid, bound = covered_fraction(centres, 70.0, 1000.0, cells=200)
        assert abs(grid - exact) <= bound + err
        assert bound < 0.2


# -- how far a connected team can spread (item 16) ------------------------------------------


def test_connected_coverage_bound_closed_form():
    r = 100.0
    assert connected_coverage_bound(1, r) == pytest.approx(math.pi * r**2)
    assert connected_coverage_bound(60, r) == pytest.approx(r**2 * (math.pi + 1.9132 * 59), rel=1e-4)
    assert bound_fraction(60, r, 1000.0) == 1.0
    assert bound_fraction(100, r, 2500.0) == pytest.approx(connected_coverage_bound(100, r) / 2500.0**2)


def test_a_straight_chain_at_full_range_reaches_the_bound():
    r, n = 10.0, 12
    chain = np.column_stack([50.0 + r * np.arange(n), np.full(n, 100.0)])
    lower, upper = union_area_bracket(chain, r, 300.0)
    assert lower <= connected_coverage_bound(n, r) <= upper


def connected_deployment(seed: int, n: int, r: float) -> np.ndarray:
    """Each robot placed within r of an earlier one (often at exactly r, the worst case)."""
    rng = np.random.default_rng(seed)
    pos = [np.array([0.0, 0.0])]
    for _ in range(n - 1):
        parent = pos[rng.integers(len(pos))]
        dist = r if rng.random() < 0.5 else rng.uniform(0.2 * r, r)
        angle = rng.uniform(0, 2 * math.pi)
        pos.append(parent + dist * np.array([math.cos(angle), math.sin(angle)]))
    return np.array(pos)


@pytest.mark.slow
@settings(max_examples=60, deadline=None)
@given(seed=st.integers(0, 2**31 - 1), n=st.integers(2, 40))
def test_property_no_connected_deployment_covers_more_than_the_bound(seed, n):
    """Item 16: whatever the connected deployment, its disks cover at most U(N) (the lower
    end of the exact bracket, which the true area is above)."""
    r = 10.0
    pos = connected_deployment(seed, n, r)
    assert components(pos, r + 1e-9).max() == 0
    side = 4 * r * n
    lower, _ = union_area_bracket(pos + side / 2, r, side)
    assert lower <= connected_coverage_bound(n, r)


UNEQUAL_RANGES = [100.0, 100.0, 150.0, 150.0, 150.0, 150.0]


def test_per_robot_equal_ranges_give_the_one_range_bound_bit_for_bit():
    """Item 16: one range per robot, all equal, is the one-range bound exactly (equal-range
    runs keep their outputs)."""
    for n, r, reach in [(1, 100.0, 100.0), (2, 1.0, 1.0), (60, 100.0, 100.0), (37, 80.0, 120.0), (5, 10.0, 25.0)]:
        assert connected_coverage_bound(n, r, [reach] * n) == connected_coverage_bound(n, r, reach)
        assert bound_fraction(n, r, 1e4, np.full(n, reach)) == bound_fraction(n, r, 1e4, reach)


def test_a_chain_longest_ranges_first_reaches_the_unequal_range_bound():
    """Item 16 with unequal ranges: a straight chain, the longest ranges first, each link
    at its full length min(r_a, r_b), covers exactly U (disks of the smallest range);
    the smallest range's bound is exceeded."""
    r = min(UNEQUAL_RANGES)
    x = [0.0]
    for a, b in zip(UNEQUAL_RANGES[:0:-1], UNEQUAL_RANGES[-2::-1]):
        x.append(x[-1] + min(a, b))
    chain = np.column_stack([200.0 + np.array(x), np.full(len(x), 400.0)])
    lower, upper = union_area_bracket(chain, r, 1500.0)
    assert lower <= connected_coverage_bound(6, r, UNEQUAL_RANGES) <= upper
    assert lower > connected_coverage_bound(6, r, r)


def linked(pos: np.ndarray, ranges: np.ndarray) -> bool:
    """Whether the network of links ``|p_a - p_b| <= min(r_a, r_b)`` is connected."""
    d = np.hypot(*(pos[:, None, :] - pos[None, :, :]).transpose(2, 0, 1))
    adjacent = d <= np.minimum.outer(ranges, ranges) + 1e-9
    seen, todo = {0}, [0]
    while todo:
        for j in np.flatnonzero(adjacent[todo.pop()]).tolist():
            if j not in seen:
                seen.add(j)
                todo.append(j)
    return len(seen) == len(pos)


@pytest.mark.slow
@settings(max_examples=60, deadline=None)
@given(seed=st.integers(0, 2**31 - 1), n=st.integers(2, 30), scale=st.sampled_from([1.0, 1.5]))
def test_property_with_unequal_ranges_no_connected_deployment_covers_more_than_the_bound(seed, n, scale):
    """Item 16 with one range per robot: whatever the connected deployment (each robot
    placed within, often at, its link's reach min(r_i, r_parent) of an earlier one), the
    disks of the smallest range's radius (the coverage default; scale 1.5: larger
    disks) cover at most U."""
    rng = np.random.default_rng(seed)
    ranges = rng.choice([100.0, 120.0, 150.0, 200.0, 260.0], n)
    pos = [np.zeros(2)]
    for i in range(1, n):
        parent = int(rng.integers(i))
        reach = min(ranges[i], ranges[parent])
        dist = reach if rng.random() < 0.6 else rng.uniform(0.2 * reach, reach)
        angle = rng.uniform(0, 2 * math.pi)
        pos.append(pos[parent] + dist * np.array([math.cos(angle), math.sin(angle)]))
    pos = np.array(pos)
    assert linked(pos, ranges)
    r = scale * ranges.min()
    side = 2 * (260.0 * n + r)
    lower, _ = union_area_bracket(pos + side / 2, r, side)
    assert lower <= connected_coverage_bound(n, r, ranges)


def test_the_bound_refuses_ranges_for_another_team_size():
    with pytest.raises(ValueError, match="3 ranges for 4 robots"):
        connected_coverage_bound(4, 1.0, [1.0, 1.0, 2.0])


def test_a_disconnected_pair_can_exceed_the_bound():
    """The bound needs connectivity: two disks far apart cover 2 pi r^2 > U(2)."""
    lower, _ = union_area_bracket([[20.0, 20.0], [80.0, 80.0]], 10.0, 100.0)
    assert lower > connected_coverage_bound(2, 10.0)


def _grid_area(shape: str) -> tuple[float, float, float, float, float]:
    """``(x0, y0, width, height, box)`` of the grid kernel's area: the plane's and the
    torus's square, or an offset rectangle."""
    if shape == "rectangle":
        return -30.0, 12.5, 140.0, 90.0, 0.0
    return 0.0, 0.0, 100.0, 100.0, (100.0 if shape == "torus" else 0.0)


@pytest.mark.parametrize("kind", ["plain", "compiled"])
@pytest.mark.parametrize("shape", ["plane", "torus", "rectangle"])
def test_grid_cell_nearest_centre_is_every_cell_against_every_centre(kind, shape):
    """The one rule of a covered cell (``netsim._kernels.grid_nearest_m``): each cell
    centre's distance (hypot, the nearest image on a torus) to its nearest point within the
    reach, else inf, exactly as every cell against every point computes it; disks crossing
    the area's edges (and, on a torus, wrapping over them) included."""
    from netsim import _kernels
    from netsim.compiled import compiled_copy
    from tests.oracles import coverage_grid as oracle

    kernels = compiled_copy("netsim._kernels") if kind == "compiled" else _kernels
    rng = np.random.default_rng(11)
    x0, y0, w, h, box = _grid_area(shape)
    p = np.column_stack([rng.uniform(x0 - 10, x0 + w + 10, 25), rng.uniform(y0 - 10, y0 + h + 10, 25)])
    for reach in (3.7, 18.0, 60.0):
        got = kernels.grid_nearest_m(p, reach, x0, y0, w, h, 64, box, False)
        want = oracle.grid_nearest_m(p, reach, x0, y0, w, h, 64, box)
        assert got.tobytes() == want.tobytes()
        assert np.isfinite(got).any()


@pytest.mark.parametrize("kind", [pytest.param("plain", marks=pytest.mark.slow), "compiled"])
@pytest.mark.parametrize("shape", ["plane", "torus", "rectangle"])
def test_grid_cells_within_reach_of_any_point_are_those_of_the_nearest(kind, shape):
    """``any_within`` (the environments' covered share) marks within the reach exactly the
    cells the nearest distance puts there: on random points, and on points placed so that
    cell centres lie at the reach itself and a few ulps inside and outside it, where the
    squared offset alone would decide some of them wrongly."""
    from netsim import _kernels
    from netsim.compiled import compiled_copy

    kernels = compiled_copy("netsim._kernels") if kind == "compiled" else _kernels
    rng = np.random.default_rng(12)
    x0, y0, w, h, box = _grid_area(shape)
    hx, hy = w / 64, h / 64
    centre = np.array([x0 + (20 + 0.5) * hx, y0 + (30 + 0.5) * hy])
    checked = 0
    for k in range(40):
        scale = rng.uniform(0.3, 6.0)
        # a point 3 and 4 units (x scale) from a cell centre: that centre is 5 x scale from it
        exact = centre + scale * np.array([3.0 * hx, 4.0 * hy]) / np.hypot(hx, hy) * np.sqrt(hx * hy)
        p = np.vstack([exact, np.column_stack([rng.uniform(x0, x0 + w, 8), rng.uniform(y0, y0 + h, 8)])])
        d_exact = float(np.hypot(*(centre - exact)))
        for reach in (d_exact, np.nextafter(d_exact, 0), np.nextafter(d_exact, np.inf), rng.uniform(2.0, 40.0)):
            nearest = kernels.grid_nearest_m(p, reach, x0, y0, w, h, 64, box, False)
            some = kernels.grid_nearest_m(p, reach, x0, y0, w, h, 64, box, True)
            assert ((some <= reach) == (nearest <= reach)).all(), (k, reach)
            checked += int((nearest <= reach).sum())
    assert checked > 10_000


@pytest.mark.parametrize("shape", ["plane", "torus", "rectangle", "region"])
def test_covered_fraction_and_its_bound_are_the_search_trees(shape):
    """The covered fraction and its error bound, from the grid kernel, equal what a search
    tree over the cell centres gives (scipy's cKDTree, periodic on a torus), on the plane, a
    torus, an offset rectangle and a region inside it."""
    import shapely

    from netsim.area import Bounds
    from tests.oracles.coverage_grid import covered_fraction_kd

    rng = np.random.default_rng(7)
    area: float | Bounds = 100.0
    region = None
    if shape == "rectangle":
        area = Bounds(-20.0, 10.0, 120.0, 70.0)
    if shape == "region":
        region = shapely.Polygon([(5, 5), (95, 10), (60, 90), (10, 70)]).difference(shapely.box(40, 30, 55, 60))
    p = rng.uniform(-5.0, 105.0, (30, 2))
    for radius in (4.0, 11.5):
        args = (p, radius, area, 150, shape == "torus", region)
        assert covered_fraction(*args) == covered_fraction_kd(*args)


@pytest.mark.parametrize("side_m", [None, 1000.0])
def test_nearest_spacing_is_the_least_distance_by_the_engines_rule(side_m):
    """Each point's spacing is its least distance to another point as the engine measures a
    link's length (netsim.geometry.distances_m), to the last bit, on the plane and on a
    torus: the same number a table of pairs in range would give."""
    from netsim.geometry import distances_m

    def least_m(p):
        i, j = np.triu_indices(len(p), 1)
        d = distances_m(p[i], p[j], side_m)
        least = np.full((len(p), len(p)), np.inf)
        least[i, j] = least[j, i] = d
        return least.min(axis=1)

    rng = np.random.default_rng(3)
    p = rng.uniform(0.0, 1000.0, (60, 2))
    assert np.array_equal(nearest_spacing(p, side_m), least_m(p))
    # Hexagonal lattices, where the coverage control leads: six neighbours nearly as near,
    # which the engine may tell apart in the last bit.
    col, row = np.meshgrid(np.arange(8), np.arange(8))
    for _ in range(100):
        r = rng.uniform(5.0, 50.0)
        lattice = np.c_[(col + 0.5 * (row % 2)).ravel() * r * np.sqrt(3), (row * 1.5 * r).ravel()]
        lattice += rng.uniform(0.0, 100.0, 2)
        assert np.array_equal(nearest_spacing(lattice, side_m), least_m(lattice))


# -- rules the mutation audit found unguarded ------------------------------------------------


def test_random_coverage_is_one_minus_the_chance_all_n_disks_miss_a_point():
    """Item 15's closed form at sizes where it is plain: no disk covers nothing, one disk
    covers its own share, and each further disk misses a point with that share's complement."""
    p = math.pi * 5.0**2 / 1000.0
    assert random_coverage(0, 5.0, 1000.0) == 0.0
    assert random_coverage(1, 5.0, 1000.0) == pytest.approx(p, rel=1e-12)
    assert random_coverage(3, 5.0, 1000.0) == pytest.approx(1 - (1 - p) ** 3, rel=1e-12)


def test_grid_side_accepts_one_to_max_grid_cells_inclusive():
    """A configuration's grid may have exactly the most cells the check names, and at least one."""
    from netsim.metrics import MAX_GRID_CELLS, grid_side

    assert grid_side(1) is None and grid_side(MAX_GRID_CELLS) is None
    assert grid_side(MAX_GRID_CELLS + 1) == "must be at most 4,000"
    assert grid_side(0) == "must be > 0"


def test_a_cell_exactly_half_a_diagonal_from_the_disks_edge_counts_as_uncertain():
    """The bound counts every cell whose centre is within h/sqrt(2) of the boundary, that
    distance included. Cells of 3 m x 4 m: half a diagonal is 2.5 m, exactly; the cell
    centred at (1.5, 2) is 3.5 m from the centre, 2.5 m outside a disk of 1 m, and is
    uncertain with the two cells above, nearer the edge; the fourth, farther, is not."""
    from netsim.area import Bounds

    frac, bound = covered_fraction([[1.5, 5.5]], 1.0, Bounds(0.0, 0.0, 6.0, 8.0), cells=2)
    assert frac == 0.25
    assert bound == 0.75


def test_nearest_spacing_on_a_torus_folds_points_outside_the_square_in():
    """Points given outside ``[0, side)`` are measured as their images inside it."""
    got = nearest_spacing([[-1.0, 0.0], [5.0, 0.0], [10.0, 3.0]], side_m=10.0)
    # -1 folds to 9 and 10 to 0: 9 -> 0 is 1 across the edge, in x, then 3 in y.
    assert got.tolist() == pytest.approx([math.hypot(1.0, 3.0), 4.0, math.hypot(1.0, 3.0)])


def test_hexagonality_counts_neighbours_to_1_2_spacings_and_leaves_out_points_with_one():
    """A square of side 1.1 spacings: each corner's two neighbours (within 1.2 spacings; the
    diagonal is not) sit 90 degrees apart, whose sixfold phases cancel, so psi_6 is 0. A
    pair far away has one neighbour each and is left out, not counted as a perfect 1."""
    s = 10.0
    square = np.array([[0.0, 0.0], [11.0, 0.0], [11.0, 11.0], [0.0, 11.0]])
    pair = np.array([[100.0, 100.0], [111.0, 100.0]])
    assert hexagonality(square, s) == pytest.approx(0.0, abs=1e-12)
    assert hexagonality(np.r_[square, pair], s) == pytest.approx(0.0, abs=1e-12)
