"""Who is within range of a robot now: exact answers from a neighbour list built earlier.

Rebuilding a spatial index for every transmission would cost O(N) or more each. Instead,
at ``t_build`` a grid of cells (:func:`netsim.geometry.near_pairs`)
lists, for every robot, the robots within ``R + 2 s`` of it (a Verlet list, as in molecular
dynamics), where ``R`` is the largest range and ``s`` a slack. Until some robot could
have moved more than ``s`` since then (``speed_high_water * (t - t_build) > s``, the highest
speed any robot has had in the run), every
robot in range of ``i`` now is on ``i``'s list, so a query is a slice of the list filtered
on exact current positions. Rebuilding costs O(N) every ``s / v_max`` seconds; a larger
slack means fewer rebuilds and longer lists. The default slack is a fifth of the largest range.

A query's filter is one loop (:func:`netsim._kernels.within`) and the lists are built by
one (:func:`netsim._kernels.neighbour_lists`), compiled or plain Python as
:func:`netsim.compiled.load` decides for the run.
"""

from __future__ import annotations

import numpy as np

from netsim._kernels import Motion
from netsim.compiled import load
from netsim.geometry import near_pairs
from netsim.state import RobotState

_NONE = np.empty(0, dtype=np.int64)
_NO_DISTANCE = np.empty(0)


class RangeIndex:
    """Exact range queries against a :class:`RobotState` at non-decreasing times."""

    def __init__(self, state: RobotState, slack_m: float | None = None, reach_m: float | None = None):
        self.state = state
        # The largest radius asked for: the largest range, or the radio's reach.
        self.reach_m = float(reach_m) if reach_m is not None else float(state.range_m.max()) if state.n else 0.0
        self.slack_m = float(slack_m) if slack_m is not None else 0.2 * self.reach_m
        self._t_build = -np.inf
        self._jumps = -1
        self._indptr = np.zeros(state.n + 1, dtype=np.int64)
        self._bounds = self._indptr.tolist()
        self._indices = _NONE
        self.rebuilds = 0
        self.kernels = load("netsim._kernels", state.n)
        # The robots' motion as the queries read it (netsim._kernels.Motion):
        # arrays kept for the run, so put together once.
        self._motion = tuple(Motion(state.origin_m, state.velocity_mps, state.t0_s, state.torus, state.side_m))

    def _build(self, t: float) -> None:
        st = self.state
        pos = st.positions_at(t)
        pairs = near_pairs(pos, self.reach_m + 2 * self.slack_m, st.torus_side_m)
        self._indptr, self._indices = self.kernels.neighbour_lists(pairs, st.n)
        # The same offsets as Python ints: read once per query, cheaper than numpy scalars.
        self._bounds = self._indptr.tolist()
        self._t_build = t
        self._jumps = st.jumps
        # Raised, never lowered: another index on the same state (a shared medium's) may have
        # been built earlier, when some robot was faster than any is now.
        st.speed_high_water_mps = max(st.speed_high_water_mps, float(st.speed_mps.max(initial=0.0)))
        self.rebuilds += 1

    def within(self, t: float, i: int, radius_m: float | None = None) -> tuple[np.ndarray, np.ndarray]:
        """Robots other than ``i`` within ``radius_m`` (default: i's range) of ``i`` at ``t``.

        Returns ``(ids, distances_m)``, ids ascending.
        """
        st = self.state
        r = float(st.range_m[i]) if radius_m is None else float(radius_m)
        cand, lo, hi = self._candidate_span(t, i, r)
        cand = cand[lo:hi]
        if len(cand) == 0:
            return _NONE, _NO_DISTANCE
        return self.kernels.within(cand, self._motion, int(i), float(t), r)

    def pair_within(self, t: float, i: int, j: int, radius_m: float) -> tuple[bool, float]:
        """Whether ``j`` is within ``radius_m`` of ``i`` at ``t``, and their distance, as
        :meth:`within` measures them."""
        n = self.state.n
        if not (-n <= i < n and -n <= j < n):
            raise IndexError(f"robot index out of range for {n} robots: {i}, {j}")
        hit, d = self.kernels.pair_reach(self._motion, int(i), int(j), float(t), float(radius_m))
        return bool(hit), float(d)

    def within_alive(self, t: float, i: int) -> tuple[np.ndarray, bool]:
        """Robots other than ``i`` within ``i``'s range at ``t``, ids ascending (those of
        :meth:`within`, without their distances), and whether all of them are alive: what
        a transmission needs when nothing after asks the distances."""
        st = self.state
        r = float(st.range_m[i])
        cand, lo, hi = self._candidate_span(t, i, r)
        if lo == hi:
            return _NONE, True
        return self.kernels.within_alive(cand, lo, hi, self._motion, int(i), float(t), r, st.alive)

    def lists(self, t: float) -> tuple[np.ndarray, np.ndarray]:
        """Every robot's neighbour list, valid at ``t`` (rebuilt first if some robot may
        have moved past the slack): ``(indptr, indices)``, robot ``i``'s at
        ``indices[indptr[i]:indptr[i + 1]]``, ascending, holding every robot within the
        reach of ``i`` at ``t`` (and more)."""
        self._refresh(t)
        return self._indptr, self._indices

    def _refresh(self, t: float) -> None:
        """Rebuild the lists at ``t`` if some robot may have moved past the slack since they
        were built (or jumped, or time went back)."""
        st = self.state
        if st.jumps != self._jumps or t < self._t_build or st.speed_high_water_mps * (t - self._t_build) > self.slack_m:
            self._build(t)

    def _candidate_span(self, t: float, i: int, r: float) -> tuple[np.ndarray, int, int]:
        """The robots that may be within ``r`` of ``i`` at ``t``, as ``array[lo:hi]`` of the
        ``(array, lo, hi)`` returned: its neighbour list (rebuilt first if some robot may have
        moved past the slack), or all others past the reach."""
        self._refresh(t)
        st = self.state
        if r > self.reach_m:
            return np.delete(np.arange(st.n), i), 0, st.n - 1
        bounds = self._bounds
        return self._indices, bounds[i], bounds[i + 1]
