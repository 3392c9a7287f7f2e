"""Reference oracles of the covered fraction on a grid (:func:`netsim.metrics.covered_fraction`,
:func:`netsim._kernels.grid_nearest_m`): a search tree over the cell centres, and every cell
against every centre with numpy."""

from __future__ import annotations

import math
from typing import Any

import numpy as np
import numpy.typing as npt
from scipy.spatial import cKDTree

from netsim.area import Bounds, as_bounds


def grid_nearest_m(p, reach_m, x0_m, y0_m, width_m, height_m, cells, box):
    """Every cell centre against every point (and its 8 images on a torus), the same
    arithmetic as the kernel: the nearest distance within ``reach_m``, else ``inf``."""
    hx, hy = width_m / cells, height_m / cells
    cx = (np.arange(cells) + 0.5) * hx
    cy = (np.arange(cells) + 0.5) * hy
    out = np.full((cells, cells), np.inf)
    for x, y in np.asarray(p, dtype=float).reshape(-1, 2) - np.array([x0_m, y0_m]):
        if box > 0:
            x, y = x % box, y % box
        shifts = (-1, 0, 1) if box > 0 else (0,)
        for iy in shifts:
            for ix in shifts:
                d = np.hypot(cx[None, :] - (x - ix * box), (cy[:, None] - (y - iy * box)))
                d = np.where(d <= reach_m, d, np.inf)
                out = np.minimum(out, d)
    return out


def covered_fraction_kd(
    centres_m: npt.ArrayLike,
    radius_m: float,
    area: float | Bounds,
    cells: int = 500,
    torus: bool = False,
    region: Any = None,
) -> tuple[float, float]:
    """:func:`netsim.metrics.covered_fraction` by a search tree: each cell centre's nearest
    centre found by scipy's ``cKDTree`` (periodic on a torus), not by the grid kernel."""
    centres = np.asarray(centres_m, dtype=float).reshape(-1, 2)
    b = as_bounds(area)
    side_m = b.width
    if b.is_square_at_origin:
        h = side_m / cells
        axis = (np.arange(cells) + 0.5) * h
        gx, gy = np.meshgrid(axis, axis)
        half_diagonal = h / math.sqrt(2)
    else:
        hx, hy = b.width / cells, b.height / cells
        gx, gy = np.meshgrid(b.x_min + (np.arange(cells) + 0.5) * hx, b.y_min + (np.arange(cells) + 0.5) * hy)
        half_diagonal = 0.5 * math.hypot(hx, hy)
    points = np.column_stack([gx.ravel(), gy.ravel()])
    edge = np.zeros(len(points), dtype=bool)
    if region is not None:
        import shapely

        inside = shapely.contains_xy(region, points[:, 0], points[:, 1])
        edge = shapely.dwithin(region.boundary, shapely.points(points[inside]), half_diagonal)
        points = points[inside]
    if len(centres) == 0 or len(points) == 0:
        return 0.0, float(np.mean(edge)) if len(edge) else 0.0
    if torus:
        tree = cKDTree(np.mod(centres, side_m) % side_m, boxsize=side_m)
    else:
        tree = cKDTree(centres)
    dist, _ = tree.query(points, distance_upper_bound=radius_m + half_diagonal)
    fraction = float(np.mean(dist <= radius_m))
    uncertain = (np.abs(dist - radius_m) <= half_diagonal) | edge
    return fraction, float(np.mean(uncertain))
