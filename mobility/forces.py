"""Virtual-force laws (paper section 1.4; docs/model.md section 5).

A robot ``i`` feels from each neighbouring robot ``j`` at distance ``d < 2 r_c`` (in the
paper's controller, "follow", leaders only) a force along the line from ``j`` to ``i`` of
signed magnitude ``f(d)`` (positive: repulsive, away from ``j``), and nothing from robots
``2 r_c`` or more away. The target spacing is
``sqrt(3) r_c``: the hexagonal lattice of disks of radius ``r_c`` covers the plane with the
least overlap, and a gateway at the midpoint of two leaders keeps them connected.

- ``spring`` (default): ``k (sqrt(3) r_c - d)``: repulsive when closer than the target,
  attractive between the target and ``2 r_c``, zero at the target.
- ``repulsion`` (the paper's law): ``k (sqrt(3) r_c - d)`` when closer than the target,
  zero beyond; leaders only push apart, and stop when the target spacing is reached.
- ``inverse_square`` (after Zou and Chakrabarty's virtual force algorithm):
  ``k r_c^3 (1 / d^2 - 1 / (sqrt(3) r_c)^2)`` (in metres, as the others): strong repulsion at short range, a weak pull
  between the target and ``2 r_c``, zero at the target.
"""

from __future__ import annotations

import math
from enum import StrEnum

import numpy as np

from netsim.area import Bounds, as_bounds
from netsim.geometry import distances_m, inside_margin_m

SQRT3 = math.sqrt(3.0)
# The expansion's cap, as a fraction of r_c: half the border's strongest push, so that the
# border still holds a robot the expansion drives at it well inside the area.
EXPANSION_CAP = SQRT3 / 4


def spring(d, range_m: float, gain: float):
    d = np.asarray(d, dtype=float)
    return np.where(d < 2 * range_m, gain * (SQRT3 * range_m - d), 0.0)


def repulsion(d, range_m: float, gain: float):
    d = np.asarray(d, dtype=float)
    return np.where(d < SQRT3 * range_m, gain * (SQRT3 * range_m - d), 0.0)


def inverse_square(d, range_m: float, gain: float):
    d = np.maximum(np.asarray(d, dtype=float), 1e-9)
    target = SQRT3 * range_m
    return np.where(d < 2 * range_m, gain * range_m**3 * (1 / d**2 - 1 / target**2), 0.0)


class Law(StrEnum):
    """The force laws (module notes)."""

    SPRING = "spring"
    REPULSION = "repulsion"
    INVERSE_SQUARE = "inverse_square"


LAWS = {Law.SPRING: spring, Law.REPULSION: repulsion, Law.INVERSE_SQUARE: inverse_square}


def pair_resultants(
    n: int,
    target: np.ndarray,
    at_xy: np.ndarray,
    source_xy: np.ndarray,
    law,
    range_m: float,
    gain: float,
    n_robots: int | None = None,
) -> np.ndarray:
    """Resultant forces on ``n`` robots (row ``i``: robot ``i``) from pairs: pair ``k`` adds
    the force on robot ``target[k]``, at ``at_xy[k]``, from a robot (or a position heard of
    one) at ``source_xy[k]``, at the distance :func:`netsim.geometry.distances_m` measures
    (in a team of ``n_robots``; None: ``n``). Pairs at distance 0 push nowhere."""
    at_xy = np.asarray(at_xy, dtype=float).reshape(-1, 2)
    source_xy = np.asarray(source_xy, dtype=float).reshape(-1, 2)
    delta = at_xy - source_xy
    d = distances_m(at_xy, source_xy, None, n if n_robots is None else n_robots)
    ok = d > 0
    mag = law(d[ok], range_m, gain) / d[ok]
    fx = np.bincount(target[ok], weights=mag * delta[ok, 0], minlength=n)
    fy = np.bincount(target[ok], weights=mag * delta[ok, 1], minlength=n)
    return np.column_stack([fx, fy])


def component_centres(p: np.ndarray, component: np.ndarray) -> np.ndarray:
    """For every row of ``p`` (k, 2), the centre (mean position) of its ``component``.

    >>> component_centres(np.array([[0.0, 0.0], [10.0, 0.0], [50.0, 50.0]]), np.array([0, 0, 1])).tolist()
    [[5.0, 0.0], [5.0, 0.0], [50.0, 50.0]]
    """
    p = np.asarray(p, dtype=float).reshape(-1, 2)
    count = np.bincount(component, minlength=int(component.max(initial=-1)) + 1)
    centre = np.column_stack([np.bincount(component, weights=p[:, k], minlength=len(count)) for k in range(2)])
    return (centre / np.maximum(count, 1)[:, None])[component]


def expansion_forces(p: np.ndarray, centre: np.ndarray, factor: float, range_m: float, gain: float) -> np.ndarray:
    """``gain x min(factor x |p - c|, EXPANSION_CAP x r_c)`` away from ``c`` for every row of
    ``p`` (k, 2), ``c`` its row of ``centre`` (or one point for all): a push away from the
    centre that grows with the distance from it, up to the cap (forces in metres).

    >>> p = np.array([[0.0, 0.0], [10.0, 0.0], [5.0, 900.0]])
    >>> expansion_forces(p, np.array([5.0, 0.0]), 0.1, 40.0, 1.0).round(2).tolist()
    [[-0.5, 0.0], [0.5, 0.0], [0.0, 17.32]]
    """
    p = np.asarray(p, dtype=float).reshape(-1, 2)
    off = p - centre
    d = distances_m(p, centre, None, len(p))
    scale = np.minimum(factor, EXPANSION_CAP * range_m / np.maximum(d, 1e-300))
    return gain * scale[:, None] * off


def border_forces(p: np.ndarray, area: float | Bounds, range_m: float, gain: float) -> np.ndarray:
    """Push back from the borders of the area (Bounds, or the side of the square ``[0,
    side]^2``) on every row of ``p`` (k, 2): ``k (m - distance)`` inward within a margin
    ``m = sqrt(3) r_c / 2`` of a border (half the target spacing: a robot there covers up
    to the border with the least waste)."""
    b = as_bounds(area)
    margin = SQRT3 * range_m / 2
    p = np.asarray(p, dtype=float).reshape(-1, 2)
    return gain * (inside_margin_m(p - b.lo, margin) - inside_margin_m(b.hi - p, margin))
