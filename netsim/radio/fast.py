"""The loss chains of :mod:`netsim.radio.propagation` in one pass: the channel's hot path.

A transmission asks which of its few tens of candidate receivers can hear it. Through the
generic chain that costs some fifty numpy operations, whatever the number of pairs; here it
is two loops (:mod:`netsim.radio._kernels`, compiled or plain Python as
:func:`netsim.compiled.load` decides for the run) and one draw of normals.
:class:`CompiledChain` accepts the chains
that :func:`~netsim.radio.propagation.log_distance` and
:func:`~netsim.radio.propagation.unit_disk` build (their ``fast``) and decides exactly as the chain does: the
same pairs are dropped before shadowing (so the same normals are drawn), the same shadowing
updates are made, and the same sums are compared with the sensitivity. Pairs in one batch
must be distinct (a broadcast's receivers are).

A model whose chain has other terms brings no one-pass path
(:attr:`~netsim.radio.propagation.Propagation.fast` is None): :class:`GenericChain`
evaluates it with numpy, term by term.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from netsim._kernels import Motion
from netsim.compiled import load
from netsim.radio._kernels import Decided, PathLoss, Points, Robots, Shadow
from netsim.radio.chain import (
    LineOfSightLoss,
    LogDistanceLoss,
    Pairs,
    RangeLoss,
    ShadowingLoss,
    WallLoss,
)
from netsim.radio.shadowing import pair_keys
from netsim.world.los import VERTEX_TOLERANCE_CELLS

_NO_GRID = np.zeros(1, dtype=bool)
# Stand-ins for the arrays a pass does not read (no walls: no grid points; no shadowing: no
# keys, travels or draws).
_NO_POINTS = np.zeros((1, 2))
_NO_KEYS = np.zeros(1, dtype=np.int64)
_NO_FLOATS = np.zeros(1)
_NO_SHADOW = tuple(Shadow(_NO_KEYS, _NO_FLOATS, _NO_FLOATS, _NO_FLOATS))

# The constants of one run's frames, set once (CompiledChain.frame) and read by name in the
# compiled passes: path loss (log-distance), shadowing, walls, the unit disk, the map grid.
FRAME = np.dtype(
    [
        ("budget_slack", np.float64),  # P_t - sensitivity with the chain's early-drop slack, dB
        ("tx_dbm", np.float64),
        ("sensitivity_dbm", np.float64),
        ("d0_m", np.float64),  # log-distance: reference distance
        ("pl0_db", np.float64),  # log-distance: path loss at d0
        ("n10", np.float64),  # log-distance: 10 n
        ("step_m", np.float64),  # shadowing: the travel step a pair's value is anchored to
        ("clip_db", np.float64),  # shadowing: |X| at most this
        ("sigma_db", np.float64),  # shadowing: 0 without
        ("decorrelation_m", np.float64),
        ("dense_n", np.int64),  # shadowing: robots whose every pair has a slot (0: none)
        ("wall_db", np.float64),  # loss per wall (0: no walls)
        ("per_robot", np.bool_),  # unit disk: one range per robot
        ("use_map", np.bool_),  # unit disk: line of sight on the map
        ("map_h", np.int64),  # the map grid: rows, columns, origin, cell size, vertex tolerance
        ("map_w", np.int64),
        ("map_ox", np.float64),
        ("map_oy", np.float64),
        ("res_m", np.float64),
        ("eps", np.float64),
    ]
)


class CompiledChain:
    """``receivable(pairs)`` of a :class:`~netsim.radio.propagation.Propagation` in one
    pass, for a run of ``n_robots`` robots."""

    def __init__(self, propagation: Any, n_robots: int):
        self.propagation = propagation
        self.k = load("netsim.radio._kernels", n_robots)
        parts = _built_in(propagation.chain)
        if parts is None:
            raise ValueError(f"no compiled form for the chain {[type(t).__name__ for t in propagation.chain.terms]}")
        self.log, self.shadow, self.walls, self.range, self.sight = parts
        budget = propagation.radio.budget_db
        # The chain's own early-drop budget (the same function as LossChain.receivable's).
        self.budget_slack = self.k.with_slack(budget)
        term = self.walls or self.sight
        occupancy = term.occupancy if term is not None else None
        self.occupancy = occupancy
        self.frame = self._frame_record()

    def _frame_record(self) -> np.ndarray:
        """The run's constants that the compiled passes read (:data:`FRAME`), one row."""
        # Read by field name, not a recarray (numba would type it through attribute lookups).
        frame = np.zeros(1, dtype=np.dtype((np.record, FRAME)))
        row = frame[0]
        row["budget_slack"] = self.budget_slack
        row["tx_dbm"] = self.propagation.radio.tx_power_dbm
        row["sensitivity_dbm"] = self.propagation.radio.sensitivity_dbm
        # (Compared with None: a PairShadowing with no pair seen yet is falsy, it has a length.)
        sh = self.shadow
        row["decorrelation_m"] = 1.0 if sh is None else sh.decorrelation_m
        if sh is not None:
            row["step_m"], row["clip_db"], row["sigma_db"] = sh.step_m, sh.clip_db, sh.sigma_db
            row["dense_n"] = sh.dense_n
        if self.log is not None:
            p = self.log.params
            row["d0_m"], row["pl0_db"], row["n10"] = (
                p.reference_distance_m,
                p.reference_loss_db,
                10.0 * p.path_loss_exponent,
            )
        row["wall_db"] = self.walls.wall_loss_db if self.walls is not None else 0.0
        if self.range is not None:
            row["per_robot"] = self.range.range_m.ndim == 1
            row["use_map"] = self.sight is not None
        m = self.occupancy
        row["eps"] = VERTEX_TOLERANCE_CELLS
        row["map_h"], row["map_w"] = (m.shape[0], m.shape[1]) if m is not None else (1, 1)
        if m is not None:
            row["map_ox"], row["map_oy"], row["res_m"] = float(m.origin_m[0]), float(m.origin_m[1]), m.resolution_m
        else:
            row["res_m"] = 1.0
        return frame

    def _grid(self, pairs: Pairs):
        """The map's occupied cells and the pairs' ends in its grid units (:func:`pair_points`)."""
        kn = len(pairs.a)
        g0, g1 = np.empty((kn, 2)), np.empty((kn, 2))
        pos_a = np.ascontiguousarray(pairs.pos_a, dtype=float)
        pos_b = np.ascontiguousarray(pairs.pos_b, dtype=float)
        self.k.pair_points(self.frame, pos_a, pos_b, tuple(Points(g0, g1)))
        return self.occupancy.occupied.ravel(), g0, g1  # type: ignore[union-attr]

    def receivable(self, pairs: Pairs) -> np.ndarray:
        keys = s_new = None
        if self.shadow is not None and len(pairs.a):
            keys = pair_keys(pairs.a, pairs.b, self.shadow.n_robots)
            travel = np.zeros(len(pairs.a)) if pairs.travel_m is None else np.asarray(pairs.travel_m, dtype=float)
            s_new = self.shadow.anchor(travel)
        return self._receivable(pairs, keys, s_new)

    def transmission(self, state, t: float, sender: int, receivers: np.ndarray, distances_m: np.ndarray) -> np.ndarray:
        """:meth:`receivable` of ``sender``'s frame at ``t`` to ``receivers`` (ids, distinct):
        the channel's per-frame call, one kernel call that also finds the robots' positions
        on the map and the pairs' travels (:func:`netsim._kernels.travel`, as
        ``state.travelled_m``)."""
        k = len(receivers)
        sh = self.shadow
        # A torus has no map (config), so the passes never place its robots on a grid; the
        # pairs' travels, the shadowing's clock, do not depend on where the robots are.
        flat = self.occupancy.occupied.ravel() if self.occupancy is not None else _NO_GRID
        out = np.empty(k, dtype=bool)
        if self.range is not None:
            robots = tuple(Motion(state.origin_m, state.velocity_mps, state.t0_s, state.torus, state.side_m))
            r = np.atleast_1d(self.range.range_m)
            self.k.disk_frame(self.frame, t, sender, receivers, distances_m, r, robots, flat, out)
            return out
        if sh is not None:
            keys = np.empty(k, dtype=np.int64)
            s_new = np.empty(k)
            table_keys, table_x, table_s = sh.table()
            shadow = tuple(Shadow(table_keys, table_x, table_s, sh.normals(k)))
        else:
            keys, s_new = _NO_KEYS, _NO_FLOATS
            shadow = _NO_SHADOW
        x_new = np.empty(k)
        new = np.empty(k, dtype=bool)
        robots = tuple(Robots(state.odometer_m, state.speed_mps, state.t0_s, state.origin_m, state.velocity_mps))
        decided = tuple(Decided(keys, s_new, x_new, new, out))
        count = self.k.log_frame(self.frame, t, sender, receivers, distances_m, robots, shadow, flat, decided)
        if sh is not None:
            sh.consume(count)
            if not sh.dense and new.any():
                self._insert_new(keys, x_new, s_new, new)
        return out

    def _receivable(self, pairs: Pairs, keys, s_new) -> np.ndarray:
        kn = len(pairs.a)
        out = np.empty(kn, dtype=bool)
        if kn == 0:
            return out
        flat, g0, g1 = self._grid(pairs) if self.occupancy is not None else (_NO_GRID, None, None)
        if self.range is not None:
            r = np.atleast_1d(self.range.range_m)
            if g0 is None or g1 is None:
                g0 = g1 = np.zeros((kn, 2))
            self.k.disk_pass(self.frame, pairs.distance_m, pairs.a, r, flat, tuple(Points(g0, g1)), out)
            return out
        sh = self.shadow
        loss = np.empty(kn)
        alive = np.empty(kn, dtype=bool)
        count = self.k.path_loss_pass(self.frame, pairs.distance_m, loss, alive)
        if g0 is None or g1 is None:
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
        columns = tuple(Decided(keys, s_new, x_new, new, out))
        path, shadow = tuple(PathLoss(loss, alive)), tuple(Shadow(tk, tx, ts, z))
        self.k.budget_pass(self.frame, sigma, path, shadow, flat, tuple(Points(g0, g1)), columns)
        if sh is not None and new.any():
            self._insert_new(keys, x_new, s_new, new)
        return out

    def _insert_new(self, keys, x_new, s_new, new) -> None:
        idx = np.flatnonzero(new)
        uniq, first = np.unique(keys[idx], return_index=True)
        if len(uniq) < len(idx):
            raise ValueError("the pairs of one batch must be distinct")
        self.shadow.insert(uniq, x_new[idx[first]], s_new[idx[first]])  # type: ignore[union-attr]


def _built_in(chain) -> tuple | None:
    """The built-in terms of a chain that has a compiled form, ``(log, shadowing, walls,
    range, sight)`` (None where absent): log-distance, then shadowing, then walls; or the
    unit disk, then line of sight. None: the chain has other terms (a subclass of a built-in
    term is one: its ``loss_db`` is its own law), or another order."""
    terms = list(chain.terms)
    log = shadow = walls = disk = sight = None
    # The classes themselves: a subclass may bring a law of its own, which only the chain
    # term by term evaluates.
    if terms and type(terms[0]) is LogDistanceLoss:
        log = terms.pop(0)
        if terms and type(terms[0]) is ShadowingLoss:
            shadow = terms.pop(0).shadowing
        if terms and type(terms[0]) is WallLoss:
            walls = terms.pop(0)
    elif terms and type(terms[0]) is RangeLoss:
        disk = terms.pop(0)
        if terms and type(terms[0]) is LineOfSightLoss:
            sight = terms.pop(0)
    if terms or (log is None and disk is None):
        return None
    return log, shadow, walls, disk, sight


def one_pass(propagation: Any):
    """The one-pass path a run's channel takes for a propagation (:class:`~netsim.radio.reception.Reception`):
    its own (``fast``), or :class:`CompiledChain` when its chain is made of built-in terms
    (whoever built it), so that a run never decides a built-in rule in numpy; None: a
    model's own terms (:class:`GenericChain`)."""
    if propagation.fast is not None:
        return propagation.fast
    return CompiledChain if _built_in(propagation.chain) is not None else None


class GenericChain:
    """``receivable(pairs)`` of a :class:`~netsim.radio.propagation.Propagation` with a
    model's own terms, with numpy: the path of a model that brings no compiled one. Every pair carries both
    robots' positions and their travel (what any term may read); the chain is evaluated as
    :meth:`~netsim.radio.propagation.LossChain.receivable` does, pairs dropped as soon as
    they cannot make it."""

    # What the channel and a medium ask of a compiled path: a generic model declares no
    # map, shadowing, walls or path loss of the built-in kinds.
    occupancy = shadow = walls = log = None

    def __init__(self, propagation: Any):
        self.propagation = propagation

    def receivable(self, pairs: Pairs) -> np.ndarray:
        return self.propagation.receivable(pairs)

    def transmission(self, state, t: float, sender: int, receivers: np.ndarray, distances_m: np.ndarray) -> np.ndarray:
        """:meth:`receivable` of ``sender``'s frame at ``t`` to ``receivers`` (as
        :meth:`CompiledChain.transmission`)."""
        k = len(receivers)
        a = np.full(k, sender, dtype=np.int64)
        pos_a = np.broadcast_to(state.positions_at(t, [sender]), (k, 2))
        travel = state.pair_travelled_m(t, a, receivers)
        pairs = Pairs(a, receivers, pos_a, state.positions_at(t, receivers), distances_m, travel, state.n)
        return self.propagation.receivable(pairs)
