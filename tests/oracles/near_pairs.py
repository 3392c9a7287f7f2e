"""Reference oracles of the pairs within range (:mod:`netsim._kernels`' grid), written with
numpy and scipy's KD-tree: the tests compare the kernels, plain and compiled, with them."""

from __future__ import annotations

import numpy as np

from netsim.geometry import in_box


def wrap(d: np.ndarray, box: float | None) -> np.ndarray:
    """The nearest image of each displacement on a torus of side ``box`` (None: the plane)."""
    return d if box is None else d - box * np.round(d / box)


def all_pairs_within(pos_m: np.ndarray, range_m: float, side_m: float | None) -> np.ndarray:
    """Pairs ``(i, j)``, ``i < j``, within ``range_m`` of each other (periodic on a torus of
    side ``side_m``), every pair looked at, in the order ``(i, j)``."""
    i, j = np.triu_indices(len(pos_m), 1)
    d = wrap(pos_m[i] - pos_m[j], side_m)
    keep = np.hypot(d[:, 0], d[:, 1]) <= range_m
    return np.stack([i[keep], j[keep]], axis=1).astype(np.int64)


def kd_tree_pairs(pos_m: np.ndarray, range_m: float, side_m: float | None) -> np.ndarray:
    """Pairs ``(i, j)``, ``i < j``, within ``range_m`` by scipy's KD-tree (periodic on a
    torus of side ``side_m``), in its order."""
    from scipy.spatial import cKDTree

    pts = in_box(np.asarray(pos_m, float), side_m)
    if len(pts) < 2:
        return np.empty((0, 2), np.int64)
    tree = cKDTree(pts, boxsize=side_m) if side_m is not None else cKDTree(pts)
    return tree.query_pairs(range_m, output_type="ndarray").astype(np.int64, copy=False)


def reach_keys(positions_m: np.ndarray, ranges_m: np.ndarray, side_m: float | None = None) -> np.ndarray:
    """``receiver * n + sender`` for every ordered pair where the sender reaches the
    receiver (``hypot <= r_sender``, the nearest image on a torus), ascending: the KD-tree's
    candidate pairs within the largest range (with a relative 1e-9 of slack), each pair's
    two directions filtered and all keys sorted."""
    positions_m = np.asarray(positions_m, float)
    n = len(positions_m)
    ranges_m = np.broadcast_to(np.asarray(ranges_m, float), (n,))
    if n < 2:
        return np.empty(0, np.int64)
    pairs = kd_tree_pairs(positions_m, float(ranges_m.max()) * (1.0 + 1e-9), side_m)
    i, j = pairs[:, 0], pairs[:, 1]
    d = positions_m[i] - positions_m[j]
    if side_m is not None:
        d -= side_m * np.round(d / side_m)
    dist = np.hypot(d[:, 0], d[:, 1])
    fwd, back = dist <= ranges_m[i], dist <= ranges_m[j]
    return np.sort(np.concatenate([j[fwd] * n + i[fwd], i[back] * n + j[back]]))


def ball_neighbours(pos_m: np.ndarray, range_m: float) -> list[np.ndarray]:
    """For each point, the positions of the other points within ``range_m``, ascending by
    index: scipy's KD-tree ``query_ball_point`` (sorted for many points)."""
    from scipy.spatial import cKDTree

    tree = cKDTree(pos_m)
    return [pos_m[[j for j in js if j != k]] for k, js in enumerate(tree.query_ball_point(pos_m, range_m))]
