"""Coverage and connectivity metrics: pure functions of positions.

- :func:`covered_fraction_exact`: the fraction of the square covered by the union of
  disks, from the areas of two polygon unions that bracket it (below: every disk replaced
  by its inscribed regular polygon; above: by its circumscribed one), with the bracket's
  half-width as a rigorous error bound (about 1e-3 of the area or less);
- :func:`covered_fraction`: the same by a grid of sample points (a cheap estimate), with a
  rigorous bound on its error;
- :func:`connected_coverage_bound`: ``U(N)``, the most that ``N`` robots whose network is
  connected can cover (docs/validation.md item 16);
- :func:`components`: connected components of the unit-disk network; :func:`components_of_links`:
  those of any radio's links (a link solver's); :func:`components_in_links_table`: their
  number over time in a links table (``links.parquet``);
- :func:`nearest_spacing`: each leader's distance to its nearest leader;
- :func:`hexagonality`: the bond-orientational order parameter psi_6 (1 on a perfect
  hexagonal lattice, near 0 for a random arrangement).
"""

from __future__ import annotations

import itertools
import math
from typing import Any

import numpy as np
import numpy.typing as npt

from netsim.area import Bounds, as_bounds
from netsim.compiled import load
from netsim.geometry import cell_centres_m, distances_m, in_box
from netsim.topology import geometric_pairs

# Mean distance between two uniform points of the unit square (docs/validation.md item 2):
# the mean leg of random waypoint on a square of side a is this times a.
MEAN_LEG_UNIT_SQUARE = (2 + math.sqrt(2) + 5 * math.log(1 + math.sqrt(2))) / 15
# Kershner (1939): the least density of a covering of the plane by equal disks, reached
# by centres on a triangular lattice of spacing sqrt(3) r.
KERSHNER_DENSITY = 2 * math.pi / (3 * math.sqrt(3))
# Area shared by two disks of radius r whose centres are sqrt(3) r apart, over r^2.
LENS_AREA_AT_HEX_SPACING = math.pi / 3 - math.sqrt(3) / 2
# Area shared by two disks of radius r whose centres are r apart, over r^2 (1.2284).
LENS_AREA_AT_RANGE = 2 * math.pi / 3 - math.sqrt(3) / 2
# What each robot after the first adds at most to a connected team's covered area, over
# r^2: a disk minus the least it can share with a neighbour in range (1.9132).
CONNECTED_AREA_PER_ROBOT = math.pi - LENS_AREA_AT_RANGE
# Vertices of the regular polygons that bracket each disk (shapely: 4 x quad_segs).
QUAD_SEGS = 16


def mean_distance_rectangle(a: float, b: float) -> float:
    """Mean distance between two points uniform in an ``a x b`` rectangle (Ghosh 1951):
    the mean leg of random waypoint there.

    >>> round(mean_distance_rectangle(1.0, 1.0), 6) == round(MEAN_LEG_UNIT_SQUARE, 6)
    True
    """
    d = math.hypot(a, b)
    return (
        a**3 / b**2
        + b**3 / a**2
        + d * (3 - a**2 / b**2 - b**2 / a**2)
        + 2.5 * (b**2 / a * math.log((a + d) / b) + a**2 / b * math.log((b + d) / a))
    ) / 15


def lens_area(radius_m: float, distance_m: float) -> float:
    """Area shared by two disks of radius ``radius_m`` whose centres are ``distance_m`` apart.

    >>> round(lens_area(1.0, 1.0), 4), lens_area(1.0, 2.0)
    (1.2284, 0.0)
    """
    r, d = radius_m, min(distance_m, 2 * radius_m)
    return 2 * r * r * math.acos(d / (2 * r)) - 0.5 * d * math.sqrt(4 * r * r - d * d)


def connected_coverage_bound(n: int, radius_m: float, range_m: float | npt.ArrayLike | None = None) -> float:
    """``U(N) = r^2 (pi + 1.9132 (N - 1))``, m^2: the most that ``n`` disks of radius
    ``radius_m`` can cover when their centres form a connected network of range
    ``range_m`` (default: the radius; docs/validation.md item 16), one range for all or
    one per robot.

    A link joins two robots at most ``min(r_a, r_b)`` apart (docs/events.md). Root a
    spanning tree of the network at a robot of the largest range: every other robot ``i``
    has a parent within ``min(r_i, r_parent) <= r_i``, and its disk shares with the
    parent's at least the lens at distance ``r_i`` (the lens shrinks with the distance).
    So each robot but one of the largest range adds at most ``pi r^2 - lens(r, r_i)``.
    A straight chain, the longest ranges first, each link at its full length, reaches the
    bound exactly (equal ranges: at spacing ``r``).

    >>> round(connected_coverage_bound(2, 1.0), 4)
    5.0548
    >>> round(connected_coverage_bound(3, 1.0, [1.0, 2.0, 2.0]), 4)
    8.1964
    >>> connected_coverage_bound(0, 1.0)
    0.0
    """
    if n <= 0:
        return 0.0
    disk = math.pi * radius_m**2
    if range_m is None or np.ndim(range_m) == 0:
        reach = radius_m if range_m is None else float(range_m)  # type: ignore[arg-type]
        return disk + (disk - lens_area(radius_m, reach)) * (n - 1)
    ranges = np.asarray(range_m, dtype=float).ravel()
    if len(ranges) != n:
        raise ValueError(f"{len(ranges)} ranges for {n} robots")
    # Equal ranges give one term, (disk - lens) (n - 1): the scalar formula, bit for bit.
    reaches, counts = np.unique(np.sort(ranges)[:-1], return_counts=True)
    return disk + sum((disk - lens_area(radius_m, float(r))) * int(c) for r, c in zip(reaches, counts))


def bound_fraction(
    n: int,
    radius_m: float,
    area: float | Bounds,
    range_m: float | npt.ArrayLike | None = None,
    free_area_m2: float | None = None,
) -> float:
    """``min(1, U(N) / A)``: the largest fraction of the area (Bounds, or the side of the
    square ``[0, side]^2``) a connected team can cover; ``A`` is the area's, in m^2, or on a
    map ``free_area_m2``, that of the free region the team can reach (docs/model.md 5.3);
    ``range_m`` one range or one per robot (:func:`connected_coverage_bound`).

    >>> bound_fraction(2, 1.0, 10.0) == bound_fraction(2, 1.0, 100.0, free_area_m2=100.0)
    True
    """
    a = as_bounds(area).area if free_area_m2 is None else float(free_area_m2)
    return min(1.0, connected_coverage_bound(n, radius_m, range_m) / a)


def union_area_bracket(
    centres_m: npt.ArrayLike, radius_m: float, area: float | Bounds, quad_segs: int = QUAD_SEGS, region: Any = None
) -> tuple[float, float]:
    """Area (m^2) of the union of the disks clipped to the area (Bounds, or the side of the
    square ``[0, side]^2``), or to ``region`` (a shapely geometry inside the area: a map's
    free region, :func:`netsim.world.free_space.region_polygon`) when given, bracketed:
    ``(lower, upper)`` from the unions of the inscribed and the circumscribed regular
    polygons with ``4 quad_segs`` vertices (each polygon inside, resp. around, its disk,
    so the unions are too). Computed with shapely (GEOS).

    >>> lo, hi = union_area_bracket([[50.0, 50.0]], 10.0, 100.0)
    >>> lo < math.pi * 100 < hi and hi - lo < 0.8
    True
    """
    import shapely

    centres = np.asarray(centres_m, dtype=float).reshape(-1, 2)
    if len(centres) == 0:
        return 0.0, 0.0
    b = as_bounds(area)
    box = shapely.box(b.x_min, b.y_min, b.x_max, b.y_max) if region is None else region
    points = shapely.points(centres)
    vertices = 4 * quad_segs
    areas = []
    for r in (radius_m, radius_m / math.cos(math.pi / vertices)):
        union = shapely.union_all(shapely.buffer(points, r, quad_segs=quad_segs))
        areas.append(float(shapely.intersection(union, box).area))
    return areas[0], areas[1]


def covered_fraction_exact(
    centres_m: npt.ArrayLike, radius_m: float, area: float | Bounds, quad_segs: int = QUAD_SEGS, region: Any = None
) -> tuple[float, float]:
    """Fraction of the area (Bounds, or the side of the square ``[0, side]^2``), or of
    ``region`` (a shapely geometry inside it: a map's free region) when given, within
    ``radius_m`` of some centre: ``(fraction, error_bound)``, the true fraction being within
    ``error_bound`` of ``fraction``.

    From :func:`union_area_bracket` ``[lower, upper]``. A polygon's shortfall along the
    union's boundary is about twice the circumscribed polygon's excess (``r^2 theta^3 /
    12`` against ``r^2 theta^3 / 24`` per side of angle ``theta``), so ``(lower + 2 upper)
    / 3`` is nearly exact; the error bound is its distance to the farther end of the
    bracket, which is rigorous.

    >>> f, err = covered_fraction_exact([[50.0, 50.0]], 10.0, 100.0)
    >>> abs(f - math.pi / 100) < 1e-6 and err < 6e-5
    True
    """
    lower, upper = union_area_bracket(centres_m, radius_m, area, quad_segs, region)
    a = as_bounds(area).area if region is None else float(region.area)
    value = (lower + 2.0 * upper) / 3.0
    return value / a, max(value - lower, upper - value) / a


# The most cells a side of a covered fraction's grid may have, as a configuration allows:
# every sample holds arrays of their square, which past this outgrow a machine's memory.
MAX_GRID_CELLS = 4_000


def grid_side(cells: int) -> str | None:
    """The check of a configuration's cells per side of the covered fraction's grid."""
    if cells <= 0:
        return "must be > 0"
    return None if cells <= MAX_GRID_CELLS else f"must be at most {MAX_GRID_CELLS:,}"


def covered_fraction(
    centres_m: npt.ArrayLike,
    radius_m: float,
    area: float | Bounds,
    cells: int = 500,
    torus: bool = False,
    region: Any = None,
    n_robots: int | None = None,
) -> tuple[float, float]:
    """Fraction of the area (Bounds, or the side of the square ``[0, side]^2``; a torus is
    the square) within ``radius_m`` of some centre, estimated on a ``cells x cells`` grid of
    cell centres (cheap; :func:`covered_fraction_exact` is exact): a centre is covered by
    the kernel :func:`netsim._kernels.grid_nearest_m`, the environments' rule too. Returns
    ``(fraction, error_bound)``. With ``region`` (a shapely geometry inside the area: a
    map's free region) the fraction is of the grid's cells whose centre lies in it, and the
    cells the region's boundary crosses count as uncertain too. ``n_robots``: the team's
    size, for :func:`netsim.compiled.load` (None: not known, the compiled kernel).

    The bound is rigorous: a cell can be misclassified only if the union's boundary
    crosses it, i.e. only if its centre is within ``h / sqrt(2)`` (``h``: the cell size)
    of the boundary of the nearest disk; those cells, counted, bound the error. It is
    about ``sqrt(2) L h / A`` for a union of perimeter ``L``; the actual error is usually
    far smaller (misclassifications cancel).

    >>> round(covered_fraction([[50.0, 50.0]], 10.0, 100.0)[0], 3)
    0.031
    """
    centres = np.asarray(centres_m, dtype=float).reshape(-1, 2)
    b = as_bounds(area)
    side_m = b.width
    hx, hy = b.width / cells, b.height / cells
    # h / sqrt(2) for square cells, to the last bit the bound the runs' tables carry.
    half_diagonal = hx / math.sqrt(2) if hx == hy else 0.5 * math.hypot(hx, hy)
    inside = slice(None)
    edge = np.zeros(cells * cells, dtype=bool)
    if region is not None:
        import shapely

        axes = (cell_centres_m(b.x_min, hx, np.arange(cells)), cell_centres_m(b.y_min, hy, np.arange(cells)))
        gx, gy = np.meshgrid(*axes)
        inside = shapely.contains_xy(region, gx.ravel(), gy.ravel())
        edge = shapely.dwithin(region.boundary, shapely.points(gx.ravel()[inside], gy.ravel()[inside]), half_diagonal)
    if len(edge) == 0:
        return 0.0, 0.0  # a region that holds no cell's centre
    kernels = load("netsim._kernels", n_robots)
    box = side_m if torus else 0.0
    dist = kernels.grid_nearest_m(
        centres, radius_m + half_diagonal, b.x_min, b.y_min, b.width, b.height, cells, box, False
    )
    dist = dist.ravel()[inside]
    fraction = float(kernels.share_within(np.ascontiguousarray(dist), float(radius_m)))
    uncertain = (np.abs(dist - radius_m) <= half_diagonal) | edge
    return fraction, float(np.mean(uncertain))


def random_coverage(n: int, radius_m: float, area_m2: float) -> float:
    """Expected covered fraction for ``n`` uniform centres, ignoring borders (item 15)."""
    return 1.0 - (1.0 - math.pi * radius_m**2 / area_m2) ** n


def components(positions_m: np.ndarray, range_m: float | np.ndarray, side_m: float | None = None) -> np.ndarray:
    """Component label of every robot in the two-way unit-disk network."""
    i, j, _ = geometric_pairs(positions_m, range_m, side_m)
    return components_of_links(len(positions_m), i, j)


def components_at_link_events(
    a: np.ndarray, b: np.ndarray, t_up_s: np.ndarray, t_down_s: np.ndarray, censored_end: np.ndarray, n: int
) -> tuple[np.ndarray, np.ndarray]:
    """The number of components of the network of ``n`` robots whose links are up over
    ``[t_up_s, t_down_s)`` (the columns of ``links.parquet``; a link ``censored_end`` is
    up until the end), at every instant a link goes up or down, just after it: arrays
    ``(t_s, components)``.

    >>> up, down, cut = np.array([0.0, 0.0]), np.array([5.0, 9.0]), np.array([False, True])
    >>> components_at_link_events(np.array([0, 1]), np.array([1, 2]), up, down, cut, 3)
    (array([0., 5.]), array([1, 2]))

    Notes
    -----
    ``O(E)`` per event, ``E`` the links in the table.
    """
    censored_end = np.asarray(censored_end, bool)
    times = np.unique(np.r_[t_up_s, t_down_s[~censored_end & np.isfinite(t_down_s)]])
    counts = np.empty(len(times), dtype=np.int64)
    for k, t in enumerate(times.tolist()):
        up = links_up_at(t_up_s, t_down_s, censored_end, t)
        counts[k] = component_count(n, a[up], b[up])
    return times, counts


def links_up_at(t_up_s: np.ndarray, t_down_s: np.ndarray, censored_end: np.ndarray, t: float) -> np.ndarray:
    """Which rows of a links table are up at ``t``: on ``[t_up_s, t_down_s)``, and a link
    still up at the run's end (``censored_end``) at its ``t_down_s``, the end, too."""
    return (t_up_s <= t) & ((t_down_s > t) | (censored_end & (t_down_s >= t)))


def components_of_links(n: int, a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Component label of every robot in the network of ``n`` robots whose links are the
    pairs ``(a[k], b[k])`` (the links a radio makes, as a link solver's ``up_pairs()``).

    >>> components_of_links(4, np.array([0, 2]), np.array([1, 3])).tolist()
    [0, 0, 1, 1]
    """
    a = np.ascontiguousarray(a, np.int64)
    b = np.ascontiguousarray(b, np.int64)
    # int32, as scipy's connected_components numbers them (the tables' columns keep their type).
    return load("netsim._kernels", n).component_labels(n, a, b).astype(np.int32)


def component_count(n: int, a: np.ndarray, b: np.ndarray) -> int:
    """Number of connected components of the network of :func:`components_of_links`.

    >>> component_count(4, np.array([0, 2]), np.array([1, 3]))
    2
    """
    a = np.ascontiguousarray(a, np.int64)
    b = np.ascontiguousarray(b, np.int64)
    return int(load("netsim._kernels", n).component_count(n, a, b))


def components_in_links_table(links: Any, n: int, times_s: npt.ArrayLike) -> np.ndarray:
    """Number of connected components, at each of ``times_s``, of the network whose links
    are the rows of a links table (``links.parquet``: a link is up on ``[t_up_s,
    t_down_s)``, so at an instant where it goes down and another comes up, the state after
    both; a link still up at the run's end, ``censored_end``, is up at its ``t_down_s``,
    the end, too). ``O(E)`` per instant.

    >>> import pandas as pd
    >>> links = pd.DataFrame({"a": [0, 1], "b": [1, 2], "t_up_s": [0.0, 5.0], "t_down_s": [10.0, 8.0]})
    >>> components_in_links_table(links, 3, [0.0, 5.0, 8.0, 10.0]).tolist()
    [2, 1, 2, 3]
    >>> links["censored_end"] = [True, False]
    >>> components_in_links_table(links, 3, [10.0]).tolist()
    [2]
    """
    a = np.asarray(links["a"], np.int64)
    b = np.asarray(links["b"], np.int64)
    up_s = np.asarray(links["t_up_s"], float)
    down_s = np.asarray(links["t_down_s"], float)
    open_end = np.asarray(links["censored_end"], bool) if "censored_end" in links else np.zeros(len(a), bool)
    out = []
    for t in np.asarray(times_s, float).reshape(-1).tolist():
        up = links_up_at(up_s, down_s, open_end, t)
        out.append(component_count(n, a[up], b[up]))
    return np.array(out, np.int64)


def nearest_spacing(positions_m: npt.ArrayLike, side_m: float | None = None) -> np.ndarray:
    """Distance from each point to its nearest other point (NaN with fewer than two), on a
    torus of side ``side_m`` (None: the plane; points folded into ``[0, side)``): the
    nearest found by a k-d tree, its distance by the engine's one rule of a link's length
    (:func:`netsim.geometry.distances_m`), as every other distance in the tables.

    >>> nearest_spacing([[0.0, 0.0], [3.0, 4.0], [3.0, 5.0]]).tolist()
    [5.0, 1.0, 1.0]
    """
    from scipy.spatial import cKDTree  # imported when asked: a run without it does not load it

    p = in_box(np.asarray(positions_m, dtype=float).reshape(-1, 2), side_m)
    if len(p) < 2:
        return np.full(len(p), np.nan)
    tree = cKDTree(p, boxsize=side_m)
    d, _ = tree.query(p, k=2)
    # The tree measures by its own arithmetic: of neighbours nearly as near (a lattice's
    # six), the one it names may be the longer by the engine's. So every point within a
    # hair of the tree's nearest is measured by the engine's rule, and the least kept.
    near = tree.query_ball_point(p, d[:, 1] * (1.0 + 1e-9), return_sorted=False)
    count = np.fromiter(map(len, near), np.int64, len(p))
    i = np.repeat(np.arange(len(p)), count)
    j = np.fromiter(itertools.chain.from_iterable(near), np.int64, int(count.sum()))
    other = i != j
    i, j = i[other], j[other]
    out = np.full(len(p), np.inf)
    np.minimum.at(out, i, distances_m(p[i], p[j], side_m, len(p)))
    return out


def hexagonality(positions_m: npt.ArrayLike, spacing_m: float) -> float:
    """Mean over points of ``|mean_j exp(6 i theta_ij)|``, over the neighbours ``j`` within
    ``1.2 spacing``; points with fewer than two such neighbours are left out. 1 on a
    perfect hexagonal lattice of that spacing."""
    p = np.asarray(positions_m, dtype=float).reshape(-1, 2)
    if len(p) < 3:
        return float("nan")
    i, j, _ = geometric_pairs(p, 1.2 * spacing_m)
    a, b = np.r_[i, j], np.r_[j, i]
    d = p[b] - p[a]
    phase = np.exp(6j * np.arctan2(d[:, 1], d[:, 0]))
    count = np.bincount(a, minlength=len(p))
    total = np.bincount(a, weights=phase.real, minlength=len(p)) + 1j * np.bincount(
        a, weights=phase.imag, minlength=len(p)
    )
    ok = count >= 2
    return float(np.mean(np.abs(total[ok] / count[ok]))) if ok.any() else float("nan")


def hex_lattice(rows: int, cols: int, spacing_m: float, origin: tuple[float, float] = (0.0, 0.0)) -> np.ndarray:
    """Centres of a triangular lattice (the hexagonal covering) of the given spacing."""
    pts = [
        (origin[0] + c * spacing_m + (r % 2) * spacing_m / 2, origin[1] + r * spacing_m * math.sqrt(3) / 2)
        for r in range(rows)
        for c in range(cols)
    ]
    return np.array(pts)
