"""Pairs of positions within a distance, on the plane or a torus: the geometry that the
range index, the topology snapshots and the link solvers share."""

from __future__ import annotations

import numpy as np

from netsim.compiled import filled, load


def wrap(d: np.ndarray, box: float | None, n_robots: int) -> np.ndarray:
    """The nearest image of each displacement (rows of ``d``) on a torus of side ``box``
    (None: the plane, ``d`` itself), in a run of ``n_robots``
    (:func:`netsim._kernels.nearest_image`)."""
    if box is None:
        return d
    rows = np.ascontiguousarray(d, dtype=float).reshape(-1, 2)
    return load("netsim._kernels", n_robots).nearest_images(rows, float(box)).reshape(np.shape(d))


def beyond(points_m: np.ndarray, centres_m: np.ndarray, radius_m: np.ndarray, n_robots: int) -> np.ndarray:
    """Whether each point (rows, or any shape ending in 2) lies farther than its radius from
    its centre, in a run of ``n_robots``: the rule of in range
    (:func:`netsim._kernels.beyond_disks`)."""
    shape = np.broadcast_shapes(np.shape(points_m), np.shape(centres_m))[:-1]
    points = filled(points_m, (*shape, 2)).reshape(-1, 2)
    centres = filled(centres_m, (*shape, 2)).reshape(-1, 2)
    out = np.empty(len(points), bool)
    load("netsim._kernels", n_robots).beyond_disks(points, centres, filled(radius_m, shape).reshape(-1), out)
    return out.reshape(shape)


def speeds_mps(velocity_mps: np.ndarray) -> np.ndarray:
    """The speed of each row ``(vx, vy)``: numpy's ``abs`` of ``vx + i vy``, the one law of a
    robot's speed (its odometer and the shadowing's clock run on it, the local plan bounds
    a known robot's travel by it). The same bits for a row whichever rows come with it; a
    compiled ``abs`` or ``hypot`` may differ in the last bit.

    >>> speeds_mps(np.array([[3.0, 4.0], [0.0, -2.0]])).tolist()
    [5.0, 2.0]
    """
    v = np.ascontiguousarray(velocity_mps, dtype=np.float64).reshape(-1, 2)
    return np.abs(v.view(np.complex128)[:, 0])


def near_pairs(pos_m: np.ndarray, range_m: float, side_m: float | None) -> np.ndarray:
    """Pairs ``(i, j)``, ``i < j``, of positions within ``range_m`` (periodic on a torus of
    side ``side_m``), as an ``(m, 2)`` array in the grid's fixed order
    (:func:`netsim._kernels.near_pairs`). Pairs further apart than ``range_m`` by up to a
    relative 1e-9 may be among them: a distance at the range rounds either way, and a pair
    exactly at the range must not depend on how (robots standing still at their range);
    callers filter exactly."""
    pts = in_box(pos_m, side_m)
    if len(pts) < 2:
        return np.empty((0, 2), np.int64)
    finite_positions(pts)
    kernels = load("netsim._kernels", len(pts))
    return kernels.near_pairs(np.ascontiguousarray(pts, dtype=float), float(range_m), float(side_m or 0.0))


def finite_positions(pos_m: np.ndarray) -> None:
    """Refuse positions that are not finite (no grid holds them)."""
    if not np.isfinite(pos_m).all():
        raise ValueError("robot positions must be finite to find the pairs in range")


def in_box(pos: np.ndarray, box: float | None, n_robots: int | None = None) -> np.ndarray:
    """Positions folded into ``[0, box)`` on a torus, as a robot's position is
    (:func:`netsim._kernels.fold`), for a team of ``n_robots`` (None: one per row);
    unchanged on the plane."""
    if box is None:
        return pos
    pos = np.asarray(pos, dtype=float)
    return load("netsim._kernels", n_robots, values=len(pos)).fold(pos, float(box))
