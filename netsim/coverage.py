"""Coverage and connectivity metrics: pure functions of positions.

- :func:`covered_fraction`: the fraction of the square covered by the union of disks, by
  a grid of sample points, with a stated bound on its error;
- :func:`components`: connected components of the unit-disk network;
- :func:`nearest_spacing`: each leader's distance to its nearest leader;
- :func:`hexagonality`: the bond-orientational order parameter psi_6 (1 on a perfect
  hexagonal lattice, near 0 for a random arrangement).
"""

from __future__ import annotations

import math

import numpy as np
from scipy.sparse import csr_matrix
from scipy.sparse.csgraph import connected_components
from scipy.spatial import cKDTree

from netsim.topology import geometric_pairs

# Kershner (1939): the least density of a covering of the plane by equal disks, reached
# by centres on a triangular lattice of spacing sqrt(3) r.
KERSHNER_DENSITY = 2 * math.pi / (3 * math.sqrt(3))
# Area shared by two disks of radius r whose centres are sqrt(3) r apart, over r^2.
LENS_AREA_AT_HEX_SPACING = math.pi / 3 - math.sqrt(3) / 2


def covered_fraction(centres_m, radius_m: float, side_m: float, cells: int = 500, torus: bool = False):
    """Fraction of the ``side_m`` square within ``radius_m`` of some centre.

    Estimated on a ``cells x cells`` grid of cell centres. Returns ``(fraction,
    error_bound)``: only cells cut by a circle can be misclassified, so the error is at
    most ``n 2 pi r sqrt(2) h / side^2`` with ``h`` the cell size (a bound, usually loose).

    >>> round(covered_fraction([[50.0, 50.0]], 10.0, 100.0)[0], 3)
    0.031
    """
    centres = np.asarray(centres_m, dtype=float).reshape(-1, 2)
    h = side_m / cells
    axis = (np.arange(cells) + 0.5) * h
    gx, gy = np.meshgrid(axis, axis)
    points = np.column_stack([gx.ravel(), gy.ravel()])
    if len(centres) == 0:
        return 0.0, 0.0
    if torus:
        tree = cKDTree(np.mod(centres, side_m) % side_m, boxsize=side_m)
    else:
        tree = cKDTree(centres)
    dist, _ = tree.query(points, distance_upper_bound=radius_m)
    fraction = float(np.mean(dist <= radius_m))
    bound = min(1.0, len(centres) * 2 * math.pi * radius_m * math.sqrt(2) * h / side_m**2)
    return fraction, bound


def random_coverage(n: int, radius_m: float, area_m2: float) -> float:
    """Expected covered fraction for ``n`` uniform centres, ignoring borders (item 15)."""
    return 1.0 - (1.0 - math.pi * radius_m**2 / area_m2) ** n


def components(positions_m, range_m, side_m: float | None = None) -> np.ndarray:
    """Component label of every robot in the two-way unit-disk network."""
    n = len(positions_m)
    i, j, _ = geometric_pairs(positions_m, range_m, side_m)
    graph = csr_matrix((np.ones(len(i)), (i, j)), shape=(n, n))
    return connected_components(graph, directed=False)[1]


def nearest_spacing(positions_m) -> np.ndarray:
    """Distance from each point to its nearest other point (NaN with fewer than two)."""
    p = np.asarray(positions_m, dtype=float).reshape(-1, 2)
    if len(p) < 2:
        return np.full(len(p), np.nan)
    d, _ = cKDTree(p).query(p, k=2)
    return d[:, 1]


def hexagonality(positions_m, spacing_m: float) -> float:
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


def hex_lattice(rows: int, cols: int, spacing_m: float, origin=(0.0, 0.0)) -> np.ndarray:
    """Centres of a triangular lattice (the hexagonal covering) of the given spacing."""
    pts = [
        (origin[0] + c * spacing_m + (r % 2) * spacing_m / 2, origin[1] + r * spacing_m * math.sqrt(3) / 2)
        for r in range(rows)
        for c in range(cols)
    ]
    return np.array(pts)
