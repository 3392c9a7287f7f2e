"""The area robots move in: an axis-aligned rectangle in the world frame (``world.bounds_m``).

By default the square ``[0, side_m]^2``; on a map it may be any rectangle the map covers,
``"map"`` meaning the map's whole extent, in the map's own frame (a ``map_saver`` map whose
origin is ``[-10, -10]`` puts the start pose ``(0, 0)`` ten metres inside it). Placement,
every mobility model, the coverage controller, the metrics and the figures take the area
from here; the torus stays the square ``[0, side_m]^2``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np

from netsim.errors import ConfigError

KEY = "world.bounds_m"
# The farthest a coordinate of the area may lie from the origin (metres): far beyond any
# team's area, yet where a double still resolves a position to well under a millimetre
# and the areas and squared distances the engine forms are far from overflow.
MAX_COORDINATE_M = 1e12


def within_reach_of_doubles(v: float) -> str | None:
    """A length or coordinate of the area: at most :data:`MAX_COORDINATE_M` in size."""
    return None if abs(v) <= MAX_COORDINATE_M else f"must be at most {MAX_COORDINATE_M:g} m in size"


def area_side(v: float) -> str | None:
    """The side of the square area: positive, at most :data:`MAX_COORDINATE_M`."""
    return None if v > 0 and not within_reach_of_doubles(v) else f"must be in (0, {MAX_COORDINATE_M:g}] (metres)"


class OnTorus:
    """What has a square of side ``side_m`` that wraps when ``torus`` (the world's
    configuration, the robots' state, a control step): the side its distances are measured
    on, :attr:`torus_side_m`."""

    side_m: float
    torus: bool

    @property
    def torus_side_m(self) -> float | None:
        """The side of the torus distances are measured on (to the nearest image), None on
        the plane: the ``side_m`` of :func:`netsim.geometry.distances_m` and its kin."""
        return self.side_m if self.torus else None


@dataclass(frozen=True)
class Bounds:
    """The rectangle ``[x_min, x_max] x [y_min, y_max]``, metres.

    >>> b = Bounds(-10.0, -20.0, 50.0, 20.0)
    >>> b.width, b.height, b.area
    (60.0, 40.0, 2400.0)
    >>> b.contains([[0.0, 0.0], [51.0, 0.0]]).tolist()
    [True, False]
    """

    x_min: float
    y_min: float
    x_max: float
    y_max: float

    @classmethod
    def square(cls, side_m: float) -> Bounds:
        """The square ``[0, side_m]^2``."""
        return cls(0.0, 0.0, float(side_m), float(side_m))

    @property
    def width(self) -> float:
        return self.x_max - self.x_min

    @property
    def height(self) -> float:
        return self.y_max - self.y_min

    @property
    def area(self) -> float:
        """Area, m^2 (a square's as ``side**2``)."""
        return self.width**2 if self.width == self.height else self.width * self.height

    @property
    def diagonal(self) -> float:
        """Length of the diagonal, m (a square's as ``side * sqrt(2)``)."""
        return self.width * math.sqrt(2) if self.width == self.height else math.hypot(self.width, self.height)

    @property
    def lo(self) -> np.ndarray:
        """``[x_min, y_min]``."""
        return np.array([self.x_min, self.y_min])

    @property
    def hi(self) -> np.ndarray:
        """``[x_max, y_max]``."""
        return np.array([self.x_max, self.y_max])

    @property
    def size(self) -> np.ndarray:
        """``[width, height]``."""
        return np.array([self.width, self.height])

    @property
    def is_square_at_origin(self) -> bool:
        return self.x_min == 0.0 and self.y_min == 0.0 and self.width == self.height

    def as_list(self) -> list[float]:
        return [self.x_min, self.y_min, self.x_max, self.y_max]

    def uniform(self, rng: np.random.Generator, n: int) -> np.ndarray:
        """``n`` points uniform over the rectangle, shape ``(n, 2)`` (on ``[0, side]^2`` the
        same draws, bit for bit, as ``rng.uniform(0, side, (n, 2))``)."""
        if self.is_square_at_origin:
            return rng.uniform(0.0, self.x_max, (n, 2))
        return self.lo + rng.uniform(0.0, 1.0, (n, 2)) * self.size

    def contains(self, points_m: Any, tol_m: float = 0.0) -> np.ndarray:
        """Whether each point lies in the closed rectangle (widened by ``tol_m``)."""
        p = np.asarray(points_m, dtype=float).reshape(-1, 2)
        return (
            (p[:, 0] >= self.x_min - tol_m)
            & (p[:, 0] <= self.x_max + tol_m)
            & (p[:, 1] >= self.y_min - tol_m)
            & (p[:, 1] <= self.y_max + tol_m)
        )

    def clip(self, points_m: Any) -> np.ndarray:
        """Points moved to the nearest point of the rectangle (a copy)."""
        return np.clip(np.asarray(points_m, dtype=float), self.lo, self.hi)

    def landing(self, p_m: Any, v_mps: Any, travel_s: float) -> np.ndarray:
        """Where a point at ``p_m`` (2,) moving by ``v_mps`` meets the border after
        ``travel_s``, :func:`time_to_border`'s time: exactly on the border along the axis
        (or both) it runs out at. ``p + v t`` can fall a rounding error inside, and a point
        not on the border is free to head out of the area again.

        >>> Bounds.square(10.0).landing([1.0, 5.0], [-0.5, 0.25], 2.0).tolist()
        [0.0, 5.5]
        """
        p, v = np.asarray(p_m, dtype=float), np.asarray(v_mps, dtype=float)
        end = self.clip(p + v * travel_s)
        for k, (lo, hi) in enumerate(zip(self.lo, self.hi, strict=True)):
            # Each axis' exit time as exit_times computes it: the least is travel_s itself.
            if v[k] > 0 and (hi - p[k]) / v[k] <= travel_s:
                end[k] = hi
            elif v[k] < 0 and -(p[k] - lo) / v[k] <= travel_s:
                end[k] = lo
        return end


def as_bounds(area: float | Bounds) -> Bounds:
    """``area`` as Bounds: a number is the side of the square ``[0, side]^2``."""
    return area if isinstance(area, Bounds) else Bounds.square(float(area))


def exit_times(p: np.ndarray, v: np.ndarray, lo: Any, hi: Any) -> np.ndarray:
    """For each row of ``p`` (k, 2) moving by ``v`` (k, 2) per unit of time, when it leaves the
    box ``[lo, hi]`` (rows, or one box for all): ``(hi - p) / v`` along an axis it moves up,
    ``-(p - lo) / v`` along one it moves down, the least of the two axes; ``inf`` at rest,
    negative when already outside on the way out.

    >>> p, v = np.array([[1.0, 5.0], [5.0, 5.0]]), np.array([[-0.5, 0.0], [0.0, 0.0]])
    >>> exit_times(p, v, (0.0, 0.0), (10.0, 10.0)).tolist()
    [2.0, inf]
    """
    p, v = np.asarray(p, dtype=float), np.asarray(v, dtype=float)
    t = np.full(np.broadcast_shapes(p.shape, v.shape), math.inf)
    # A move of a few ulps overflows the quotient to inf, which is right: it stays inside.
    with np.errstate(over="ignore"):
        np.divide(np.subtract(hi, p), v, out=t, where=v > 0)
        np.divide(-np.subtract(p, lo), v, out=t, where=v < 0)
    # + 0: a robot on the border, moving out, leaves at time +0, never -0, whose sign a
    # step scaled by it would carry into the tables.
    return t.min(axis=1) + 0.0


def time_to_border(p: np.ndarray, v: np.ndarray, area: float | Bounds) -> np.ndarray:
    """Time for each robot at ``p`` (k, 2) moving at ``v`` (k, 2) to reach the border of the
    area (Bounds, or the side of the square ``[0, side]^2``; ``inf`` at rest; 0 when on the
    border and heading out).

    >>> time_to_border(np.array([[1.0, 5.0]]), np.array([[-0.5, 0.0]]), 10.0).tolist()
    [2.0]
    """
    b = as_bounds(area)
    return np.maximum(exit_times(p, v, b.lo, b.hi), 0.0)


def parse_bounds(key: str, value: Any) -> tuple[float, float, float, float] | str:
    """A configuration value of ``world.bounds_m``: ``"map"``, or four finite numbers
    ``[x_min, y_min, x_max, y_max]`` with ``x_max > x_min`` and ``y_max > y_min``."""
    allowed = 'must be [x_min, y_min, x_max, y_max] (metres, x_max > x_min, y_max > y_min) or "map"'
    if value == "map":
        return "map"
    if isinstance(value, str) or not isinstance(value, list | tuple) or len(value) != 4:
        raise ConfigError(key, value, allowed)
    out = []
    for v in value:
        if isinstance(v, bool) or not isinstance(v, int | float) or not math.isfinite(float(v)):
            raise ConfigError(key, list(value), allowed)
        out.append(float(v))
    x0, y0, x1, y1 = out
    if not (x1 > x0 and y1 > y0):
        raise ConfigError(key, list(value), allowed)
    for v in out:
        if within_reach_of_doubles(v):
            raise ConfigError(key, list(value), f"each coordinate {within_reach_of_doubles(v)}")
    return x0, y0, x1, y1


def parse_start(key: str, value: Any) -> tuple[float, float] | str:
    """A configuration value of ``world.start_m``: ``"centre"`` or two finite numbers ``[x, y]``."""
    allowed = 'must be [x, y] (metres) or "centre"'
    if value == "centre":
        return "centre"
    if isinstance(value, str) or not isinstance(value, list | tuple) or len(value) != 2:
        raise ConfigError(key, value, allowed)
    if any(isinstance(v, bool) or not isinstance(v, int | float) or not math.isfinite(float(v)) for v in value):
        raise ConfigError(key, list(value), allowed)
    return float(value[0]), float(value[1])
