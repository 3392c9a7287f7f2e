"""The loss chains of :mod:`netsim.radio.propagation` compiled into one pass: the channel's hot path.

A transmission asks which of its few tens of candidate receivers can hear it. Through the
generic chain that costs some fifty numpy operations, whatever the number of pairs; here it
is two compiled loops and one draw of normals. :class:`CompiledChain` accepts the chains
that :func:`~netsim.radio.propagation.log_distance` and
:func:`~netsim.radio.propagation.unit_disk` build and decides exactly as the chain does: the
same pairs are dropped before shadowing (so the same normals are drawn), the same shadowing
updates are made, and the same sums are compared with the sensitivity. Pairs in one batch
must be distinct (a broadcast's receivers are).

Without numba it hands every batch to the generic chain. A model whose chain has other
terms brings no compiled path (:attr:`~netsim.radio.propagation.Propagation.fast` is None):
:class:`GenericChain` evaluates it with numpy, term by term.
"""

from __future__ import annotations

import numpy as np

from netsim.radio import compiled_kernels
from netsim.radio.los import VERTEX_TOLERANCE_CELLS
from netsim.radio.propagation import (
    LineOfSightLoss,
    LogDistanceLoss,
    Pairs,
    Propagation,
    RangeLoss,
    ShadowingLoss,
    WallLoss,
)
from netsim.radio.shadowing import pair_keys

_NO_GRID = np.zeros(1, dtype=bool)
# Stand-ins for the arrays a pass does not read (no walls: no grid points; no shadowing: no
# keys, travels or draws).
_NO_POINTS = np.zeros((1, 2))
_NO_KEYS = np.zeros(1, dtype=np.int64)
_NO_FLOATS = np.zeros(1)


class CompiledChain:
    """``receivable(pairs)`` of a :class:`~netsim.radio.propagation.Propagation`, compiled."""

    def __init__(self, propagation: Propagation):
        self.propagation = propagation
        self.k = compiled_kernels()
        terms = list(propagation.chain.terms)
        kinds = [type(t) for t in terms]
        self.log = self.shadow = self.walls = self.range = self.sight = None
        if kinds and kinds[0] is LogDistanceLoss:
            self.log = terms.pop(0)
            if terms and isinstance(terms[0], ShadowingLoss):
                self.shadow = terms.pop(0).shadowing
            if terms and isinstance(terms[0], WallLoss):
                self.walls = terms.pop(0)
        elif kinds and kinds[0] is RangeLoss:
            self.range = terms.pop(0)
            if terms and isinstance(terms[0], LineOfSightLoss):
                self.sight = terms.pop(0)
        if terms or (self.log is None and self.range is None):
            raise ValueError(f"no compiled form for the chain {[k.__name__ for k in kinds]}")
        budget = propagation.tx_power_dbm - propagation.sensitivity_dbm
        # The chain's own early-drop rule, slack included.
        self.budget_slack = budget + 1e-9 * (1.0 + abs(budget))
        term = self.walls or self.sight
        occupancy = term.occupancy if term is not None else None
        self.occupancy = occupancy
        if self.log is not None:
            p = self.log.params
            # (Compared with None: a PairShadowing with no pair seen yet is falsy, it has a length.)
            step, clip, sigma, dcorr = (
                (0.0, 0.0, 0.0, 1.0)
                if self.shadow is None
                else (self.shadow.step_m, self.shadow.clip_db, self.shadow.sigma_db, self.shadow.decorrelation_m)
            )
            # log_frame's arguments from step_m to decorrelation_m: fixed for the run.
            self._frame_constants = (
                step, p.reference_distance_m, p.reference_loss_db, 10.0 * p.path_loss_exponent, clip,
                self.budget_slack, propagation.tx_power_dbm, propagation.sensitivity_dbm, sigma, dcorr,
            )  # fmt: skip

    def _grid(self, pairs: Pairs):
        m = self.occupancy
        if m is None:
            return _NO_GRID, 1, 1, _NO_POINTS, _NO_POINTS
        origin = np.asarray(m.origin_m)
        h, w = m.shape
        g0 = (pairs.pos_a - origin) / m.resolution_m
        g1 = (pairs.pos_b - origin) / m.resolution_m
        return m.occupied.ravel(), h, w, g0, g1

    def receivable(self, pairs: Pairs) -> np.ndarray:
        if self.k is None:
            return self.propagation.receivable(pairs)
        keys = s_new = None
        if self.shadow is not None and len(pairs.a):
            keys = pair_keys(pairs.a, pairs.b)
            travel = np.zeros(len(pairs.a)) if pairs.travel_m is None else np.asarray(pairs.travel_m, dtype=float)
            s_new = self.shadow.anchor(travel)
        return self._receivable(pairs, keys, s_new)

    def transmission(
        self, state, t: float, sender: int, receivers: np.ndarray, distances_m: np.ndarray, speed_mps: np.ndarray
    ) -> np.ndarray:
        """:meth:`receivable` of ``sender``'s frame at ``t`` to ``receivers`` (ids, distinct):
        the channel's per-frame call, one compiled call that also finds the robots' positions
        on the map and the pairs' travels. ``speed_mps``: every robot's ``|v|`` as numpy's
        ``abs`` gives it (a compiled ``abs`` may differ in the last bit, and the pairs'
        travels must be exactly those of ``state.travelled_m``)."""
        k = len(receivers)
        sh = self.shadow
        if self.k is None or k == 0 or state.torus:
            pairs = self._pairs(state, t, sender, receivers, distances_m)
            if sh is not None:
                travel = state.travelled_m(t, receivers) + float(state.travelled_m(t, [sender])[0])
                pairs = pairs._replace(travel_m=travel)
            return self.receivable(pairs)
        m = self.occupancy
        if m is not None:
            flat, h, w = m.occupied.ravel(), m.shape[0], m.shape[1]
            ox, oy, res = float(m.origin_m[0]), float(m.origin_m[1]), m.resolution_m
        else:
            flat, h, w, ox, oy, res = _NO_GRID, 1, 1, 0.0, 0.0, 1.0
        out = np.empty(k, dtype=bool)
        if self.range is not None:
            r = np.atleast_1d(self.range.range_m)
            self.k.disk_frame(
                sender, receivers, distances_m, r, self.range.range_m.ndim == 1, self.sight is not None,
                flat, h, w, state.origin_m, state.velocity_mps, state.t0_s, t, ox, oy, res, VERTEX_TOLERANCE_CELLS, out,
            )  # fmt: skip
            return out
        wall_db = self.walls.wall_loss_db if self.walls is not None else 0.0
        if sh is not None:
            keys = np.empty(k, dtype=np.int64)
            s_new = np.empty(k)
            tables = (*sh.table(), sh.dense_n, sh.normals(k))
        else:
            keys, s_new = _NO_KEYS, _NO_FLOATS
            tables = (_NO_KEYS, _NO_FLOATS, _NO_FLOATS, 0, _NO_FLOATS)
        x_new = np.empty(k)
        new = np.empty(k, dtype=bool)
        count = self.k.log_frame(
            sender, receivers, distances_m, state.odometer_m, speed_mps, state.t0_s, t, *self._frame_constants,
            *tables, wall_db, flat, h, w, state.origin_m, state.velocity_mps, ox, oy, res, VERTEX_TOLERANCE_CELLS,
            keys, s_new, x_new, new, out,
        )  # fmt: skip
        if sh is not None:
            sh.consume(count)
            if not sh.dense and new.any():
                self._insert_new(keys, x_new, s_new, new)
        return out

    def _pairs(self, state, t: float, sender: int, receivers: np.ndarray, distances_m: np.ndarray) -> Pairs:
        k = len(receivers)
        a = np.full(k, sender, dtype=np.int64)
        if self.occupancy is None:
            return Pairs(a, receivers, None, None, distances_m, None)
        pos_a = np.broadcast_to(state.positions_at(t, [sender]), (k, 2))
        return Pairs(a, receivers, pos_a, state.positions_at(t, receivers), distances_m, None)

    def _receivable(self, pairs: Pairs, keys, s_new) -> np.ndarray:
        kn = len(pairs.a)
        out = np.empty(kn, dtype=bool)
        if kn == 0:
            return out
        flat, h, w, g0, g1 = self._grid(pairs) if (self.walls or self.sight) else (_NO_GRID, 1, 1, None, None)
        if self.range is not None:
            r = np.atleast_1d(self.range.range_m)
            if g0 is None:
                g0 = g1 = np.zeros((kn, 2))
            self.k.disk_pass(
                pairs.distance_m, pairs.a, r, self.range.range_m.ndim == 1,
                self.sight is not None, flat, h, w, g0, g1, VERTEX_TOLERANCE_CELLS, out,
            )  # fmt: skip
            return out
        p = self.log.params  # type: ignore[union-attr]  # compiled only with a log-distance term
        sh = self.shadow
        clip = sh.clip_db if sh is not None else 0.0
        loss = np.empty(kn)
        alive = np.empty(kn, dtype=bool)
        count = self.k.path_loss_pass(
            pairs.distance_m, p.reference_distance_m, p.reference_loss_db, 10.0 * p.path_loss_exponent,
            -clip, self.budget_slack, loss, alive,
        )  # fmt: skip
        if g0 is None:
            g0 = g1 = _NO_POINTS
        if sh is not None and count:
            z = sh.normals(count)
            sh.consume(count)
            (tk, tx, ts), sigma = sh.table(), sh.sigma_db
        else:
            keys, s_new, z = _NO_KEYS, _NO_FLOATS, _NO_FLOATS
            tk, tx, ts, sigma = np.zeros(0, dtype=np.int64), np.zeros(0), np.zeros(0), 0.0
        x_new = np.empty(kn)
        new = np.empty(kn, dtype=bool)
        wall_db = self.walls.wall_loss_db if self.walls is not None else 0.0
        self.k.budget_pass(
            loss, alive, keys, s_new, z, sigma, sh.decorrelation_m if sh is not None else 1.0, clip,
            tk, tx, ts, wall_db, flat, h, w, g0, g1, VERTEX_TOLERANCE_CELLS, self.budget_slack,
            self.propagation.tx_power_dbm, self.propagation.sensitivity_dbm, x_new, new, out,
            sh.dense_n if sh is not None else 0,
        )  # fmt: skip
        if sh is not None and new.any():
            self._insert_new(keys, x_new, s_new, new)
        return out

    def _insert_new(self, keys, x_new, s_new, new) -> None:
        idx = np.flatnonzero(new)
        uniq, first = np.unique(keys[idx], return_index=True)
        if len(uniq) < len(idx):
            raise ValueError("the pairs of one batch must be distinct")
        self.shadow.insert(uniq, x_new[idx[first]], s_new[idx[first]])  # type: ignore[union-attr]


class GenericChain:
    """``receivable(pairs)`` of any :class:`~netsim.radio.propagation.Propagation`, with
    numpy: the path of a model that brings no compiled one. Every pair carries both
    robots' positions and their travel (what any term may read); the chain is evaluated as
    :meth:`~netsim.radio.propagation.LossChain.receivable` does, pairs dropped as soon as
    they cannot make it."""

    # What the channel and a medium ask of a compiled path: a generic model declares no
    # map, shadowing, walls or path loss of the built-in kinds.
    occupancy = shadow = walls = log = None

    def __init__(self, propagation: Propagation):
        self.propagation = propagation

    def receivable(self, pairs: Pairs) -> np.ndarray:
        return self.propagation.receivable(pairs)

    def transmission(
        self, state, t: float, sender: int, receivers: np.ndarray, distances_m: np.ndarray, speed_mps: np.ndarray
    ) -> np.ndarray:
        """:meth:`receivable` of ``sender``'s frame at ``t`` to ``receivers`` (as
        :meth:`CompiledChain.transmission`)."""
        k = len(receivers)
        a = np.full(k, sender, dtype=np.int64)
        pos_a = np.broadcast_to(state.positions_at(t, [sender]), (k, 2))
        travel = state.travelled_m(t, receivers) + float(state.travelled_m(t, [sender])[0])
        pairs = Pairs(a, receivers, pos_a, state.positions_at(t, receivers), distances_m, travel)
        return self.propagation.receivable(pairs)
