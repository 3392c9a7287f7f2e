"""Pairs of positions within a distance, on the plane or a torus: the geometry that the
range index, the topology snapshots and the link solvers share."""

from __future__ import annotations

import numpy as np

from netsim.compiled import load


def wrap(d: np.ndarray, box: float | None) -> np.ndarray:
    """The nearest image of each displacement on a torus of side ``box`` (None: the plane)."""
    return d if box is None else d - box * np.round(d / box)


def near_pairs(pos_m: np.ndarray, range_m: float, side_m: float | None) -> np.ndarray:
    """Pairs ``(i, j)``, ``i < j``, of positions within ``range_m`` (periodic on a torus of
    side ``side_m``), as an ``(m, 2)`` array (in the grid's fixed order, the KD-tree's or
    ``(i, j)``): for more than a small run's robots a compiled grid
    (:func:`netsim._kernels.near_pairs`), else, or where a grid would need many more cells
    than there are robots (a few robots far from the others, a line of robots), every pair
    for up to :data:`ALL_PAIRS_MAX` positions, and a KD-tree for more (scipy's, imported
    only then: a large run does without it). Whichever finds them, pairs further apart than
    ``range_m`` by up to a relative 1e-9 may be among them: each finder rounds a distance at
    the range its own way (a hypot, a sum of squares), and a pair exactly at the range must
    not depend on which (robots standing still at their range); callers filter exactly."""
    pts = in_box(pos_m, side_m)
    if len(pts) < 2:
        return np.empty((0, 2), np.int64)
    if not np.isfinite(pts).all():
        raise ValueError("robot positions must be finite to find the pairs in range")
    kernels = load("netsim._kernels", len(pts))
    if kernels is not None and range_m > 0 and grid_cells(pts, range_m, side_m) <= 16 * len(pts) + 64:
        return kernels.near_pairs(np.ascontiguousarray(pts, dtype=float), float(range_m), float(side_m or 0.0))
    # The grid's own slack, for the other finders.
    reach = range_m * (1.0 + 1e-9)
    if len(pts) <= ALL_PAIRS_MAX:
        return all_pairs_within(pts, reach, side_m)
    from scipy.spatial import cKDTree

    tree = cKDTree(pts, boxsize=side_m) if side_m is not None else cKDTree(pts)
    return tree.query_pairs(reach, output_type="ndarray").astype(np.int64, copy=False)


# Up to this many positions every pair is looked at: a few thousand distances cost less
# than importing scipy's KD-tree (about 0.15 s, a third of a small run's process).
ALL_PAIRS_MAX = 64


def all_pairs_within(pos_m: np.ndarray, range_m: float, side_m: float | None) -> np.ndarray:
    """Pairs ``(i, j)``, ``i < j``, within ``range_m`` of each other (periodic on a torus of
    side ``side_m``), every pair looked at, in the order ``(i, j)``."""
    i, j = np.triu_indices(len(pos_m), 1)
    d = wrap(pos_m[i] - pos_m[j], side_m)
    keep = np.hypot(d[:, 0], d[:, 1]) <= range_m
    return np.stack([i[keep], j[keep]], axis=1).astype(np.int64)


def grid_cells(pts: np.ndarray, range_m: float, side_m: float | None) -> float:
    """How many cells :func:`netsim._kernels.near_pairs` lays over ``pts`` for ``range_m``
    (cells a little wider than the range, over the torus or the points' bounding box)."""
    wide = range_m * (1.0 + 1e-6)
    if side_m is not None:
        return float(side_m // wide) ** 2
    span = pts.max(axis=0) - pts.min(axis=0)
    return float(span[0] // wide + 1) * float(span[1] // wide + 1)


def in_box(pos: np.ndarray, box: float | None) -> np.ndarray:
    """Positions folded into ``[0, box)`` on a torus (unchanged on the plane)."""
    if box is None:
        return pos
    # cKDTree's periodic box wants coordinates in [0, box).
    pos = np.mod(pos, box)
    return np.where(pos >= box, 0.0, pos)
