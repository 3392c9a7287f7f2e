"""Pairs of positions within a distance, on the plane or a torus: the geometry that the
range index, the topology snapshots and the link solvers share."""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

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


def link_segments_m(pa_m: np.ndarray, pb_m: np.ndarray, side_m: float | None = None) -> np.ndarray:
    """The segments that draw the links from ``pa_m[k]`` to ``pb_m[k]``, shape ``(m, 2, 2)``:
    on the plane each link itself; on a torus of side ``side_m`` a link across the border
    is two segments, one from each end toward the other's nearest image, each leaving the
    square where the link does (a drawing clips them at its border), as the replay draws it.

    >>> link_segments_m(np.array([[1.0, 5.0]]), np.array([[9.0, 5.0]]), 10.0).tolist()
    [[[1.0, 5.0], [-1.0, 5.0]], [[11.0, 5.0], [9.0, 5.0]]]
    """
    pa, pb = np.asarray(pa_m, float).reshape(-1, 2), np.asarray(pb_m, float).reshape(-1, 2)
    d, seam = _across_border(pa, pb, side_m)
    return np.concatenate([np.stack([pa, pa + d], axis=1), np.stack([pb[seam] - d[seam], pb[seam]], axis=1)])


def crosses_border(pa_m: np.ndarray, pb_m: np.ndarray, side_m: float | None = None) -> np.ndarray:
    """Whether the segment from each ``pa_m[k]`` to the nearest image of ``pb_m[k]`` crosses
    the border of a torus of side ``side_m`` (never on the plane, None)."""
    pa, pb = np.asarray(pa_m, float).reshape(-1, 2), np.asarray(pb_m, float).reshape(-1, 2)
    return _across_border(pa, pb, side_m)[1]


def _across_border(pa: np.ndarray, pb: np.ndarray, side_m: float | None) -> tuple[np.ndarray, np.ndarray]:
    """The nearest image's offset of each row, and whether it is not the plain one."""
    raw = pb - pa
    d = wrap(raw, side_m, max(len(pa), 1))
    return d, (d != raw).any(axis=1)


def distances_m(
    p_m: np.ndarray, q_m: np.ndarray, side_m: float | None = None, n_robots: int | None = None
) -> np.ndarray:
    """The length of each segment from row ``p_m[k]`` to row ``q_m[k]`` (``q_m``: one row per
    row of ``p_m``, or one point for every row): on a torus of side
    ``side_m`` its nearest image (None: the plane), in a run of ``n_robots`` (None: as many
    as the rows) (:func:`netsim._kernels.distances`, the engine's one rule of a link's
    length).

    >>> distances_m(np.array([[0.0, 0.0], [1.0, 1.0]]), np.array([[3.0, 4.0], [9.0, 1.0]]), 10.0).tolist()
    [5.0, 2.0]
    """
    p = _rows(p_m, np.size(p_m) // 2)
    q = _rows(q_m, len(p))
    out = np.empty(len(p))
    load("netsim._kernels", n_robots, values=len(p)).distances(p, q, float(side_m or 0.0), out)
    return out


def _rows(values_m: Any, k: int) -> np.ndarray:
    """``values_m`` as ``k`` rows of two floats that a kernel reads: itself when it already
    is such an array (writable, C-contiguous: one compiled type), else a new one (one point
    broadcast to every row)."""
    a = np.asarray(values_m, dtype=float)
    if a.shape == (k, 2) and a.flags.c_contiguous and a.flags.writeable:
        return a
    rows = np.empty((k, 2))
    rows[...] = np.reshape(a, (-1, 2))
    return rows


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


def _per_pair(kernel: Callable[..., object], per_robot: np.ndarray, a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """``kernel(per_robot, a, b, out)`` of a rule of a pair's two robots' values, ``out``
    returned."""
    out = np.empty(len(a))
    kernel(np.asarray(per_robot, float), np.asarray(a, np.int64), np.asarray(b, np.int64), out)
    return out


def link_ranges_m(range_m: np.ndarray, a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """The range of each pair ``(a[m], b[m])`` of robots whose ranges are ``range_m``: the
    smaller of the two (:func:`netsim._kernels.link_range`).

    >>> link_ranges_m(np.array([30.0, 50.0, 40.0]), np.array([0, 1]), np.array([1, 2])).tolist()
    [30.0, 40.0]
    """
    return _per_pair(load("netsim._kernels", len(range_m)).link_ranges, range_m, a, b)


def pair_travels_m(travel_m: np.ndarray, a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """The travel of each pair ``(a[m], b[m])`` of robots whose path lengths are
    ``travel_m``: their sum (:func:`netsim._kernels.pair_total`), the clock a pair's
    shadowing runs on.

    >>> pair_travels_m(np.array([1.0, 2.5, 4.0]), np.array([0, 2]), np.array([1, 1])).tolist()
    [3.5, 6.5]
    """
    return _per_pair(load("netsim._kernels", len(travel_m)).pair_totals, travel_m, a, b)


def cell_centres_m(x0_m: float, h_m: float, k: np.ndarray) -> np.ndarray:
    """The centres of cells ``k`` (any shape) of a row of cells of size ``h_m`` starting at
    ``x0_m``: ``x0 + (k + 1/2) h`` (:func:`netsim._kernels.cell_centre`, the grid's one
    rule of where a cell is).

    >>> cell_centres_m(10.0, 2.0, np.arange(3)).tolist()
    [11.0, 13.0, 15.0]
    """
    k = np.asarray(k)
    out = np.empty(k.shape)
    load("netsim._kernels", None, values=k.size).cell_centres(float(x0_m), float(h_m), k.reshape(-1), out.reshape(-1))
    return out


def inside_margin_m(d_m: np.ndarray, margin_m: float) -> np.ndarray:
    """How far inside a margin of ``margin_m`` about an edge (a wall, the area's border) a
    robot ``d_m`` from it stands: ``margin - d`` within it, 0 beyond. The edges push with
    ``gain`` times it.

    >>> inside_margin_m(np.array([0.0, 5.0, 20.0]), 10.0).tolist()
    [10.0, 5.0, 0.0]
    """
    return np.maximum(margin_m - np.asarray(d_m, dtype=float), 0.0)


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


def in_motion(velocity_mps: np.ndarray) -> np.ndarray:
    """Which rows ``(vx, vy)`` (a velocity, a step or a wish) ask a robot to move at all:
    those not both zero.

    >>> in_motion(np.array([[0.0, 0.0], [0.0, -1e-300]])).tolist()
    [False, True]
    """
    return (np.asarray(velocity_mps) != 0).any(axis=1)


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


# No robot is driven faster than light: past it the legs' crossing times' squares overflow.
SPEED_OF_LIGHT_MPS = 299_792_458.0


def drivable(velocity_mps: Any) -> np.ndarray:
    """Whether a robot can be driven at each row ``(vx, vy)`` of ``velocity_mps`` (or at one
    such pair): its speed (:func:`speeds_mps`) finite and no faster than light (NaN compares
    false, so a NaN velocity is not drivable).

    >>> drivable([[3.0, 4.0], [float("nan"), 0.0], [0.0, 3e8]]).tolist()
    [True, False, False]
    """
    return speeds_mps(np.asarray(velocity_mps, dtype=float)) <= SPEED_OF_LIGHT_MPS


def row_starts(rows: np.ndarray, n: int) -> np.ndarray:
    """Where each of the rows ``0 .. n - 1`` begins in ``rows``, ascending ids of the rows
    its items belong to (a table sorted by robot, pairs sorted by their first end), and
    ``len(rows)`` after them: row ``i``'s items are ``starts[i]:starts[i + 1]``.

    >>> row_starts(np.array([0, 0, 2, 2, 2]), 4).tolist()
    [0, 2, 2, 5, 5]
    """
    return np.searchsorted(rows, np.arange(n + 1), "left")
