"""Who is within range of a robot now: exact answers from a KD-tree built a while ago.

Rebuilding a tree for every transmission would cost O(N log N) each. Instead the tree
holds positions at ``t_build``; since then no robot has moved more than
``s = speed_high_water * (t - t_build)``, so every robot in range ``r`` of the sender now
lies within ``r + s`` of the sender's current position in the tree. The candidates are
then filtered on their exact current positions (the Verlet-list idea of molecular
dynamics). The tree is rebuilt when ``s`` exceeds a slack (default a fifth of the largest
range: a rebuild costs O(N log N) once, a larger slack costs more candidates per query).
"""

from __future__ import annotations

import numpy as np
from scipy.spatial import cKDTree

from netsim.state import RobotState


def _wrap(d: np.ndarray, side: float) -> np.ndarray:
    return (d.real - side * np.round(d.real / side)) + 1j * (d.imag - side * np.round(d.imag / side))


_NONE = np.empty(0, dtype=np.int64)
_NO_DISTANCE = np.empty(0)


class RangeIndex:
    """Exact range queries against a :class:`RobotState` at non-decreasing times."""

    def __init__(self, state: RobotState, slack_m: float | None = None):
        self.state = state
        self.slack_m = float(slack_m) if slack_m is not None else 0.2 * float(state.range_m.max())
        self._tree: cKDTree | None = None
        self._t_build = -np.inf
        self._jumps = -1
        self.rebuilds = 0

    def _build(self, t: float) -> None:
        st = self.state
        pos = st.positions_at(t)
        if st.torus:
            # cKDTree's periodic box wants coordinates in [0, side).
            pos = np.where(pos >= st.side_m, 0.0, pos)
            self._tree = cKDTree(pos, boxsize=st.side_m)
        else:
            self._tree = cKDTree(pos)
        self._t_build = t
        self._jumps = st.jumps
        speeds = np.hypot(st.velocity_mps[:, 0], st.velocity_mps[:, 1])
        st.speed_high_water_mps = float(speeds.max()) if st.n else 0.0
        self.rebuilds += 1

    def within(self, t: float, i: int, radius_m: float | None = None):
        """Robots other than ``i`` within ``radius_m`` (default: i's range) of ``i`` at ``t``.

        Returns ``(ids, distances_m)``, ids ascending.
        """
        st = self.state
        r = float(st.range_m[i]) if radius_m is None else float(radius_m)
        if self._tree is None or st.jumps != self._jumps or t < self._t_build:
            self._build(t)
        drift = st.speed_high_water_mps * (t - self._t_build)
        if drift > self.slack_m:
            self._build(t)
            drift = 0.0
        x, y = st.position(i, t)
        cand = self._tree.query_ball_point((x, y), r + drift)
        if len(cand) <= 1:
            return _NONE, _NO_DISTANCE
        cand = np.array(cand, dtype=np.int64)
        cand.sort()
        # Complex views of the (n, 2) arrays: one operation per step instead of two.
        d = st.origin_c.take(cand) + st.velocity_c.take(cand) * (t - st.t0_s.take(cand)) - complex(x, y)
        if st.torus:
            d = _wrap(d, st.side_m)
        dist2 = d.real * d.real + d.imag * d.imag
        keep = dist2 <= r * r
        keep[np.searchsorted(cand, i)] = False
        return cand[keep], np.sqrt(dist2[keep])
