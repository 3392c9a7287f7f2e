"""What every coverage plan shares: the limits of one control step, the plan it returns,
and the geometry of shortening a straight step so that it ends inside a disk or the area.

Both plans (:mod:`netsim.mobility.bridges`, :mod:`netsim.mobility.spread`) rest on one fact: over a
step every robot moves in a straight line at constant speed, so the distance between two
robots is a convex function of time; a link within range at both ends of the step is
within range throughout it.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import NamedTuple

import numpy as np

from netsim.area import Bounds, as_bounds, exit_times
from netsim.compiled import filled, load
from netsim.geometry import in_motion

# Steps are cut a hair short of a constraint's boundary, against rounding.
SAFETY = 1.0 - 1e-9


@dataclass(frozen=True)
class StepLimits:
    """The physical limits of one control step.

    period_s : duration of the step.
    range_m : communication range ``r_c`` (the smallest, with unequal ranges).
    margin_m : kept links end the step at most ``range_m - margin_m`` long (unless longer
        already, then no longer than they are).
    speed_max_mps : speed cap of every robot.
    side_m : side of the square area ``[0, side_m]^2``; every robot stays inside it.
    area : the area, when given (``world.bounds_m``): then it, not ``side_m``, is the box.
    """

    period_s: float
    range_m: float
    margin_m: float
    speed_max_mps: float
    side_m: float
    area: Bounds | None = None

    @property
    def box(self) -> Bounds:
        """The area every robot stays in."""
        return self.area if self.area is not None else Bounds.square(self.side_m)

    @property
    def keep_m(self) -> float:
        return self.range_m - self.margin_m

    @property
    def reach_m(self) -> float:
        """The longest step a robot can take."""
        return self.speed_max_mps * self.period_s


class Plan(NamedTuple):
    velocity_mps: np.ndarray  # (N, 2) over the step
    commander: np.ndarray  # leader whose command a robot needs to move (-1: none)
    held: np.ndarray  # robots whose step was shortened for connectivity or the border
    bridges: int  # kept links (follow: between groups; spread: of the spanning forest)
    kept: np.ndarray | None = None  # spread: the rows of the candidate links kept


class Candidates(NamedTuple):
    """The links a plan may keep (up when the step starts), with what keeps each one up
    (:mod:`netsim.mobility.keep`).

    i, j : the two robots (``i < j``); d : the length now.
    weight : the spanning forest prefers low weights (positive).
    keep_m : a kept link ends the step at most ``max(keep_m, d)`` long.
    travel_m : the pair's travel (sum of both robots' path lengths) allowed over the step
        (inf: no bound; shadowing bounds it).
    range_m : the unit disk's range of the pair (for line of sight on a map).
    reserve_db : log-distance: the shadowing the link must withstand at every instant
        (the measured value plus its budget; 0 without shadowing).
    """

    i: np.ndarray
    j: np.ndarray
    d: np.ndarray
    weight: np.ndarray
    keep_m: np.ndarray
    travel_m: np.ndarray
    range_m: np.ndarray
    reserve_db: np.ndarray | None = None


def step_limit(offset: np.ndarray, radius: np.ndarray, move: np.ndarray, n_robots: int | None = None) -> np.ndarray:
    """Largest ``s`` in [0, 1] with ``|offset + s move| <= radius``, row-wise (``|offset|
    <= radius`` holds: standing still is always allowed), cut by :data:`SAFETY`: the link
    solvers' rule of when a straight leg leaves a disk (:func:`netsim._kernels.disk_exits`).
    ``n_robots``: the team's size, which decides whether it runs compiled (None: as many as
    the rows).

    >>> step_limit(np.array([[0.0, 0.0]]), np.array([1.0]), np.array([[4.0, 0.0]])).round(6)
    array([0.25])
    """
    k = len(move)
    out = np.empty(k)
    kernels = load("netsim._kernels", n_robots, values=k)
    kernels.disk_exits(filled(offset, (k, 2)), filled(radius, k), filled(move, (k, 2)), SAFETY, out)
    return out


def fell_short(wish: np.ndarray, move: np.ndarray, range_m: float) -> np.ndarray:
    """Which robots a plan held: those that wished to move (:func:`in_motion`) and whose
    step ``move`` ends farther from their ``wish`` than rounding (a billionth of the range)."""
    return in_motion(wish) & (np.hypot(*(move - wish).T) > 1e-9 * range_m)


def box_limit(pos: np.ndarray, move: np.ndarray, area: float | Bounds) -> np.ndarray:
    """Largest ``s`` in [0, 1] keeping ``pos + s move`` inside the area (Bounds, or the side
    of the square ``[0, side]^2``), row-wise."""
    b = as_bounds(area)
    return np.clip(exit_times(pos, move, b.lo, b.hi) * SAFETY, 0.0, 1.0)


def cap_length(move: np.ndarray, cap_m: float | np.ndarray) -> np.ndarray:
    """``move`` with every row longer than ``cap_m`` (one for all, or one per row)
    shortened to it (in place)."""
    length = np.hypot(*move.T)
    cap = np.broadcast_to(np.asarray(cap_m, float), length.shape)
    over = length > cap
    move[over] *= (cap[over] / length[over])[:, None]
    return move
